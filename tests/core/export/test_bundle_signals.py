"""The exported SUMO bundle at a signalized junction: it carries the test-case's signal
program, its runner and its plain-sumo configuration load it, and run.py reproduces the
in-service evaluation (real SUMO, no mocks)."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import pytest

from service.core.checker.check import check_testcase
from service.core.export.bundle import export_bundle
from service.core.generator.extension import extend_testcase
from service.core.motion.trajectory import read_trajectory
from service.core.sim.controllers import BUILT_IN
from service.core.sim.replay import SIGNALS_FILE, evaluate
from service.core.sumo.binaries import sumo_binary
from service.core.testcase import TestCase, load_testcase_intersection, new_testcase
from tests.core.sim.test_replay_signals import EGO_ROUTE, with_offset


@pytest.fixture(scope="module")
def red_start() -> TestCase:
    """The ego's light red until 8 s, then green until 28 s."""
    return with_offset(new_testcase("4way-signal", EGO_ROUTE, duration=45.0, name="red"), 8.0)


@pytest.fixture(scope="module")
def with_car(red_start: TestCase) -> TestCase:
    return extend_testcase(red_start, ["N2C_1:C2E_1"], seed=0, budget=120).testcase


def test_the_plain_sumo_configuration_loads_the_program(
    red_start: TestCase, tmp_path: Path
) -> None:
    export_bundle(red_start, tmp_path)
    config = (tmp_path / "testcase.sumocfg").read_text()
    assert f'<additional-files value="testcase.types.xml,{SIGNALS_FILE}"/>' in config
    subprocess.run(
        [sumo_binary("sumo"), "-c", "testcase.sumocfg", "--end", "10"],
        cwd=tmp_path, check=True, capture_output=True, timeout=120,
    )  # fmt: skip


RUN_CONTROLLERS = """
import sys
import run
for controller in sys.argv[1:]:
    code = run.main(["--controller", controller, "--fcd-output", controller + ".fcd.xml"])
    assert code == 0, (controller, code)
"""


def test_the_bundle_runner_reproduces_the_evaluation_at_a_light(
    with_car: TestCase, tmp_path: Path
) -> None:
    """As test_bundle.test_the_bundle_runner_reproduces_the_evaluation does for the
    stop-sign cases: `run.py` in the exported bundle drives the ego along the trajectory of
    `scengen evaluate` (to a micrometre), with the same verdict, at a signalized junction,
    for every built-in controller."""
    intersection = load_testcase_intersection(with_car)
    export_bundle(with_car, tmp_path, intersection)
    subprocess.run(
        [sys.executable, "-c", RUN_CONTROLLERS, *BUILT_IN],
        cwd=tmp_path, check=True, capture_output=True, timeout=300,
    )  # fmt: skip
    for controller in BUILT_IN:
        evaluation = evaluate(with_car, controller, intersection)
        ego = read_trajectory(tmp_path / f"{controller}.fcd.xml", "ego", with_car.ego.length)
        assert len(ego) == len(evaluation.trajectory), controller
        for ours, theirs in zip(ego, evaluation.trajectory, strict=True):
            assert ours.t == theirs.t, controller
            assert math.dist((ours.x, ours.y), (theirs.x, theirs.y)) < 1e-6, controller
        bundle = check_testcase(with_car, ego, controller, intersection)
        assert bundle.passed == evaluation.verdict.passed, controller
        assert {v.rule for v in bundle.violations} == {
            v.rule for v in evaluation.verdict.violations
        }, controller
