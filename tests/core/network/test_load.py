"""The intersection model of the bundled and the CARLA junctions."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
import sumolib

from service.core.errors import (
    InvalidInput,
    UnknownJunction,
    UnknownLane,
    UnknownNetwork,
    UnknownRoute,
    UnsupportedIntersection,
)
from service.core.network import (
    ControlType,
    Intersection,
    Turn,
    bundled_networks,
    load_intersection,
)
from tests.conftest import DATA, TOWN05, TOWN07


def test_bundled_networks_are_the_seven_documented_ones() -> None:
    assert set(bundled_networks()) == {
        "4way-stop",
        "t-stop",
        "y-uncontrolled",
        "4way-signal",
        "t-signal",
        "crosswalk-stop",
        "crosswalk-signal",
    }


@pytest.mark.parametrize(
    ("name", "control", "arms"),
    [
        ("4way-stop", ControlType.ALLWAY_STOP, 4),
        ("t-stop", ControlType.PRIORITY_STOP, 3),
        ("y-uncontrolled", ControlType.RIGHT_BEFORE_LEFT, 3),
        ("crosswalk-stop", ControlType.ALLWAY_STOP, 4),
        ("crosswalk-signal", ControlType.TRAFFIC_LIGHT, 4),
    ],
)
def test_load_bundled_network_control_and_arms(name: str, control: ControlType, arms: int) -> None:
    intersection = load_intersection(name)
    assert intersection.junction == "C"
    assert intersection.control is control
    assert not intersection.overridden
    assert len({fork.edge for fork in intersection.forks.values()}) == arms


@pytest.mark.parametrize(
    "name", ["4way-stop", "t-stop", "y-uncontrolled", "crosswalk-stop", "crosswalk-signal"]
)
def test_bundled_roads_are_long_enough(name: str) -> None:
    net = sumolib.net.readNet(str(bundled_networks()[name]))
    for edge in net.getEdges():
        assert edge.getLength() >= 100.0, edge.getID()


def test_four_way_routes_and_turns(four_way: Intersection) -> None:
    assert len(four_way.forks) == 8
    assert len(four_way.routes) == 16
    assert four_way.route("S2C_1:C2W_1").turn is Turn.LEFT
    assert four_way.route("S2C_0:C2E_0").turn is Turn.RIGHT
    assert four_way.route("S2C_0:C2N_0").turn is Turn.STRAIGHT
    assert four_way.route("S2C_1:C2N_1").turn is Turn.STRAIGHT
    turns = [r.turn for r in four_way.routes.values()]
    assert turns.count(Turn.LEFT) == 4
    assert turns.count(Turn.RIGHT) == 4
    assert turns.count(Turn.STRAIGHT) == 8


def test_four_way_every_fork_has_a_stop_sign(four_way: Intersection) -> None:
    assert all(fork.stop_sign for fork in four_way.forks.values())


def test_four_way_right_and_opposite(four_way: Intersection) -> None:
    # Northbound traffic (from S) has eastern arm on its right, northern arm opposite.
    assert four_way.to_its_right["S2C_0"] == {"E2C_0", "E2C_1"}
    assert four_way.opposite["S2C_0"] == {"N2C_0", "N2C_1"}
    assert four_way.to_its_right["W2C_1"] == {"S2C_0", "S2C_1"}
    assert four_way.same_direction["S2C_0"] == {"S2C_1"}
    assert four_way.on_different_highways("S2C_0", "W2C_0")
    assert not four_way.on_different_highways("S2C_0", "N2C_1")
    assert not four_way.on_different_highways("S2C_0", "S2C_1")


def test_right_of_is_a_cycle_around_the_four_way(four_way: Intersection) -> None:
    edges = {lane: four_way.forks[lane].edge for lane in four_way.forks}
    right_edge = {
        edges[lane]: {edges[other] for other in others}
        for lane, others in four_way.to_its_right.items()
    }
    assert right_edge == {"S2C": {"E2C"}, "E2C": {"N2C"}, "N2C": {"W2C"}, "W2C": {"S2C"}}


@pytest.mark.parametrize(
    ("first", "second"),
    [
        ("S2C_1:C2W_1", "N2C_0:C2S_0"),  # left turn crosses oncoming straight
        ("S2C_1:C2W_1", "W2C_0:C2E_0"),  # left turn crosses traffic from the left
        ("S2C_0:C2N_0", "E2C_0:C2W_0"),  # perpendicular straights cross
        ("S2C_0:C2N_0", "E2C_0:C2N_0"),  # merge into the same exit lane
        ("S2C_1:C2W_1", "E2C_1:C2W_1"),  # merge: left turn into the lane of a straight
    ],
)
def test_four_way_conflicting_routes(four_way: Intersection, first: str, second: str) -> None:
    assert second in four_way.conflicts[first]
    assert first in four_way.conflicts[second]


@pytest.mark.parametrize(
    ("first", "second"),
    [
        ("S2C_1:C2W_1", "S2C_1:C2N_1"),  # same fork: car-following, never right-of-way
        ("S2C_0:C2N_0", "S2C_1:C2N_1"),  # side by side on one road
        ("S2C_0:C2N_0", "N2C_0:C2S_0"),  # opposite straights
        ("S2C_0:C2E_0", "N2C_0:C2W_0"),  # opposite right turns
        ("S2C_1:C2W_1", "N2C_1:C2E_1"),  # opposite left turns pass each other
        ("S2C_0:C2E_0", "E2C_0:C2N_0"),  # right turns in different corners
    ],
)
def test_four_way_non_conflicting_routes(four_way: Intersection, first: str, second: str) -> None:
    assert second not in four_way.conflicts[first]
    assert first not in four_way.conflicts[second]


def test_t_stop_stop_sign_only_on_the_terminating_road(t_stop: Intersection) -> None:
    assert {lane for lane, fork in t_stop.forks.items() if fork.stop_sign} == {"S2C_0"}
    assert t_stop.route("S2C_0:C2W_0").link_state == "s"
    assert t_stop.route("E2C_0:C2S_0").link_state == "m"  # left turn from the through road
    assert t_stop.route("W2C_0:C2E_0").link_state == "M"


def test_t_stop_relations(t_stop: Intersection) -> None:
    assert t_stop.opposite["E2C_0"] == {"W2C_0"}
    assert t_stop.opposite["S2C_0"] == frozenset()
    assert t_stop.to_its_right["S2C_0"] == {"E2C_0"}
    assert t_stop.to_its_right["W2C_0"] == {"S2C_0"}
    assert t_stop.to_its_right["E2C_0"] == frozenset()
    assert {r.id: r.turn for r in t_stop.routes.values()} == {
        "E2C_0:C2S_0": Turn.LEFT,
        "E2C_0:C2W_0": Turn.STRAIGHT,
        "S2C_0:C2E_0": Turn.RIGHT,
        "S2C_0:C2W_0": Turn.LEFT,
        "W2C_0:C2E_0": Turn.STRAIGHT,
        "W2C_0:C2S_0": Turn.RIGHT,
    }


def test_t_stop_slivers_are_not_conflicts(t_stop: Intersection) -> None:
    # The through road's left turn and the minor road's right turn graze at the border.
    first = t_stop.connecting_lane_of(t_stop.route("E2C_0:C2S_0")).polygon
    second = t_stop.connecting_lane_of(t_stop.route("S2C_0:C2E_0")).polygon
    assert first.intersection(second).area > 0
    assert "S2C_0:C2E_0" not in t_stop.conflicts["E2C_0:C2S_0"]
    assert "W2C_0:C2E_0" in t_stop.conflicts["E2C_0:C2S_0"]


def test_y_junction_right_of_without_right_angles(y_junction: Intersection) -> None:
    # Arms point north, south-west (215 deg) and south-east (325 deg): none is opposite,
    # and traffic from the next arm clockwise (seen from above) approaches from the right.
    assert all(not others for others in y_junction.opposite.values())
    assert y_junction.to_its_right == {
        "N2C_0": {"SW2C_0"},
        "SW2C_0": {"SE2C_0"},
        "SE2C_0": {"N2C_0"},
    }
    assert y_junction.route("N2C_0:C2SE_0").turn is Turn.LEFT
    assert y_junction.route("N2C_0:C2SW_0").turn is Turn.RIGHT


def test_y_junction_conflicts(y_junction: Intersection) -> None:
    assert y_junction.conflicts["N2C_0:C2SE_0"] == {
        "SE2C_0:C2SW_0",
        "SW2C_0:C2N_0",
        "SW2C_0:C2SE_0",
    }
    assert y_junction.conflicts["N2C_0:C2SW_0"] == {"SE2C_0:C2SW_0"}


def test_town07_y_override_rebuilds_sumo_logic(town07_y: Intersection) -> None:
    assert town07_y.overridden
    assert town07_y.control is ControlType.RIGHT_BEFORE_LEFT
    assert town07_y.network_file != town07_y.source_file
    net = sumolib.net.readNet(str(town07_y.network_file), withInternal=True)
    assert net.getNode("358").getType() == "right_before_left"
    # SUMO's own link states changed: CARLA had the straight -35 -> -41 as minor ('m').
    assert town07_y.route("-35_0:-41_0").link_state == "="


def test_town07_y_relations(town07_y: Intersection) -> None:
    assert set(town07_y.forks) == {"-35_0", "-40_0", "41_0"}
    assert not any(fork.stop_sign for fork in town07_y.forks.values())
    assert town07_y.opposite["41_0"] == {"-35_0"}  # the curved through road
    assert town07_y.to_its_right["-35_0"] == {"-40_0"}
    assert town07_y.to_its_right["-40_0"] == {"41_0"}
    assert town07_y.to_its_right["41_0"] == frozenset()
    assert town07_y.route("-40_0:35_0").turn is Turn.LEFT
    # The two directions of the through road rub along the centre line: a sliver.
    assert "41_0:35_0" not in town07_y.conflicts["-35_0:-41_0"]
    assert "-40_0:35_0" in town07_y.conflicts["41_0:35_0"]


def test_town05_allway_override(town05_allway: Intersection) -> None:
    assert town05_allway.control is ControlType.ALLWAY_STOP
    assert len({fork.edge for fork in town05_allway.forks.values()}) == 4
    assert all(fork.stop_sign for fork in town05_allway.forks.values())
    assert all(r.link_state == "w" for r in town05_allway.routes.values())
    for lane, others in town05_allway.to_its_right.items():
        assert len({town05_allway.forks[o].edge for o in others}) == 1, lane
        assert len({town05_allway.forks[o].edge for o in town05_allway.opposite[lane]}) == 1


def test_override_is_cached(cache_dir: Path, town07_y: Intersection) -> None:
    again = load_intersection(TOWN07, "358", "right_before_left", cache_dir)
    assert again.network_file == town07_y.network_file


def test_unsupported_control_type_is_refused_with_its_name() -> None:
    with pytest.raises(UnsupportedIntersection) as caught:
        load_intersection(DATA / "junctions" / "skewed-unregulated.net.xml", "C")
    message = str(caught.value)
    assert "'C'" in message and "'unregulated'" in message
    assert (
        "SUMO junction types and their rule sets: allway_stop -> allway_stop, priority -> "
        "priority, priority_stop -> priority_stop, right_before_left -> right_before_left, "
        "traffic_light -> traffic_light, traffic_light_right_on_red -> traffic_light" in message
    )


def test_a_priority_junction_loads_under_its_own_rule_set() -> None:
    """SUMO's priority type: the minor road yields (CVC 21803), read from the links."""
    junction = load_intersection(TOWN07, "358")
    assert junction.control is ControlType.PRIORITY and not junction.overridden
    assert {f.edge for f in junction.forks.values() if f.yield_sign} == {"41"}
    assert not any(f.stop_sign for f in junction.forks.values())


def test_a_real_signalized_junction_loads_with_its_fixed_time_program() -> None:
    junction = load_intersection(TOWN05, "1126")
    assert junction.control is ControlType.TRAFFIC_LIGHT
    assert junction.signals is not None and junction.tls == junction.signals.tls
    assert junction.signals.links == junction.tls_links
    assert all(0 <= r.link_index < junction.tls_links for r in junction.routes.values())


def test_junction_must_be_named_when_none_is_supported() -> None:
    with pytest.raises(UnknownJunction, match="--junction") as caught:
        load_intersection(TOWN07)
    assert "358 (priority)" in str(caught.value)


def test_unknown_junction_lists_candidates() -> None:
    with pytest.raises(UnknownJunction, match=r"'nope'.*C"):
        load_intersection("4way-stop", junction="nope")


def test_unknown_network_lists_bundled() -> None:
    with pytest.raises(
        UnknownNetwork,
        match="4way-signal, 4way-stop, crosswalk-signal, crosswalk-stop, t-signal, t-sto",
    ):
        load_intersection("5way-stop")


def test_unknown_control_type_lists_choices() -> None:
    with pytest.raises(InvalidInput, match="allway_stop, priority, priority_stop, right_before_l"):
        load_intersection("4way-stop", control="zipper")


def test_unknown_route_and_lanes_name_valid_ones(four_way: Intersection) -> None:
    with pytest.raises(UnknownLane, match="valid forks: E2C_0"):
        four_way.route("X_0:C2W_1")
    with pytest.raises(UnknownLane, match="valid exits: C2E_0"):
        four_way.route("S2C_1:X_0")
    with pytest.raises(UnknownRoute, match="no connection from fork 'S2C_1' to exit 'C2E_0'"):
        four_way.route("S2C_1:C2E_0")
    with pytest.raises(UnknownRoute, match="FORK_LANE:EXIT_LANE"):
        four_way.route("S2C_1")


def test_network_that_is_not_xml_is_invalid_input(tmp_path: Path) -> None:
    broken = tmp_path / "broken.net.xml"
    broken.write_text("<net><junction")
    with pytest.raises(InvalidInput, match="cannot read SUMO network"):
        load_intersection(broken)


def test_a_network_without_lanes_or_with_nan_coordinates_is_refused(tmp_path: Path) -> None:
    """Refused when read (at upload on the server), not later inside SUMO or the checker."""
    text = (bundled_networks()["4way-stop"]).read_text()
    nan_junction = tmp_path / "nan.net.xml"
    centre = '<junction id="C" type="allway_stop" x='
    nan_junction.write_text(text.replace(f'{centre}"150.00"', f'{centre}"nan"'))
    with pytest.raises(InvalidInput, match="junction 'C' has a coordinate that is not a finite"):
        load_intersection(nan_junction)
    nan_lane = tmp_path / "nan-lane.net.xml"
    lane = 'shape="145.20,160.40 145.20,139.60"'  # lane :C_1_0
    nan_lane.write_text(text.replace(lane, lane.replace("145.20,160.40", "nan,160.40")))
    with pytest.raises(InvalidInput, match="shape point that is not a finite number"):
        load_intersection(nan_lane)
    head, _, _ = text.partition("<edge ")
    bare = tmp_path / "bare.net.xml"
    bare.write_text(head + '<junction id="C" type="allway_stop" x="0" y="0" incLanes="" '
                    'intLanes="" shape="0,0 1,1"/>\n</net>\n')  # fmt: skip
    with pytest.raises(InvalidInput, match="has no lanes"):
        load_intersection(bare)


def _degenerate_t(folder: Path) -> Path:
    """The bundled T with CARLA's degenerate shapes: the straight W2C->C2E connection a
    0.1 m internal lane written as two equal points, the left turn S2C->C2W with its first
    point repeated, and the junction's own shape a single point."""
    text = bundled_networks()["t-stop"].read_text()
    edits = [
        ('length="14.40" shape="142.80,148.40 157.20,148.40"',
         'length="0.10" shape="142.80,148.40 142.80,148.40"'),
        ('shape="151.60,142.80 151.05,146.65', 'shape="151.60,142.80 151.60,142.80 151.05,146.65'),
    ]  # fmt: skip
    for old, new in edits:
        assert text.count(old) == 1, old
        text = text.replace(old, new)
    text = re.sub(r'(<junction id="C" [^>]*shape=")[^"]*"', r'\g<1>150.00,150.00"', text)
    path = folder / "degenerate-t.net.xml"
    path.write_text(text)
    return path


def test_load_degenerate_lane_shapes(tmp_path: Path) -> None:
    intersection = load_intersection(_degenerate_t(tmp_path), "C")
    straight = intersection.connecting_lane_of(intersection.route("W2C_0:C2E_0"))
    # a straight line as long as SUMO says, centred on the point, along the way of travel
    coords = [c for point in straight.centreline.coords for c in point]
    assert coords == pytest.approx([142.75, 148.4, 142.85, 148.4])
    assert straight.polygon.area == pytest.approx(0.1 * straight.width, rel=1e-6)
    left = intersection.connecting_lane_of(intersection.route("S2C_0:C2W_0"))
    assert left.centreline.coords[0] == left.centreline.coords[0] != left.centreline.coords[1]
    assert left.length == pytest.approx(14.19, abs=0.05)
    assert intersection.polygon.area > 50.0  # the hull of the paths through it
    assert "W2C_0:C2E_0" in intersection.conflicts and intersection.conflicts["E2C_0:C2W_0"]


@pytest.mark.parametrize(
    ("network", "node", "roads"),
    [(TOWN05, "15.14", "2 roads lead into it (-14, 15)"),
     (TOWN05, "40.18", "2 roads lead into it (-18, 40)"),
     (TOWN07, "65.64", "1 road leads into it (-64)")],
)  # fmt: skip
def test_refuse_a_node_with_fewer_than_three_approaches(
    network: Path, node: str, roads: str, cache_dir: Path
) -> None:
    for control in (None, "allway_stop"):
        with pytest.raises(
            UnsupportedIntersection,
            match=rf"node '{node}' is not a junction to "
            rf"test: {re.escape(roads)}, a junction has 3 or more approaches",
        ):
            load_intersection(network, node, control, cache_dir)  # fmt: skip


def test_refuse_a_junction_where_no_routes_cross_or_merge() -> None:
    network = Path(__file__).parents[2] / "data" / "junctions" / "no-conflicts.net.xml"
    with pytest.raises(UnsupportedIntersection, match=r"none of its 3 routes crosses or merges"):
        load_intersection(network, "C")


def test_with_control_the_only_junction_of_three_approaches_is_taken(cache_dir: Path) -> None:
    # y-uncontrolled: its one junction of three approaches; its other nodes are dead ends
    chosen = load_intersection("y-uncontrolled", control="allway_stop", cache_dir=cache_dir)
    assert chosen.junction == "C" and chosen.control is ControlType.ALLWAY_STOP
    with pytest.raises(
        UnknownJunction,
        match=r"Town05.net.xml has several junctions with 3 or "
        r"more approaches; name one with --junction: 1126 \(traffic_light\)",
    ):
        load_intersection(TOWN05, control="allway_stop")  # fmt: skip
    with pytest.raises(UnknownJunction, match=r"several junctions of a supported control type"):
        load_intersection(TOWN05)
