"""Replay at a signalized junction: SUMO runs the test-case's signal program, its drivers
obey it, and a user controller sees its light (real SUMO, no mocks)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from service.core.export.bundle import export_bundle
from service.core.sim.replay import SIGNALS_FILE, evaluate
from service.core.testcase import (
    TestCase,
    dump_testcase,
    load_testcase_intersection,
    new_testcase,
    parse_testcase,
)

EGO_ROUTE = "S2C_0:C2N_0"  # link 9 of traffic light C


def with_offset(testcase: TestCase, offset: float) -> TestCase:
    document = json.loads(dump_testcase(testcase))
    document["signals"]["offset"] = offset
    return parse_testcase(json.dumps(document))


@pytest.fixture(scope="module")
def red_start() -> TestCase:
    """The ego's light red until 8 s (offset 8: the program's first phase starts then),
    green until 28 s, yellow, then red; it reaches the line during the red."""
    return with_offset(new_testcase("4way-signal", EGO_ROUTE, duration=45.0, name="red"), 8.0)


def test_the_program_is_the_testcases_not_the_networks(red_start: TestCase) -> None:
    intersection = load_testcase_intersection(red_start)
    assert intersection.signals is not None
    link = intersection.route(EGO_ROUTE).link_index
    assert intersection.signals.timeline(link, 45.0)[:2] == [(0.0, 8.0, "r"), (8.0, 28.0, "G")]


RECORD_LIGHTS = """
import json, sys
from pathlib import Path
import libsumo
import run

states = []

def on_step(traci, row, present):
    states.append((row["t"], traci.trafficlight.getRedYellowGreenState("C"),
                   traci.trafficlight.getProgram("C")))
    traci.vehicle.setSpeed("ego", 0.0)  # it stands: it never reaches its goal and leaves
    return None

run.run(libsumo, Path(run.PLAN_FILE), {"kind": "external"}, on_step)
print(json.dumps(states))
"""


def test_sumo_shows_the_testcases_lights_at_every_step(red_start: TestCase, tmp_path: Path) -> None:
    """Every step of the bundle's runner (the replay's loop), SUMO's state of traffic light
    C is the program's at that time for every link, phase changes included (offset 8:
    8, 28, 31, 33 s)."""
    testcase = red_start
    program = load_testcase_intersection(testcase).signals
    assert program is not None
    export_bundle(testcase, tmp_path)
    assert f'programID="{program.program_id}-scengen"' in (tmp_path / SIGNALS_FILE).read_text()
    done = subprocess.run(
        [sys.executable, "-c", RECORD_LIGHTS], cwd=tmp_path, check=True,
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    states = json.loads(done.stdout.splitlines()[-1])
    # the ego stands before the line (speed 0): every step of the 45 s but the last (the
    # runner asks no controller there)
    assert len(states) == 450
    for t, state, active in states:
        expected = "".join(program.colour(link, t) for link in range(program.links))
        assert state == expected, t
        assert active == f"{program.program_id}-scengen"
    shown = {round(t, 1): state for t, state, _ in states}
    assert shown[7.9][9] == "r" and shown[8.0][9] == "G"


@pytest.mark.parametrize(
    "controller", ["sumo", "sumo-cautious", "sumo-rolling-stop", "sumo-aggressive"]
)
def test_sumo_drivers_stop_at_the_red_light(red_start: TestCase, controller: str) -> None:
    evaluation = evaluate(red_start, controller)
    assert evaluation.verdict.passed, evaluation.verdict.reasons
    stopped = [s.t for s in evaluation.trajectory if s.speed < 0.1]
    assert stopped and stopped[-1] < 8.0  # waits for the green
    entered = [e.t for e in evaluation.verdict.ego_events if e.kind == "entered"]
    assert entered and entered[0] >= 8.0


RECORDER = """
import json

class Recorder:
    def __init__(self):
        self.seen = []

    def step(self, obs):
        self.seen.append((obs.t, obs.signal))
        with open("seen.json", "w") as out:
            json.dump(self.seen, out)
        return 0.0
"""


def test_a_user_controller_sees_its_light(
    red_start: TestCase, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    (tmp_path / "recorder.py").write_text(RECORDER)
    monkeypatch.chdir(tmp_path)
    evaluate(red_start, "recorder:Recorder")
    seen = json.loads((tmp_path / "seen.json").read_text())
    program = load_testcase_intersection(red_start).signals
    assert program is not None and len(seen) > 20
    assert [signal for _, signal in seen] == [program.colour(9, t) for t, _ in seen]
    assert seen[0][1] == "r"


def test_no_signal_at_an_unsignalized_junction(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    (tmp_path / "recorder.py").write_text(RECORDER)
    monkeypatch.chdir(tmp_path)
    evaluate(new_testcase("4way-stop", EGO_ROUTE, duration=10.0), "recorder:Recorder")
    seen = json.loads((tmp_path / "seen.json").read_text())
    assert seen and {signal for _, signal in seen} == {None}


def test_right_on_red_needs_a_stop_that_only_the_rolling_stop_skips() -> None:
    """t-signal's right turn S2C_0:C2E_0 shows ``s`` (right on red after a stop) until
    22 s: SUMO's driver stops, then turns on red; the rolling stop rolls through."""
    testcase = new_testcase("t-signal", "S2C_0:C2E_0", duration=30.0)
    assert testcase.control == "traffic_light_right_on_red"
    stops = evaluate(testcase, "sumo")
    assert stops.verdict.passed, stops.verdict.reasons
    assert any(s.speed < 0.1 for s in stops.trajectory)
    rolls = evaluate(testcase, "sumo-rolling-stop")
    assert [v.rule for v in rolls.verdict.violations] == ["stopBeforeRightOnRed"]
    assert min(s.speed for s in rolls.trajectory) >= 2.9
