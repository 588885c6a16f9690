"""The major road of a priority_stop or priority junction: chosen by geometry where every
road in has the same priority, read from the links, or named by the user; the rebuilt
network is cached by it."""

from __future__ import annotations

from pathlib import Path

import pytest

from service.core.errors import InvalidInput
from service.core.network import Intersection, load_intersection
from service.core.network.override import rebuild_with_control
from tests.conftest import TOWN05, TOWN07

JUNCTIONS = Path(__file__).parents[2] / "data" / "junctions"


def stopping_roads(intersection: Intersection) -> set[str]:
    return {fork.edge for fork in intersection.forks.values() if fork.stop_sign}


# Town05's T junctions, whose roads all have priority 1: netconvert alone makes the stem
# (three lanes) the major road. The through road's two arms, and the stem.
T_JUNCTIONS = [("1882", {"-45", "46"}, {"4"}), ("2240", {"-41", "42"}, {"51"})]


@pytest.mark.parametrize(("junction", "through", "stem"), T_JUNCTIONS)
def test_priority_stop_on_a_t_stops_the_stem_not_the_through_road(
    junction: str, through: set[str], stem: set[str], cache_dir: Path
) -> None:
    intersection = load_intersection(TOWN05, junction, "priority_stop", cache_dir)
    assert intersection.major_road is not None and set(intersection.major_road) == through
    assert stopping_roads(intersection) == stem
    # the major road runs straight across: its two arms approach head-on
    headings = [f.heading for f in intersection.forks.values() if f.edge in through]
    assert abs(abs(max(headings) - min(headings)) - 180.0) < 5.0


def test_priority_stop_on_a_t_stops_the_stem_whatever_the_maps_priorities(
    cache_dir: Path,
) -> None:
    """Town07's T 907: the map gives the stem (-47) priority 1 and the through road (-42,
    43) priority 0; priority_stop's rules are the T's, so the stem stops; --major can say
    otherwise."""
    by_geometry = load_intersection(TOWN07, "907", "priority_stop", cache_dir)
    assert set(by_geometry.major_road or ()) == {"-42", "43"}
    assert stopping_roads(by_geometry) == {"-47"}
    named = load_intersection(TOWN07, "907", "priority_stop", cache_dir, major_road=["-47", "43"])
    assert named.major_road == ("-47", "43") and stopping_roads(named) == {"-42"}


def test_priority_stop_on_the_uneven_y_takes_the_straightest_pair(cache_dir: Path) -> None:
    """Arms N 0, ESE 105, SW 233 degrees: ESE-SW bends 52 degrees from straight, N-SW 53,
    N-ESE 75; both near-straight pairs have the same lanes and speed, so the straighter."""
    intersection = load_intersection(JUNCTIONS / "y-uneven.net.xml", "C", "priority_stop",
                                     cache_dir)  # fmt: skip
    assert intersection.major_road == ("ESE2C", "SW2C")
    assert stopping_roads(intersection) == {"N2C"}


def test_the_major_road_is_the_one_the_user_names(cache_dir: Path) -> None:
    intersection = load_intersection(TOWN05, "1882", "priority_stop", cache_dir,
                                     major_road=["4", "46"])  # fmt: skip
    assert intersection.major_road == ("4", "46")
    assert stopping_roads(intersection) == {"-45"}


def test_a_native_priority_stop_junction_is_rebuilt_with_the_road_named(cache_dir: Path) -> None:
    native = load_intersection("t-stop")
    assert not native.overridden and native.major_road is None
    rebuilt = load_intersection("t-stop", major_road=["S2C", "E2C"], cache_dir=cache_dir)
    assert rebuilt.overridden and stopping_roads(rebuilt) == {"W2C"}


@pytest.mark.parametrize(
    ("major", "control", "message"),
    [
        (["-45"], "priority_stop", r"name two different roads into junction '1882', EDGE,EDGE; "
         r"roads into it: -45, 4, 46"),
        (["-45", "-45"], "priority_stop", r"name two different roads"),
        (["-45", "46", "4"], "priority_stop", r"name two different roads"),
        (["-45", "45"], "priority_stop", r"'45' is not a road into junction '1882'; roads into "
         r"it: -45, 4, 46"),
        (["-45", "nowhere"], "priority_stop", r"'nowhere' is not a road into"),
        (["-45", "46"], "allway_stop", r"applies to a priority_stop or priority junction; "
         r"junction '1882' is allway_stop"),
        (["-45", "46"], None, r"junction '1882' is traffic_light \(give --control priority_stop "
         r"or priority"),
    ],
)  # fmt: skip
def test_a_wrong_major_road_is_refused_naming_the_roads_in(
    major: list[str], control: str | None, message: str, cache_dir: Path
) -> None:
    with pytest.raises(InvalidInput, match=message):
        load_intersection(TOWN05, "1882", control, cache_dir, major_road=major)


def test_the_choice_is_the_same_every_time(tmp_path: Path) -> None:
    first = load_intersection(TOWN05, "2240", "priority_stop", tmp_path / "a")
    second = load_intersection(TOWN05, "2240", "priority_stop", tmp_path / "b")
    assert first.major_road == second.major_road == ("-41", "42")
    assert first.network_file.read_bytes() == second.network_file.read_bytes()


def test_the_cached_network_is_keyed_by_the_major_road(tmp_path: Path) -> None:
    plain = rebuild_with_control(TOWN05, "1882", "priority_stop", tmp_path)
    through = rebuild_with_control(TOWN05, "1882", "priority_stop", tmp_path, {"-45": 2, "46": 2})
    stem = rebuild_with_control(TOWN05, "1882", "priority_stop", tmp_path, {"4": 2, "46": 2})
    again = rebuild_with_control(TOWN05, "1882", "priority_stop", tmp_path, {"46": 2, "-45": 2})
    assert len({plain, through, stem}) == 3 and again == through
    assert '<edge id="-45" from="396" to="1882" priority="2"' in through.read_text()


# Every priority junction of Town05 and Town07 and its minor road as SUMO's links give it
# (tests/data/carla): where netconvert made a bent major road (Town07 358, 430, 642, 851,
# 907: one road turns left into the other, which turns right out, its straight link "m")
# and where a minor road's right turn that nobody crosses is "M" (Town05 720's 32).
YIELDING = [
    (TOWN05, "1930", {"-3"}), (TOWN05, "2062", {"-20"}), (TOWN05, "359", {"-48"}),
    (TOWN05, "396", {"-44", "45"}), (TOWN05, "562", {"-42", "43"}),
    (TOWN05, "720", {"-31", "32"}),
    (TOWN07, "123", {"-37"}), (TOWN07, "146", {"-1"}), (TOWN07, "169", {"-36", "37"}),
    (TOWN07, "260", {"-15"}), (TOWN07, "288", {"3"}), (TOWN07, "314", {"-67"}),
    (TOWN07, "358", {"41"}), (TOWN07, "402", {"16"}), (TOWN07, "430", {"-58"}),
    (TOWN07, "515", {"-53"}), (TOWN07, "543", {"-45"}), (TOWN07, "566", {"-8"}),
    (TOWN07, "605", {"-29"}), (TOWN07, "642", {"-3"}), (TOWN07, "851", {"-12"}),
    (TOWN07, "879", {"-18"}), (TOWN07, "907", {"43"}),
]  # fmt: skip


@pytest.mark.parametrize(("town", "junction", "minor"), YIELDING,
                         ids=[f"{t.stem}-{j}" for t, j, _ in YIELDING])  # fmt: skip
def test_a_priority_junction_yields_on_the_minor_road_of_its_links(
    town: Path, junction: str, minor: set[str]
) -> None:
    intersection = load_intersection(town, junction)
    assert {fork.edge for fork in intersection.forks.values() if fork.yield_sign} == minor
    # every link of a yielding road that crosses the major road is minor, as SUMO drives it
    for route in intersection.routes.values():
        if intersection.fork(route.fork).edge in minor and route.turn != "right":
            assert route.link_state == "m", (junction, route.id)


def test_major_names_the_road_that_keeps_the_right_of_way_at_a_yield(cache_dir: Path) -> None:
    """--major on a priority junction: netconvert rebuilds it with those roads lifted, and
    the others yield."""
    made = load_intersection(TOWN07, "358", "priority", cache_dir, major_road=["41", "-40"])
    assert made.major_road == ("41", "-40")
    assert {fork.edge for fork in made.forks.values() if fork.yield_sign} == {"-35"}
