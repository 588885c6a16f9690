"""Benchmark: what the RSS guard costs per replay step with six cars.

A chain grown to level 5 on the bundled four-way (the ego and five non-egos; the ego on the
route that meets the most other forks, as bench_chains does) is replayed in libsumo, in
this process, with `sumo` and with `sumo+rss`, alternately, REPEATS times each: the
difference of the medians over the steps is the guard's cost per step as a replay sees it.
The guard's own calls (building RSS's world model and asking ad-rss) are timed too. Each
time is taken twice: the CPU time of this process (what the guard costs, robust to other
work on the machine) and the wall-clock time (which on a busy machine also holds the time
slices other processes took: the load average is printed beside).

Run with `make bench` (or `python -m bench.bench_rss`). Target (issue 33): at most 2 ms per
step on the 2-core machine.
"""

from __future__ import annotations

import os
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
from service.core.sumo.rss_guard import CarState, Restriction, RssGuard, WalkerState
from service.core.testcase import TestCase, new_testcase

LEVELS = 5
REPEATS = 5


class TimedGuard(RssGuard):
    """The guard, with the CPU and wall-clock time of each of its steps."""

    def __post_init__(self) -> None:
        super().__post_init__()
        self.cpu: list[float] = []
        self.wall: list[float] = []

    def step(
        self,
        t: float,
        ego: CarState,
        others: dict[str, CarState],
        signals: str | None,
        pedestrians: dict[str, WalkerState] | None = None,
        ego_pose: tuple[float, float, float] | None = None,
    ) -> Restriction | None:
        cpu, wall = time.process_time(), time.perf_counter()
        found = super().step(t, ego, others, signals, pedestrians, ego_pose)
        self.cpu.append(time.process_time() - cpu)
        self.wall.append(time.perf_counter() - wall)
        return found


def six_cars() -> TestCase:
    intersection = load_intersection("4way-stop")
    start = new_testcase("4way-stop", deepest_ego(intersection), duration=45.0)
    grown = grow_chain(start, LEVELS, seed=0, budget_per_level=60.0)
    return grown[-1].extension.testcase


def replay(plan_file: Path, controller: str, guard: RssGuard | None) -> tuple[float, float]:
    """CPU and wall-clock seconds per step of one replay, in this process."""
    import libsumo

    spec: dict[str, Any] = controller_spec(resolve_driver(controller))
    cpu, wall = time.process_time(), time.perf_counter()
    rows, _ = sumo_run.run(libsumo, plan_file, spec, guard=guard)
    return (time.process_time() - cpu) / len(rows), (time.perf_counter() - wall) / len(rows)


def row(label: str, cpu: list[float], wall: list[float]) -> str:
    ms = 1000.0
    return f"| {label} | {statistics.median(cpu) * ms:.3f} | {statistics.median(wall) * ms:.3f} |"


def main() -> None:
    testcase = six_cars()
    intersection = load_intersection("4way-stop")
    plain: list[tuple[float, float]] = []
    guarded: list[tuple[float, float]] = []
    own_cpu: list[float] = []
    own_wall: list[float] = []
    with tempfile.TemporaryDirectory(prefix="bench-rss-") as folder:
        ego, others = departures(testcase, intersection)
        network = str(intersection.network_file.resolve())
        write_run_files(testcase, ego, others, Path(folder), network, intersection)
        plan_file = Path(folder) / sumo_run.PLAN_FILE
        plan = sumo_run.load_plan(plan_file)
        summary: dict[str, Any] = {}
        for _ in range(REPEATS):
            plain.append(replay(plan_file, "sumo", None))
            guard = TimedGuard(plan["rss"])
            guarded.append(replay(plan_file, "sumo+rss", guard))
            own_cpu += guard.cpu
            own_wall += guard.wall
            summary = guard.summary()
    cpu_cost = statistics.median(g[0] for g in guarded) - statistics.median(p[0] for p in plain)
    wall_cost = statistics.median(g[1] for g in guarded) - statistics.median(p[1] for p in plain)
    cars = len(testcase.nonegos) + 1
    print(f"RSS guard, {date.today()}, {platform.machine()} {platform.processor() or ''}, "
          f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}, {cars} cars, "
          f"{summary['steps']} steps, {REPEATS} replays each")  # fmt: skip
    print("| ms per step (median) | CPU | wall-clock |")
    print("|---|---|---|")
    print(row("replay with sumo", [p[0] for p in plain], [p[1] for p in plain]))
    print(row("replay with sumo+rss", [g[0] for g in guarded], [g[1] for g in guarded]))
    print(f"| the guard's cost in a replay (difference) | {cpu_cost * 1000:.3f} | "
          f"{wall_cost * 1000:.3f} |")  # fmt: skip
    print(row("the guard's own step", own_cpu, own_wall))
    print(f"| the guard's own step, mean | {statistics.mean(own_cpu) * 1000:.3f} | "
          f"{statistics.mean(own_wall) * 1000:.3f} |")  # fmt: skip
    print(f"interventions: {summary['interventions']} of {summary['steps']} steps "
          f"(by car: {summary['by_car']}); fallback: {summary['fallback']}")  # fmt: skip
    print(f"target <= 2 ms per step (CPU): {'met' if cpu_cost <= 0.002 else 'NOT met'}")


if __name__ == "__main__":
    main()
