"""Benchmark: what the RSS guard costs per replay step with six cars.

A chain grown to level 5 on the bundled four-way (the ego and five non-egos; the ego on the
route that meets the most other forks, as bench_chains does) is replayed in libsumo, in
this process, with `sumo` and with `sumo+rss`, alternately, REPEATS times each: the
difference of the medians over the steps is the guard's cost per step as a replay sees it.
The guard's own calls (building RSS's world model and asking ad-rss) are timed too.

Run with `make bench` (or `python -m bench.bench_rss`). Target (issue 33): at most 2 ms per
step on the 2-core machine.
"""

from __future__ import annotations

import platform
import statistics
import tempfile
import time
from datetime import date
from pathlib import Path
from typing import Any

from bench.bench_chains import deepest_ego
from service.core.generator.chain import grow_chain
from service.core.network import load_intersection
from service.core.sim.controllers import resolve_driver
from service.core.sim.replay import controller_spec, departures, write_run_files
from service.core.sumo import run as sumo_run
from service.core.sumo.rss_guard import CarState, Restriction, RssGuard
from service.core.testcase import TestCase, new_testcase

LEVELS = 5
REPEATS = 5


class TimedGuard(RssGuard):
    """The guard, with the time of each of its steps."""

    def __post_init__(self) -> None:
        super().__post_init__()
        self.times: list[float] = []

    def step(
        self, t: float, ego: CarState, others: dict[str, CarState], signals: str | None
    ) -> Restriction | None:
        started = time.perf_counter()
        found = super().step(t, ego, others, signals)
        self.times.append(time.perf_counter() - started)
        return found


def six_cars() -> TestCase:
    intersection = load_intersection("4way-stop")
    start = new_testcase("4way-stop", deepest_ego(intersection), duration=45.0)
    grown = grow_chain(start, LEVELS, seed=0, budget_per_level=60.0)
    return grown[-1].extension.testcase


def replay(plan_file: Path, controller: str, guard: RssGuard | None) -> tuple[float, int]:
    """Seconds and steps of one replay, in this process."""
    import libsumo

    spec: dict[str, Any] = controller_spec(resolve_driver(controller))
    started = time.perf_counter()
    rows, _ = sumo_run.run(libsumo, plan_file, spec, guard=guard)
    return time.perf_counter() - started, len(rows)


def main() -> None:
    testcase = six_cars()
    intersection = load_intersection("4way-stop")
    plain, guarded, own = [], [], []
    with tempfile.TemporaryDirectory(prefix="bench-rss-") as folder:
        ego, others = departures(testcase, intersection)
        network = str(intersection.network_file.resolve())
        write_run_files(testcase, ego, others, Path(folder), network, intersection)
        plan_file = Path(folder) / sumo_run.PLAN_FILE
        plan = sumo_run.load_plan(plan_file)
        summary: dict[str, Any] = {}
        for _ in range(REPEATS):
            seconds, steps = replay(plan_file, "sumo", None)
            plain.append(seconds / steps)
            guard = TimedGuard(plan["rss"])
            seconds, steps = replay(plan_file, "sumo+rss", guard)
            guarded.append(seconds / steps)
            own += guard.times
            summary = guard.summary()
    ms = 1000.0
    cost = (statistics.median(guarded) - statistics.median(plain)) * ms
    own.sort()
    cars = len(testcase.nonegos) + 1
    print(f"RSS guard, {date.today()}, {platform.machine()} {platform.processor() or ''}, "
          f"{cars} cars, {summary['steps']} steps, {REPEATS} replays each")  # fmt: skip
    print("| measure | ms per step |")
    print("|---|---|")
    print(f"| replay with sumo (median) | {statistics.median(plain) * ms:.3f} |")
    print(f"| replay with sumo+rss (median) | {statistics.median(guarded) * ms:.3f} |")
    print(f"| the guard's cost in a replay (difference) | {cost:.3f} |")
    print(f"| the guard's own step (median / p95 / max) | {statistics.median(own) * ms:.3f} / "
          f"{own[int(0.95 * (len(own) - 1))] * ms:.3f} / {own[-1] * ms:.3f} |")  # fmt: skip
    print(f"interventions: {summary['interventions']} of {summary['steps']} steps "
          f"(by car: {summary['by_car']}); fallback: {summary['fallback']}")  # fmt: skip
    print(f"target <= 2 ms per step: {'met' if cost <= 2.0 else 'NOT met'}")


if __name__ == "__main__":
    main()
