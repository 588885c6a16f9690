"""Crossings and walks (docs/pedestrians.md): the bundled crosswalk junctions, a Y with
guessed crossings (tests/data/junctions/y-crosswalk), CARLA's towns with --guess-crossings,
held to SUMO's own lane lengths and to libsumo walking people over them (nothing mocked).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from pathlib import Path

import libsumo
import numpy as np
import pytest
from shapely.geometry import Point, Polygon

from service.core.errors import UnknownLane, UnknownRoute, UnknownWalk
from service.core.motion.events import overlapping
from service.core.network import Intersection, Walk, load_intersection, walk_id
from service.core.network.geometry import junction_geometry
from service.core.network.lanes import heading_difference
from service.core.network.load import junction_arms, parsed_network
from service.core.network.relations import SLIVER_RADIUS, overlap_thickness
from service.core.sumo.binaries import sumo_binary
from tests.conftest import TOWN05, TOWN07
from tests.core.network.test_forks import car_at, entered

Y_CROSSWALK = Path(__file__).parents[2] / "data" / "junctions" / "y-crosswalk.net.xml"
ARMS = {"N": ":C_c0", "E": ":C_c1", "S": ":C_c2", "W": ":C_c3"}  # bundled: c0 north, clockwise


@pytest.fixture(scope="module")
def stop() -> Intersection:
    return load_intersection("crosswalk-stop")


@pytest.fixture(scope="module")
def signal() -> Intersection:
    return load_intersection("crosswalk-signal")


@pytest.fixture(scope="module")
def y_walks() -> Intersection:
    return load_intersection(Y_CROSSWALK)


def arm_routes(intersection: Intersection, edges: Iterable[str]) -> set[str]:
    """The routes that enter or leave the junction by one of ``edges`` (an arm's roads)."""
    roads = set(edges)
    net = parsed_network(intersection.network_file)

    def edge(lane: str) -> str:
        return str(net.getLane(lane).getEdge().getID())

    return {
        r.id for r in intersection.routes.values() if edge(r.fork) in roads or edge(r.exit) in roads
    }


@pytest.mark.parametrize("name", ["stop", "signal"])
def test_the_bundled_four_ways_have_a_crossing_over_every_arm(
    name: str, request: pytest.FixtureRequest
) -> None:
    intersection: Intersection = request.getfixturevalue(name)
    assert list(intersection.crossings) == [":C_c0", ":C_c1", ":C_c2", ":C_c3"]
    for arm, crossing_id in ARMS.items():
        crossing = intersection.crossings[crossing_id]
        assert crossing.lane == crossing_id + "_0"
        assert crossing.edges == (f"C2{arm}", f"{arm}2C")
        assert crossing.width == 4.0
        assert crossing.polygon.area == pytest.approx(crossing.length * 4.0, rel=1e-3)
    assert sorted(intersection.walks) == sorted(
        walk_id(c, along) for c in intersection.crossings for along in (True, False)
    )
    assert intersection.walk("C_c0+").crossing == ":C_c0"
    # sidewalks are lane 0 and never forks, exits or routes: the car lanes are 1 and 2
    assert sorted(intersection.forks) == [f"{a}2C_{k}" for a in "ENSW" for k in (1, 2)]
    assert sorted(intersection.exits) == [f"C2{a}_{k}" for a in "ENSW" for k in (1, 2)]
    assert len(intersection.routes) == 16


def test_walks_go_from_one_walking_area_to_the_other(
    stop: Intersection, signal: Intersection, y_walks: Intersection
) -> None:
    for intersection in (stop, signal, y_walks):
        net = parsed_network(intersection.network_file)
        for walk in intersection.walks.values():
            crossing = intersection.crossings[walk.crossing]
            along = walk.id.endswith("+")
            assert (walk.start, walk.end) == (crossing.ends if along else crossing.ends[::-1])
            start = Polygon(net.getEdge(walk.start).getLanes()[0].getShape())
            end = Polygon(net.getEdge(walk.end).getLanes()[0].getShape())
            first, last = Point(walk.path.coords[0]), Point(walk.path.coords[-1])
            # SUMO draws a walking area's outline within a metre of the curb
            assert start.distance(first) < min(1.0, end.distance(first)), walk.id
            assert end.distance(last) < min(1.0, start.distance(last)), walk.id
            # lengths as SUMO's lanes have them
            assert walk.length == pytest.approx(net.getLane(crossing.lane).getLength(), abs=0.03)
            other = intersection.walks[walk_id(walk.crossing, not along)]
            assert heading_difference(walk.heading, other.heading) == pytest.approx(180.0)
            assert walk.conflicts == other.conflicts


def test_a_walk_crosses_its_road_square_to_it_even_on_a_skewed_arm(stop: Intersection) -> None:
    """crosswalk-stop's east arm leaves at bearing 65: its walks head 335 and 155."""
    assert stop.walk("C_c1+").heading == pytest.approx(335.0, abs=0.5)
    assert stop.walk("C_c1-").heading == pytest.approx(155.0, abs=0.5)
    for walk in stop.walks.values():
        road = stop.crossings[walk.crossing].edges[1]  # the road into the junction
        fork = next(f for f in stop.forks.values() if f.edge == road)
        assert heading_difference(walk.heading, fork.heading) == pytest.approx(90.0, abs=1.0)


@pytest.mark.parametrize("name", ["stop", "signal"])
def test_a_walk_conflicts_with_every_route_by_its_arm_and_no_other(
    name: str, request: pytest.FixtureRequest
) -> None:
    intersection: Intersection = request.getfixturevalue(name)
    for crossing in intersection.crossings.values():
        expected = arm_routes(intersection, crossing.edges)
        assert len(expected) == 8  # 2 x 2 in, 2 x 2 out
        for along in (True, False):
            walk = intersection.walks[walk_id(crossing.id, along)]
            assert set(walk.conflicts) == expected, walk.id


def test_the_y_walks_conflict_by_their_arm_and_a_left_turn_cuts_a_corner(
    y_walks: Intersection,
) -> None:
    """A Y of one lane each way: each walk conflicts with the routes by its arm; the left
    turn N -> ESE also cuts across the corner of the crosswalk over the SW arm (its lane
    overlaps the strip 0.74 m deep, well over a sliver)."""
    assert y_walks.control.value == "right_before_left"
    assert len(y_walks.crossings) == 3 and len(y_walks.walks) == 6
    for crossing in y_walks.crossings.values():
        walk = y_walks.walks[walk_id(crossing.id, True)]
        extra = set(walk.conflicts) - arm_routes(y_walks, crossing.edges)
        assert arm_routes(y_walks, crossing.edges) <= set(walk.conflicts)
        assert extra == ({"N2C_1:C2ESE_1"} if crossing.edges == ("C2SW", "SW2C") else set())
    corner = y_walks.connecting_lane_of(y_walks.route("N2C_1:C2ESE_1")).polygon
    depth = overlap_thickness(corner, y_walks.crossings[":C_c2"].polygon)
    assert SLIVER_RADIUS < depth < 1.0


def test_the_pedestrian_signal_walks_with_the_parallel_traffic(signal: Intersection) -> None:
    """Links 16-19 of the light are the crosswalks; each walks (G) beside the traffic it
    runs parallel to, then shows flashing don't-walk (y) while that traffic keeps its green,
    and don't-walk (r) otherwise. While a crosswalk shows walk or flashing don't-walk, every
    route across it is permissive (g: yields) or red, never protected."""
    assert signal.tls_links == 20 and signal.signals is not None
    links = {c.id: c.link_index for c in signal.crossings.values()}
    assert links == {":C_c0": 16, ":C_c1": 17, ":C_c2": 18, ":C_c3": 19}
    east, north = signal.crossings[":C_c1"], signal.crossings[":C_c0"]
    assert [signal.signal_colour_of_crossing(east, t) for t in (0, 14.9, 15, 19.9, 20, 30)] == [
        "G", "G", "y", "y", "r", "r"
    ]  # fmt: skip
    assert [signal.signal_colour_of_crossing(north, t) for t in (0, 25, 40, 45)] == [
        "r", "G", "y", "r"
    ]  # fmt: skip
    assert signal.signal_colour(signal.route("N2C_1:C2S_1"), 0) == "G"  # beside the east one
    for crossing in signal.crossings.values():
        walk = signal.walks[walk_id(crossing.id, True)]
        for t in np.arange(0.0, signal.signals.cycle, 0.5):
            if signal.signal_colour_of_crossing(crossing, float(t)) in ("G", "y"):
                colours = {signal.signal_colour(signal.route(r), float(t)) for r in walk.conflicts}
                assert colours <= {"g", "r"}, (walk.id, t, colours)


def test_a_car_at_its_limit_line_is_not_on_the_crosswalk(
    stop: Intersection, signal: Intersection
) -> None:
    """The junction's polygon holds the crosswalks; the limit line is before them: a car
    waiting 1 m before the line touches no crosswalk and has not entered; 0.2 m past the
    line it has entered, before it reaches its arm's crosswalk."""
    for intersection in (stop, signal):
        for fork in intersection.forks.values():
            assert fork.entry is intersection.polygon
            waiting = car_at(fork, 1.0)
            for crossing in intersection.crossings.values():
                assert not overlapping(waiting, crossing.polygon)[0], (fork.lane, crossing.id)
                assert intersection.polygon.buffer(0.01).contains(crossing.polygon)
            assert not entered(fork, 1.0) and not entered(fork, 0.01) and entered(fork, -0.2)


def test_a_junction_without_crossings_says_how_to_add_them(four_way: Intersection) -> None:
    assert four_way.crossings == {} and four_way.walks == {}
    with pytest.raises(UnknownWalk, match=r"no pedestrian crossings.*--guess-crossings"):
        four_way.walk("C_c0+")


def test_an_unknown_walk_names_the_valid_ones(stop: Intersection) -> None:
    with pytest.raises(UnknownWalk) as refused:
        stop.walk("C_c9+")
    assert str(refused.value).endswith(
        "valid walks: C_c0+, C_c0-, C_c1+, C_c1-, C_c2+, C_c2-, C_c3+, C_c3-"
    )


def test_the_geometry_draws_the_crossings_and_their_walking_areas(signal: Intersection) -> None:
    shapes = junction_geometry(signal)
    assert [c["id"] for c in shapes["crossings"]] == list(ARMS.values())
    assert [c["link_index"] for c in shapes["crossings"]] == [16, 17, 18, 19]
    assert [w["id"] for w in shapes["walking_areas"]] == [f":C_w{k}" for k in range(4)]
    for crossing in shapes["crossings"]:
        ring = crossing["polygon"][0]
        assert ring[0] == ring[-1] and len(ring) == 5  # a strip: four corners
    for area in shapes["walking_areas"]:
        assert len(area["polygon"]) == 1 and len(area["polygon"][0]) >= 4


# libsumo: a person added on a walk's ``before`` edge, walking to ``after``'s, takes the walk's
# crossing and no other one (a walk from a traffic island has no ``before``: not walked).


def walked_lanes(intersections: list[Intersection]) -> dict[str, list[str]]:
    """The lanes libsumo walks each walk's person over (SUMO's own router and pedestrian
    model), by junction/walk; the intersections share one network file."""
    (network,) = {i.network_file for i in intersections}
    net = parsed_network(network)
    libsumo.start([sumo_binary("sumo"), "-n", str(network), "--no-step-log", "true",
                   "--no-warnings", "true", "--step-length", "0.5"])  # fmt: skip
    people: dict[str, list[str]] = {}
    try:
        for intersection in intersections:
            for walk in (w for w in intersection.walks.values() if w.before):
                person = f"{intersection.junction}/{walk.id}"
                start, arrival = _depart(net, walk, intersection.junction)
                first, last = (
                    net.getLane(lane).getEdge().getID() for lane in (walk.before, walk.after)
                )
                libsumo.person.add(person, first, start, depart=0.0)
                libsumo.person.appendWalkingStage(person, [first, last], arrival)
                people[person] = []
        for _ in range(600):  # 300 s: a whole signal cycle and the walk
            libsumo.simulationStep()
            for person in libsumo.person.getIDList():
                lane = libsumo.person.getLaneID(person)
                if lane and (not people[person] or people[person][-1] != lane):
                    people[person].append(lane)
            if libsumo.simulation.getMinExpectedNumber() == 0:
                break
        assert libsumo.simulation.getMinExpectedNumber() == 0, "somebody is still walking"
    finally:
        libsumo.close()
    return people


def _depart(net: object, walk: Walk, junction: str) -> tuple[float, float]:
    """Where the person starts on ``before`` and arrives on ``after``: 1 m from the junction
    on a sidewalk (half way on a shorter one); on the crossing itself (``after`` on a
    traffic island), at its far curb."""
    before = net.getLane(walk.before)  # type: ignore[attr-defined]
    after = net.getLane(walk.after)  # type: ignore[attr-defined]

    def near(lane: object) -> float:
        length = float(lane.getLength())  # type: ignore[attr-defined]
        into = lane.getEdge().getToNode().getID() == junction  # type: ignore[attr-defined]
        return max(length - 1.0, length / 2) if into else min(1.0, length / 2)

    if after.getEdge().getFunction() == "crossing":
        arrival = after.getLength() - 0.1 if walk.id.endswith("+") else 0.1
    else:
        arrival = near(after)
    return near(before), arrival


def _check_walks(intersections: list[Intersection]) -> int:
    """Every walk with a ``before``, walked by libsumo: how many."""
    walked = walked_lanes(intersections)
    net = parsed_network(intersections[0].network_file)
    for intersection in intersections:
        for walk in (w for w in intersection.walks.values() if w.before):
            lanes = walked[f"{intersection.junction}/{walk.id}"]
            crossed = [
                lane for lane in lanes if net.getLane(lane).getEdge().getFunction() == "crossing"
            ]
            assert crossed == [intersection.crossings[walk.crossing].lane], (
                intersection.junction, walk.id, walk.before, walk.after, lanes
            )  # fmt: skip
    return len(walked)


@pytest.mark.parametrize("name", ["stop", "signal", "y_walks"])
def test_libsumo_walks_a_person_from_before_to_after_over_the_walks_crossing(
    name: str, request: pytest.FixtureRequest
) -> None:
    intersection: Intersection = request.getfixturevalue(name)
    assert _check_walks([intersection]) == len(intersection.walks)
    for walk in intersection.walks.values():
        crossing = intersection.crossings[walk.crossing]
        assert walk.before.endswith("_0") and not walk.before.startswith(":")
        assert walk.after.endswith("_0") and not walk.after.startswith(":")
        # of a road the crossing does not cross: the only way between them is this crossing
        net = parsed_network(intersection.network_file)
        for lane in (walk.before, walk.after):
            assert net.getLane(lane).getEdge().getID() not in crossing.edges
            assert not net.getLane(lane).allows("passenger")


def test_guessed_crossings_on_town05_walk_over_their_crossing_islands_too(
    cache_dir: Path,
) -> None:
    """Every junction of Town05 under its own type (the 15 lights) with guessed crossings,
    in one SUMO run. Junctions 2014 and 2328 split a road round a median: a walk that
    ends on the island ends on the crossing at the island's curb; one that starts there
    has no ``before`` (Step 1 places her: service.core.network.crossings)."""
    net = parsed_network(TOWN05)
    junctions = [
        load_intersection(TOWN05, str(n.getID()), cache_dir=cache_dir, guess_crossings=True)
        for n in net.getNodes()
        if n.getType().startswith("traffic_light") and junction_arms(n) >= 3
    ]
    assert len(junctions) == 15 and all(j.walks for j in junctions)
    island = next(j for j in junctions if j.junction == "2014")
    assert island.walk("2014_c0+").before == ""  # from the island
    assert island.walk("2014_c0-").after == ":2014_c0_0"  # ends on the crossing
    assert island.walk("2014_c0-").before == "-36_0"
    from_islands = [w.id for j in junctions for w in j.walks.values() if not w.before]
    assert len(from_islands) == 8  # 2 junctions x 2 islands x 2 crossings
    assert sum(len(j.walks) for j in junctions) == 118
    assert _check_walks(junctions) == 118 - 8


def _bumped(lane: str) -> str:
    edge, _, index = lane.rpartition("_")
    return f"{edge}_{int(index) + 1}"


@pytest.mark.parametrize(("town", "junction"), [(TOWN05, "1126"), (TOWN07, "358")])
def test_guess_crossings_adds_walks_and_moves_the_car_lanes_up(
    town: Path, junction: str, cache_dir: Path
) -> None:
    control = None if junction == "1126" else "right_before_left"
    plain = load_intersection(town, junction, control, cache_dir)
    guessed = load_intersection(town, junction, control, cache_dir, guess_crossings=True)
    assert not plain.walks and not plain.crossings_guessed
    assert guessed.crossings_guessed and guessed.overridden == plain.overridden
    assert guessed.network_file != plain.network_file
    assert len(guessed.walks) == 2 * len(guessed.crossings) >= 6
    renamed = {f"{_bumped(r.fork)}:{_bumped(r.exit)}" for r in plain.routes.values()}
    assert set(guessed.routes) == renamed
    for route in plain.routes.values():
        moved = guessed.route(f"{_bumped(route.fork)}:{_bumped(route.exit)}")
        assert moved.turn == route.turn
    # every route that leaves by a road is in conflict with the walks over that road
    for walk in guessed.walks.values():
        assert arm_routes(guessed, guessed.crossings[walk.crossing].edges) <= set(walk.conflicts)
    with pytest.raises((UnknownLane, UnknownRoute), match="every car lane's index is one higher"):
        guessed.route(next(iter(plain.routes)))


def test_guessed_crossings_are_cached_by_network(cache_dir: Path) -> None:
    """One rebuilt network for every junction of a map under its own type; the control
    override and the crossings in one rebuild otherwise."""
    a = load_intersection(TOWN05, "1126", cache_dir=cache_dir, guess_crossings=True)
    b = load_intersection(TOWN05, "53", cache_dir=cache_dir, guess_crossings=True)
    assert a.network_file == b.network_file
    c = load_intersection(TOWN05, "396", "allway_stop", cache_dir, guess_crossings=True)
    assert c.network_file != a.network_file and c.overridden and c.walks


def test_crossing_lengths_are_sumos(cache_dir: Path) -> None:
    intersection = load_intersection(TOWN07, "725", cache_dir=cache_dir, guess_crossings=True)
    net = parsed_network(intersection.network_file)
    for crossing in intersection.crossings.values():
        sumo = net.getLane(crossing.lane)
        assert crossing.length == pytest.approx(sumo.getLength(), abs=0.03)
        assert crossing.width == sumo.getWidth()
        assert math.isclose(crossing.polygon.area, crossing.length * crossing.width, rel_tol=1e-3)
