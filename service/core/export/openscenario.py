"""Export a test-case as ASAM OpenSCENARIO XML on an ASAM OpenDRIVE road network.

The folder holds:

- ``testcase.xodr``: the junction's network (the one SUMO runs, with the control override
  applied) written by ``netconvert --opendrive-output``, in SUMO's network coordinates,
  with what scengen adds: stop signs, and at a signalized junction the controller of its
  signal heads (``opendrive``, ``openscenario_signals``).
- ``testcase.xosc``: every non-ego follows its trajectory (``FollowTrajectoryAction`` over
  a time-stamped ``Polyline`` of ``WorldPosition`` vertices, one per time step, absolute
  time, ``followingMode="position"``), placed at its first pose by a ``TeleportAction``;
  the ego (``type = ego_vehicle``, the convention of CARLA's ScenarioRunner) is teleported
  to its start with its start speed and gets its route, and no trajectory: the system
  under test drives it. The scenario stops when the ego has reached its goal (where
  scengen's judgement ends: ``goal_stop``), or at the duration. A signalized test-case's
  program is the RoadNetwork's TrafficSignalController (one TrafficSignalState per head and
  phase), its cycle starting where SUMO's stands at t = 0, so that it shows SUMO's colour
  at every moment (``openscenario_signals``: the offset, the heads, the colour words).
- ``testcase.solvability.xosc`` and ``testcase.complexity.xosc`` (when the test-case has
  certificates): the same scenario with the ego following that certificate.
- ``verdict-rules.md``: the pass-fail criteria that scengen applies (OpenSCENARIO cannot
  state right-of-way criteria); at a signalized junction also the program, which head is
  which route, the colour words and the signal rules (``verdict_rules``).

Conventions: a vehicle's reference point is the centre of its footprint (its bounding box
is centred on it), where scengen's samples are; heading h = radians(90 - SUMO angle), SUMO's
angle being degrees clockwise from north and OpenSCENARIO's heading radians counter-clockwise
from the x axis.

The CARLA flavour (``flavour="carla"``) writes OpenSCENARIO 1.0 (what ScenarioRunner reads),
one vertex every 0.05 s (CARLA's 20 Hz), and names the CARLA town as the road network when
the test-case's network is one (ScenarioRunner loads the town by name, not the file).
Its signal states name no red-yellow (CARLA's lights have none: ``u`` is ``red``).
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from pathlib import Path

from scenariogeneration import xosc
from shapely.geometry import LineString

from service.core.errors import InvalidInput
from service.core.export import Flavour, check_flavour
from service.core.export.opendrive import CREATED, NAME, opendrive_text
from service.core.export.openscenario_signals import signal_controller
from service.core.export.verdict_rules import RULES_FILE, rules_text
from service.core.files import replacing, write_atomically
from service.core.motion.poses import CLEARANCE, interpolate_heading, start_front
from service.core.network import Intersection, parsed_network
from service.core.network.lanes import departure_polyline
from service.core.sumo.run import front_to_centre
from service.core.testcase import Pedestrian, Sample, TestCase, load_testcase_intersection

CARLA_STEP = 0.05  # s: CARLA's fixed 20 Hz
HEIGHT = 1.5  # m: a car's height (scengen has none)
PEDESTRIAN_HEIGHT = 1.75  # m: an adult's height (scengen has none)
PEDESTRIAN_MASS = 80.0  # kg
CARLA_WALKER = "walker.pedestrian.0001"  # ScenarioRunner's walker for a pedestrian entity


def heading_of(angle: float) -> float:
    """OpenSCENARIO's heading (radians counter-clockwise from the x axis, in [0, 2 pi)) of
    SUMO's angle (degrees clockwise from north)."""
    return math.radians((90.0 - angle) % 360.0)


def angle_of(heading: float) -> float:
    """The inverse of ``heading_of``: SUMO's angle in [0, 360)."""
    return (90.0 - math.degrees(heading)) % 360.0


def _world(x: float, y: float, angle: float) -> xosc.WorldPosition:
    return xosc.WorldPosition(x=round(x, 4), y=round(y, 4), z=0.0, h=round(heading_of(angle), 6))


def _vehicle(testcase: TestCase, name: str, length: float, width: float) -> xosc.Vehicle:
    params = testcase.params
    box = xosc.BoundingBox(width, length, HEIGHT, 0.0, 0.0, HEIGHT / 2)
    axle = 0.3 * length  # axles either side of the footprint's centre, the reference point
    front = xosc.Axle(0.5, 0.6, width - 0.2, axle, 0.3)
    rear = xosc.Axle(0.0, 0.6, width - 0.2, -axle, 0.3)
    return xosc.Vehicle(
        name, xosc.VehicleCategory.car, box, front, rear,
        params.v_max, params.a_max, -params.a_min,
    )  # fmt: skip


def _pedestrian(person: Pedestrian, flavour: Flavour) -> xosc.Pedestrian:
    """A person on foot as a Pedestrian entity: the bounding box of its rectangle centred
    on the reference point, as a car's; CARLA's flavour names the walker ScenarioRunner
    spawns (OpenSCENARIO 1.0 requires a model), the ASAM one leaves the model to the
    player."""
    box = xosc.BoundingBox(
        person.width, person.length, PEDESTRIAN_HEIGHT, 0.0, 0.0, PEDESTRIAN_HEIGHT / 2
    )
    model = CARLA_WALKER if flavour == "carla" else None
    entity = xosc.Pedestrian(
        person.id, PEDESTRIAN_MASS, xosc.PedestrianCategory.pedestrian, box, model
    )
    entity.add_property("scengen_walk", person.walk)
    return entity


def _resampled(samples: Sequence[Sample], step: float | None) -> list[Sample]:
    """``samples`` at every ``step`` seconds from the first (linear in position and speed,
    heading the short way round); all of them when ``step`` is None."""
    if step is None:
        return list(samples)
    out, k, j = [], 0, 0
    end = samples[-1].t
    while (t := samples[0].t + k * step) <= end + 1e-9:
        while j + 1 < len(samples) - 1 and samples[j + 1].t <= t:
            j += 1
        a, b = samples[j], samples[min(j + 1, len(samples) - 1)]
        share = 0.0 if b.t == a.t else min(1.0, max(0.0, (t - a.t) / (b.t - a.t)))
        out.append(
            Sample(
                t=round(t, 6),
                x=a.x + share * (b.x - a.x),
                y=a.y + share * (b.y - a.y),
                heading=interpolate_heading(a.heading, b.heading, share),
                speed=a.speed + share * (b.speed - a.speed),
                distance=a.distance + share * (b.distance - a.distance),
            )
        )
        k += 1
    return out


def _follow(name: str, samples: Sequence[Sample], step: float | None, minor: int) -> xosc.Event:
    """An event that makes its actor follow ``samples`` from simulation time 0."""
    vertices = _resampled(samples, step)
    polyline = xosc.Polyline(
        [round(s.t, 6) for s in vertices], [_world(s.x, s.y, s.heading) for s in vertices]
    )
    trajectory = xosc.Trajectory(f"{name}_trajectory", False)
    trajectory.add_shape(polyline)
    action = xosc.FollowTrajectoryAction(
        trajectory, xosc.FollowingMode.position, xosc.ReferenceContext.absolute, 1, 0
    )
    priority = xosc.Priority.override if minor >= 2 else xosc.Priority.overwrite
    event = xosc.Event(f"{name}_follows", priority)
    event.add_action(f"{name}_follow_trajectory", action)
    event.add_trigger(_starts_now(f"{name}_at_the_start", minor))
    return event


def _leave(name: str, end: float, where: str = "road") -> xosc.Event:
    """An event that removes its actor when its trajectory ends: it reached the end of its
    road (a pedestrian: of its walk) and left the map there (as SUMO removes it)."""
    event = xosc.Event(f"{name}_leaves", xosc.Priority.parallel)
    event.add_action(f"{name}_leaves_the_map", xosc.DeleteEntityAction(name))
    event.add_trigger(
        xosc.ValueTrigger(
            f"{name}_at_the_end_of_its_{where}", 0, xosc.ConditionEdge.none,
            xosc.SimulationTimeCondition(round(end, 6), xosc.Rule.greaterThan),
        )
    )  # fmt: skip
    return event


def _starts_now(name: str, minor: int) -> xosc.ValueTrigger:
    rule = xosc.Rule.greaterOrEqual if minor >= 2 else xosc.Rule.greaterThan
    return xosc.ValueTrigger(
        name, 0, xosc.ConditionEdge.none, xosc.SimulationTimeCondition(0, rule)
    )


def _ego_start(testcase: TestCase, intersection: Intersection) -> tuple[float, float, float]:
    """The ego's start pose (centre x, y and SUMO angle): the front bumper at its start
    distance before the line, where the checker expects it (``start_front``); the heading,
    as SUMO's, from the rear bumper to the front one along the road (the chord on a curve),
    or the fork's approach heading where the road behind is shorter than the car."""
    ego = testcase.ego
    route = intersection.route(ego.route.id)
    front = start_front(intersection, route, ego.start.distance)
    try:
        rear = start_front(intersection, route, ego.start.distance + ego.length)
    except InvalidInput:
        angle = intersection.forks[route.fork].heading
    else:
        angle = math.degrees(math.atan2(front[0] - rear[0], front[1] - rear[1])) % 360.0
    x, y = front_to_centre(*front, angle, ego.length)
    return x, y, angle


def _ego_route(
    testcase: TestCase, intersection: Intersection, start: xosc.WorldPosition
) -> xosc.Route:
    """The ego's route from its start through the junction to the end of its exit lane."""
    path = intersection.network_file
    net = parsed_network(path)
    exit_lane = net.getLane(intersection.route(testcase.ego.route.id).exit)
    shape = LineString(exit_lane.getShape())
    end, before = shape.coords[-1], shape.interpolate(max(0.0, shape.length - 1.0))
    angle = math.degrees(math.atan2(end[0] - before.x, end[1] - before.y)) % 360.0
    route = xosc.Route(f"ego_route_{testcase.ego.route.id.replace(':', '_to_')}", False)
    route.add_waypoint(start, xosc.RouteStrategy.shortest)
    route.add_waypoint(_world(end[0], end[1], angle), xosc.RouteStrategy.shortest)
    return route


def goal_stop(testcase: TestCase, intersection: Intersection, minor: int) -> xosc.ConditionGroup:
    """The run stops once the ego has reached its goal, where scengen's judgement ends, as
    the replay's ego leaves there (service.core.sim.replay.goal_end): its reference point
    (the centre of its footprint) within half its exit lane's width of a point on the road
    after the junction, that point placed so that the earliest it comes within is with the
    ego's rear Step 1's CLEARANCE past the start of its exit lane. ASAM's 1.2 says it
    with a DistanceCondition, CARLA's 1.0 with a ReachPositionCondition."""
    net = parsed_network(intersection.network_file)
    exit_lane = net.getLane(intersection.route(testcase.ego.route.id).exit)
    tolerance = exit_lane.getWidth() / 2.0
    along = testcase.ego.length / 2.0 + CLEARANCE + tolerance
    road = LineString(departure_polyline(net, exit_lane, intersection.junction, along + 1.0))
    point, before = road.interpolate(along), road.interpolate(max(0.0, along - 1.0))
    angle = math.degrees(math.atan2(point.x - before.x, point.y - before.y)) % 360.0
    position = _world(point.x, point.y, angle)
    condition: xosc.DistanceCondition | xosc.ReachPositionCondition
    if minor >= 2:
        condition = xosc.DistanceCondition(
            tolerance, xosc.Rule.lessOrEqual, position, alongroute=False, freespace=False,
            distance_type=xosc.RelativeDistanceType.euclidianDistance,
            coordinate_system=xosc.CoordinateSystem.entity,
        )  # fmt: skip
    else:
        condition = xosc.ReachPositionCondition(position, tolerance)
    group = xosc.ConditionGroup("stop")
    group.add_condition(
        xosc.EntityTrigger("ego_reached_its_goal", 0, xosc.ConditionEdge.none, condition, "ego")
    )
    return group


def _network_file(testcase: TestCase, flavour: str) -> str:
    town = re.match(r"Town\d+(?:HD)?(?:_Opt)?(?![A-Za-z0-9])", Path(testcase.network.ref).name)
    if flavour == "carla" and town:  # Town05.net.xml, an upload Town05-1a2b...
        return town.group(0)  # ScenarioRunner loads CARLA's map by its name
    return f"{NAME}.xodr"


def _road_network(
    testcase: TestCase, intersection: Intersection, flavour: Flavour
) -> xosc.RoadNetwork:
    """The network file, and the traffic light's program where the test-case has one."""
    network = xosc.RoadNetwork(_network_file(testcase, flavour))
    if testcase.signals is not None:
        program = testcase.signals.to_program()
        network.add_traffic_signal_controller(signal_controller(program, intersection, flavour))
    return network


def scenario(
    testcase: TestCase,
    intersection: Intersection,
    flavour: str = "asam",
    certificate: str | None = None,
) -> xosc.Scenario:
    """The test-case as an OpenSCENARIO scenario; with ``certificate`` ("solvability" or
    "complexity"), the ego follows that certificate instead of being left to the system
    under test."""
    known = check_flavour(flavour)
    minor = 0 if flavour == "carla" else 2
    step = CARLA_STEP if flavour == "carla" else None
    entities = xosc.Entities()
    init = xosc.Init()
    ego = testcase.ego
    ego_vehicle = _vehicle(testcase, "ego_vehicle", ego.length, ego.width)
    if certificate is None:
        ego_vehicle.add_property("type", "ego_vehicle")
    else:
        ego_vehicle.add_property("scengen_certificate", certificate)
    entities.add_scenario_object("ego", ego_vehicle)
    x, y, angle = _ego_start(testcase, intersection)
    start = _world(x, y, angle)
    init.add_init_action("ego", xosc.TeleportAction(start))
    init.add_init_action(
        "ego",
        xosc.AbsoluteSpeedAction(
            ego.start.speed,
            xosc.TransitionDynamics(xosc.DynamicsShapes.step, xosc.DynamicsDimension.time, 0),
        ),
    )
    init.add_init_action("ego", xosc.AssignRouteAction(_ego_route(testcase, intersection, start)))

    followers: list[tuple[str, Sequence[Sample], str]] = []  # name, samples, what it ends
    for user in testcase.road_users:  # the cars, then the pedestrians
        if isinstance(user, Pedestrian):
            entities.add_scenario_object(user.id, _pedestrian(user, known))
            followers.append((user.id, user.trajectory, "walk"))
        else:
            entities.add_scenario_object(
                user.id, _vehicle(testcase, user.id, user.length, user.width)
            )
            followers.append((user.id, user.trajectory, "road"))
        first = user.trajectory[0]
        init.add_init_action(user.id, xosc.TeleportAction(_world(first.x, first.y, first.heading)))
    if certificate is not None:
        if testcase.certificates is None:
            raise InvalidInput("the test-case has no certificates (an ego-only test-case)")
        followers.append(("ego", getattr(testcase.certificates, certificate), "road"))

    duration = xosc.ConditionGroup("stop")
    duration.add_condition(
        xosc.ValueTrigger(
            "duration_reached", 0, xosc.ConditionEdge.none,
            xosc.SimulationTimeCondition(testcase.duration, xosc.Rule.greaterThan),
        )
    )  # fmt: skip
    stop = xosc.Trigger("stop")  # either: the goal reached, or the duration over
    stop.add_conditiongroup(goal_stop(testcase, intersection, minor))
    stop.add_conditiongroup(duration)
    storyboard = xosc.StoryBoard(init, stop)
    if followers:
        act = xosc.Act("trajectories", _starts_now("at_the_start", minor))
        for name, samples, where in followers:
            maneuver = xosc.Maneuver(f"{name}_maneuver")
            maneuver.add_event(_follow(name, samples, step, minor))
            if samples[-1].t < testcase.duration - testcase.timestep / 2:
                maneuver.add_event(_leave(name, samples[-1].t, where))
            group = xosc.ManeuverGroup(f"{name}_group")
            group.add_actor(name)
            group.add_maneuver(maneuver)
            act.add_maneuver_group(group)
        story = xosc.Story("scengen")
        story.add_act(act)
        storyboard.add_story(story)
    description = f"scengen test-case {testcase.name or testcase.junction}" + (
        f", the ego on its {certificate} certificate" if certificate else ""
    )
    if testcase.pedestrians:
        walks = ", ".join(f"{p.id} on walk {p.walk}" for p in testcase.pedestrians)
        laws = "21950, 21951" + (", 21451, 21453, 21456" if testcase.signals else "")
        description += f"; pedestrians: {walks} (their rules, CVC {laws}: {RULES_FILE})"
    return xosc.Scenario(
        description,
        "scengen",
        xosc.ParameterDeclarations(),
        entities,
        storyboard,
        _road_network(testcase, intersection, known),
        xosc.Catalog(),
        osc_minor_version=minor,
        creation_date=CREATED,
    )


def export_openscenario(
    testcase: TestCase,
    folder: Path,
    intersection: Intersection | None = None,
    flavour: str = "asam",
) -> list[Path]:
    """Write the OpenSCENARIO files of ``testcase`` into ``folder``; the files written."""
    check_flavour(flavour)
    junction = intersection or load_testcase_intersection(testcase)
    folder.mkdir(parents=True, exist_ok=True)
    written = [folder / f"{NAME}.xodr"]
    write_atomically(written[0], opendrive_text(junction))
    variants: list[tuple[str, str | None]] = [(f"{NAME}.xosc", None)]
    if testcase.certificates is not None:
        variants += [(f"{NAME}.{kind}.xosc", kind) for kind in ("solvability", "complexity")]
    for name, certificate in variants:
        with replacing(folder / name) as partial:
            scenario(testcase, junction, flavour, certificate).write_xml(str(partial))
        written.append(folder / name)
    write_atomically(folder / RULES_FILE, rules_text(testcase, junction, flavour))
    written.append(folder / RULES_FILE)
    return written
