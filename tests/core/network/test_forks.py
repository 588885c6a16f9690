"""Limit lines: where a fork's cars stop (SUMO's stop line for its link) and enter.

joined-signal (tests/data/junctions): the cluster C (C1 and C2 joined) and the node U
12 m before it share the traffic light J; the fork U2C is 0.2 m long after U, and C's
junction shape reaches 4 m upstream of U's stop line. nuremberg-cluster (tests/data/osm):
the Nuremberg junction of issue 43, the same case as netconvert made it from OpenStreetMap.
The sweep drives SUMO's own driver towards every fork of real and bundled junctions and
checks that it stands still where the model puts the limit line, not yet entered.
"""

from __future__ import annotations

import math
import subprocess
import xml.etree.ElementTree as ET
from collections.abc import Iterable
from pathlib import Path

import numpy as np
import pytest
from shapely.geometry import LineString, Point

from service.core.errors import ScengenError, UnsupportedIntersection
from service.core.motion.events import overlapping, rectangles
from service.core.motion.poses import longest_start, plan_drive
from service.core.network import Fork, Intersection, load_intersection
from service.core.network.load import SUPPORTED, junction_arms, parsed_network
from service.core.sumo.binaries import sumo_binary
from tests.conftest import TOWN05, TOWN07

DATA = Path(__file__).parents[2] / "data"
JOINED = DATA / "junctions" / "joined-signal.net.xml"
NUREMBERG = DATA / "osm" / "nuremberg-cluster.net.xml"
CLUSTER = "cluster_2069369114_250652038_264048471_265360716_3686017348"
LENGTH, WIDTH = 5.0, 1.8  # SUMO's default car
START = 15.0  # metres before the limit line the sweep's cars start (or the whole road)
SUMO_GAP = 1.5  # metres: SUMO's driver stands about 1 m before the line it stops at


@pytest.fixture(scope="module")
def joined() -> Intersection:
    return load_intersection(JOINED, "C")


@pytest.fixture(scope="module")
def nuremberg() -> Intersection:
    return load_intersection(NUREMBERG, CLUSTER)


def car_at(fork: Fork, before: float) -> np.ndarray:
    """The rectangle of a car on ``fork``'s road, its front ``before`` metres before the
    limit line (negative: past it) and its rear LENGTH behind along the road (straight on
    beyond the road's end)."""
    line = fork.approach
    at = line.project(Point(fork.stop_line)) - before
    (fx, fy), (rx, ry) = _along(line, at), _along(line, at - LENGTH)
    heading = math.degrees(math.atan2(fx - rx, fy - ry)) % 360.0
    centre = np.array([(fx + rx) / 2]), np.array([(fy + ry) / 2])
    return rectangles(*centre, np.array([heading]), LENGTH, WIDTH)


def _along(line: LineString, at: float) -> tuple[float, float]:
    if at <= line.length:
        point = line.interpolate(at)
        return point.x, point.y
    (ax, ay), (bx, by) = line.coords[-2], line.coords[-1]
    share = (at - line.length) / math.dist((ax, ay), (bx, by))
    return bx + (bx - ax) * share, by + (by - ay) * share


def entered(fork: Fork, before: float) -> bool:
    return bool(overlapping(car_at(fork, before), fork.entry)[0])


def test_limit_line_before_a_short_fork_between_two_nodes_of_one_light(
    joined: Intersection,
) -> None:
    net = parsed_network(JOINED)
    for lane, upstream, internal, link in (
        ("U2C_0", "S2U_0", ":U_0_0", 14),
        ("U2C_1", "S2U_1", ":U_0_1", 15),
    ):
        fork = joined.forks[lane]
        assert fork.limit_lane == upstream
        assert fork.stop_line == tuple(net.getLane(upstream).getShape()[-1])
        between = net.getLane(internal).getLength() + net.getLane(lane).getLength()
        assert fork.limit_offset == pytest.approx(between, abs=1e-6)
        assert 0 < fork.limit_offset < 5.0
        # every route of the fork shows U's link, the one SUMO's driver obeys at that line
        assert {r.link_index for r in joined.routes.values() if r.fork == lane} == {link}
    for lane, fork in joined.forks.items():
        if not lane.startswith("U2C"):
            assert (fork.limit_lane, fork.limit_offset) == (lane, 0.0)
            assert fork.stop_line == tuple(net.getLane(lane).getShape()[-1])
    own = {r.id: r.link_index for r in joined.routes.values() if not r.fork.startswith("U2C")}
    assert own["N2C_0:C2W_0"] == 0 and own["W2C_0:C2N_1"] == 13


def test_limit_line_of_the_nuremberg_cluster(nuremberg: Intersection) -> None:
    """The ego's fork 248976051#1_2 of issue 43: 0.2 m after node 3686017351, whose link 2
    (light joinedS_1) SUMO's driver stops for, 1.67 m before the fork's end."""
    fork = nuremberg.forks["248976051#1_2"]
    assert (fork.limit_lane, fork.limit_offset) == ("248976051#0_2", pytest.approx(1.67))
    assert nuremberg.route("248976051#1_2:-248976032_0").link_index == 2
    assert nuremberg.forks["248976051#1_0"].limit_lane == "248976051#0_0"
    assert nuremberg.route("248976051#1_0:248976053_0").link_index == 0
    assert nuremberg.forks["248976032_0"].limit_offset == 0.0


@pytest.mark.parametrize(
    ("network", "lane"),
    [("joined", "U2C_0"), ("joined", "U2C_1"), ("nuremberg", "248976051#1_2"),
     ("nuremberg", "248976051#1_0")],
)  # fmt: skip
def test_a_car_waiting_at_the_limit_line_has_not_entered(
    network: str, lane: str, request: pytest.FixtureRequest
) -> None:
    """The junction's polygon reaches upstream of the limit line: a car standing 1 m
    before it (where SUMO's driver waits) overlaps the polygon but has not entered; 0.2 m
    past the line it has."""
    intersection: Intersection = request.getfixturevalue(network)
    fork = intersection.forks[lane]
    assert overlapping(car_at(fork, 1.0), intersection.polygon)[0]
    assert not entered(fork, 1.0)
    assert not entered(fork, 0.01)
    assert entered(fork, -0.2)


def test_the_entry_area_is_the_polygon_where_nothing_lies_behind_the_line(
    four_way: Intersection, t_stop: Intersection
) -> None:
    for intersection in (four_way, t_stop):
        for fork in intersection.forks.values():
            assert fork.entry is intersection.polygon
            assert fork.limit_offset == 0.0 and fork.limit_lane == fork.lane


# The sweep: SUMO's driver, alone on each fork, where it first stands still.


def supported_junctions(network: Path) -> list[Intersection]:
    """Every junction of ``network`` that loads under its own control type."""
    net = parsed_network(network)
    found = []
    for node in net.getNodes():
        if node.getType() not in SUPPORTED or junction_arms(node) < 3:
            continue
        try:
            found.append(load_intersection(network, str(node.getID())))
        except ScengenError:
            continue  # refused with a reason (tests/cli/test_real_maps.py)
    return found


def _lights(net: object, red: set[str]) -> str:
    """An additional file that turns the lights in ``red`` red for good and every other
    light of ``net`` off (``O``: no signal, its roads' priorities decide)."""
    lines = ["<additional>"]
    for tls in net.getTrafficLights():  # type: ignore[attr-defined]
        links = 1 + max(int(c[2]) for c in tls.getConnections())
        colour = "r" if tls.getID() in red else "O"
        lines.append(f'  <tlLogic id="{tls.getID()}" programID="sweep" type="static" offset="0">')
        lines.append(f'    <phase duration="1000" state="{colour * links}"/>')
        lines.append("  </tlLogic>")
    return "\n".join([*lines, "</additional>"]) + "\n"


def _vehicles(intersections: Iterable[Intersection]) -> list[tuple[str, str, str, list[str]]]:
    """One car per fork: (its fork as junction/lane, its id, the lane it departs on, its
    route's lines)."""
    cars = []
    for intersection in intersections:
        for lane in intersection.offered_forks:
            route = next(r for r in intersection.offered_routes.values() if r.fork == lane)
            start = longest_start(intersection, route, START)
            plan = plan_drive(intersection, route, start, 5.0, 30.0, 0.1)
            name = f"car{len(cars)}"
            cars.append((
                f"{intersection.junction}/{lane}", name, f"{plan.edges[0]}_{plan.depart_lane}",
                [f'  <vehicle id="{name}" type="car" depart="0" departLane="{plan.depart_lane}" '
                 f'departPos="{plan.depart_pos:.3f}" departSpeed="0" insertionChecks="none">',
                 f'    <route edges="{" ".join(plan.edges)}"/>', "  </vehicle>"],
            ))  # fmt: skip
    return cars


def sumo_stops(
    network: Path, intersections: list[Intersection], folder: Path
) -> dict[str, dict[str, str]]:
    """Where each fork's car (SUMO's default driver; the junctions' lights red, any other
    light off) first stands still after it drove off: its FCD row (front bumper x, y,
    angle, lane, pos), by fork (junction/lane)."""
    net = parsed_network(network)
    red = {i.tls for i in intersections if i.tls is not None}
    (folder / "red.add.xml").write_text(_lights(net, red))
    batches: list[list[tuple[str, str, str, list[str]]]] = []
    for car in _vehicles(intersections):  # one car per departure lane and run
        batch = next((b for b in batches if all(c[2] != car[2] for c in b)), None)
        if batch is None:
            batches.append(batch := [])
        batch.append(car)
    stops: dict[str, dict[str, str]] = {}
    for k, batch in enumerate(batches):
        routes, fcd = folder / f"cars{k}.rou.xml", folder / f"fcd{k}.xml"
        routes.write_text("\n".join([
            "<routes>", '  <vType id="car" length="5" width="1.8" sigma="0" '
            'lcStrategic="-1" lcSpeedGain="0" lcKeepRight="0"/>',
            *[line for car in batch for line in car[3]], "</routes>",
        ]) + "\n")  # fmt: skip
        subprocess.run(
            [sumo_binary("sumo"), "-n", str(network), "-r", str(routes),
             "--additional-files", str(folder / "red.add.xml"), "--fcd-output", str(fcd),
             "--step-length", "0.1", "--end", "20", "--no-step-log", "true",
             "--no-warnings", "true", "--time-to-teleport", "-1"],
            check=True, capture_output=True, timeout=120,
        )  # fmt: skip
        forks = {name: fork for fork, name, _, _ in batch}
        moved: set[str] = set()
        for step in ET.parse(fcd).getroot().iter("timestep"):
            for row in step.iter("vehicle"):
                fork, speed = forks[row.get("id", "")], float(row.get("speed", "0"))
                if speed > 1.0:
                    moved.add(fork)
                elif speed <= 0.01 and fork in moved and fork not in stops:
                    stops[fork] = dict(row.attrib)
    return stops


def fork_predecessors(intersection: Intersection, fork: Fork) -> list[str]:
    """The internal lanes that lead into the limit lane."""
    lane = parsed_network(intersection.network_file).getLane(fork.limit_lane)
    return [c.getViaLaneID() for c in lane.getIncomingConnections() if c.getViaLaneID()]


def _check_stops(intersections: list[Intersection], stops: dict[str, dict[str, str]]) -> int:
    checked = 0
    for intersection in intersections:
        for lane in intersection.offered_forks:
            fork = intersection.forks[lane]
            car = f"{intersection.junction}/{lane}"
            if not intersection.control.signalized and not fork.stop_sign:
                continue  # nothing to stop for: the line is the fork's end (no link to obey)
            assert car in stops, f"{car}: SUMO's driver never stood still"
            row = stops[car]
            where = (car, row["lane"], fork.limit_lane)
            # on the limit lane, or (before a fork shorter than SUMO_GAP) the junction before it
            assert row["lane"] in (fork.limit_lane, *fork_predecessors(intersection, fork)), where
            rad = math.radians(fork.heading)
            front = (float(row["x"]), float(row["y"]))
            ahead = (fork.stop_line[0] - front[0]) * math.sin(rad)
            ahead += (fork.stop_line[1] - front[1]) * math.cos(rad)
            assert 0.0 < ahead <= SUMO_GAP, (*where, ahead)
            angle = float(row["angle"])
            x = front[0] - math.sin(math.radians(angle)) * LENGTH / 2
            y = front[1] - math.cos(math.radians(angle)) * LENGTH / 2
            standing = rectangles(np.array([x]), np.array([y]), np.array([angle]), LENGTH, WIDTH)
            assert not overlapping(standing, fork.entry)[0], (*where, "entered while waiting")
            assert entered(fork, -0.2), (*where, "not entered 0.2 m past the line")
            checked += 1
    return checked


@pytest.mark.parametrize(
    ("network", "counted"),
    [(TOWN05, 15), (TOWN07, 5), (NUREMBERG, 1), (JOINED, 1)],
    ids=["Town05", "Town07", "nuremberg-cluster", "joined-signal"],
)
def test_sumo_stops_every_car_at_its_forks_limit_line(
    network: Path, counted: int, tmp_path: Path
) -> None:
    """Every junction the model accepts under its own type, every offered fork with a light
    or a stop sign: SUMO's driver, alone and every light red, stands still on the fork's
    limit lane within SUMO_GAP before the limit line, not entered; 0.2 m past it a car has
    entered. (A junction of SUMO type priority has no line to stand at: its minor road
    yields without stopping, and a car alone drives through.)"""
    intersections = [
        junction
        for junction in supported_junctions(network)
        if junction.control.signalized or any(f.stop_sign for f in junction.forks.values())
    ]
    assert len(intersections) == counted
    stops = sumo_stops(network, intersections, tmp_path)
    assert _check_stops(intersections, stops) >= 2 * counted


@pytest.mark.parametrize(
    "network", ["4way-stop", "t-stop", "4way-signal", "t-signal", "crosswalk-signal"]
)
def test_sumo_stops_at_the_limit_line_of_the_bundled_junctions(
    network: str, tmp_path: Path
) -> None:
    """An all-way stop, a T with a stop sign and two signals, one of them with crosswalks
    (SUMO's driver stops before the crosswalk): the fork's end is the limit line and the
    entry area is the junction's polygon. (crosswalk-stop is left out: there SUMO's driver
    on S2C_1 slows to 0.1 m/s 1 m before the line and drives on without standing still;
    test_crossings.py holds its limit lines to the crosswalks.)"""
    intersection = load_intersection(network)
    stops = sumo_stops(intersection.network_file, [intersection], tmp_path)
    assert _check_stops([intersection], stops) >= 1


@pytest.mark.parametrize("control", ["allway_stop", "priority_stop", "right_before_left"])
def test_a_joined_cluster_keeps_its_light_under_another_type(control: str, cache_dir: Path) -> None:
    """netconvert keeps C's links in the light J it shares with U when C gets another type:
    SUMO's drivers would still obey J, so the model refuses rather than judge stop signs
    or right before left that SUMO does not drive by."""
    with pytest.raises(UnsupportedIntersection, match=r"traffic light J, which also controls U"):
        load_intersection(JOINED, "C", control, cache_dir)
