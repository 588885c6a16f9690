"""Test helpers: trajectories with chosen speed profiles along Step 1 poses."""

from __future__ import annotations

import dataclasses
import functools
import json
from collections.abc import Callable, Sequence
from pathlib import Path

import shapely
from shapely.geometry import LineString, Point, Polygon

from service.cli.examples import EXAMPLES, run_example
from service.core.generator.additions import candidate_routes
from service.core.generator.extension import extend_testcase
from service.core.motion.poses import PoseSample, PoseTrack
from service.core.network import parsed_network
from service.core.testcase import (
    TestCase,
    dump_testcase,
    load_testcase_intersection,
    new_testcase,
    parse_testcase,
)


def retime(
    track: PoseTrack,
    profile: Callable[[float], tuple[float, float]],
    duration: float,
    timestep: float,
) -> list[PoseSample]:
    """Samples every ``timestep`` where ``profile(t)`` gives (distance, speed) on ``track``."""
    samples = []
    for k in range(round(duration / timestep) + 1):
        t = k * timestep
        distance, speed = profile(t)
        x, y, heading = track.pose_at(distance)
        samples.append(PoseSample(t, x, y, heading, speed, distance))
    return samples


def stop_and_go(
    cruise: float, stop_at: float, brake: float, wait: float, accelerate: float
) -> Callable[[float], tuple[float, float]]:
    """Cruise, brake at ``brake`` m/s^2 to stand at ``stop_at`` m, wait, accelerate back."""
    braking_time = cruise / brake
    braking_from = stop_at - cruise * braking_time / 2.0
    t_brake = braking_from / cruise
    t_stand = t_brake + braking_time
    t_go = t_stand + wait
    t_cruise = t_go + cruise / accelerate

    def profile(t: float) -> tuple[float, float]:
        if t <= t_brake:
            return cruise * t, cruise
        if t <= t_stand:
            s = t - t_brake
            return braking_from + cruise * s - brake * s * s / 2.0, cruise - brake * s
        if t <= t_go:
            return stop_at, 0.0
        if t <= t_cruise:
            s = t - t_go
            return stop_at + accelerate * s * s / 2.0, accelerate * s
        s = t - t_cruise
        return stop_at + cruise * cruise / (2 * accelerate) + cruise * s, cruise

    return profile


def drive_with_stops(
    stops: list[tuple[float, float]],
    cruise: float = 8.0,
    accelerate: float = 2.0,
    brake: float = 3.0,
    start_speed: float | None = None,
    crawl: float | None = None,
    step: float = 0.001,
) -> Callable[[float], tuple[float, float]]:
    """A driver that cruises, brakes to stand at each (distance, wait) of ``stops`` and
    waits there, then goes on (at ``crawl`` at most once it has stopped, if given);
    returns its (distance, speed) at any time."""
    times, distances, speeds = [0.0], [0.0], [cruise if start_speed is None else start_speed]
    limit = cruise
    pending = sorted(stops)
    held = 0.0
    t, d, v = 0.0, 0.0, speeds[0]
    while t < 120.0:
        if pending and d >= pending[0][0] - 1e-3 and v <= 1e-6:
            held += step
            if held >= pending[0][1]:
                pending.pop(0)
                held = 0.0
                limit = crawl or cruise
            v = 0.0
        elif pending and v * v / (2 * brake) >= pending[0][0] - d:
            v = max(0.0, v - brake * step)
        elif v > limit:
            v = max(limit, v - brake * step)
        else:
            v = min(limit, v + accelerate * step)
        if pending:
            d = min(d + v * step, pending[0][0])
        else:
            d += v * step
        t += step
        times.append(t)
        distances.append(d)
        speeds.append(v)

    def profile(at: float) -> tuple[float, float]:
        k = min(round(at / step), len(times) - 1)
        return distances[k], speeds[k]

    return profile


def with_nonegos(
    testcase: TestCase, nonegos: list[tuple[str, str, list[PoseSample]]], **changes: object
) -> TestCase:
    """``testcase`` with non-egos (id, route id, samples) added and fields changed."""
    document = json.loads(dump_testcase(testcase))
    document.update(changes)
    for car_id, route, samples in nonegos:
        fork, exit_lane = route.split(":")
        document["nonegos"].append(
            {
                "id": car_id,
                "route": {"fork": fork, "exit": exit_lane},
                "added_in": 1,
                "trajectory": [dataclasses.asdict(s) for s in samples],
            }
        )
    return parse_testcase(document)


@functools.cache
def car_ahead_of_ego() -> TestCase:
    """The queue of docs/rules.md: on the four-way stop the ego (E2C_0:C2N_0, 30 m out) turns
    right, and the generator adds a car ahead of it on its fork that goes straight on."""
    from service.core.generator.extension import extend_testcase
    from service.core.testcase import new_testcase

    old = new_testcase("4way-stop", "E2C_0:C2N_0", duration=45.0, name="queue")
    return extend_testcase(old, ["E2C_0:C2W_0"], seed=0, budget=120).testcase


def _real_map_chain(network: Path, junction: str, control: str, ego: str) -> list[TestCase]:
    """An ego-only test-case on a CARLA map at the default start, and one extension."""
    start = new_testcase(network, ego, junction=junction, control=control, duration=25.0)
    intersection = load_testcase_intersection(start)
    ego_fork = start.ego.route.fork
    new = next(r for r in candidate_routes(start, intersection)
           if intersection.routes[r].fork != ego_fork)  # fmt: skip
    return [start, extend_testcase(start, [new], seed=0, budget=120).testcase]


def every_exported_case() -> list[TestCase]:
    """Every level of every example, a queue (a new car ahead of the ego at an all-way
    stop), and two real-map chains: Town05's four-arm junction 396 as an all-way stop, and
    Town07's Y 358, whose short fork lanes put the default start inside the junction
    before it. The export tests share them (tests.conftest's exported_cases)."""
    from tests.conftest import TOWN05, TOWN07

    cases = [level for example in EXAMPLES.values() for level in run_example(example)]
    queue = new_testcase("4way-stop", "E2C_0:C2N_0", duration=45.0, name="queue")
    cases.append(extend_testcase(queue, ["E2C_0:C2W_0"], seed=0, budget=120).testcase)
    cases += _real_map_chain(TOWN05, "396", "allway_stop", "-44_1:-9_1")
    cases += _real_map_chain(TOWN07, "358", "right_before_left", "-40_0:35_0")
    return cases


ON_ROAD_TOLERANCE = 1.0  # m beyond a lane's edge: a car's centre cuts a curve's chord


@functools.cache
def _road_area(network_file: Path) -> shapely.Geometry:
    """Every lane of the network (internal ones too) as the area it covers."""
    net = parsed_network(network_file)
    areas = []
    for edge in net.getEdges(withInternal=True):
        for lane in edge.getLanes():
            shape = lane.getShape()
            if len(shape) >= 2 and LineString(shape).length > 0:
                areas.append(LineString(shape).buffer(lane.getWidth() / 2 + ON_ROAD_TOLERANCE))
    return shapely.union_all(areas)


def off_road_samples(
    testcase: TestCase, extra: Sequence[tuple[str, list[PoseSample]]] = ()
) -> list[str]:
    """Every sample of the test-case's non-egos and certificates (and of ``extra``) whose
    centre lies off every lane of the network, as "car at t: (x, y)"."""
    network_file = load_testcase_intersection(testcase).network_file
    area = _road_area(network_file)
    cars: list[tuple[str, Sequence[object]]] = [(n.id, n.trajectory) for n in testcase.nonegos]
    if testcase.certificates is not None:
        cars.append(("complexity", testcase.certificates.complexity))
        cars.append(("solvability", testcase.certificates.solvability))
    cars += list(extra)
    found = []
    for name, samples in cars:
        for sample in samples:
            x, y = float(sample.x), float(sample.y)  # type: ignore[attr-defined]
            if not area.contains(Point(x, y)):
                found.append(f"{name} at {sample.t:g} s: ({x:.1f}, {y:.1f})")  # type: ignore[attr-defined]
    return found


def _walkable_area(network_file: Path) -> shapely.Geometry:
    """Where people may walk: sidewalks (lanes for pedestrians only), walking areas and
    crossings, each as the area it covers."""
    net = parsed_network(network_file)
    areas = []
    for edge in net.getEdges(withInternal=True):
        for lane in edge.getLanes():
            shape = [(x, y) for x, y, *_ in lane.getShape()]
            if edge.getFunction() == "walkingarea" and len(shape) >= 3:
                areas.append(Polygon(shape).buffer(ON_ROAD_TOLERANCE))
            elif lane.allows("pedestrian") and len(shape) >= 2 and LineString(shape).length > 0:
                areas.append(LineString(shape).buffer(lane.getWidth() / 2 + ON_ROAD_TOLERANCE))
    return shapely.union_all(areas)


def off_walkable_samples(testcase: TestCase) -> list[str]:
    """Every sample of the test-case's pedestrians whose centre lies off the sidewalks,
    walking areas and crossings of the network, as "ped at t: (x, y)"."""
    network_file = load_testcase_intersection(testcase).network_file
    area = _walkable_area(network_file)
    return [
        f"{person.id} at {s.t:g} s: ({s.x:.1f}, {s.y:.1f})"
        for person in testcase.pedestrians
        for s in person.trajectory
        if not area.contains(Point(s.x, s.y))
    ]


NEXT_JUNCTION_NODES = """<nodes>
    <node id="C" x="0" y="0" type="allway_stop"/>
    <node id="W" x="-150" y="0" type="dead_end"/>
    <node id="E" x="150" y="0" type="dead_end"/>
    <node id="S" x="0" y="-150" type="dead_end"/>
    <node id="D" x="0" y="80" type="traffic_light"/>
    <node id="DW" x="-150" y="80" type="dead_end"/>
    <node id="DE" x="150" y="80" type="dead_end"/>
    <node id="N" x="0" y="230" type="dead_end"/>
</nodes>
"""
# D's lights stay red: a SUMO driver that drives on to D stands there to the end
NEXT_JUNCTION_LIGHTS = """<additional>
    <tlLogic id="D" type="static" programID="0" offset="0">
        <phase duration="1000" state="rrrrrrrrrrrr"/>
    </tlLogic>
</additional>
"""


def next_junction_network(folder: Path) -> Path:
    """A network with a second junction after the first: the all-way stop C, and 80 m
    north of it the signalized D, whose lights are always red. Single-lane roads; the
    ego's route S2C_0:C2D_0 goes straight on from C towards D."""
    from service.core.network.override import run_netconvert

    pairs = [("S", "C"), ("W", "C"), ("E", "C"), ("C", "D"), ("D", "N"), ("DW", "D"), ("DE", "D")]
    edges = [
        f'    <edge id="{a}2{b}" from="{a}" to="{b}" numLanes="1" speed="13.89" priority="1"/>'
        for one, other in pairs
        for a, b in ((one, other), (other, one))
    ]
    (folder / "next.nod.xml").write_text(NEXT_JUNCTION_NODES)
    (folder / "next.edg.xml").write_text("<edges>\n" + "\n".join(edges) + "\n</edges>\n")
    (folder / "next.tll.xml").write_text(NEXT_JUNCTION_LIGHTS)
    network = folder / "next-junction.net.xml"
    arguments = ["-n", str(folder / "next.nod.xml"), "-e", str(folder / "next.edg.xml"),
                 "-i", str(folder / "next.tll.xml"), "--no-turnarounds", "true",
                 "-o", str(network)]  # fmt: skip
    failed = run_netconvert(arguments, network, "build the two-junction network")
    assert failed is None, failed
    return network


def past_the_next_junction(network: Path) -> TestCase:
    """Level 1 of a chain on ``next_junction_network``: the ego goes straight on from C
    towards D (30 m out, 45 s); car1, generated (seed 0), turns left from the west into
    the ego's exit lane after it and drives on through D's red light as its trajectory
    says. A SUMO driver that drives on to D stands at its light, and car1 runs into it
    there, 17 s after the ego's goal (issue 43's defect 2, the pattern of the sweep)."""
    start = new_testcase(network, "S2C_0:C2D_0", junction="C", duration=45.0, name="next")
    return extend_testcase(start, ["W2C_0:C2D_0"], seed=0, budget=120).testcase
