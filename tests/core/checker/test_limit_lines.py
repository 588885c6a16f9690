"""The checker where the limit line lies before a short fork of a joined cluster.

joined-signal (tests/data/junctions, program in joined-signal.tll.xml): from the south
the cars stop at U's line for U's links 14 (lane 0) and 15 (lane 1), green 21-39 s; C's
links of lane 1 (9, 10) are green from 0 s already (clearing what came through U). The
cluster's shape reaches 4 m upstream of U's line, so before the fix a car waiting there
had "entered" on red, and a car running U's red on lane 1 entered "on green" (link 9).
Real Step 1 drives (libsumo), real clingo; the ego starts 30 m before the limit line.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from service.core.checker.check import check_testcase
from service.core.checker.verdict import Verdict
from service.core.motion.poses import PoseSample, generate_poses
from service.core.testcase import TestCase, load_testcase_intersection, new_testcase
from tests.helpers import retime, stop_and_go

JOINED = Path(__file__).parents[2] / "data" / "junctions" / "joined-signal.net.xml"
DURATION = 45.0
START = 30.0
GREEN = 21.0  # U's links 14 and 15 turn green


@pytest.fixture(scope="module", params=["U2C_0:C2N_0", "U2C_1:C2W_0"])
def testcase(request: pytest.FixtureRequest) -> TestCase:
    return new_testcase(JOINED, request.param, junction="C", duration=DURATION)


def drive(testcase: TestCase, wait_until: float | None) -> list[PoseSample]:
    """The ego at 8 m/s; with ``wait_until``, standing with its front 1 m before the limit
    line (where SUMO's driver waits) until then."""
    junction = load_testcase_intersection(testcase)
    route = junction.route(testcase.ego.route.id)
    track = generate_poses(junction, [(route, START)], 8.0, DURATION, 0.1)[0]
    if wait_until is None:
        return list(track.samples)
    braking = 8.0 / 3.0  # s at 3 m/s^2
    stands = (START - 1.0 - 8.0 * braking / 2.0) / 8.0 + braking  # when it stands still
    profile = stop_and_go(8.0, START - 1.0, 3.0, wait_until - stands, 2.0)
    return retime(track, profile, DURATION, 0.1)


def rules(verdict: Verdict) -> list[str]:
    return [v.rule for v in verdict.violations]


def entry(verdict: Verdict) -> float:
    return next(e.t for e in verdict.ego_events if e.kind == "entered")


def test_waiting_at_the_limit_line_for_the_green_passes(testcase: TestCase) -> None:
    verdict = check_testcase(testcase, drive(testcase, GREEN + 0.5))
    assert verdict.passed, verdict.reasons
    kinds = [e.kind for e in verdict.ego_events]
    assert kinds.index("arrived") < kinds.index("stopped") < kinds.index("entered")
    assert entry(verdict) > GREEN


def test_running_the_red_at_the_limit_line_is_a_red_light_violation(testcase: TestCase) -> None:
    """At 8 m/s the ego crosses U's line 30 m on, at 3.75 s, on U's red: entered there
    (not where the cluster's polygon begins, 4 m before), and the light it ran is U's (on
    lane 1 C's own link shows green then)."""
    verdict = check_testcase(testcase, drive(testcase, None))
    assert rules(verdict) == ["stopAtRed"]
    assert entry(verdict) == pytest.approx(START / 8.0, abs=1e-3)
    arrived = next(e.t for e in verdict.ego_events if e.kind == "arrived")
    assert arrived == pytest.approx((START - 10.0) / 8.0, abs=1e-3)


def test_going_before_the_green_is_a_red_light_violation(testcase: TestCase) -> None:
    verdict = check_testcase(testcase, drive(testcase, 15.0))
    assert rules(verdict) == ["stopAtRed"]
    assert 15.0 < entry(verdict) < GREEN
