"""Coverage of the generator: for every bundled intersection, every ego route and every
route that conflicts with it (on another fork), extend the ego-only test-case by one car
on that route and record the outcome: found (verified), none exists (proved), or none
found within the budget.

Run with `make coverage` (two worker processes; about two minutes on two cores). The
summary goes to stdout; docs/benchmarks.md keeps the last one.
"""

from __future__ import annotations

import platform
import sys
import time
from collections import Counter
from concurrent.futures import ProcessPoolExecutor
from datetime import date

from service.core.errors import NoMoreComplexTestCase, NoneFound, ScengenError
from service.core.generator.extension import extend_testcase
from service.core.network import load_intersection
from service.core.testcase import new_testcase

BUDGET = 30.0
NETWORKS = ("4way-stop", "t-stop", "y-uncontrolled")


def pairs() -> list[tuple[str, str, str]]:
    found = []
    for network in NETWORKS:
        junction = load_intersection(network)
        for ego in sorted(junction.routes):
            fork = junction.route(ego).fork
            for other in sorted(junction.conflicts[ego]):
                if junction.route(other).fork != fork:
                    found.append((network, ego, other))
    return found


def extend(case: tuple[str, str, str]) -> tuple[str, str, str, str, float, int]:
    network, ego, route = case
    started = time.perf_counter()
    try:
        extension = extend_testcase(new_testcase(network, ego, duration=30.0), [route], 0, BUDGET)
        outcome, tried = "found", len(extension.attempts)
    except NoMoreComplexTestCase:
        outcome, tried = "none exists", 0
    except NoneFound:
        outcome, tried = "none found", 0
    except ScengenError as exc:
        outcome, tried = f"error: {exc}", 0
    return network, ego, route, outcome, time.perf_counter() - started, tried


def main() -> None:
    cases = pairs()
    print(f"# generator coverage, {date.today()}, {platform.node()}, {len(cases)} pairs, "
          f"budget {BUDGET:g} s, seed 0")  # fmt: skip
    outcomes: dict[str, Counter[str]] = {}
    times: list[float] = []
    with ProcessPoolExecutor(2) as pool:
        for network, ego, route, outcome, seconds, tried in pool.map(extend, cases):
            print(f"{network:15s} {ego:14s} + {route:14s} {outcome:12s} {seconds:6.1f} s "
                  f"{tried:4d} answer sets", flush=True)  # fmt: skip
            outcomes.setdefault(network, Counter())[outcome] += 1
            if outcome == "found":
                times.append(seconds)
    print()
    print("| intersection | pairs | found | none exists | none found |")
    print("|---|---|---|---|---|")
    for network, counts in outcomes.items():
        total = sum(counts.values())
        print(f"| {network} | {total} | {counts['found']} | {counts['none exists']} | "
              f"{counts['none found']} |")  # fmt: skip
    times.sort()
    if times:
        print(f"\nfound: median {times[len(times) // 2]:.1f} s, max {times[-1]:.1f} s")
    sys.exit(0)


if __name__ == "__main__":
    main()
