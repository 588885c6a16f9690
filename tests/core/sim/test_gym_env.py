"""The Gymnasium environment over the replay (real SUMO in its child process, no mocks)."""

from __future__ import annotations

import gc
import math
import os
import re
import signal
import subprocess
import sys
import textwrap
import warnings
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from service.core.errors import BudgetExceeded, InvalidInput
from service.core.generator.extension import extend_testcase
from service.core.sim.gym_env import EGO_FEATURES, NEIGHBOUR_FEATURES, ScengenEnv
from service.core.sim.replay import evaluate
from service.core.testcase import TestCase, dump_testcase, new_testcase

DOCS = Path(__file__).resolve().parents[3] / "docs" / "controllers.md"


@pytest.fixture(scope="module")
def alone() -> TestCase:
    """The ego alone, straight through the four-way stop."""
    return new_testcase("4way-stop", "S2C_0:C2N_0", duration=25.0, name="gym")


@pytest.fixture(scope="module")
def crossing(alone: TestCase) -> TestCase:
    """The same with a car from the east turning left across the ego's path."""
    return extend_testcase(alone, ["E2C_1:C2S_1"], seed=0, budget=120).testcase


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return True


def _run(env: ScengenEnv, policy: Any) -> tuple[list[Any], dict[str, Any], float, bool, bool]:
    """An episode from reset with ``policy(observation)``: observations seen, last info."""
    _, info = env.reset()
    seen = [info["observation"]]
    while True:
        _, reward, terminated, truncated, info = env.step(np.array([policy(seen[-1])]))
        if terminated or truncated:
            return seen, info, reward, terminated, truncated
        seen.append(info["observation"])


def test_the_docs_example_gets_the_plugins_verdict_and_trajectory(
    crossing: TestCase, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The docs' careful controller as a plug-in (``evaluate``) and as the policy of the
    docs' Gymnasium example: the same verdict, the same trajectory."""
    blocks = re.findall(r"```python\n(.*?)```", DOCS.read_text(), re.DOTALL)
    (careful,) = [block for block in blocks if "class Careful" in block]
    (example,) = [block for block in blocks if "ScengenEnv" in block]
    (tmp_path / "careful.py").write_text(careful)
    (tmp_path / "four-way-1.json").write_text(dump_testcase(crossing))
    monkeypatch.chdir(tmp_path)
    monkeypatch.syspath_prepend(str(tmp_path))
    evaluation = evaluate(crossing, "careful:Careful")
    assert evaluation.verdict.passed, evaluation.verdict.reasons

    names: dict[str, Any] = {}
    exec(example, names)  # the docs' loop, as written
    verdict, reward = names["verdict"], names["reward"]
    assert verdict.controller == "gym"
    assert replace(verdict, controller="careful:Careful") == evaluation.verdict
    assert (reward, names["terminated"], names["truncated"]) == (1.0, True, False)
    mine, theirs = names["info"]["evaluation"].trajectory, evaluation.trajectory
    assert len(mine) == len(theirs) > 10
    for ours, its in zip(mine, theirs, strict=True):
        assert (ours.t, ours.distance, ours.speed) == pytest.approx(
            (its.t, its.distance, its.speed), abs=1e-9
        )
        assert math.dist((ours.x, ours.y), (its.x, its.y)) < 1e-9
    assert min(s.speed for s in mine) < 0.05  # it stopped at the sign, then went


def test_flooring_it_through_the_stop_sign_fails_the_stop_sign(alone: TestCase) -> None:
    with ScengenEnv(alone) as env:
        seen, info, reward, terminated, truncated = _run(env, lambda obs: 100.0)
    verdict = info["verdict"]
    assert verdict.controller == "gym" and verdict.goal_reached and not verdict.passed
    assert [v.rule for v in verdict.violations] == ["stopAtSign"]
    assert (reward, terminated, truncated) == (-1.0, True, False)
    speeds = [o.ego.speed for o in seen]  # clipped to a_max, then v_max, as a plug-in's
    assert speeds[1] - speeds[0] == pytest.approx(alone.params.a_max * alone.timestep)
    assert max(speeds) == pytest.approx(alone.params.v_max)


def test_standing_still_runs_out_of_time(alone: TestCase) -> None:
    short = alone.model_copy(update={"duration": 3.0})
    with ScengenEnv(short) as env:
        seen, info, reward, terminated, truncated = _run(env, lambda obs: obs.a_min)
    assert (reward, terminated, truncated) == (-1.0, False, True)
    assert not info["verdict"].goal_reached
    assert info["observation"].t == pytest.approx(3.0) and len(seen) == 30


def test_the_observation_vector_says_what_the_docs_say(crossing: TestCase) -> None:
    with ScengenEnv(crossing, neighbours=2) as env:
        vector, info = env.reset()
        assert vector.shape == env.observation_space.shape == (EGO_FEATURES + 2 * 7,)
        assert env.observation_space.contains(vector)
        observation = info["observation"]
        ego, (car,) = observation.ego, observation.others
        assert vector[:8].tolist() == pytest.approx(
            [ego.speed, observation.to_stop_line, 0, 100, 0, 0, 0, 0], abs=1e-4
        )
        # car1 comes from the east: ahead-right of the ego driving north, heading west
        present, ahead, left, speed, cos, sin, pedestrian = vector[8:15]
        assert (present, pedestrian) == (1.0, 0.0)
        assert ahead == pytest.approx(car.y - ego.y, abs=1e-3)
        assert left == pytest.approx(ego.x - car.x, abs=1e-3)
        assert speed == pytest.approx(car.speed, abs=1e-4)
        assert (cos, sin) == pytest.approx((0.0, 1.0), abs=0.05)  # turned left of the ego
        assert vector[15:].tolist() == [0.0] * NEIGHBOUR_FEATURES  # padding


def test_gymnasiums_env_checker_passes(alone: TestCase) -> None:
    env = ScengenEnv(alone)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # advice (a normalized action space), not failures
        check_env(env, skip_render_check=True)
    env.close()


def test_reset_in_the_middle_starts_over_the_same(alone: TestCase, crossing: TestCase) -> None:
    with ScengenEnv(alone) as env:
        first, _ = env.reset()
        for _ in range(5):
            moved, *_ = env.step(np.array([2.0]))
        again, info = env.reset()
        assert np.array_equal(first, again) and not np.array_equal(first, moved)
        _, info = env.reset(options={"testcase": crossing})
        assert [o.id for o in info["observation"].others] == ["car1"]
        gentler = crossing.model_copy(
            update={"params": crossing.params.model_copy(update={"a_max": 1.0})}
        )
        with pytest.raises(InvalidInput, match="action space"):
            env.reset(options={"testcase": gentler})


def test_close_and_garbage_collection_leave_no_child(alone: TestCase) -> None:
    env = ScengenEnv(alone)
    env.reset()
    process = env._held.process
    assert process is not None and _alive(process.pid)
    env.close()
    assert process.returncode is not None and not _alive(process.pid)
    env.close()  # twice is fine

    env = ScengenEnv(alone)
    env.reset()
    process = env._held.process
    assert process is not None
    del env
    gc.collect()
    assert process.returncode is not None and not _alive(process.pid)


def test_a_budget_too_small_is_an_error_and_kills_the_child(alone: TestCase) -> None:
    with ScengenEnv(alone, budget=0.01) as env:
        with pytest.raises(BudgetExceeded, match=r"budget of 0.01 s .*no verdict"):
            env.reset()
        assert env._held.process is None
        env.budget = 60.0
        env.reset()  # a fresh child


SCRIPT = """
import sys, time
from service.core.sim.gym_env import ScengenEnv
from service.core.testcase import new_testcase

env = ScengenEnv(new_testcase("4way-stop", "S2C_0:C2N_0", duration=600.0))
env.reset()
print(env._held.process.pid, flush=True)
while True:
    env.step(0.0)
    time.sleep(0.01)
"""


def _as_a_shell_starts_it() -> None:
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def test_ctrl_c_leaves_no_child_and_no_files(tmp_path: Path) -> None:
    script = tmp_path / "policy.py"
    script.write_text(textwrap.dedent(SCRIPT))
    scratch = tmp_path / "tmp"  # the script's temporary files, and its child's
    scratch.mkdir()
    process = subprocess.Popen(
        [sys.executable, str(script)],
        env={**os.environ, "TMPDIR": str(scratch)},
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,  # its own process group, as a terminal's foreground job
        preexec_fn=_as_a_shell_starts_it,
    )
    assert process.stdout is not None
    child = int(process.stdout.readline())
    os.killpg(process.pid, signal.SIGINT)  # what Ctrl-C sends: the whole group
    _, err = process.communicate(timeout=30)
    assert "KeyboardInterrupt" in err, err
    survivors = subprocess.run(
        ["pgrep", "-g", str(process.pid)], capture_output=True, text=True, check=False
    )
    assert survivors.stdout == "" and not _alive(child)
    assert list(scratch.iterdir()) == []  # nothing half-written left
