"""Benchmark: a replay in a warm child against one in a fresh child.

Run with `make bench`. The four-way example's level 2 (two cars) replayed with four
built-in controllers, several rounds, each replay in a warm child of
``service.core.sim.replay.REPLAYS`` and in a fresh child (``run_with_budget``, as every
replay ran before), interleaved in one run so that the ratio holds on a noisy machine.
The evaluations are compared too: the same in both.
"""

from __future__ import annotations

import platform
import statistics
import time
from datetime import date

from service.cli.examples import EXAMPLES, run_example
from service.core.budget import run_with_budget
from service.core.sim import replay
from service.core.testcase import load_testcase_intersection

CONTROLLERS = ("sumo", "sumo-rolling-stop", "sumo+rss", "certificate:complexity")
ROUNDS = 5


def main() -> None:
    testcase = run_example(EXAMPLES["four-way"])[2]
    intersection = load_testcase_intersection(testcase)
    warm_call = replay.REPLAYS.call
    times: dict[str, list[float]] = {"warm": [], "fresh": []}
    replay.evaluate(testcase, "sumo", intersection)  # the first warm child starts here
    for _ in range(ROUNDS):
        for name in CONTROLLERS:
            evaluations = {}
            for kind, call in (("warm", warm_call), ("fresh", run_with_budget)):
                replay.REPLAYS.call = call  # type: ignore[method-assign]
                started = time.perf_counter()
                evaluations[kind] = replay.evaluate(testcase, name, intersection)
                times[kind].append(time.perf_counter() - started)
            assert evaluations["warm"] == evaluations["fresh"], name
    replay.REPLAYS.call = warm_call  # type: ignore[method-assign]
    warm, fresh = statistics.median(times["warm"]), statistics.median(times["fresh"])
    print(f"replays of {testcase.name} ({testcase.duration:g} s), {len(CONTROLLERS)} "
          f"controllers x {ROUNDS} rounds, {date.today()} on {platform.node()} "
          f"({platform.machine()}, Python {platform.python_version()}):")  # fmt: skip
    print(f"  warm child:  median {warm:.3f} s (min {min(times['warm']):.3f}, "
          f"max {max(times['warm']):.3f})")  # fmt: skip
    print(f"  fresh child: median {fresh:.3f} s (min {min(times['fresh']):.3f}, "
          f"max {max(times['fresh']):.3f})")  # fmt: skip
    print(f"  fresh / warm: {fresh / warm:.1f}x; the same evaluations in both")


if __name__ == "__main__":
    main()
