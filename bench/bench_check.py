"""Benchmark: the checker on the bundled 4-way stop with three non-egos.

Run with `make bench`. Prints the median and spread of wall-clock times over repeated
checks of one trajectory, next to Step 1 and event computation for scale (same run, so the
ratios hold on a noisy machine). Then the cost of the criticality measures: the check of
the four-way example's level 3 (three non-egos) with its complexity certificate as the
ego, with and without the measures, interleaved in one run; then SUMO's SSM device
against our measures on the same replays (bench.ssm_compare).
"""

from __future__ import annotations

import platform
import statistics
import time
from collections.abc import Callable
from datetime import date

from bench.ssm_compare import main as compare_with_sumo
from service.cli.examples import EXAMPLES, run_example
from service.core.checker.check import check_testcase
from service.core.motion.events import compute_events
from service.core.motion.poses import PoseSample, generate_poses
from service.core.network import load_intersection
from service.core.testcase import load_testcase_intersection, new_testcase
from tests.helpers import drive_with_stops, retime, with_nonegos

ROUTES = {
    "ego": "S2C_1:C2W_1",
    "car1": "W2C_0:C2E_0",
    "car2": "N2C_0:C2S_0",
    "car3": "E2C_1:C2S_1",
}
WAITS = {"ego": 5.0, "car1": 0.5, "car2": 3.0, "car3": 6.0}


def timed(function: Callable[[], object], repeats: int) -> list[float]:
    times = []
    for _ in range(repeats):
        started = time.perf_counter()
        function()
        times.append(time.perf_counter() - started)
    return times


def main() -> None:
    intersection = load_intersection("4way-stop")
    started = time.perf_counter()
    tracks = generate_poses(
        intersection, [(intersection.route(r), 40.0) for r in ROUTES.values()], 8.0, 20.0, 0.1
    )
    step1 = time.perf_counter() - started
    samples = {
        car: retime(track, drive_with_stops([(39.5, WAITS[car])]), 20.0, 0.1)
        for car, track in zip(ROUTES, tracks, strict=True)
    }
    testcase = with_nonegos(
        new_testcase("4way-stop", ROUTES["ego"], start_distance=40.0),
        [(car, ROUTES[car], samples[car]) for car in ("car1", "car2", "car3")],
    )
    verdict = check_testcase(testcase, samples["ego"], "bench", intersection)
    check = timed(lambda: check_testcase(testcase, samples["ego"], "bench", intersection), 20)
    events = timed(
        lambda: compute_events(samples["ego"], 5.0, 1.8, intersection, "S2C_1", 10.0, 0.1), 20
    )
    print(f"# scengen benchmark, {date.today()}, {platform.node()}, Python "
          f"{platform.python_version()}, {platform.machine()}")  # fmt: skip
    print(f"verdict: {'pass' if verdict.passed else 'fail: ' + '; '.join(verdict.reasons)}")
    print(f"Step 1, 4 cars in one SUMO process:     {step1 * 1000:8.1f} ms (once)")
    for name, values in (("check, 4-way stop, 3 non-egos:", check), ("events of one car:", events)):
        ms = [v * 1000 for v in values]
        spread = f"min {min(ms):7.1f}, max {max(ms):7.1f} (n={len(ms)})"
        print(f"{name:40s} median {statistics.median(ms):7.1f} ms, {spread}")
    criticality_cost()
    compare_with_sumo()


def criticality_cost(repeats: int = 30) -> None:
    """The check with and without the criticality measures, alternating, on a level-3
    test-case; the ratio of the medians is the measures' share."""
    level3 = run_example(EXAMPLES["four-way"])[3]
    assert level3.certificates is not None
    junction = load_testcase_intersection(level3)
    ego = [PoseSample(**s.model_dump()) for s in level3.certificates.complexity]
    runs: dict[bool, list[float]] = {False: [], True: []}
    for _ in range(repeats):
        for measured in (False, True):
            runs[measured] += timed(
                lambda m=measured: check_testcase(level3, ego, "bench", junction, criticality=m),
                1,
            )
    plain, measured = (statistics.median(runs[k]) * 1000 for k in (False, True))
    print(f"check, four-way level 3, without criticality: median {plain:7.1f} ms (n={repeats})")
    print(f"check, four-way level 3, with criticality:    median {measured:7.1f} ms "
          f"(+{(measured - plain) / plain:.0%})")  # fmt: skip


if __name__ == "__main__":
    main()
