"""Chains of extensions on real cities' junctions as the maps have them (issue 45): a yield
junction and an actuated light of Nuremberg and of West Oakland, two levels each; real SUMO,
clingo and z3, and every level checked by the checker alone."""

from __future__ import annotations

from pathlib import Path

import pytest

from service.core.generator.extension import extend_testcase
from service.core.motion.poses import generate_poses
from service.core.network import load_intersection
from service.core.testcase import load_testcase_intersection, new_testcase
from tests.cli.test_city_maps import NUREMBERG, OAKLAND
from tests.core.generator.test_extension import assert_strictly_more_complex

NUREMBERG_LIGHT = "cluster_33028836_34912162_418027507_418027513_418027531_418027538_560938497"
OAKLAND_LIGHT = "cluster_436645469_53131081"


@pytest.mark.parametrize(
    ("network", "junction", "ego", "duration", "levels"),
    [
        # the ego turns left from the minor road; cars on the major road from either side
        (NUREMBERG, "33059581", "-4984772#0_0:128048761#0_0", 25.0,
         ["-128048761#0_0:-248976030_0", "248976030_0:128048761#0_0"]),
        # a permissive left turn at the light; the oncoming car, then one turning in after it
        (NUREMBERG, NUREMBERG_LIGHT, "248976047#0_2:128048760#1_0", 30.0,
         ["32020663#0_1:32020663#4_1", "32020663#0_0:128048760#1_0"]),
        # straight across the major road from a yield sign
        (OAKLAND, "53027354", "-6329561#1_0:-6329561#0_0", 25.0,
         ["202455444#0_0:202455444#2_0", "-202455444#2_0:-202455444#1_0"]),
        # a permissive left turn on the light's second green (51 s into its 90 s cycle)
        (OAKLAND, OAKLAND_LIGHT, "-202455444#1_0:202455449#0_0", 91.0,
         ["162921797_0:202455444#0_0", "393667837_2:202455444#0_0"]),
    ],
    ids=["Nuremberg-yield", "Nuremberg-actuated", "West-Oakland-yield", "West-Oakland-actuated"],
)  # fmt: skip
def test_a_chain_grows_on_a_city_junction(
    network: Path, junction: str, ego: str, duration: float, levels: list[str], cache_dir: Path
) -> None:
    testcase = new_testcase(network, ego, junction, duration=duration, cache_dir=cache_dir)
    if testcase.signals is not None:  # read from the map's actuated program, and said so
        assert "actuated program" in (testcase.signals.note or "")
    else:
        assert (testcase.control, testcase.rules) == ("priority", "priority")
    intersection = load_testcase_intersection(testcase, cache_dir)
    for level, route in enumerate(levels, start=1):
        extended = extend_testcase(testcase, [route], seed=0, budget=120, intersection=intersection)
        assert_strictly_more_complex(testcase, extended.testcase)
        assert [n.added_in for n in extended.testcase.nonegos] == list(range(1, level + 1))
        testcase = extended.testcase


def test_a_car_keeps_its_lane_where_one_lane_widens_to_three(cache_dir: Path) -> None:
    """West Oakland's 417704456 widens from the one lane of the road before it to three, two
    of which turn into the two lanes of 202455451#0: a car starting on that road takes the
    lane its route names (SUMO, left to itself, takes the rightmost and turns into the
    wrong lane)."""
    intersection = load_intersection(OAKLAND, OAKLAND_LIGHT, None, cache_dir)
    route = intersection.route("417704456_1:202455451#0_1")
    [track] = generate_poses(intersection, [(route, 40.0)], speed=10.0, duration=10.0,
                             timestep=0.1)  # fmt: skip
    assert track.start_distance == 40.0
    assert track.samples[-1].distance > 60.0  # through the junction, on the lane it names
