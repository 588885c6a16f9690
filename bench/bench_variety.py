"""Benchmark: how many different test-cases the generator makes, and at what cost (issue 34).

"Distinct" is service.core.generator.variety's: two extensions are the same test-case when
they add cars on the same routes that both stop or both do not, keep the same order of
events among the test-case's cars, and every new car arrives and enters the junction
within DISTINCT_GAP (1 s) of its counterpart (``distinct_count``), not byte equality.

1. Variety, on bench_generate's cases (an ego-only test-case of 25 s extended by one, two
   or three new cars): distinct extensions from seeds 0 to 4 (one ``extend_testcase``
   each), and how many exist: ``extend_testcases`` with count 10 (seed 0) and its
   shortfall. The target: 5 of 5 where at least 5 exist.
2. Count 10 against one: the CPU time of ``extend_testcases(count=10)`` and of
   ``extend_testcase`` (seed 0 both), alternated call by call REPEATS times in this run,
   the ratio of the medians. The target: 10 distinct where 10 exist, in at most 3 times
   the time of one.
3. Against random search: distinct verified extensions per CPU-second of the generator
   (one ``extend_testcases`` call with count 10, seed 0, the median CPU time of REPEATS
   calls) and of bench/random_search.py's sampler (unchanged; every verified extension it
   finds within its CPU budget is kept and counted by ``distinct_count``), at level 1 and
   level 2 on the bundled four-way stop, the T and the uncontrolled Y. Level 2 extends
   the generator's level 1 (seed 0) for both. The target: 100 times the sampler.

4. The command line as a user runs it: the wall clock of a fresh ``scengen extend`` and of
   ``scengen extend --count 10`` (each a new process: Python, the network, SUMO's start),
   alternated REPEATS times on the level-1 tasks of part 3, the ratio of the medians.

CPU time is bench.cpu's: this process, its finished children and the warm SUMO worker
(both searches are charged alike). Run with `make bench` (or `python -m
bench.bench_variety`); the markdown it prints goes to docs/benchmarks.md.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from datetime import date
from pathlib import Path
from typing import TypeVar

from bench.bench_generate import CASES
from bench.cpu import cpu_seconds
from bench.random_search import budgeted_search
from service.core.errors import ScengenError
from service.core.generator.extension import extend_testcase, extend_testcases
from service.core.generator.variety import distinct_count
from service.core.testcase import TestCase, new_testcase

SEEDS = range(5)
COUNT = 10
REPEATS = 3
BUDGET = 60.0  # seconds of wall clock a call may take (only ever stops a call)
DURATION = 25.0
RANDOM_TASKS = [  # (name, network, ego, duration, level 1 route, level 2 route)
    ("4way-stop", "4way-stop", "E2C_1:C2S_1", 20.0, "S2C_1:C2N_1", "W2C_1:C2E_1"),
    ("t-stop", "t-stop", "E2C_0:C2S_0", 25.0, "W2C_0:C2E_0", "S2C_0:C2W_0"),
    ("y-uncontrolled", "y-uncontrolled", "N2C_0:C2SE_0", 25.0, "SW2C_0:C2N_0", "SE2C_0:C2SW_0"),
]  # fmt: skip

Result = TypeVar("Result")


def cpu_timed(call: Callable[..., Result], *args: object) -> tuple[Result, float]:
    """The call's result and the CPU seconds it took (bench.cpu's count)."""
    clock = cpu_seconds()
    result = call(*args)
    return result, cpu_seconds() - clock


def describe(network: str, old: TestCase, routes: Sequence[str]) -> str:
    return f"{network} {old.ego.route.id} + {' + '.join(routes)}"


def variety() -> None:
    print("## Variety: distinct extensions from seeds 0-4, how many exist, count 10 against one\n")
    print(f"Count {COUNT} and one: seed 0, alternated {REPEATS} times, median CPU seconds.\n")
    print(f"| case | distinct of 5 seeds | count {COUNT}: distinct returned | shortfall | "
          f"one: CPU s | count {COUNT}: CPU s | ratio |")  # fmt: skip
    print("|---|---|---|---|---|---|---|")
    for network, ego, routes in CASES:
        start = new_testcase(network, ego, duration=DURATION)
        made = []
        for seed in SEEDS:
            try:
                made.append(extend_testcase(start, routes, seed=seed, budget=BUDGET).testcase)
            except ScengenError:
                continue
        case, seeded = describe(network, start, routes), distinct_count(made)
        ones, tens = [], []
        try:
            for _ in range(REPEATS):
                ones.append(cpu_timed(extend_testcase, start, routes, 0, BUDGET)[1])
                many, spent = cpu_timed(extend_testcases, start, routes, COUNT, 0, BUDGET)
                tens.append(spent)
        except ScengenError as error:
            print(f"| {case} | {seeded} | {type(error).__name__} | | | | |", flush=True)
            continue
        found = distinct_count([e.testcase for e in many.found])
        one, ten = statistics.median(ones), statistics.median(tens)
        print(f"| {case} | {seeded} | {found} | {many.shortfall(COUNT) or '-'} | {one:.2f} | "
              f"{ten:.2f} | {ten / one:.1f}x |", flush=True)  # fmt: skip
    print()


def against_random(cpu_budget: float) -> None:
    print("## Against random search: distinct verified extensions per CPU-second\n")
    print(f"Generator: one call with count {COUNT}, seed 0, median CPU of {REPEATS}; random: "
          f"bench/random_search.py, seed 0, {cpu_budget:g} CPU-seconds per task.\n")  # fmt: skip
    print("| task | generator: distinct / CPU s | per CPU-s | random: verified, distinct / "
          "CPU s | per CPU-s | ratio |")  # fmt: skip
    print("|---|---|---|---|---|---|")
    for name, network, ego, duration, first, second in RANDOM_TASKS:
        empty = new_testcase(network, ego, duration=duration)
        level1 = extend_testcase(empty, [first], seed=0, budget=BUDGET).testcase
        for level, old, route in ((1, empty, first), (2, level1, second)):
            spent = []
            for _ in range(REPEATS):
                many, cpu = cpu_timed(extend_testcases, old, [route], COUNT, 0, BUDGET)
                spent.append(cpu)
            ours = distinct_count([e.testcase for e in many.found])
            ours_cpu = statistics.median(spent)
            run = budgeted_search(old, route, 0, cpu_budget)
            theirs = distinct_count(run.found)
            rate, baseline = ours / ours_cpu, theirs / run.cpu_seconds
            ratio = f"{rate / baseline:.0f}x" if theirs else f"> {rate * run.cpu_seconds:.0f}x"
            shown = f"{baseline:.3f}" if theirs else f"< {1 / run.cpu_seconds:.3f} (none)"
            print(f"| {name} level {level}: + {route} | {ours} / {ours_cpu:.2f} | {rate:.2f} | "
                  f"{run.successes}, {theirs} / {run.cpu_seconds:.1f} | {shown} | {ratio} |",
                  flush=True)  # fmt: skip
    print()


def command_line() -> None:
    print(f"## The command line: a fresh `scengen extend` against `--count {COUNT}`\n")
    print(f"Wall clock of each process, alternated {REPEATS} times, medians.\n")
    print(f"| task | one: s | count {COUNT}: s | ratio |")
    print("|---|---|---|---|")
    scengen = [sys.executable, "-m", "service"]
    for name, network, ego, duration, first, _ in RANDOM_TASKS:
        with tempfile.TemporaryDirectory() as folder:
            old = Path(folder) / "old.json"
            new = [*scengen, "new", network, "--ego", ego, "--duration", str(duration)]
            subprocess.run([*new, "-o", str(old)], check=True, capture_output=True)
            extend = [*scengen, "extend", str(old), "--add", first]
            ones, tens = [], []
            for _ in range(REPEATS):
                for extra, times in (([], ones), (["--count", str(COUNT)], tens)):
                    clock = time.perf_counter()
                    subprocess.run([*extend, *extra, "-o", str(Path(folder) / "new.json")],
                                   check=True, capture_output=True)  # fmt: skip
                    times.append(time.perf_counter() - clock)
        one, ten = statistics.median(ones), statistics.median(tens)
        print(f"| {name} level 1: + {first} | {one:.2f} | {ten:.2f} | {ten / one:.1f}x |",
              flush=True)  # fmt: skip
    print()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--random-cpu", type=float, default=60.0,
                        help="CPU seconds of random search per task (default 60)")  # fmt: skip
    parser.add_argument("--only", choices=("variety", "random", "command-line"),
                        help="run one of the parts")  # fmt: skip
    args = parser.parse_args()
    load = ", ".join(f"{v:.1f}" for v in os.getloadavg())
    print(f"# variety benchmark, {date.today()}, {platform.node()}, Python "
          f"{platform.python_version()}, {platform.machine()}, {os.cpu_count()} CPUs, "
          f"load at the start {load}\n")  # fmt: skip
    if args.only in (None, "variety"):
        variety()
    if args.only in (None, "random"):
        against_random(args.random_cpu)
    if args.only in (None, "command-line"):
        command_line()
    print(f"load at the end: {', '.join(f'{v:.1f}' for v in os.getloadavg())}")


if __name__ == "__main__":
    main()
