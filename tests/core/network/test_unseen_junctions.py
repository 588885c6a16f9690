"""The intersection model on junctions it was never tuned on: no arm at a right angle.

skewed-allway: all-way stop, arms at compass bearings N 0, ENE 70, SSW 195, WSW 255 degrees.
y-uneven: uncontrolled Y, arms at N 0, ESE 105, SW 233 degrees (gaps 105, 128, 127).
One lane each way on every arm. Built from the plain-XML sources beside the .net.xml.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from service.core.network import ControlType, Intersection, Turn, load_intersection
from service.core.network.describe import describe_intersection
from service.core.testcase import new_testcase

JUNCTIONS = Path(__file__).parents[2] / "data" / "junctions"
SKEWED = JUNCTIONS / "skewed-allway.net.xml"
Y_UNEVEN = JUNCTIONS / "y-uneven.net.xml"
NETWORKS = {"skewed-allway": SKEWED, "y-uneven": Y_UNEVEN}


@pytest.fixture(scope="module")
def skewed() -> Intersection:
    return load_intersection(SKEWED, junction="C")


@pytest.fixture(scope="module")
def y_uneven() -> Intersection:
    return load_intersection(Y_UNEVEN, junction="C")


@pytest.fixture(scope="module", params=sorted(NETWORKS))
def unseen(request: pytest.FixtureRequest) -> Intersection:
    return load_intersection(NETWORKS[request.param], junction="C")


def arm_of(lane: str) -> str:
    """'N2C_0' -> 'N', 'C2ENE_0' -> 'ENE'."""
    edge = lane.rpartition("_")[0]
    return edge.removesuffix("2C").removeprefix("C2")


def test_load_skewed_allway_forks_and_control(skewed: Intersection) -> None:
    assert skewed.junction == "C"
    assert skewed.control is ControlType.ALLWAY_STOP
    assert not skewed.overridden
    # Approach headings are the arm bearings turned round: traffic drives towards C.
    assert {lane: fork.heading for lane, fork in skewed.forks.items()} == pytest.approx(
        {"N2C_0": 180.0, "ENE2C_0": 250.0, "SSW2C_0": 15.0, "WSW2C_0": 75.0}, abs=0.01
    )


def test_load_y_uneven_forks_and_control(y_uneven: Intersection) -> None:
    assert y_uneven.junction == "C"
    assert y_uneven.control is ControlType.RIGHT_BEFORE_LEFT
    assert not y_uneven.overridden
    assert {lane: fork.heading for lane, fork in y_uneven.forks.items()} == pytest.approx(
        {"N2C_0": 180.0, "ESE2C_0": 285.0, "SW2C_0": 53.0}, abs=0.01
    )


def test_route_every_fork_to_every_other_arm(unseen: Intersection) -> None:
    arms = {arm_of(lane) for lane in unseen.forks}
    assert {arm_of(lane) for lane in unseen.exits} == arms
    for lane in unseen.forks:
        reached = [arm_of(r.exit) for r in unseen.routes.values() if r.fork == lane]
        assert sorted(reached) == sorted(arms - {arm_of(lane)}), lane  # no U-turn, no repeats


def test_classify_skewed_allway_turns(skewed: Intersection) -> None:
    # Each arm has one straight (within 15 degrees), one left and one right.
    assert {r.id: r.turn for r in skewed.routes.values()} == {
        "N2C_0:C2ENE_0": Turn.LEFT,
        "N2C_0:C2SSW_0": Turn.STRAIGHT,
        "N2C_0:C2WSW_0": Turn.RIGHT,
        "ENE2C_0:C2N_0": Turn.RIGHT,
        "ENE2C_0:C2SSW_0": Turn.LEFT,
        "ENE2C_0:C2WSW_0": Turn.STRAIGHT,
        "SSW2C_0:C2ENE_0": Turn.RIGHT,
        "SSW2C_0:C2N_0": Turn.STRAIGHT,
        "SSW2C_0:C2WSW_0": Turn.LEFT,
        "WSW2C_0:C2ENE_0": Turn.STRAIGHT,
        "WSW2C_0:C2N_0": Turn.LEFT,
        "WSW2C_0:C2SSW_0": Turn.RIGHT,
    }


def test_classify_y_uneven_turns(y_uneven: Intersection) -> None:
    assert {r.id: r.turn for r in y_uneven.routes.values()} == {
        "N2C_0:C2ESE_0": Turn.LEFT,
        "N2C_0:C2SW_0": Turn.RIGHT,
        "ESE2C_0:C2N_0": Turn.RIGHT,
        "ESE2C_0:C2SW_0": Turn.LEFT,
        "SW2C_0:C2ESE_0": Turn.RIGHT,
        "SW2C_0:C2N_0": Turn.LEFT,
    }


def test_stop_every_fork_of_the_skewed_allway(skewed: Intersection) -> None:
    assert all(fork.stop_sign for fork in skewed.forks.values())
    assert {r.link_state for r in skewed.routes.values()} == {"w"}


def test_stop_no_fork_of_the_y_uneven(y_uneven: Intersection) -> None:
    assert not any(fork.stop_sign for fork in y_uneven.forks.values())


def test_relate_skewed_allway_right_and_opposite(skewed: Intersection) -> None:
    # Two skewed highways: N-SSW (160 degrees apart) and ENE-WSW (175 degrees apart).
    assert skewed.opposite == {
        "N2C_0": {"SSW2C_0"},
        "SSW2C_0": {"N2C_0"},
        "ENE2C_0": {"WSW2C_0"},
        "WSW2C_0": {"ENE2C_0"},
    }
    # Southbound from N the right hand points west: WSW. Around the junction, each arm has
    # the next arm counter-clockwise (seen from above) on its right.
    assert skewed.to_its_right == {
        "N2C_0": {"WSW2C_0"},
        "WSW2C_0": {"SSW2C_0"},
        "SSW2C_0": {"ENE2C_0"},
        "ENE2C_0": {"N2C_0"},
    }
    assert skewed.on_different_highways("N2C_0", "ENE2C_0")
    assert not skewed.on_different_highways("N2C_0", "SSW2C_0")


def test_relate_y_uneven_right_without_opposite(y_uneven: Intersection) -> None:
    # No two arms are 135 degrees or more apart, so none is opposite (a through road).
    assert all(not others for others in y_uneven.opposite.values())
    assert y_uneven.to_its_right == {
        "N2C_0": {"SW2C_0"},
        "SW2C_0": {"ESE2C_0"},
        "ESE2C_0": {"N2C_0"},
    }


def test_relate_right_of_as_one_cycle_through_every_fork(unseen: Intersection) -> None:
    for lane, others in unseen.to_its_right.items():
        assert len(others) == 1, lane
        (other,) = others
        assert lane not in unseen.to_its_right[other], (lane, other)  # never both ways
        assert other not in unseen.opposite[lane], (lane, other)
    for lane, others in unseen.opposite.items():
        assert all(lane in unseen.opposite[o] for o in others), lane
    start = next(iter(unseen.forks))
    visited = [start]
    while len(visited) <= len(unseen.forks):
        (following,) = unseen.to_its_right[visited[-1]]
        visited.append(following)
    assert visited[-1] == start
    assert set(visited) == set(unseen.forks)


def test_conflict_symmetrically_and_never_within_a_fork(unseen: Intersection) -> None:
    for route_ref, others in unseen.conflicts.items():
        for other in others:
            assert route_ref in unseen.conflicts[other], (route_ref, other)
            assert unseen.routes[other].fork != unseen.routes[route_ref].fork


def test_conflict_every_left_turn_crosses_a_route(unseen: Intersection) -> None:
    # A crossing, not only a merge: the conflicting route leaves by another exit.
    for route in unseen.routes.values():
        if route.turn is not Turn.LEFT:
            continue
        crossing = {
            other for other in unseen.conflicts[route.id] if unseen.routes[other].exit != route.exit
        }
        assert crossing, route.id


def test_conflict_skewed_allway_left_turn_from_north(skewed: Intersection) -> None:
    assert skewed.conflicts["N2C_0:C2ENE_0"] == {
        "SSW2C_0:C2N_0",  # oncoming straight
        "ENE2C_0:C2SSW_0",  # left turn from the arm on its left
        "ENE2C_0:C2WSW_0",  # straight from the left
        "WSW2C_0:C2N_0",  # left turn from the right
        "SSW2C_0:C2ENE_0",  # merge: oncoming right turn into the same exit
        "WSW2C_0:C2ENE_0",  # merge: straight from the right into the same exit
    }


@pytest.mark.parametrize(
    ("first", "second"),
    [
        ("N2C_0:C2ENE_0", "SSW2C_0:C2WSW_0"),  # opposite left turns pass each other
        ("N2C_0:C2WSW_0", "WSW2C_0:C2N_0"),  # both ways between two arms: a sliver
        ("ENE2C_0:C2SSW_0", "SSW2C_0:C2ENE_0"),  # both ways between two arms: a sliver
        ("N2C_0:C2WSW_0", "SSW2C_0:C2ENE_0"),  # right turns in different corners
    ],
)
def test_conflict_skewed_allway_not_between(skewed: Intersection, first: str, second: str) -> None:
    assert second not in skewed.conflicts[first]
    assert first not in skewed.conflicts[second]


def test_conflict_y_uneven_left_turn_from_north(y_uneven: Intersection) -> None:
    assert y_uneven.conflicts["N2C_0:C2ESE_0"] == {
        "ESE2C_0:C2SW_0",
        "SW2C_0:C2N_0",
        "SW2C_0:C2ESE_0",  # merge into the same exit
    }
    assert y_uneven.conflicts["N2C_0:C2SW_0"] == {"ESE2C_0:C2SW_0"}


def test_describe_unseen_junction(unseen: Intersection) -> None:
    described = describe_intersection(unseen)
    assert described["junction"] == "C"
    assert {f["lane"] for f in described["forks"]} == set(unseen.forks)
    assert {r["id"] for r in described["routes"]} == set(unseen.routes)


@pytest.mark.parametrize(
    ("name", "ego_route"),
    [
        ("skewed-allway", "N2C_0:C2ENE_0"),
        ("skewed-allway", "ENE2C_0:C2SSW_0"),
        ("skewed-allway", "SSW2C_0:C2WSW_0"),
        ("skewed-allway", "WSW2C_0:C2N_0"),
        ("y-uneven", "N2C_0:C2ESE_0"),
        ("y-uneven", "ESE2C_0:C2SW_0"),
        ("y-uneven", "SW2C_0:C2N_0"),
    ],
)
def test_create_testcase_for_a_left_turn_from_every_fork(name: str, ego_route: str) -> None:
    testcase = new_testcase(NETWORKS[name], ego_route)
    assert testcase.junction == "C"
    assert f"{testcase.ego.route.fork}:{testcase.ego.route.exit}" == ego_route
