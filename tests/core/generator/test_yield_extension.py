"""Extensions at junctions of SUMO type priority (yield signs on the minor road, CVC
21803), loaded as the map has them: real SUMO, clingo and z3; every result checked by the
checker alone (assert_strictly_more_complex)."""

from __future__ import annotations

from pathlib import Path

import pytest

from service.core.checker.check import check_testcase
from service.core.generator.extension import extend_testcase
from service.core.testcase import load_testcase_intersection, new_testcase
from tests.conftest import DATA, TOWN05, TOWN07
from tests.core.generator.test_extension import assert_strictly_more_complex, samples

SKEWED = DATA / "junctions" / "skewed-yield.net.xml"


@pytest.mark.parametrize(
    ("network", "junction", "ego", "new", "rules"),
    [
        # the ego on the minor road: the new car on the major road is owed 21803 (a)
        (SKEWED, "C", "S2C_0:C2N_0", "W2C_0:C2E_0", {"yieldAtYieldSign"}),
        # the ego on the major road: a car from the yield sign that entered first (21803 (b)),
        # or one it must not cut off otherwise
        (SKEWED, "C", "W2C_0:C2E_0", "S2C_0:C2N_0", None),
        # a T: the stem turns left across the major road
        (TOWN05, "1930", "-3_1:-11_1", "11_1:10_1", {"yieldAtYieldSign"}),
        # the Y: its minor road turns left across the bent major road
        (TOWN07, "358", "41_0:40_0", "-40_0:35_0", {"yieldAtYieldSign"}),
    ],
    ids=["skewed-minor", "skewed-major", "Town05-1930", "Town07-358"],
)
def test_a_priority_junction_extends_under_its_yield_rules(
    network: Path, junction: str, ego: str, new: str, rules: set[str] | None, cache_dir: Path
) -> None:
    old = new_testcase(network, ego, junction, duration=25.0, cache_dir=cache_dir)
    assert (old.control, old.rules) == ("priority", "priority")
    intersection = load_testcase_intersection(old, cache_dir)
    extended = extend_testcase(old, [new], seed=0, budget=120, intersection=intersection)
    assert_strictly_more_complex(old, extended.testcase)
    assert extended.testcase.certificates is not None
    complexity = samples(extended.testcase.certificates.complexity)
    verdict = check_testcase(extended.testcase, complexity, "complexity")
    broken = {v.rule for v in verdict.violations}
    assert broken and broken <= {
        "yieldAtYieldSign", "yieldToCarFromYieldSign", "leftTurnYieldsToOncoming",
        "oncomingYieldsToLeftTurn",
    }  # fmt: skip
    if rules is not None:
        assert broken == rules
