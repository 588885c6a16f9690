"""The generator on signalized junctions: every level verified, every new car obeys its
signal, and the complexity certificate breaks a signal rule of a new car (real SUMO,
clingo and z3)."""

from __future__ import annotations

from pathlib import Path

import pytest

from service.core.checker.check import check_testcase
from service.core.errors import NoMoreComplexTestCase
from service.core.generator.extension import extend_testcase
from service.core.motion.poses import PoseSample
from service.core.testcase import TestCase, load_testcase_intersection, new_testcase
from tests.conftest import TOWN05, TOWN07
from tests.core.generator.test_extension import assert_strictly_more_complex

JUNCTIONS = Path(__file__).parents[2] / "data" / "junctions"
SIGNALS = Path(__file__).parents[2] / "data" / "signals"  # real maps' kinds of program
SIGNAL_RULES = {"turnOnGreenYieldsToOncoming", "yieldToInsideOnGreen", "yieldToInsideOnArrow",
                "yieldOnRightOnRed"}  # fmt: skip


def _samples(rows: object) -> list[PoseSample]:
    return [PoseSample(**s.model_dump()) for s in rows]  # type: ignore[attr-defined]


def _lawful_entries(testcase: TestCase) -> None:
    junction = load_testcase_intersection(testcase)
    for car in testcase.nonegos:
        route = junction.route(car.route.id)
        entries = [e for e in car.events if e.kind.value == "entered"]
        for entry in entries:
            colour = junction.signal_colour(route, entry.t)
            stopped = any(e.kind.value == "stopped" for e in car.events)
            go = ("G", "g", "y", "Y", "O", "o")
            assert colour in go or (colour == "s" and stopped), (car.id, colour)


@pytest.mark.parametrize(
    ("network", "junction", "ego", "routes"),
    [
        ("4way-signal", None, "S2C_1:C2W_1", ["N2C_1:C2S_1", "N2C_0:C2S_0"]),
        ("t-signal", None, "S2C_0:C2E_0", ["W2C_0:C2E_0"]),
        (str(JUNCTIONS / "skewed-signal.net.xml"), None, "SSW2C_0:C2N_0", ["N2C_0:C2ENE_0"]),
        (str(JUNCTIONS / "y-signal.net.xml"), None, "SW2C_0:C2N_0", ["ESE2C_0:C2SW_0"]),
        (str(TOWN05), "1126", "7_1:46_1", ["-6_0:-7_0", "-6_1:-7_1"]),
        (str(TOWN05), "1882", "46_1:-4_2", ["-45_0:-46_0"]),  # a T: its stem on red first
        (str(TOWN07), "68", "0_0:44_0", ["55_0:-0_0"]),
        # the new car's limit line is U's, before the short fork U2C (joined cluster)
        (str(JUNCTIONS / "joined-signal.net.xml"), "C", "N2C_0:C2W_0", ["U2C_1:C2W_0"]),
        (str(SIGNALS / "tee-actuated.net.xml"), None, "N2J_0:J2A_0", ["B2J_0:J2A_0"]),
        (str(SIGNALS / "tee-major-yellow.net.xml"), None, "A2J_0:J2N_0", ["B2J_0:J2A_0"]),
        (str(SIGNALS / "tee-long-phase.net.xml"), None, "A2J_0:J2N_0", ["B2J_0:J2A_0"]),
        (str(SIGNALS / "tee-off.net.xml"), None, "N2J_0:J2A_0", ["B2J_0:J2A_0"]),
    ],
    ids=["4way-signal", "t-signal", "skewed-signal", "y-signal", "Town05-1126", "Town05-1882",
         "Town07-68", "joined-signal", "tee-actuated", "tee-major-yellow", "tee-long-phase",
         "tee-off"],
)  # fmt: skip
def test_each_level_is_verified_and_breaks_a_signal_rule(
    network: str, junction: str | None, ego: str, routes: list[str]
) -> None:
    """Each level strictly more complex, judged by the checker alone (certificates, old cars
    kept, drivable, on the road), its complexity certificate breaking a signal rule of the
    new car, and every new car entering on a colour that lets it go."""
    testcase = new_testcase(network, ego, junction=junction, duration=45)
    for level, route in enumerate(routes, start=1):
        old = testcase
        testcase = extend_testcase(old, [route], seed=0, budget=120).testcase
        assert_strictly_more_complex(old, testcase)
        assert testcase.signals == old.signals and testcase.provenance is not None
        assert testcase.provenance["level"] == level
        violated = {v["rule"] for v in testcase.provenance["complexity_certificate_violates"]}
        assert violated and violated <= SIGNAL_RULES
        assert testcase.certificates is not None
        complex_ = check_testcase(testcase, _samples(testcase.certificates.complexity))
        assert {v.rule for v in complex_.violations} & SIGNAL_RULES
        _lawful_entries(testcase)


def test_extending_never_changes_the_program() -> None:
    old = new_testcase("t-signal", "S2C_0:C2E_0", duration=45)
    new = extend_testcase(old, ["W2C_0:C2E_0"], seed=0, budget=120).testcase
    assert new.signals == old.signals


def test_a_new_car_never_runs_its_red() -> None:
    """Town05 1126 (42 s green, 3 s yellow each way), ego turning left on its green: a new
    car from 47 faces red until 45 s, so in a 45 s test-case it could only take part by
    entering on red; no such order exists (asp/extension.lp's lawful-entry constraint),
    which is a proof, not a search that gave up. With events after the end it would enter
    on its next green: the refusal says the duration is what limits."""
    old = new_testcase(TOWN05, "-6_1:-47_1", junction="1126", duration=45)
    with pytest.raises(NoMoreComplexTestCase, match="the duration is what limits: no order "
                       "of events fits within 45 s") as refused:  # fmt: skip
        extend_testcase(old, ["47_1:46_1"], seed=0, budget=120)
    assert refused.value.context["longer"] > 45  # a duration past its red
