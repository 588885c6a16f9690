"""Baseline: random search for verified extensions, judged by the project's own checker.

The generator must beat this sampler by 100x in verified extensions per CPU-second. It is
plain random search over speed profiles, with the domain knowledge an honest baseline has
and nothing more:

- Step 1 once per (route, start): the poses of the ego's route (from the ego's start) and
  of the new car's route (from the same start distance, as the generator does) at a
  constant cruise speed, with ``service.core.motion.poses.generate_poses``. The lane events of
  these constant-speed drives (``compute_events``) give the distances of the arrival, the
  entry into the junction and the exit from it along each route.
- A speed profile is piecewise-constant acceleration over pieces of 0.5-3 s (whole time
  steps), integrated exactly within each step with the speed clamped to [0, v_max]. By
  default each piece's acceleration is uniform in [-b, b] with b = min(-a_min, a_max):
  uniform in [a_min, a_max] (``symmetric=False``, ``--accelerations uniform``) has a mean
  of (a_min + a_max) / 2, -0.5 m/s^2 with the default parameters, which in a 20 s
  test-case drifts every car to a halt, often inside the junction; the symmetric draw
  found about 2.5x more extensions per CPU-second at the 4-way stop. With some
  probability the profile makes a full stop before the line: always for an ego at a stop
  sign (a legal ego must stop), 1/2 for the new car at a sign (non-egos are not judged:
  it may stop or run it), 1/3 at a fork without a sign (a yielding stand). The stop's end
  is uniform between the arrival distance and the entry, its braking deceleration uniform
  in [1 m/s^2, -a_min]; the car keeps its random pieces until going on would need harder
  braking than that, brakes at the constant deceleration that stops it exactly there
  (never harder than a_min), stands 0.5-4 s, and pulls away with a first piece uniform in
  (0, a_max]. Every acceleration lies within [a_min, a_max]. The certificates start at
  the ego's start speed, the new car at a speed uniform in [0, v_max]. Samples at every
  time step from 0 to the duration; distances stop at the end of the poses.
- One trial samples three profiles independently (new car, solvability ego, complexity
  ego), builds the candidate document as the generator does and asks
  ``service.core.generator.verification.verify_extension``; only None counts as a success. Cheap
  rejections come first, each one a rejection the judge itself would make: a certificate
  whose last sample is still short of the junction's exit cannot reach its goal, and the
  judge's own collision test (``first_collision``, on the very samples it will see)
  between a certificate and any non-ego, or between the new car and an old non-ego.
  A verified find gets its new car's lane events written in (``compute_events``, as the
  generator writes them) after the verdict, so that its arrival and entry can be read
  (issue 34 counts distinct finds by variety.signature).

Everything random comes from ``random.Random(seed)``; no decision depends on the clock.
CPU time is this process's plus that of its finished children (Step 1 runs SUMO in a
child process); it includes Step 1.

Run: ``.venv/bin/python -m bench.random_search [--budget CPU_SECONDS] [--seed N]
[--accelerations symmetric|uniform]``.
"""

from __future__ import annotations

import argparse
import hashlib
import math
import random
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from bench.cpu import cpu_seconds
from service.core.generator.verification import verify_extension
from service.core.motion.collisions import Motion, first_collision
from service.core.motion.events import EventKind, compute_events
from service.core.motion.poses import PoseSample, PoseTrack, generate_poses
from service.core.network import Intersection, Route
from service.core.testcase import (
    Params,
    TestCase,
    dump_testcase,
    load_testcase_intersection,
    new_testcase,
    parse_testcase,
)

STEP1_SPEED = 8.0  # m/s: cruise speed of the Step 1 drives; sets only how dense the poses are
PIECE_SECONDS = (0.5, 3.0)  # length of one constant-acceleration piece
STAND_SECONDS = (0.5, 4.0)  # how long a full stop stands
MIN_BRAKE = 1.0  # m/s^2: the gentlest braking a stop may be planned with
STOP_MARGIN = 0.1  # metres after the arrival and before the entry where a stop may end
EXIT_MARGIN = 0.05  # metres short of the exit that still go to the judge (rounding slack)
P_STOP_EGO_AT_SIGN = 1.0  # a legal ego must stop at a sign
P_STOP_NEW_AT_SIGN = 0.5  # a non-ego is not judged: it may stop or run the sign
P_STOP_NO_SIGN = 1.0 / 3.0  # a stand before the line where there is no sign (yielding)
CHUNK = 20  # trials between two looks at the CPU budget
DEFAULT_BUDGET = 60.0  # CPU seconds per task in main()


@dataclass(frozen=True)
class RandomSearchResult:
    """What one search found and what it cost."""

    testcase: TestCase | None  # the first verified extension, or None
    trials: int  # trials used (the successful one included)
    cpu_seconds: float  # Step 1 included
    wall_seconds: float


@dataclass(frozen=True)
class _Window:
    """Distances along one route's poses: where a stop may end, and the junction's exit."""

    stop_from: float
    stop_to: float
    exit: float  # the back has left the junction here (the goal needs at least this)
    end: float  # how far the poses go


@dataclass(frozen=True)
class _Profile:
    speeds: list[float]
    distances: list[float]


def _step(v: float, a: float, dt: float, v_max: float) -> tuple[float, float]:
    """(speed, distance covered) after ``dt`` at acceleration ``a``, speed in [0, v_max]."""
    after = v + a * dt
    if after < 0.0:  # stops within the step and stays
        return 0.0, v * v / (-2.0 * a)
    if after > v_max:  # reaches the limit within the step and holds it
        ramp = (v_max - v) / a if a > 0 else 0.0
        return v_max, v * ramp + a * ramp * ramp / 2.0 + v_max * (dt - ramp)
    return after, v * dt + a * dt * dt / 2.0


def _acceleration(rng: random.Random, params: Params, symmetric: bool, going: bool) -> float:
    """One piece's acceleration: (0, a_max] when pulling away after a stand, else uniform in
    [-b, b] with b = min(-a_min, a_max) (symmetric), or uniform in [a_min, a_max]."""
    if going:
        return rng.uniform(0.0, params.a_max)
    if symmetric:
        bound = min(-params.a_min, params.a_max)
        return rng.uniform(-bound, bound)
    return rng.uniform(params.a_min, params.a_max)


def _steps(rng: random.Random, seconds: tuple[float, float], dt: float) -> int:
    return max(1, round(rng.uniform(*seconds) / dt))


def _profile(
    rng: random.Random,
    old: TestCase,
    window: _Window,
    start_speed: float,
    p_stop: float,
    symmetric: bool,
) -> _Profile:
    """A random speed profile sampled at every time step, distances capped at the poses' end."""
    params, dt = old.params, old.timestep
    count = round(old.duration / dt) + 1
    stop_at: float | None = None
    brake, stand = 0.0, 0
    if rng.random() < p_stop:
        stop_at = rng.uniform(window.stop_from, window.stop_to)
        brake = rng.uniform(min(MIN_BRAKE, -params.a_min), -params.a_min)
        stand = _steps(rng, STAND_SECONDS, dt)
    v, d = start_speed, 0.0
    speeds, distances = [v], [d]
    mode, left, a = "drive", 0, 0.0
    going = False
    for _ in range(count - 1):
        if mode == "drive":
            if left == 0:
                a = _acceleration(rng, params, symmetric, going)
                going = False
                left = _steps(rng, PIECE_SECONDS, dt)
            if stop_at is not None and v > 0.0:
                gap = stop_at - d
                nv, covered = _step(v, a, dt, params.v_max)
                ahead = gap - covered
                if ahead <= 0.0 or nv * nv / (2.0 * ahead) > brake:
                    mode = "brake"
                    a = -params.a_min if gap <= 0.0 else min(v * v / (2.0 * gap), -params.a_min)
                    a = -a
            if mode == "drive":
                left -= 1
        if mode == "stand":
            a = 0.0
            stand -= 1
            if stand <= 0:
                mode, left, stop_at = "drive", 0, None
                going = True
        v, covered = _step(v, a, dt, params.v_max)
        d = min(d + covered, window.end)
        if mode == "brake" and v == 0.0:
            mode = "stand"
        speeds.append(v)
        distances.append(d)
    return _Profile(speeds, distances)


def _samples(profile: _Profile, track: PoseTrack, old: TestCase) -> list[dict[str, float]]:
    """The profile along the track as rounded document samples (as the generator writes)."""
    rows = []
    for k, (speed, distance) in enumerate(zip(profile.speeds, profile.distances, strict=True)):
        x, y, heading = track.pose_at(distance)
        sample = PoseSample(round(k * old.timestep, 9), x, y, heading, speed, distance)
        rows.append(
            {
                "t": round(sample.t, 6),
                "x": round(sample.x, 6),
                "y": round(sample.y, 6),
                "heading": round(sample.heading, 6) % 360.0,
                "speed": round(sample.speed, 6),
                "distance": round(sample.distance, 6),
            }
        )
    return rows


def _window(track: PoseTrack, junction: Intersection, route: Route, old: TestCase) -> _Window:
    events = compute_events(
        track.samples,
        track.length,
        track.width,
        junction,
        route.fork,
        old.params.arrival_distance,
        old.params.v_stop,
    )
    first = {}
    for event in events:
        first.setdefault(event.kind, event.distance)
    exited = [e.distance for e in events if e.kind is EventKind.EXITED]
    entered = first[EventKind.ENTERED]
    arrived = first.get(EventKind.ARRIVED, 0.0)
    stop_to = max(arrived, entered - STOP_MARGIN)
    stop_from = min(arrived + STOP_MARGIN, stop_to)
    return _Window(stop_from, stop_to, exited[-1], track.samples[-1].distance)


def _new_id(old: TestCase) -> str:
    taken = {n.id for n in old.nonegos}
    return next(f"car{k}" for k in range(1, len(taken) + 2) if f"car{k}" not in taken)


class _Sampler:
    """Step 1 done once for one (old test-case, route); then trial after trial."""

    def __init__(self, old: TestCase, route_id: str, seed: int, symmetric: bool) -> None:
        self.old, self.seed, self.symmetric, self.trials = old, seed, symmetric, 0
        self.junction = load_testcase_intersection(old)
        ego_route = self.junction.route(old.ego.route.id)
        self.route = self.junction.route(route_id)
        forks = {ego_route.fork, *(n.route.fork for n in old.nonegos)}
        if self.route.fork in forks:
            raise ValueError(f"route {route_id} starts on a fork that is already used")
        start = old.ego.start.distance
        self.ego_track, self.new_track = generate_poses(
            self.junction,
            [(ego_route, start), (self.route, start)],
            STEP1_SPEED,
            old.duration,
            old.timestep,
            old.ego.length,
            old.ego.width,
        )
        self.ego_window = _window(self.ego_track, self.junction, ego_route, old)
        self.new_window = _window(self.new_track, self.junction, self.route, old)
        self.ego_sign = self.junction.forks[ego_route.fork].stop_sign
        self.new_sign = self.junction.forks[self.route.fork].stop_sign
        self.new_id = _new_id(old)
        self.level = 1 + max((n.added_in for n in old.nonegos), default=0)
        self.base: dict[str, Any] = old.model_dump(mode="json", by_alias=True, exclude_none=True)
        self.parent = hashlib.sha256(dump_testcase(old).encode()).hexdigest()
        self.old_motions = [
            Motion([PoseSample(**s.model_dump()) for s in n.trajectory], n.length, n.width)
            for n in old.nonegos
        ]
        self.rng = random.Random(seed)

    def trial(self) -> TestCase | None:
        """One trial: a verified extension, or None."""
        old, rng = self.old, self.rng
        self.trials += 1
        p_ego = P_STOP_EGO_AT_SIGN if self.ego_sign else P_STOP_NO_SIGN
        p_new = P_STOP_NEW_AT_SIGN if self.new_sign else P_STOP_NO_SIGN
        new_speed = rng.uniform(0.0, old.params.v_max)
        start, symmetric = old.ego.start.speed, self.symmetric
        new = _profile(rng, old, self.new_window, new_speed, p_new, symmetric)
        solvability = _profile(rng, old, self.ego_window, start, p_ego, symmetric)
        complexity = _profile(rng, old, self.ego_window, start, p_ego, symmetric)
        reach = self.ego_window.exit - EXIT_MARGIN
        if solvability.distances[-1] < reach or complexity.distances[-1] < reach:
            return None  # still in the junction at the end: the goal cannot be reached
        rows = {
            "new": _samples(new, self.new_track, old),
            "solvability": _samples(solvability, self.ego_track, old),
            "complexity": _samples(complexity, self.ego_track, old),
        }
        size = (old.ego.length, old.ego.width)
        motions = {
            key: Motion([PoseSample(**r) for r in value], *size) for key, value in rows.items()
        }
        # The judge's own collision test, on the very samples it will see: any hit here
        # is a rejection by verify_extension (a certificate collides, or the new car hits
        # an old non-ego).
        if any(first_collision(motions["new"], other) for other in self.old_motions):
            return None
        for certificate in ("solvability", "complexity"):
            others = [motions["new"], *self.old_motions]
            if any(first_collision(motions[certificate], other) for other in others):
                return None
        document = dict(self.base)
        document["nonegos"] = [
            *self.base.get("nonegos", []),
            {
                "id": self.new_id,
                "route": {"fork": self.route.fork, "exit": self.route.exit},
                "length": old.ego.length,
                "width": old.ego.width,
                "trajectory": rows["new"],
                "events": [],
                "added_in": self.level,
            },
        ]
        document["certificates"] = {
            "complexity": rows["complexity"],
            "solvability": rows["solvability"],
        }
        document["provenance"] = {
            "parent": self.parent,
            "level": self.level,
            "new_nonegos": [self.new_id],
            "seed": self.seed,
            "sampler": "random_search",
            "trial": self.trials,
        }
        candidate = parse_testcase(document)
        if verify_extension(old, candidate, self.junction, [self.new_id]) is not None:
            return None
        return self._with_events(document, motions["new"], rows["new"])

    def _with_events(
        self, document: dict[str, Any], motion: Motion, rows: list[dict[str, float]]
    ) -> TestCase:
        """A verified find with its new car's lane events written in, as the generator
        writes them (variety.signature reads a test-case's arrivals and entries from them);
        only finds pay for this, after the verdict."""
        events = compute_events(
            [PoseSample(**r) for r in rows],
            motion.length,
            motion.width,
            self.junction,
            self.route.fork,
            self.old.params.arrival_distance,
            self.old.params.v_stop,
        )
        document["nonegos"][-1]["events"] = [
            {"kind": e.kind.value, "lane": e.lane, "t": round(e.time, 6),
             "distance": round(e.distance, 6)}
            for e in events
        ]  # fmt: skip
        return parse_testcase(document)


def random_extension(
    old: TestCase, route: str, seed: int, trials: int, *, symmetric: bool = True
) -> RandomSearchResult:
    """The first verified extension of ``old`` by one new car on ``route`` within ``trials``."""
    cpu, wall = cpu_seconds(), time.perf_counter()
    sampler = _Sampler(old, route, seed, symmetric)
    found = None
    while found is None and sampler.trials < trials:
        found = sampler.trial()
    return RandomSearchResult(
        found, sampler.trials, cpu_seconds() - cpu, time.perf_counter() - wall
    )


@dataclass(frozen=True)
class BudgetRun:
    """Sampling until a CPU budget is spent: trials and every verified extension found."""

    trials: int
    found: list[TestCase]  # in the order found (the same ones may repeat a test-case)
    cpu_seconds: float
    wall_seconds: float

    @property
    def successes(self) -> int:
        return len(self.found)


def budgeted_search(
    old: TestCase, route: str, seed: int, cpu_budget: float, *, symmetric: bool = True
) -> BudgetRun:
    """Trials in chunks of CHUNK until ``cpu_budget`` CPU-seconds (Step 1 included) are
    spent, counting every verified extension."""
    cpu, wall = cpu_seconds(), time.perf_counter()
    sampler = _Sampler(old, route, seed, symmetric)
    found: list[TestCase] = []
    while cpu_seconds() - cpu < cpu_budget:
        for _ in range(CHUNK):
            candidate = sampler.trial()
            if candidate is not None:
                found.append(candidate)
    return BudgetRun(sampler.trials, found, cpu_seconds() - cpu, time.perf_counter() - wall)


def _report(name: str, run: BudgetRun) -> None:
    rate = run.successes / run.cpu_seconds if run.cpu_seconds > 0 else math.nan
    print(
        f"{name:44s} {run.trials:7d} {run.successes:9d} {run.cpu_seconds:8.1f} "
        f"{run.wall_seconds:8.1f} {rate:12.4f}",
        flush=True,
    )


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description="random-search baseline for extensions")
    parser.add_argument("--budget", type=float, default=DEFAULT_BUDGET, help="CPU-seconds per task")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--accelerations",
        choices=("symmetric", "uniform"),
        default="symmetric",
        help="pieces uniform in [-b, b], b = min(-a_min, a_max) (default), or in [a_min, a_max]",
    )
    args = parser.parse_args(argv)
    symmetric = args.accelerations == "symmetric"

    def run(old: TestCase, route: str) -> BudgetRun:
        return budgeted_search(old, route, args.seed, args.budget, symmetric=symmetric)

    print(
        f"# random search baseline: seed {args.seed}, {args.accelerations} accelerations, "
        f"CPU budget {args.budget:g} s per task"
    )
    print(f"{'task':44s} {'trials':>7s} {'successes':>9s} {'CPU s':>8s} {'wall s':>8s} "
          f"{'ext/CPU-s':>12s}")  # fmt: skip
    four_way = new_testcase("4way-stop", "E2C_1:C2S_1", duration=20.0)
    level1 = run(four_way, "S2C_1:C2N_1")
    _report("4way-stop E2C_1:C2S_1 + S2C_1:C2N_1 (level 1)", level1)
    name = "4way-stop level 1 + W2C_1:C2E_1 (level 2)"
    if not level1.found:
        print(f"{name:44s} skipped: level 1 found no extension to extend", flush=True)
    else:
        _report(name, run(level1.found[0], "W2C_1:C2E_1"))
    y = new_testcase("y-uncontrolled", "N2C_0:C2SE_0", duration=25.0)
    _report("y-uncontrolled N2C_0:C2SE_0 + SW2C_0:C2N_0", run(y, "SW2C_0:C2N_0"))


if __name__ == "__main__":
    main()
