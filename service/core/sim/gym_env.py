"""A Gymnasium environment over the replay: ``reset()`` to a test-case, ``step(acceleration)``.

For researchers who train or evaluate policies in Python as Gymnasium environments. It is
the replay of ``scengen evaluate`` (service.core.sim.replay) driven from outside: the same
runner files, the same runner loop (service.core.sumo.run), the same observation as a
plug-in controller's (service.core.sim.controllers.Observation, in ``info["observation"]``)
and the same clipping of the command (``apply_command``); at the end ``info["verdict"]`` is
the checker's verdict on the ego's trajectory, exactly as ``evaluate`` judges it.

SUMO runs in a child process (``python -m service.core.sim.replay_child``; libsumo is a
per-process singleton), one per environment, reused from one episode to the next. Every
call (``reset``, ``step``) waits for it at most ``budget`` seconds: beyond that the child is
killed and the call raises BudgetExceeded (no verdict). ``close()``, garbage collection,
the end of the interpreter, and Ctrl-C during a call kill it; it dies with its parent.

The observation vector (float32; docs/controllers.md, "Gymnasium environment"):

======  =================================================================================
index   component
======  =================================================================================
0       the ego's speed (m/s)
1       metres from the ego's front bumper to its stop line (negative once past it)
2-4     the leader: 1 if there is one within 100 m, its gap (m; 100 without), its speed
5-7     the ego's signal: 1 for green (``G``, ``g``), yellow (``y``, ``Y``), stop (``r``,
        ``u``, ``s``); all 0 without a signal (or one that is off)
8 + 7k  the k-th nearest other road user (cars and pedestrians, by centre distance, then
        id), k < ``neighbours``: 1 if there is one, its centre's metres ahead of the ego's
        centre and to its left, its speed (m/s), the cosine and sine of its heading
        relative to the ego's (counterclockwise), 1 if a pedestrian; all 0 as padding
======  =================================================================================

Reward: 0 at every step but the last, +1 there if the verdict passes, -1 if it fails.
"""

from __future__ import annotations

import contextlib
import math
import pickle
import shutil
import subprocess
import sys
import tempfile
import time
import weakref
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

from service.core.budget import FRAME, kill_and_reap, read_frame
from service.core.checker.verdict import Verdict
from service.core.errors import BudgetExceeded, InvalidInput, ScengenError
from service.core.names import REPLAY_BUDGET
from service.core.network import Intersection
from service.core.sim.controllers import LEADER_LOOKAHEAD, Observation, Vehicle
from service.core.sim.replay import Evaluation, judge, prepare_replay
from service.core.testcase import TestCase, load_testcase_intersection, read_testcase

CHILD_COMMAND = [sys.executable, "-m", "service.core.sim.replay_child"]
EGO_FEATURES = 8
NEIGHBOUR_FEATURES = 7
SIGNAL_GROUPS = ("Gg", "yY", "rus")  # green, yellow, stop

Obs = NDArray[np.float32]
Action = NDArray[np.float64]


class ScengenEnv(gym.Env[Obs, Action]):
    """One test-case replayed in SUMO with the ego driven by ``step(acceleration)``.

    ``testcase``: a TestCase or a test-case file; ``reset(options={"testcase": ...})``
    switches to another with the same bounds (the action space is the first one's).
    ``controller``: the name the verdict gives the driver. ``neighbours``: how many other
    road users the observation vector holds."""

    metadata: dict[str, Any] = {"render_modes": []}  # noqa: RUF012 (gymnasium's attribute)

    def __init__(
        self,
        testcase: TestCase | str | Path,
        *,
        budget: float = REPLAY_BUDGET,
        neighbours: int = 8,
        controller: str = "gym",
        intersection: Intersection | None = None,
    ) -> None:
        self.testcase, self.intersection = _load(testcase, intersection)
        self.budget, self.neighbours, self.controller = budget, neighbours, controller
        bounds = self.testcase.params
        self._bounds = bounds.a_min, bounds.a_max
        self.action_space = gym.spaces.Box(bounds.a_min, bounds.a_max, (1,), np.float64)
        low = [0.0, -np.inf, 0.0, -np.inf, 0.0, 0.0, 0.0, 0.0]
        high = [np.inf, np.inf, 1.0, np.inf, np.inf, 1.0, 1.0, 1.0]
        low += [0.0, -np.inf, -np.inf, 0.0, -1.0, -1.0, 0.0] * neighbours
        high += [1.0, np.inf, np.inf, np.inf, 1.0, 1.0, 1.0] * neighbours
        self.observation_space = gym.spaces.Box(
            np.array(low, np.float32), np.array(high, np.float32), dtype=np.float32
        )
        self._held = _Held()  # the child and the runner's folder
        self._running = False
        self._last: Observation | None = None
        weakref.finalize(self, self._held.release)  # at garbage collection and at exit

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Obs, dict[str, Any]]:
        """Start the test-case (``options["testcase"]``: another one, a TestCase or a
        path); the first observation and ``info["observation"]``. The replay is
        deterministic: ``seed`` changes nothing."""
        super().reset(seed=seed)
        if options and options.get("testcase") is not None:
            testcase, intersection = _load(options["testcase"], options.get("intersection"))
            bounds = testcase.params.a_min, testcase.params.a_max
            if bounds != self._bounds:
                raise InvalidInput(
                    f"test-case bounds a_min, a_max = {bounds} differ from this environment's "
                    "action space; make a ScengenEnv for it"
                )
            self.testcase, self.intersection = testcase, intersection
        if self._running:  # end the episode under way; the child stays
            self._running = False
            self._expect(self._ask(("stop",), "ending the episode"), "done")
        self._held.remove_folder()
        self._held.folder = tempfile.mkdtemp(prefix="scengen-gym-")
        plan_file = prepare_replay(self.testcase, self.intersection, Path(self._held.folder))
        reply = self._expect(self._ask(("episode", str(plan_file)), "reset"), "observation")
        self._running = True
        self._last = reply[1]
        return self.features(reply[1]), {"observation": reply[1]}

    def step(self, action: Action | float) -> tuple[Obs, float, bool, bool, dict[str, Any]]:
        """Drive one step with the ego's acceleration (m/s², clipped to the test-case's
        bounds and the speed to [0, v_max], as a plug-in controller's command). At the end,
        ``info["verdict"]`` (the checker's Verdict) and ``info["evaluation"]`` (with the
        ego's trajectory); terminated: the ego is past its goal (or left the map),
        truncated: the test-case's duration is over."""
        if not self._running:
            raise ScengenError("the episode is over: call reset() first")
        command = float(np.asarray(action, dtype=np.float64).reshape(-1)[0])
        if not math.isfinite(command):
            raise ValueError(f"acceleration {command!r} is not a finite number")
        reply = self._ask(("action", command), "step")
        if reply[0] == "observation":
            self._last = reply[1]
            return self.features(reply[1]), 0.0, False, False, {"observation": reply[1]}
        _, rows, error, last = self._expect(reply, "done")
        self._running = False
        evaluation: Evaluation = judge(
            self.testcase, rows, error, self.controller, self.intersection
        )
        verdict: Verdict = evaluation.verdict
        observation = last or self._last
        assert observation is not None
        duration_over = rows[-1]["t"] >= self.testcase.duration - 1e-9
        left = last is not None and last.lane == ""  # past its goal, or off its route
        terminated = left or not duration_over
        info = {"observation": observation, "verdict": verdict, "evaluation": evaluation}
        reward = 1.0 if verdict.passed else -1.0
        return self.features(observation), reward, terminated, not terminated, info

    def features(self, observation: Observation) -> Obs:
        """The observation vector of ``observation`` (the module's docstring)."""
        ego = observation.ego
        leader = observation.leader
        values = [ego.speed, observation.to_stop_line]
        values += (
            [0.0, LEADER_LOOKAHEAD, 0.0] if leader is None else [1.0, leader.gap, leader.speed]
        )
        colour = observation.signal or ""
        values += [float(bool(colour) and colour in group) for group in SIGNAL_GROUPS]
        users = [(user, 0.0) for user in observation.others]
        users += [(user, 1.0) for user in observation.pedestrians]
        users.sort(key=lambda pair: (math.hypot(pair[0].x - ego.x, pair[0].y - ego.y), pair[0].id))
        for user, pedestrian in users[: self.neighbours]:
            values += [1.0, *_relative(ego, user), user.speed, *_turn(ego, user), pedestrian]
        values += [0.0] * (
            NEIGHBOUR_FEATURES * (self.neighbours - min(len(users), self.neighbours))
        )
        return np.array(values, dtype=np.float32)

    def close(self) -> None:
        """Kill the child and remove the runner's files."""
        self._running = False
        self._held.release()

    def _ask(self, message: tuple[Any, ...], what: str) -> tuple[Any, ...]:
        """Send ``message`` to the child and wait for its answer within the budget."""
        data = pickle.dumps(message)
        try:
            process = self._held.child()
            assert process.stdin is not None and process.stdout is not None
            process.stdin.write(FRAME.pack(len(data)) + data)
            process.stdin.flush()
            reply = read_frame(process.stdout.fileno(), time.monotonic() + self.budget)
        except TimeoutError:
            self._kill()
            raise BudgetExceeded(
                f"the gym environment's {what} did not finish within its budget of "
                f"{self.budget:g} s and was stopped; no verdict (raise the budget)"
            ) from None
        except (OSError, EOFError):
            self._kill()
            raise ScengenError(f"the gym environment's {what}: SUMO's process died") from None
        except BaseException:  # Ctrl-C: the child's state is unknown
            self._kill()
            raise
        answer = tuple(pickle.loads(reply))
        if answer[0] in ("error", "crash"):
            self._running = False
            if answer[0] == "error":
                raise answer[1]
            raise ScengenError(f"the gym environment's {what} crashed: {answer[1].splitlines()[0]}",
                               traceback=answer[1])  # fmt: skip
        return answer

    def _kill(self) -> None:
        """Kill the child: the episode under way is lost (the next reset starts another)."""
        self._held.kill()
        self._running = False

    def _expect(self, answer: tuple[Any, ...], kind: str) -> tuple[Any, ...]:
        if answer[0] != kind:
            self._kill()
            raise ScengenError(f"the gym environment's child answered {answer[0]}, not {kind}")
        return answer


def _load(
    testcase: TestCase | str | Path, intersection: Intersection | None
) -> tuple[TestCase, Intersection]:
    if isinstance(testcase, TestCase):
        return testcase, intersection or load_testcase_intersection(testcase)
    path = Path(testcase)
    loaded = read_testcase(path)
    return loaded, intersection or load_testcase_intersection(loaded, near=path.parent)


def _relative(ego: Vehicle, user: Vehicle) -> tuple[float, float]:
    """Where ``user``'s centre is from the ego's: metres ahead, metres to its left."""
    rad = math.radians(ego.heading)
    dx, dy = user.x - ego.x, user.y - ego.y
    return dx * math.sin(rad) + dy * math.cos(rad), -dx * math.cos(rad) + dy * math.sin(rad)


def _turn(ego: Vehicle, user: Vehicle) -> tuple[float, float]:
    """Cosine and sine of ``user``'s heading relative to the ego's, counterclockwise."""
    rad = math.radians(ego.heading - user.heading)  # headings turn clockwise
    return math.cos(rad), math.sin(rad)


class _Held:
    """An environment's child process and runner's folder: what ``close()`` and garbage
    collection release (kept apart from the environment, so that its finalizer does not
    keep the environment alive)."""

    def __init__(self) -> None:
        self.process: subprocess.Popen[bytes] | None = None
        self.folder: str | None = None

    def child(self) -> subprocess.Popen[bytes]:
        """The running child, started when there is none."""
        if self.process is None or self.process.poll() is not None:
            self.process = subprocess.Popen(
                CHILD_COMMAND, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                stderr=subprocess.DEVNULL,
            )  # fmt: skip
        return self.process

    def kill(self) -> None:
        """Kill the child (if any) and reap it."""
        process, self.process = self.process, None
        if process is None:
            return
        kill_and_reap(process)
        for stream in (process.stdin, process.stdout):
            if stream is not None:
                with contextlib.suppress(OSError):
                    stream.close()

    def remove_folder(self) -> None:
        folder, self.folder = self.folder, None
        if folder is not None:
            shutil.rmtree(folder, ignore_errors=True)

    def release(self) -> None:
        self.kill()
        self.remove_folder()
