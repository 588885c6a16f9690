"""Benchmark: the generator on the bundled intersections, and Step 3 against the paper's
single nonlinear z3 formulation on the same problems (same run, so the ratio holds).

Run with `make bench`. Each case extends an ego-only test-case (duration 25 s) by the
given routes under a budget; the table has per-step times, p50/p95 of the total and the
success rate per number of new non-egos.
"""

from __future__ import annotations

import platform
import statistics
import time
from datetime import date

from service.core.budget import run_with_budget
from service.core.errors import ScengenError
from service.core.generate import extend_testcase
from service.core.testcase import new_testcase
from service.core.timing import solve_nonlinear, solve_timing

BUDGET = 20.0
NONLINEAR_BUDGET = 10.0
CASES = [
    ("4way-stop", "S2C_1:C2W_1", ("W2C_0:C2E_0",)),
    ("4way-stop", "S2C_1:C2W_1", ("N2C_0:C2S_0",)),
    ("4way-stop", "S2C_1:C2W_1", ("E2C_1:C2S_1",)),
    ("4way-stop", "S2C_1:C2W_1", ("W2C_1:C2E_1",)),
    ("t-stop", "E2C_0:C2S_0", ("W2C_0:C2E_0",)),
    ("t-stop", "E2C_0:C2S_0", ("S2C_0:C2W_0",)),
    ("y-uncontrolled", "N2C_0:C2SE_0", ("SW2C_0:C2N_0",)),
    ("y-uncontrolled", "N2C_0:C2SE_0", ("SE2C_0:C2SW_0",)),
    ("t-stop", "E2C_0:C2S_0", ("W2C_0:C2E_0", "S2C_0:C2W_0")),
    ("y-uncontrolled", "N2C_0:C2SE_0", ("SW2C_0:C2N_0", "SE2C_0:C2N_0")),
    ("4way-stop", "S2C_1:C2W_1", ("W2C_0:C2E_0", "N2C_0:C2S_0")),
    ("4way-stop", "S2C_1:C2W_1", ("W2C_0:C2E_0", "N2C_0:C2S_0", "E2C_1:C2S_1")),
]
SEEDS = (0, 1)


def percentile(values: list[float], share: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, round(share * (len(ordered) - 1)))]


def main() -> None:
    print(f"# generator benchmark, {date.today()}, {platform.node()}, Python "
          f"{platform.python_version()}, {platform.machine()}, budget {BUDGET:g} s")  # fmt: skip
    rows: dict[int, list[tuple[bool, float]]] = {}
    ratios = []
    header = f"{'case':52s} seed  result    total  poses  order timing verify  tried"
    print(header)
    for network, ego, routes in CASES:
        for seed in SEEDS:
            start = new_testcase(network, ego, duration=25.0)
            started = time.perf_counter()
            try:
                extension = extend_testcase(start, list(routes), seed=seed, budget=BUDGET)
                ok, seconds, tried = True, extension.seconds, len(extension.attempts)
            except ScengenError as exc:
                ok, seconds, tried = False, {}, 0
                reason = type(exc).__name__
            total = time.perf_counter() - started
            rows.setdefault(len(routes), []).append((ok, total))
            steps = " ".join(f"{seconds.get(k, 0.0):6.2f}" for k in
                             ("poses", "ordering", "timing", "verification"))  # fmt: skip
            name = f"{network} {ego} + {' + '.join(routes)}"
            print(f"{name:52s} {seed:4d}  {'ok' if ok else reason:8s} {total:6.2f} {steps} "
                  f"{tried:6d}")  # fmt: skip
            if ok and extension.timing_problem is not None:
                problem = extension.timing_problem
                clock = time.perf_counter()
                solve_timing(problem, BUDGET)
                linear = time.perf_counter() - clock
                clock = time.perf_counter()
                try:
                    run_with_budget(solve_nonlinear, (problem,), NONLINEAR_BUDGET, "nonlinear")
                    nonlinear = time.perf_counter() - clock
                except ScengenError:
                    nonlinear = NONLINEAR_BUDGET  # timed out: counted at the budget
                ratios.append((nonlinear, linear))
    print()
    for count, results in sorted(rows.items()):
        totals = [t for ok, t in results if ok]
        rate = len(totals) / len(results)
        if totals:
            p50, p95 = percentile(totals, 0.5), percentile(totals, 0.95)
            share = f"{len(totals)}/{len(results)}"
            print(f"{count} new non-ego(s): success {rate:.0%} ({share}), p50 {p50:.2f} s, "
                  f"p95 {p95:.2f} s")  # fmt: skip
        else:
            print(f"{count} new non-ego(s): success 0% (0/{len(results)})")
    if ratios:
        paper = statistics.median(n for n, _ in ratios)
        ours = statistics.median(lin for _, lin in ratios)
        timeouts = sum(1 for n, _ in ratios if n >= NONLINEAR_BUDGET)
        over = f"{timeouts} over its {NONLINEAR_BUDGET:g} s budget"
        print(f"Step 3 on the solved problems (n={len(ratios)}): two-phase linear median "
              f"{ours * 1000:.0f} ms; the paper's nonlinear formulation median "
              f"{paper * 1000:.0f} ms ({over}); ratio {paper / ours:.1f}x")  # fmt: skip


if __name__ == "__main__":
    main()
