"""Lanes that are not for driving through (parking lanes, bays): kept in the model, not
offered as forks, exits or routes, and usable when named.

side-lanes (tests/data/junctions): an all-way stop C where E2C_0 allows 1.39 m/s beside
E2C_1's 13.89 (a parking lane), W2C_1 is fed by no lane while W2C_0 is (WW2W feeds only
W2C_0), and C2N_1 leads nowhere while C2N_0 goes on to N2NN. E2C, N2C and S2C start at the
map's border: no lane of theirs is fed, and none of them is a side lane for that.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from service.core.errors import UnknownRoute
from service.core.generator.additions import candidate_routes
from service.core.network import Intersection, load_intersection
from service.core.network.describe import describe_intersection
from service.core.testcase import new_testcase
from tests.conftest import TOWN05

SIDE_LANES = Path(__file__).parents[2] / "data" / "junctions" / "side-lanes.net.xml"


@pytest.fixture(scope="module")
def side() -> Intersection:
    return load_intersection(SIDE_LANES, "C")


def test_side_lanes_each_with_its_reason(side: Intersection) -> None:
    assert side.side_lanes == {
        "E2C_0": "1.39 m/s where its road allows 13.89 m/s (parking or a bay)",
        "W2C_1": "no lane leads into it, while its road's other lanes are fed",
        "C2N_1": "it leads nowhere, while its road's other lanes lead on",
    }


def test_routes_on_side_lanes_are_not_offered(side: Intersection) -> None:
    hidden = set(side.routes) - set(side.offered_routes)
    assert hidden == {"E2C_0:C2N_0", "E2C_0:C2W_0", "S2C_0:C2N_1", "W2C_1:C2N_1"}
    assert set(side.offered_forks) == {"E2C_1", "N2C_0", "S2C_0", "W2C_0"}
    described = describe_intersection(side)
    assert {r["id"] for r in described["routes"]} == set(side.offered_routes)
    assert {f["lane"] for f in described["forks"]} == set(side.offered_forks)
    assert "C2N_1" not in {e["lane"] for e in described["exits"]}
    listed = [c for r in described["routes"] for c in r["conflicts"]]
    assert not set(listed) & hidden
    assert [s["lane"] for s in described["side_lanes"]] == ["C2N_1", "E2C_0", "W2C_1"]


def test_a_route_on_a_side_lane_works_when_named(side: Intersection) -> None:
    assert side.route("E2C_0:C2W_0").fork == "E2C_0"
    testcase = new_testcase(SIDE_LANES, "E2C_0:C2W_0", junction="C")
    assert testcase.ego.route.fork == "E2C_0"
    with pytest.raises(UnknownRoute) as refused:
        side.route("E2C_0:C2S_0")
    assert "E2C_0:C2W_0" not in str(refused.value)  # the choices offered: through routes


def test_a_chain_never_adds_a_car_on_a_side_lane(side: Intersection) -> None:
    testcase = new_testcase(SIDE_LANES, "S2C_0:C2W_0", junction="C")
    candidates = candidate_routes(testcase, side)
    assert candidates and not set(candidates) & (set(side.routes) - set(side.offered_routes))


def test_carla_parking_lanes_are_side_lanes(cache_dir: Path) -> None:
    junction = load_intersection(TOWN05, "53", "allway_stop", cache_dir)
    assert set(junction.side_lanes) == {"-4_0", "-5_0", "4_0", "5_0"}
    assert all("1.39 m/s" in reason for reason in junction.side_lanes.values())
    assert "-4_0:-5_0" in junction.routes and "-4_0:-5_0" not in junction.offered_routes
