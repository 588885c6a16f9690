"""Replays where the limit line lies before a short fork of a joined cluster: SUMO's driver
waits at it for the green and passes; a car that runs that light's red fails (real SUMO,
no mocks).

joined-signal (tests/data/junctions): U's links 14 and 15 (from the south) are green
21-39 s. nuremberg-cluster (tests/data/osm): issue 43's junction and program, where the
ego's light (link 2 of joinedS_1) is green from 18 s.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from service.core.network.signals import read_signals_file
from service.core.sim.replay import evaluate
from service.core.testcase import TestCase, new_testcase

DATA = Path(__file__).parents[2] / "data"
JOINED = DATA / "junctions" / "joined-signal.net.xml"
NUREMBERG = DATA / "osm" / "nuremberg-cluster.net.xml"
CLUSTER = "cluster_2069369114_250652038_264048471_265360716_3686017348"


def entry(evaluation: object) -> float:
    events = evaluation.verdict.ego_events  # type: ignore[attr-defined]
    return float(next(e.t for e in events if e.kind == "entered"))


@pytest.fixture(scope="module")
def nuremberg() -> TestCase:
    """Issue 43's level 0: the ego 30 m before its limit line at 8 m/s, 45 s."""
    program = read_signals_file(NUREMBERG.with_name("nuremberg-cluster.signals.json"))
    return new_testcase(NUREMBERG, "248976051#1_2:-248976032_0", junction=CLUSTER,
                        duration=45.0, start_speed=8.0, signals=program)  # fmt: skip


@pytest.mark.parametrize("controller", ["sumo", "sumo+rss"])
def test_sumo_waits_at_the_nuremberg_limit_line_and_passes(
    nuremberg: TestCase, controller: str
) -> None:
    evaluation = evaluate(nuremberg, controller)
    assert evaluation.verdict.passed, evaluation.verdict.reasons
    kinds = [e.kind for e in evaluation.verdict.ego_events]
    assert kinds.index("stopped") < kinds.index("entered")
    assert 18.0 < entry(evaluation) < 19.5  # on the green, at once
    assert evaluation.verdict.goal_time == pytest.approx(23.7, abs=0.2)


@pytest.mark.parametrize("route", ["U2C_0:C2N_0", "U2C_1:C2W_0"])
def test_sumo_waits_at_u_for_the_green_and_passes(route: str) -> None:
    testcase = new_testcase(JOINED, route, junction="C", duration=45.0)
    evaluation = evaluate(testcase, "sumo")
    assert evaluation.verdict.passed, evaluation.verdict.reasons
    stopped = [e.t for e in evaluation.verdict.ego_events if e.kind == "stopped"]
    assert stopped and stopped[0] < 8.0
    assert 21.0 < entry(evaluation) < 22.5


HOLDER = """
import json

class Holder:
    '''Holds its start speed through every light; writes what it was told.'''

    def __init__(self):
        self.seen = []

    def step(self, obs):
        self.seen.append((obs.t, obs.to_stop_line, obs.signal))
        with open("seen.json", "w") as out:
            json.dump(self.seen, out)
        return 0.0
"""


def test_a_car_that_runs_us_red_fails_where_it_crosses_the_line(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """On lane 1 C's own link (9) is green from 0 s, U's (15) red until 21 s: the ego that
    holds 8 m/s runs U's red. The checker's entry is where the controller was told it
    crossed its stop line, and the signal it was shown is U's."""
    (tmp_path / "holder.py").write_text(HOLDER)
    monkeypatch.chdir(tmp_path)
    testcase = new_testcase(JOINED, "U2C_1:C2N_1", junction="C", duration=25.0, start_speed=8.0)
    evaluation = evaluate(testcase, "holder:Holder")
    assert [v.rule for v in evaluation.verdict.violations] == ["stopAtRed"]
    seen = json.loads((tmp_path / "seen.json").read_text())
    crossed = next(t for t, to_line, _ in seen if to_line <= 0.0)
    assert entry(evaluation) == pytest.approx(crossed, abs=0.1 + 1e-6)
    assert {signal for t, _, signal in seen if t < 18.0} == {"r"}
