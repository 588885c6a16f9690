"""Step 1: drive one car alone along a route with libsumo and record its poses.

The car drives at a constant cruise speed, ignoring every rule (speed mode 0, no lane
changes), in SUMO steps short enough that its poses are at most SPACING apart, from a
start given as the front bumper's distance before the stop line (the fork's limit line,
service.core.network.forks: the lane's end, or before a short fork between two nodes of
one light, the end of the lane before it). Poses are rectangle centres: SUMO reports the
front-bumper centre and the heading (degrees clockwise from north), so the centre lies
half a car length behind along the heading. Where the fork or the exit lane is short, the
drive continues along the straightest upstream and downstream lanes; it never re-enters
the junction.
"""

from __future__ import annotations

import bisect
import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from shapely.geometry import LineString
from shapely.geometry import Point as ShapelyPoint

from service.core.budget import WarmWorker
from service.core.errors import InvalidInput, InvalidTestCase, SimulationFailed
from service.core.network import Intersection, Route, parsed_network
from service.core.network.lanes import (
    approach_polyline,
    is_internal,
    straightest_predecessor,
    straightest_successor,
    via_chain,
)
from service.core.sumo.run import centre_to_front as centre_to_front
from service.core.sumo.run import front_to_centre as front_to_centre

Point = tuple[float, float]

DRIVE_BUDGET = 60.0  # seconds for one batch of drives
SPACING = 0.1  # metres at most between two poses of a drive: a pose between two is
# interpolated (straight between them), and where a lane turns, SUMO's own poses do not
CLEARANCE = 1.0  # metres the back must be past the exit lane's start to count as left


@dataclass(frozen=True)
class PoseSample:
    """One time step of a car: rectangle centre, heading, speed and distance travelled."""

    t: float
    x: float
    y: float
    heading: float
    speed: float
    distance: float


@dataclass(frozen=True)
class DrivePlan:
    """Everything the SUMO process needs to drive one car; plain data, picklable."""

    network_file: str
    edges: tuple[str, ...]
    depart_lane: int
    depart_pos: float
    speed: float
    length: float
    width: float
    timestep: float
    steps: int  # at least this many SUMO steps after the first sample (covers the duration)
    leave_distance: float  # SUMO odometer reading at which the back has left the junction
    connecting_lanes: tuple[str, ...]  # internal lanes the car must drive through
    arrival_lane: int = 0  # the index of the last lane of the drive: SUMO picks, where a
    # lane leads on to several lanes of the next road, the one that leads to it
    skip: float = 0.0  # metres driven before the start (the start lies on internal lanes)
    start_on: tuple[str, float] | None = None  # that internal lane and the front's position
    road: float = math.inf  # metres from the start to the end of its last lane (SUMO
    # removes the car when its front gets there)
    reach: float = 0.0  # metres from the start the drive covers at least, where the road
    # goes that far (the farthest the car may travel in the test-case)


@dataclass(frozen=True)
class PoseTrack:
    """Poses of one car along one route, with a lookup of the pose at a distance."""

    route: str
    length: float
    width: float
    start_distance: float  # front bumper before the stop line at the first sample
    samples: tuple[PoseSample, ...]
    road: float = math.inf  # metres from the start to the end of the road: there the car
    # leaves the map (SUMO removes it), and its trajectory ends

    @functools.cached_property
    def _distances(self) -> list[float]:
        return [s.distance for s in self.samples]

    def at_time_steps(self, timestep: float) -> list[PoseSample]:
        """The samples at every ``timestep`` (a drive records several in each: SPACING)."""
        return [s for s in self.samples if abs(s.t / timestep - round(s.t / timestep)) < 1e-6]

    def pose_at(self, distance: float) -> tuple[float, float, float]:
        """(x, y, heading) at ``distance`` travelled, interpolated between samples. Beyond
        the last sample straight on along the last heading (a drive covers the farthest a
        car can travel, so only float noise at the end of the road gets there)."""
        distances = self._distances
        if distance <= distances[0]:
            first = self.samples[0]
            return first.x, first.y, first.heading
        if distance >= distances[-1]:
            last = self.samples[-1]
            beyond, heading = distance - last.distance, math.radians(last.heading)
            x = last.x + math.sin(heading) * beyond
            y = last.y + math.cos(heading) * beyond
            return x, y, last.heading
        k = bisect.bisect_right(distances, distance) - 1
        a, b = self.samples[k], self.samples[k + 1]
        share = (distance - a.distance) / (b.distance - a.distance)
        return (
            a.x + share * (b.x - a.x),
            a.y + share * (b.y - a.y),
            interpolate_heading(a.heading, b.heading, share),
        )


def interpolate_heading(a: float, b: float, share: float) -> float:
    """Heading between ``a`` and ``b`` (degrees) the short way round."""
    delta = (b - a + 180.0) % 360.0 - 180.0
    heading = (a + share * delta) % 360.0
    return 0.0 if heading >= 360.0 else heading  # -1e-15 % 360.0 is 360.0 in floats


def plan_drive(
    intersection: Intersection,
    route: Route,
    start_distance: float,
    speed: float,
    duration: float,
    timestep: float,
    length: float = 5.0,
    width: float = 1.8,
    reach: float = 0.0,
) -> DrivePlan:
    """The lanes, start and stop condition of a drive; InvalidInput if the start is off-map.
    The drive covers ``duration`` at ``speed``, and at least ``reach`` metres where the road
    goes that far."""
    if start_distance < 0:
        raise InvalidInput(f"start distance must be >= 0 m, got {start_distance:g}")
    if speed <= 0:
        raise InvalidInput(f"cruise speed must be > 0 m/s, got {speed:g}")
    path = intersection.network_file
    net = parsed_network(path)
    junction = intersection.junction
    fork_lane = net.getLane(route.fork)
    connection = next(c for c in fork_lane.getOutgoing() if c.getToLane().getID() == route.exit)
    offset = intersection.forks[route.fork].limit_offset
    to_end = start_distance + offset  # metres from the front to the fork's end
    lanes, behind, upstream = _walk_upstream(net, fork_lane, junction, to_end)
    if behind < to_end:
        raise InvalidInput(
            f"start distance {start_distance:g} m is longer than the road before fork "
            f"{route.fork!r} ({behind - offset:.1f} m)",
            route=route.id,
        )
    chain = via_chain(net, connection)
    to_exit = to_end + sum(net.getLane(v).getLength() for v in chain)
    ahead = to_exit + connection.getToLane().getLength()
    lanes.append(connection.getToLane())
    leave = to_exit + length + CLEARANCE
    # on far enough for the whole drive, and at least until the car has left the junction
    # (a far start covers the drive's length before the junction: short exit lanes still
    # need the lanes after them)
    needed = max(speed * (duration + timestep) + 2 * length, leave, reach + 2 * length)
    while ahead < needed:
        outgoing = straightest_successor(net, lanes[-1], junction)
        if outgoing is None:
            break
        ahead += sum(net.getLane(v).getLength() for v in via_chain(net, outgoing))
        lanes.append(outgoing.getToLane())
        ahead += lanes[-1].getLength()
    depart_pos = behind - to_end
    # SUMO cannot insert a car on an internal lane: when the start lies inside a junction
    # upstream, depart just before it and drop the extra metres afterwards.
    skip = max(0.0, depart_pos - (lanes[0].getLength() - 0.01))
    start_on = None
    if skip and upstream:
        start_on = _internal_start(net, upstream, depart_pos - lanes[0].getLength())
    elif skip:  # within a centimetre of the line on the fork: moved there from 1 cm before
        start_on = (lanes[0].getID(), depart_pos)
    depart_pos -= skip
    if ahead < leave:
        raise InvalidInput(
            f"the road after exit {route.exit!r} ends {ahead - to_exit:.1f} m after the junction, "
            f"too short for a {length:g} m car to leave it",
            route=route.id,
        )
    return DrivePlan(
        network_file=str(path),
        edges=tuple(lane.getEdge().getID() for lane in lanes),
        depart_lane=lanes[0].getIndex(),
        arrival_lane=lanes[-1].getIndex(),
        depart_pos=depart_pos,
        speed=speed,
        length=length,
        width=width,
        timestep=timestep,
        steps=max(
            math.ceil(duration / timestep - 1e-9), math.ceil(reach / (speed * timestep) - 1e-9)
        )
        + math.ceil(skip / (speed * timestep)),
        leave_distance=leave + skip,
        road=ahead,
        reach=reach,
        connecting_lanes=tuple(chain),
        skip=skip,
        start_on=start_on,
    )


def route_end(
    intersection: Intersection, route: Route, edges: Sequence[str], beyond: float
) -> tuple[tuple[str, ...], float] | None:
    """Where a car driving ``edges`` (a plan's, along ``route``) has its front ``beyond``
    metres past the start of the route's exit lane, counted along its lanes as SUMO drives
    them: the edges up to there and the position on the last one (SUMO's ``arrivalPos``:
    SUMO removes the car there, as at the end of any route). A point inside a junction
    further on moves to the start of the edge after it. None when the edges end first
    (SUMO removes the car at the end of the road)."""
    net = parsed_network(intersection.network_file)
    lane = net.getLane(route.exit)
    fork_edge = net.getLane(route.fork).getEdge().getID()
    index = list(edges).index(lane.getEdge().getID(), list(edges).index(fork_edge) + 1)
    left = beyond
    while lane.getLength() < left:
        left -= lane.getLength()
        onward = straightest_successor(net, lane, intersection.junction)
        if onward is None or index + 1 >= len(edges):
            return None
        if onward.getToLane().getEdge().getID() != edges[index + 1]:
            return None  # not the plan's road (plan_drive walks the same way)
        left -= sum(net.getLane(v).getLength() for v in via_chain(net, onward))
        lane, index = onward.getToLane(), index + 1
    return tuple(edges[: index + 1]), max(left, 0.0)


def start_speed_limit(intersection: Intersection, plan: DrivePlan) -> float:
    """The speed limit of the lane a drive departs on (m/s)."""
    lane = f"{plan.edges[0]}_{plan.depart_lane}"
    return float(parsed_network(intersection.network_file).getLane(lane).getSpeed())


def check_start_speed(intersection: Intersection, plan: DrivePlan, speed: float) -> None:
    """InvalidTestCase when a car under SUMO's limits (the ego) starts faster than the
    speed limit of the lane it departs on: SUMO would refuse to insert it."""
    limit = start_speed_limit(intersection, plan)
    if speed > limit + 1e-6:
        lane = f"{plan.edges[0]}_{plan.depart_lane}"
        raise InvalidTestCase(
            f"ego start speed {speed:g} m/s is above the speed limit of lane {lane!r} where "
            f"it starts ({limit:g} m/s); SUMO inserts no car faster than its lane allows: "
            f"give a start speed of at most {limit:g} m/s"
        )


def _walk_upstream(
    net: Any, fork_lane: Any, junction: str, distance: float
) -> tuple[list[Any], float, list[str]]:
    """The lanes a start ``distance`` before the fork's end needs, up to the fork, along
    the straightest predecessors (as far as the road goes): the lanes, the metres from the
    first lane's start to the fork's end, and the internal lanes between the first lane
    and the next."""
    lanes = [fork_lane]
    behind = fork_lane.getLength()
    upstream: list[str] = []
    while behind < distance:
        incoming = straightest_predecessor(net, lanes[0], junction)
        if incoming is None:
            break
        upstream = via_chain(net, incoming)
        behind += sum(net.getLane(v).getLength() for v in upstream)
        lanes.insert(0, incoming.getFromLane())
        behind += lanes[0].getLength()
    return lanes, behind, upstream


def longest_start(intersection: Intersection, route: Route, up_to: float) -> float:
    """The longest start distance up to ``up_to`` that lies on the road before the fork:
    ``up_to`` when the road is that long, else the whole road (to the centimetre below),
    measured as SUMO drives it (lane lengths) and as the start is placed (the shape)."""
    path = intersection.network_file
    net = parsed_network(path)
    offset = intersection.forks[route.fork].limit_offset
    fork_lane = net.getLane(route.fork)
    _, behind, _ = _walk_upstream(net, fork_lane, intersection.junction, up_to + offset)
    road = min(behind, _approach_line(intersection, route, up_to + offset + 1.0).length) - offset
    return up_to if road >= up_to else min(math.floor(road * 100.0) / 100.0, road)


def _internal_start(net: Any, lanes: list[str], into: float) -> tuple[str, float]:
    """The internal lane ``into`` metres along ``lanes`` and the position on it."""
    for lane in lanes:
        length = net.getLane(lane).getLength()
        if into <= length or lane == lanes[-1]:
            return lane, min(max(into, 0.0), length)
        into -= length
    raise AssertionError("a start inside a junction needs its internal lanes")


def _approach_line(intersection: Intersection, route: Route, length: float) -> LineString:
    path = intersection.network_file
    net = parsed_network(path)
    return LineString(
        approach_polyline(net, net.getLane(route.fork), intersection.junction, length)
    )


def start_front(intersection: Intersection, route: Route, start_distance: float) -> Point:
    """Where the front bumper stands at the start: ``start_distance`` before the stop line
    (the fork's limit line)."""
    offset = intersection.forks[route.fork].limit_offset
    line = _approach_line(intersection, route, start_distance + offset + 1.0)
    if line.length < start_distance + offset:
        raise InvalidInput(
            f"start distance {start_distance:g} m is longer than the road before fork "
            f"{route.fork!r} ({line.length - offset:.1f} m)",
            route=route.id,
        )
    front = line.interpolate(line.length - offset - start_distance)
    return float(front.x), float(front.y)


def start_distance_of(intersection: Intersection, route: Route, front: Point) -> float:
    """The inverse of ``start_front``: how far before the stop line ``front`` is."""
    line = _approach_line(intersection, route, 1000.0)
    offset = intersection.forks[route.fork].limit_offset
    return max(0.0, float(line.length - offset - line.project(ShapelyPoint(front))))


def drive(plans: list[DrivePlan]) -> list[list[PoseSample]]:
    """Drive each plan in libsumo, one simulation after another, in this process."""
    import libsumo  # only here: libsumo is a per-process singleton

    return [_drive_one(libsumo, plan) for plan in plans]


def substeps(plan: DrivePlan) -> int:
    """SUMO steps per time step of a drive, so that its samples are at most SPACING apart:
    a divisor of the time step in milliseconds (SUMO's steps are whole milliseconds)."""
    needed = max(1, math.ceil(plan.speed * plan.timestep / SPACING - 1e-9))
    milliseconds = max(1, round(plan.timestep * 1000))
    return next((k for k in range(needed, milliseconds) if milliseconds % k == 0), milliseconds)


def _drive_one(traci: Any, plan: DrivePlan) -> list[PoseSample]:
    traci.start([
        "sumo", "-n", plan.network_file, "--step-length", repr(plan.timestep / substeps(plan)),
        "--no-step-log", "true", "--no-warnings", "true", "--time-to-teleport", "-1",
        "--collision.action", "none", "--ignore-route-errors", "false",
    ])  # fmt: skip
    try:
        traci.vehicletype.copy("DEFAULT_VEHTYPE", "car")
        traci.vehicletype.setLength("car", plan.length)
        traci.vehicletype.setWidth("car", plan.width)
        traci.vehicletype.setMinGap("car", 0.0)
        traci.route.add("route", list(plan.edges))
        traci.vehicle.add(
            "car", "route", typeID="car", depart="0", departLane=str(plan.depart_lane),
            departPos=repr(plan.depart_pos), departSpeed="0", arrivalLane=str(plan.arrival_lane),
        )  # fmt: skip
        traci.vehicle.setSpeedMode("car", 0)
        traci.vehicle.setLaneChangeMode("car", 0)
        return _record(traci, plan)
    except traci.TraCIException as exc:
        raise SimulationFailed(f"SUMO refused the drive: {exc}") from exc
    finally:
        traci.close()


def _record(traci: Any, plan: DrivePlan) -> list[PoseSample]:
    samples: list[PoseSample] = []
    visited: list[str] = []
    step = 0
    each = substeps(plan)
    dt = plan.timestep / each
    while True:
        traci.simulationStep()
        if "car" not in traci.vehicle.getIDList():
            break
        if step == 0:
            # Departing at speed would fail SUMO's insertion checks before slow curves; the
            # speed set here holds from the first step on (speed mode 0 has no acceleration
            # limit), so the car covers speed * timestep in every step.
            traci.vehicle.setSpeed("car", plan.speed)
        lane = traci.vehicle.getLaneID("car")
        if is_internal(lane) and (not visited or visited[-1] != lane):
            visited.append(lane)
        heading = traci.vehicle.getAngle("car") % 360.0
        fx, fy = traci.vehicle.getPosition("car")
        x, y = front_to_centre(fx, fy, heading, plan.length)
        distance = traci.vehicle.getDistance("car")
        speed = plan.speed if step == 0 else traci.vehicle.getSpeed("car")
        samples.append(PoseSample(step * dt, x, y, heading, speed, distance))
        if step >= plan.steps * each and distance >= plan.leave_distance:
            break
        step += 1
    if not samples or samples[-1].distance < plan.leave_distance:
        raise SimulationFailed("the car left the simulation before it left the junction")
    if not set(plan.connecting_lanes) <= set(visited):
        raise SimulationFailed(
            f"SUMO drove through {visited} instead of the connecting lane "
            f"{list(plan.connecting_lanes)}"
        )
    return _drop_skipped(samples, plan) if plan.skip > 0 else samples


def _drop_skipped(raw: list[PoseSample], plan: DrivePlan) -> list[PoseSample]:
    """Resample a drive that started ``plan.skip`` metres early so that it starts on time."""
    shifted = PoseTrack("", plan.length, plan.width, 0.0, tuple(raw))
    samples = []
    dt = plan.timestep / substeps(plan)
    step = plan.speed * dt
    for k in range(math.floor((raw[-1].distance - plan.skip) / step + 1e-9) + 1):
        distance = k * step
        x, y, heading = shifted.pose_at(distance + plan.skip)
        samples.append(PoseSample(k * dt, x, y, heading, plan.speed, distance))
    return samples


DRIVER = WarmWorker()  # one warm SUMO process per process: libsumo loads once
# Drives are deterministic: keep them, by plan and the network file's modification time.
DRIVEN: dict[tuple[DrivePlan, int], tuple[PoseSample, ...]] = {}
DRIVEN_KEPT = 256


def generate_poses(
    intersection: Intersection,
    requests: list[tuple[Route, float]],
    speed: float,
    duration: float,
    timestep: float,
    length: float = 5.0,
    width: float = 1.8,
    budget: float = DRIVE_BUDGET,
    reach: float = 0.0,
) -> list[PoseTrack]:
    """Step 1 for (route, start distance) pairs, in one killable SUMO process; each drive
    goes on for ``duration`` at ``speed`` and at least ``reach`` metres, or to the end of
    the road (the track's ``road``). A drive is a function of its plan (network file,
    lanes, start, speed, steps), so a plan driven before in this process is not driven
    again."""
    plans = [
        plan_drive(intersection, route, start, speed, duration, timestep, length, width, reach)
        for route, start in requests
    ]
    version = intersection.network_file.stat().st_mtime_ns
    missing = list(dict.fromkeys(plan for plan in plans if (plan, version) not in DRIVEN))
    if missing:
        driven = DRIVER.call(drive, (missing,), budget, "the SUMO drive (Step 1)")
        for plan, samples in zip(missing, driven, strict=True):
            if len(DRIVEN) >= DRIVEN_KEPT:
                DRIVEN.pop(next(iter(DRIVEN)))
            DRIVEN[plan, version] = tuple(samples)
    return [
        PoseTrack(route.id, length, width, start, DRIVEN[plan, version], plan.road)
        for (route, start), plan in zip(requests, plans, strict=True)
    ]
