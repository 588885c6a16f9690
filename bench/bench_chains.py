"""Benchmark: chains grown the way a user grows them, one new car per level.

Each level adds one car on a route that conflicts with the ego's, from a fork no car uses
yet (service.core.generator.chain.grow), with a budget of 30 s per level, until no route is left or
none gives an extension. On every bundled junction, on CARLA's Town05 junction 396 made an
all-way stop (the paper's junction), on a Town05 T-junction made `priority_stop`, on
Town07 358 as `right_before_left`, on the two junctions of the test data that no
constant was tuned on (a skewed all-way stop and an uneven Y), and at signalized junctions
under their own programs (the bundled four-way and T, a skewed four-way and a Y of the
test data, Town05 1126, Town07 68). The ego takes the route that meets the most other
forks (the deepest chain the rules allow; at a light, of the routes whose light lets them
go first, a permissive one), its start 30 m before the line at 8 m/s, duration 45 s.

Run with `make bench` (or `python -m bench.bench_chains`; `--only LABEL ...` for some of
the junctions: `make bench-variety` grows them on the bundled junctions and Town05 396, as
issue 34's target names them). Prints a markdown table: the depth each seed reached and
why it stopped, the median seconds of each level over the seeds (wall clock, and CPU
seconds as bench.cpu counts them, which a busy machine changes less), and whether every
free fork was used.
"""

from __future__ import annotations

import argparse
import math
import platform
import statistics
import time
from dataclasses import dataclass
from datetime import date
from pathlib import Path

from bench.cpu import cpu_seconds
from service.core.errors import NoMoreComplexTestCase, ScengenError
from service.core.generator.additions import candidate_routes
from service.core.generator.chain import grow
from service.core.network import Intersection, load_intersection
from service.core.testcase import TestCase, new_testcase

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "tests" / "data"
JUNCTIONS = [  # (label, network, junction, control)
    ("4way-stop", "4way-stop", None, None),
    ("t-stop", "t-stop", None, None),
    ("y-uncontrolled", "y-uncontrolled", None, None),
    ("skewed all-way stop (test data)", str(DATA / "junctions" / "skewed-allway.net.xml"), "C",
     None),
    ("uneven Y (test data)", str(DATA / "junctions" / "y-uneven.net.xml"), "C", None),
    ("Town05 396 as allway_stop", str(DATA / "carla" / "Town05.net.xml"), "396", "allway_stop"),
    ("Town05 1930 (T) as priority_stop", str(DATA / "carla" / "Town05.net.xml"), "1930",
     "priority_stop"),
    ("Town07 358 as right_before_left", str(DATA / "carla" / "Town07.net.xml"), "358",
     "right_before_left"),
    ("4way-signal", "4way-signal", None, None),
    ("t-signal", "t-signal", None, None),
    ("skewed signal (test data)", str(DATA / "junctions" / "skewed-signal.net.xml"), "C", None),
    ("Y signal (test data)", str(DATA / "junctions" / "y-signal.net.xml"), "C", None),
    ("Town05 1126 (signal)", str(DATA / "carla" / "Town05.net.xml"), "1126", None),
    ("Town07 68 (signal)", str(DATA / "carla" / "Town07.net.xml"), "68", None),
]  # fmt: skip
DURATION = 45.0
BUDGET = 30.0  # seconds per level
MAX_LEVELS = 8


def deepest_ego(intersection: Intersection) -> str:
    """The route that meets the most other forks (then the most routes; then by id). At a
    signalized junction, of the routes whose light lets them go first (the ego does not
    wait out a red it cannot see the end of), a permissive one first: a turn on a circular
    green owes the most right-of-way (the unprotected left against oncoming traffic)."""
    program = intersection.signals

    def light(route: str) -> tuple[float, bool]:
        link = intersection.routes[route].link_index
        if program is None or link < 0:
            return (0.0, False)
        go = program.first_go(link)
        permissive = any(c == "g" for _, _, c in program.timeline(link, DURATION))
        return (math.inf if go is None else go, not permissive)

    def reach(route: str) -> tuple[float, bool, int, int, str]:
        forks = {intersection.routes[r].fork for r in intersection.conflicts[route]}
        forks.discard(intersection.routes[route].fork)
        return (*light(route), -len(forks), -len(intersection.conflicts[route]), route)

    return min(intersection.offered_routes, key=reach)


@dataclass
class Chain:
    seconds: list[float]  # wall clock per level
    cpu: list[float]  # CPU seconds per level (bench.cpu's count: the warm SUMO worker too)
    stopped: str  # why it stopped
    free_forks_left: int  # forks a new car could still start from when it stopped


def grow_chain(start: TestCase, intersection: Intersection, seed: int) -> Chain:
    seconds: list[float] = []
    cpu: list[float] = []
    current = start
    stopped = f"{MAX_LEVELS} levels"
    for _ in range(MAX_LEVELS):
        clock, cpu_clock = time.perf_counter(), cpu_seconds()
        try:
            growth = grow(current, seed, BUDGET, intersection)
        except NoMoreComplexTestCase as error:
            stopped = "none left" if "free fork" in str(error) else "no more complex exists"
            break
        except ScengenError as error:
            stopped = type(error).__name__ + (
                " (budget)" if error.context.get("budget_exhausted") else ""
            )
            break
        seconds.append(time.perf_counter() - clock)
        cpu.append(cpu_seconds() - cpu_clock)
        current = growth.extension.testcase
    used = {current.ego.route.fork, *(n.route.fork for n in current.nonegos)}
    free = {intersection.routes[r].fork for r in candidate_routes(current, intersection)}
    return Chain(seconds, cpu, stopped, len(free - used))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=3)
    labels = [label for label, *_ in JUNCTIONS]
    parser.add_argument("--only", nargs="+", metavar="LABEL", choices=labels,
                        help="only these junctions (labels of the table)")  # fmt: skip
    args = parser.parse_args()
    seeds = range(args.seeds)
    machine = f"{platform.node()}, Python {platform.python_version()}"
    print(f"# chain growth, {date.today()}, {machine}, {BUDGET:g} s per level, "
          f"duration {DURATION:g} s")  # fmt: skip
    print()
    print("| junction | ego | depth per seed | stopped because | median s per level | "
          "slowest level (median) | median CPU s per level | every free fork used |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|")
    for label, network, junction, control in JUNCTIONS:
        if args.only and label not in args.only:
            continue
        intersection = load_intersection(network, junction, control)
        ego = deepest_ego(intersection)
        start = new_testcase(network, ego, junction=junction, control=control, duration=DURATION)
        chains = [grow_chain(start, intersection, seed) for seed in seeds]
        depths = [len(c.seconds) for c in chains]
        levels = max(depths)
        medians = [
            statistics.median(c.seconds[k] for c in chains if len(c.seconds) > k)
            for k in range(levels)
        ]
        cpu = [statistics.median(c.cpu[k] for c in chains if len(c.cpu) > k) for k in range(levels)]
        per_level = ", ".join(f"{m:.1f}" for m in medians) or "-"
        cpu_per_level = ", ".join(f"{m:.1f}" for m in cpu) or "-"
        slowest = f"{max(medians):.1f}" if medians else "-"
        every = "yes" if all(c.free_forks_left == 0 for c in chains) else "no"
        reasons = ", ".join(sorted({c.stopped for c in chains}))
        print(f"| {label} | {ego} | {' / '.join(map(str, depths))} | {reasons} | "
              f"{per_level} | {slowest} | {cpu_per_level} | {every} |", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
