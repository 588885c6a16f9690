"""Benchmark: the generator against its targets, in one run (so every ratio holds).

1. Extensions by one, two and three new cars on the bundled junctions (duration 25 s,
   seeds 0 and 1): success rate, p50 and p95 of the wall time, per-step seconds, answer
   sets tried. Step 1 runs in the warm SUMO worker, as it does in a CLI chain, a job
   worker or the bench itself; the very first call pays its start (about 0.5 s).
2. The four-way example (three levels) for seeds 0, 1 and 2, as `scengen example` runs it.
3. Queues: two and three new cars in line on one fork in one extension (issue 16's target:
   three at one stop sign in under 5 s), seeds 0 and 1.
4. Signals: one new car at signalized junctions (the bundled four-way and T, two test
   junctions no constant was tuned on, three real junctions of Town05 and Town07 under
   their own programs; duration 45 s, seeds 0 and 1): success rate, p50 and p95 (issue
   32's targets: 100 %, 0.5 s, 2 s).
5. Step 3 against the paper's single nonlinear formulation (bench/paper_timing.py) on the
   Step 3 problems that the generator solved: the ratio of medians.

Variety and the comparison with random search (distinct verified extensions per
CPU-second) are bench/bench_variety.py's. Run with `make bench` (or `python -m
bench.bench_generate`); the markdown it prints goes to docs/benchmarks.md with the date
and the machine.
"""

from __future__ import annotations

import argparse
import platform
import statistics
import time
from datetime import date
from pathlib import Path

from bench.paper_timing import solve_paper
from service.cli.examples import EXAMPLES, run_example
from service.core.errors import ScengenError
from service.core.generator.extension import extend_testcase
from service.core.generator.timing import TimingProblem
from service.core.generator.timing_solve import solve_timing
from service.core.testcase import new_testcase

BUDGET = 20.0
PAPER_BUDGET = 10.0
CASES = [  # (network, ego, new routes)
    ("4way-stop", "S2C_1:C2W_1", ("W2C_0:C2E_0",)),
    ("4way-stop", "S2C_1:C2W_1", ("N2C_0:C2S_0",)),
    ("4way-stop", "S2C_1:C2W_1", ("E2C_1:C2S_1",)),
    ("4way-stop", "S2C_1:C2W_1", ("W2C_1:C2E_1",)),
    ("4way-stop", "E2C_1:C2S_1", ("S2C_1:C2N_1",)),
    ("t-stop", "E2C_0:C2S_0", ("W2C_0:C2E_0",)),
    ("t-stop", "E2C_0:C2S_0", ("S2C_0:C2W_0",)),
    ("y-uncontrolled", "N2C_0:C2SE_0", ("SW2C_0:C2N_0",)),
    ("y-uncontrolled", "N2C_0:C2SE_0", ("SE2C_0:C2SW_0",)),
    ("t-stop", "E2C_0:C2S_0", ("W2C_0:C2E_0", "S2C_0:C2W_0")),
    ("y-uncontrolled", "N2C_0:C2SE_0", ("SW2C_0:C2N_0", "SE2C_0:C2N_0")),
    ("4way-stop", "S2C_1:C2W_1", ("W2C_0:C2E_0", "N2C_0:C2S_0")),
    ("4way-stop", "E2C_1:C2S_1", ("S2C_1:C2N_1", "W2C_1:C2E_1")),
    ("4way-stop", "S2C_1:C2W_1", ("W2C_0:C2E_0", "N2C_0:C2S_0", "E2C_1:C2S_1")),
    ("4way-stop", "E2C_1:C2S_1", ("S2C_1:C2N_1", "W2C_1:C2E_1", "N2C_0:C2S_0")),
]
SEEDS = (0, 1)
DATA = Path(__file__).resolve().parents[1] / "tests" / "data"
SKEWED, Y_SIGNAL = (
    DATA / "junctions" / "skewed-signal.net.xml",
    DATA / "junctions" / "y-signal.net.xml",
)
TOWN05, TOWN07 = DATA / "carla" / "Town05.net.xml", DATA / "carla" / "Town07.net.xml"
SIGNAL_CASES = [  # (label, network, junction, ego, new route)
    ("4way-signal", "4way-signal", None, "N2C_1:C2E_1", "S2C_0:C2N_0"),
    ("4way-signal", "4way-signal", None, "N2C_1:C2E_1", "S2C_1:C2N_1"),
    ("4way-signal", "4way-signal", None, "N2C_1:C2E_1", "N2C_1:C2S_1"),
    ("4way-signal", "4way-signal", None, "E2C_0:C2W_0", "W2C_1:C2N_1"),
    ("t-signal", "t-signal", None, "E2C_0:C2S_0", "W2C_0:C2E_0"),
    ("t-signal", "t-signal", None, "E2C_0:C2S_0", "S2C_0:C2W_0"),
    ("t-signal", "t-signal", None, "S2C_0:C2E_0", "W2C_0:C2E_0"),
    ("skewed-signal", SKEWED, "C", "ENE2C_0:C2SSW_0", "N2C_0:C2SSW_0"),
    ("skewed-signal", SKEWED, "C", "ENE2C_0:C2SSW_0", "WSW2C_0:C2ENE_0"),
    ("y-signal", Y_SIGNAL, "C", "SW2C_0:C2N_0", "ESE2C_0:C2SW_0"),
    ("y-signal", Y_SIGNAL, "C", "SW2C_0:C2N_0", "SW2C_0:C2ESE_0"),
    ("Town05 1126", TOWN05, "1126", "-6_1:-47_1", "7_0:6_0"),
    ("Town05 1126", TOWN05, "1126", "-6_1:-47_1", "-6_1:-7_1"),
    ("Town05 1882", TOWN05, "1882", "46_1:-4_2", "-45_0:-46_0"),
    ("Town07 68", TOWN07, "68", "0_0:44_0", "55_0:-0_0"),
    ("Town07 335", TOWN07, "335", "24_0:62_0", "-23_0:62_0"),
]  # fmt: skip
QUEUES = [  # (network, ego, the fork's route, cars, duration)
    ("4way-stop", "E2C_1:C2S_1", "S2C_1:C2N_1", 2, 20.0),
    ("4way-stop", "E2C_0:C2N_0", "S2C_0:C2N_0", 3, 30.0),
    ("4way-stop", "E2C_1:C2S_1", "S2C_1:C2N_1", 3, 30.0),
    ("t-stop", "E2C_0:C2S_0", "S2C_0:C2W_0", 3, 30.0),
    ("y-uncontrolled", "N2C_0:C2SE_0", "SW2C_0:C2N_0", 3, 30.0),
]


def percentile(values: list[float], share: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, round(share * (len(ordered) - 1)))]


def cases(problems: list[TimingProblem]) -> None:
    print("## Extensions by one, two and three new cars\n")
    print("| case | seed | result | total s | poses | ordering | timing | verify | "
          "answer sets |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|---|")
    rows: dict[int, list[tuple[bool, float]]] = {}
    for network, ego, routes in CASES:
        for seed in SEEDS:
            start = new_testcase(network, ego, duration=25.0)
            clock = time.perf_counter()
            try:
                extension = extend_testcase(start, list(routes), seed=seed, budget=BUDGET)
            except ScengenError as error:
                total = time.perf_counter() - clock
                rows.setdefault(len(routes), []).append((False, total))
                print(f"| {network} {ego} + {' + '.join(routes)} | {seed} | "
                      f"{type(error).__name__} | {total:.2f} | | | | | |", flush=True)  # fmt: skip
                continue
            total = time.perf_counter() - clock
            rows.setdefault(len(routes), []).append((True, total))
            if extension.timing_problem is not None:
                problems.append(extension.timing_problem)
            s = extension.seconds
            print(f"| {network} {ego} + {' + '.join(routes)} | {seed} | ok | {total:.2f} | "
                  f"{s['poses']:.2f} | {s['ordering']:.2f} | {s['timing']:.2f} | "
                  f"{s['verification']:.2f} | {len(extension.attempts)} |", flush=True)  # fmt: skip
    print()
    for count, results in sorted(rows.items()):
        times = [t for ok, t in results if ok]
        found = f"{len(times)}/{len(results)}"
        if times:
            p50, p95 = percentile(times, 0.5), percentile(times, 0.95)
            print(f"- {count} new car(s): success {len(times) / len(results):.0%} ({found}), "
                  f"p50 {p50:.2f} s, p95 {p95:.2f} s")  # fmt: skip
        else:
            print(f"- {count} new car(s): success 0 % ({found})")
    print()


def signals() -> None:
    print("## Signals: one new car at a signalized junction (duration 45 s)\n")
    print("| junction | ego + new car | seed | result | total s | answer sets | rule broken |")
    print("|---|---|---|---|---|---|---|")
    results: list[tuple[bool, float]] = []
    for label, network, junction, ego, route in SIGNAL_CASES:
        for seed in SEEDS:
            start = new_testcase(network, ego, junction=junction, duration=45.0)
            clock = time.perf_counter()
            try:
                extension = extend_testcase(start, [route], seed=seed, budget=BUDGET)
            except ScengenError as error:
                total = time.perf_counter() - clock
                results.append((False, total))
                print(f"| {label} | {ego} + {route} | {seed} | {type(error).__name__} | "
                      f"{total:.2f} | | |", flush=True)  # fmt: skip
                continue
            total = time.perf_counter() - clock
            results.append((True, total))
            provenance = extension.testcase.provenance or {}
            broken = ", ".join(v["rule"] for v in provenance["complexity_certificate_violates"])
            print(f"| {label} | {ego} + {route} | {seed} | ok | {total:.2f} | "
                  f"{len(extension.attempts)} | {broken or 'rear-end'} |", flush=True)  # fmt: skip
    times = [t for ok, t in results if ok]
    print()
    print(f"- one new car at a light: success {len(times) / len(results):.0%} "
          f"({len(times)}/{len(results)}), p50 {percentile(times, 0.5):.2f} s, "
          f"p95 {percentile(times, 0.95):.2f} s\n")  # fmt: skip


def example_chain() -> None:
    print("## `scengen example four-way` (three levels)\n")
    for seed in (0, 1, 2):
        clock = time.perf_counter()
        try:
            run_example(EXAMPLES["four-way"], seed, budget=120.0)
            outcome = "ok"
        except ScengenError as error:
            outcome = f"{type(error).__name__}: {error}"[:120]
        print(f"- seed {seed}: {time.perf_counter() - clock:.2f} s, {outcome}", flush=True)
    print()


def queues() -> None:
    print("## Queues: new cars in line on one fork, in one extension\n")
    print("| case | seed | result | total s | answer sets |")
    print("|---|---|---|---|---|")
    for network, ego, route, count, duration in QUEUES:
        for seed in SEEDS:
            start = new_testcase(network, ego, duration=duration)
            clock = time.perf_counter()
            try:
                extension = extend_testcase(start, [route] * count, seed=seed, budget=60.0)
                outcome, tried = "ok", str(len(extension.attempts))
            except ScengenError as error:
                outcome, tried = type(error).__name__, ""
            print(f"| {network} {ego}, {count} x {route}, {duration:g} s | {seed} | {outcome} | "
                  f"{time.perf_counter() - clock:.2f} | {tried} |", flush=True)  # fmt: skip
    print()


def against_paper(problems: list[TimingProblem]) -> None:
    print("## Step 3 against the paper's nonlinear formulation\n")
    ours, paper, solved = [], [], 0
    for problem in problems:
        clock = time.perf_counter()
        solve_timing.__wrapped__(problem)  # not the remembered answer
        ours.append(time.perf_counter() - clock)
        clock = time.perf_counter()
        outcome = solve_paper(problem, PAPER_BUDGET)
        paper.append(min(time.perf_counter() - clock, PAPER_BUDGET))
        solved += isinstance(outcome, dict)
    if not problems:
        print("(no problems)")
        return
    ratio = statistics.median(paper) / statistics.median(ours)
    print(f"On the {len(problems)} Step 3 problems the generator solved: ours median "
          f"{statistics.median(ours) * 1000:.0f} ms; the paper's formulation median "
          f"{statistics.median(paper) * 1000:.0f} ms (solved {solved}, the rest counted at "
          f"its {PAPER_BUDGET:g} s budget); ratio of medians {ratio:.1f}x\n")  # fmt: skip


def main() -> None:
    argparse.ArgumentParser(description=__doc__.splitlines()[0]).parse_args()
    print(f"# generator benchmark, {date.today()}, {platform.node()}, Python "
          f"{platform.python_version()}, {platform.machine()}\n")  # fmt: skip
    problems: list[TimingProblem] = []
    cases(problems)
    signals()
    queues()
    example_chain()
    against_paper(problems)


if __name__ == "__main__":
    main()
