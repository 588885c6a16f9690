"""Benchmark: people on foot (issue 44's targets, docs/benchmarks.md).

1. One new pedestrian: on every bundled junction with crosswalks, for every ego route the
   junction offers and every walk that crosses it, an ego-only test-case of 45 s extended
   by a pedestrian on that walk. An outcome is a verified extension, a proof that none
   exists ("no more complex test-case exists": every order of events the rules allow needs
   the certificate in her lane while she is in its), or none found. Success is an answer
   that is not "none found"; CPU seconds per extension (bench.cpu: the warm SUMO worker
   too) as p50 and p95.
2. Mixed chains: on each bundled crosswalk junction and on a real map with guessed
   crosswalks (Town05 1126, a signal of CARLA's town), chains grown as a user grows them
   (service.core.generator.chain.grow: a car or a pedestrian each level, on a way no one
   takes yet first), 45 s test-cases, 30 s per level, up to 8 levels, seeds 0 to 2; the ego
   the route that meets the most other forks, as bench.bench_chains picks it.
   Per junction: the depth each seed reached, the pedestrians each chain holds, and the
   median CPU seconds of each level over the seeds.

Run with `make bench-pedestrians` (or `python -m bench.bench_pedestrians`).
"""

from __future__ import annotations

import argparse
import platform
import statistics
import tempfile
from collections import Counter
from dataclasses import dataclass
from datetime import date
from pathlib import Path

from bench.bench_chains import deepest_ego
from bench.cpu import cpu_seconds
from service.core.errors import NoMoreComplexTestCase, NoneFound, ScengenError
from service.core.generator.chain import grow
from service.core.generator.extension import extend_testcase
from service.core.network import Intersection, load_intersection
from service.core.testcase import TestCase, new_testcase

ROOT = Path(__file__).resolve().parents[1]
TOWN05 = ROOT / "tests" / "data" / "carla" / "Town05.net.xml"
DURATION = 45.0
BUDGET = 30.0
MAX_LEVELS = 8
SINGLE = ("crosswalk-stop", "crosswalk-signal")
CHAINS = [  # (label, network, junction, guess crossings)
    ("crosswalk-stop", "crosswalk-stop", None, False),
    ("crosswalk-signal", "crosswalk-signal", None, False),
    ("Town05 1126 (signal), crosswalks guessed", str(TOWN05), "1126", True),
]


def one_pedestrian(network: str) -> tuple[Counter[str], list[float]]:
    """Outcomes and CPU seconds of every (ego route, walk over it) extension."""
    junction = load_intersection(network)
    outcomes: Counter[str] = Counter()
    seconds = []
    for ego in sorted(junction.offered_routes):
        start = new_testcase(network, ego, duration=DURATION)
        for walk in sorted(w.id for w in junction.walks.values() if ego in w.conflicts):
            clock = cpu_seconds()
            try:
                extend_testcase(start, [], budget=BUDGET, intersection=junction, walks=[walk])
                outcomes["verified"] += 1
            except NoMoreComplexTestCase:
                outcomes["none exists (proved)"] += 1
            except NoneFound:
                outcomes["none found"] += 1
            seconds.append(cpu_seconds() - clock)
    return outcomes, seconds


@dataclass
class Chain:
    cpu: list[float]
    people: int
    stopped: str


def grow_mixed(start: TestCase, junction: Intersection, seed: int) -> Chain:
    cpu: list[float] = []
    current, stopped = start, f"{MAX_LEVELS} levels"
    for _ in range(MAX_LEVELS):
        clock = cpu_seconds()
        try:
            current = grow(current, seed, BUDGET, junction).extension.testcase
        except ScengenError as error:
            stopped = type(error).__name__
            break
        cpu.append(cpu_seconds() - clock)
    return Chain(cpu, len(current.pedestrians), stopped)


def _percentile(values: list[float], share: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, round(share * (len(ordered) - 1)))]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=3)
    args = parser.parse_args()
    machine = f"{platform.node()}, Python {platform.python_version()}"
    print(f"# people on foot, {date.today()}, {machine}, duration {DURATION:g} s")
    print()
    print("| junction | cases | verified | none exists (proved) | none found | "
          "success | p50 CPU s | p95 CPU s |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|")
    for network in SINGLE:
        outcomes, seconds = one_pedestrian(network)
        cases = sum(outcomes.values())
        success = (cases - outcomes["none found"]) / cases
        print(f"| {network} | {cases} | {outcomes['verified']} | "
              f"{outcomes['none exists (proved)']} | {outcomes['none found']} | "
              f"{success:.0%} | {statistics.median(seconds):.2f} | "
              f"{_percentile(seconds, 0.95):.2f} |", flush=True)  # fmt: skip
    print()
    print("| junction | ego | depth per seed | pedestrians per chain | stopped because | "
          "median CPU s per level | slowest level (median) |")  # fmt: skip
    print("|---|---|---|---|---|---|---|")
    cache = Path(tempfile.mkdtemp(prefix="bench-pedestrians-"))
    for label, network, junction_id, guess in CHAINS:
        junction = load_intersection(network, junction_id, cache_dir=cache, guess_crossings=guess)
        ego = deepest_ego(junction)
        start = new_testcase(network, ego, junction=junction_id, duration=DURATION,
                             cache_dir=cache, guess_crossings=guess)  # fmt: skip
        chains = [grow_mixed(start, junction, seed) for seed in range(args.seeds)]
        depth = max(len(c.cpu) for c in chains)
        medians = [statistics.median(c.cpu[k] for c in chains if len(c.cpu) > k)
                   for k in range(depth)]  # fmt: skip
        print(f"| {label} | {ego} | {' / '.join(str(len(c.cpu)) for c in chains)} | "
              f"{' / '.join(str(c.people) for c in chains)} | "
              f"{', '.join(sorted({c.stopped for c in chains}))} | "
              f"{', '.join(f'{m:.2f}' for m in medians) or '-'} | "
              f"{max(medians, default=0.0):.2f} |", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
