"""extend(): add new non-egos to a test-case so that it becomes strictly more complex.

Steps: poses of the ego and the new cars (Step 1, one SUMO process), their events, the
order of events (Step 2, clingo, answer sets drawn one at a time), speed curves for every
symbolic car (Step 3, z3), trajectories sampled from the curves, and verification by the
checker: the solvability certificate passes the new test-case; the complexity certificate
passes the old one and fails the new one only by a new non-ego's right-of-way; no new car
collides with anything. Only a verified test-case is returned.
"""

from __future__ import annotations

import hashlib
import itertools
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

from service.core.check import check_testcase
from service.core.collisions import Motion, first_collision
from service.core.errors import (
    InvalidInput,
    InvalidTestCase,
    NoMoreComplexTestCase,
    NoneFound,
)
from service.core.events import EventKind, LaneEvent, compute_events
from service.core.network import Intersection, Route
from service.core.ordering import (
    CarKind,
    Limits,
    Ordering,
    OrderingCar,
    OrderingSearch,
    stop_symbol,
    timed_events,
)
from service.core.poses import PoseSample, PoseTrack, generate_poses
from service.core.testcase import (
    TestCase,
    dump_testcase,
    load_testcase_intersection,
    parse_testcase,
)
from service.core.timing import (
    CarPlan,
    Knot,
    TimingFailure,
    TimingProblem,
    TimingSolution,
    solve_complete,
    solve_timing,
)

STEP1_SPEED = 8.0  # m/s: Step 1 drives at this speed; it sets only how dense the poses are
PLATOON_SPACING = 15.0  # metres between new cars that start on the same fork
HEADWAY = 2.0  # seconds between a car and the one behind it on the same fork, at each event
STOP_BEFORE_ENTRY = 0.5  # metres before entering the junction where a stopping car stands
NONLINEAR_SHARE = 1.0  # seconds at most for the nonlinear step of one answer set

Progress = Callable[[str], None]


@dataclass(frozen=True)
class Attempt:
    """What happened to one answer set."""

    index: int
    outcome: str


@dataclass
class Extension:
    """A verified, more complex test-case and how it was found."""

    testcase: TestCase
    attempts: list[Attempt]
    seconds: dict[str, float] = field(default_factory=dict)
    timing_problem: TimingProblem | None = None  # the Step 3 problem that was solved


def extend_testcase(
    old: TestCase,
    routes: Sequence[str],
    seed: int = 0,
    budget: float = 60.0,
    start_distance: float | None = None,
    progress: Progress | None = None,
    intersection: Intersection | None = None,
) -> Extension:
    """A strictly more complex, solvable test-case with new non-egos on ``routes``."""
    deadline = time.monotonic() + budget
    say = progress or (lambda _: None)
    seconds: dict[str, float] = {}
    junction = intersection or load_testcase_intersection(old)
    _check_old(old, junction)
    new_routes = _validate(old, junction, routes)
    ego_route = junction.route(old.ego.route.id)
    ids = _new_ids(old, len(new_routes))
    starts = _starts(old, new_routes, start_distance)

    clock = time.monotonic()
    tracks = generate_poses(
        junction,
        [(ego_route, old.ego.start.distance), *list(zip(new_routes, starts, strict=True))],
        STEP1_SPEED,
        old.duration,
        old.timestep,
        old.ego.length,
        old.ego.width,
        budget=max(1.0, min(60.0, deadline - time.monotonic())),
    )
    ego_track, new_tracks = tracks[0], dict(zip(ids, tracks[1:], strict=True))
    seconds["poses"] = time.monotonic() - clock
    say(f"step 1 poses: {len(tracks)} drives in {seconds['poses']:.2f} s")

    if time.monotonic() >= deadline:
        raise NoneFound(
            f"none found within the budget of {budget:g} s: Step 1 used all of it",
            routes=list(routes),
            seed=seed,
            budget_exhausted=True,
        )
    cars = _ordering_cars(old, junction, ego_track, new_tracks, new_routes, ids)
    clock = time.monotonic()
    limits = Limits(old.duration, old.params.a_min, old.params.a_max, old.params.v_max)
    search = OrderingSearch(junction, cars, old.params.m, seed, limits)
    seconds["ordering"] = time.monotonic() - clock
    attempts: list[Attempt] = []
    seconds["timing"] = seconds["verification"] = 0.0
    proven = True  # every answer set so far was shown impossible, not merely not found
    while time.monotonic() < deadline:
        clock = time.monotonic()
        ordering = search.next_ordering()
        seconds["ordering"] += time.monotonic() - clock
        if ordering is None:
            break
        clock = time.monotonic()
        result, problem = _solve_variants(
            old, junction, cars, ordering, {**new_tracks, "ego": ego_track}, deadline
        )
        seconds["timing"] += time.monotonic() - clock
        if isinstance(result, TimingFailure):
            if result.core:
                search.forbid([ordering.relations[i] for i in result.core])
            proven = proven and result.proved
            attempts.append(Attempt(ordering.index, f"timing: {result.reason}"))
            say(f"step 2/3 answer set {ordering.index + 1}: {result.reason}")
            continue
        clock = time.monotonic()
        samples = {
            car: _sample(
                curve.at,
                (ego_track if car in ("ego", "illegal") else new_tracks[car]),
                old.duration,
                old.timestep,
            )
            for car, curve in result.curves.items()
        }
        candidate = _candidate(
            old,
            junction,
            ordering,
            samples,
            new_routes,
            ids,
            seed,
            result.method,
            len(attempts) + 1,
        )
        problem_found = verify_extension(old, candidate, junction, ids)
        seconds["verification"] += time.monotonic() - clock
        if problem_found is None:
            attempts.append(Attempt(ordering.index, f"verified ({result.method} timing)"))
            say(f"step 2/3 answer set {ordering.index + 1}: verified ({result.method} timing)")
            return Extension(candidate, attempts, seconds, problem)
        proven = False
        attempts.append(Attempt(ordering.index, f"verification: {problem_found}"))
        say(f"step 2/3 answer set {ordering.index + 1}: {problem_found}")
    out_of_time = time.monotonic() >= deadline
    if not out_of_time and (not attempts or proven):
        reason = (
            search.explain_unsatisfiable()
            if not attempts
            else (
                f"all {len(attempts)} orders of events that meet the rules are physically "
                "impossible (no speed profile within the bounds realises them)"
            )
        )
        raise NoMoreComplexTestCase(
            f"no more complex test-case exists for these routes: {reason}", routes=list(routes)
        )
    tried = "; ".join(f"#{a.index + 1}: {a.outcome}" for a in attempts[:8])
    within = f"within the budget of {budget:g} s" if out_of_time else "among all orders"
    raise NoneFound(
        f"none found {within}: {len(attempts)} answer sets tried"
        + (f" ({tried})" if tried else ""),
        routes=list(routes),
        seed=seed,
        budget_exhausted=out_of_time,
    )


def _solve_variants(
    old: TestCase,
    junction: Intersection,
    cars: Sequence[OrderingCar],
    ordering: Ordering,
    tracks: dict[str, PoseTrack],
    deadline: float,
) -> tuple[TimingSolution | TimingFailure, TimingProblem]:
    """Step 3 for one answer set: the linear steps on the problem as it stands, then with
    the solvability certificate, then every symbolic car without a sign standing before
    the line; last the nonlinear step on the problem as it stands.

    Only the problem as it stands may rule the order out: the linear timing step's core
    rests on necessary conditions that hold for any motion (the stands of the variants
    only tighten them), and the nonlinear step's on the paper's formulation. The variants
    with stands only add chances."""
    base = _timing_problem(old, junction, cars, ordering, tracks)
    result = solve_timing(base, deadline - time.monotonic())
    if isinstance(result, TimingSolution) or result.proved or result.core:
        return result, base
    free = frozenset(c.car for c in cars if c.kind is not CarKind.OLD)
    for waiting in (frozenset({"ego"}), free):
        left = deadline - time.monotonic()
        if left <= 0:
            return result, base
        problem = _timing_problem(old, junction, cars, ordering, tracks, waiting)
        attempt = solve_timing(problem, left)
        if isinstance(attempt, TimingSolution):
            return attempt, problem
    complete = solve_complete(base, min(NONLINEAR_SHARE, deadline - time.monotonic()))
    if isinstance(complete, TimingFailure):
        reason = f"{result.reason}; {complete.reason}"
        return TimingFailure(reason, complete.core, complete.proved), base
    return complete, base


def _validate(old: TestCase, junction: Intersection, routes: Sequence[str]) -> list[Route]:
    if not routes:
        raise InvalidInput("name at least one new route (FORK_LANE:EXIT_LANE) to add")
    chosen = [junction.route(r) for r in routes]
    ego = junction.route(old.ego.route.id)
    for route in chosen:
        if not junction.conflicts[route.id]:
            raise InvalidInput(
                f"route {route.id} conflicts with no route at junction {junction.junction}: "
                "a car on it can never matter to anyone"
            )
        if route.fork == ego.fork:
            raise InvalidInput(
                f"route {route.id} starts on the ego's fork {ego.fork}; new cars must come "
                "from another lane (following in one lane is not modelled)"
            )
        if any(n.route.fork == route.fork for n in old.nonegos):
            raise InvalidInput(
                f"route {route.id} starts on fork {route.fork}, which an existing non-ego "
                "uses; new cars must come from another lane"
            )
    if not any(ego.id in junction.conflicts[route.id] for route in chosen):
        raise NoMoreComplexTestCase(
            "no more complex test-case exists for these routes: none of them crosses or "
            f"merges with the ego's route {ego.id}, so no ego behaviour can violate a new "
            "car's right-of-way",
            routes=list(routes),
        )
    return chosen


def _check_old(old: TestCase, junction: Intersection) -> None:
    if old.certificates is None:
        return
    samples = [PoseSample(**s.model_dump()) for s in old.certificates.solvability]
    verdict = check_testcase(old, samples, "solvability certificate", junction)
    if not verdict.passed:
        raise InvalidTestCase(
            "the old test-case fails its own checks: its solvability certificate "
            + "; ".join(verdict.reasons)
        )


def _new_ids(old: TestCase, count: int) -> list[str]:
    taken = {n.id for n in old.nonegos}
    ids: list[str] = []
    k = 1
    while len(ids) < count:
        if f"car{k}" not in taken:
            ids.append(f"car{k}")
        k += 1
    return ids


def _starts(old: TestCase, routes: Sequence[Route], start: float | None) -> list[float]:
    base = old.ego.start.distance if start is None else start
    seen: dict[str, int] = {}
    starts = []
    for route in routes:
        ahead = seen.get(route.fork, 0)
        starts.append(base + ahead * PLATOON_SPACING)
        seen[route.fork] = ahead + 1
    return starts


def _events(
    samples: Sequence[PoseSample],
    length: float,
    width: float,
    junction: Intersection,
    fork: str,
    old: TestCase,
) -> list[LaneEvent]:
    return compute_events(
        samples, length, width, junction, fork, old.params.arrival_distance, old.params.v_stop
    )


def _ordering_cars(
    old: TestCase,
    junction: Intersection,
    ego_track: PoseTrack,
    new_tracks: dict[str, PoseTrack],
    new_routes: Sequence[Route],
    ids: Sequence[str],
) -> list[OrderingCar]:
    cars = []
    for nonego in old.nonegos:
        route = junction.route(nonego.route.id)
        samples = [PoseSample(**s.model_dump()) for s in nonego.trajectory]
        events = _events(samples, nonego.length, nonego.width, junction, route.fork, old)
        cars.append(
            OrderingCar(nonego.id, CarKind.OLD, route.fork, route.connecting_lane, tuple(events))
        )
    ego_route = junction.route(old.ego.route.id)
    ego_events = tuple(
        _events(ego_track.samples, old.ego.length, old.ego.width, junction, ego_route.fork, old)
    )
    for name in ("ego", "illegal"):
        cars.append(
            OrderingCar(
                name,
                CarKind.CERTIFICATE,
                ego_route.fork,
                ego_route.connecting_lane,
                ego_events,
                old.ego.start.speed,
            )
        )
    for car_id, route in zip(ids, new_routes, strict=True):
        track = new_tracks[car_id]
        events = _events(track.samples, track.length, track.width, junction, route.fork, old)
        cars.append(
            OrderingCar(car_id, CarKind.NEW, route.fork, route.connecting_lane, tuple(events))
        )
    return cars


def _plan(
    car: OrderingCar,
    ordering: Ordering,
    track: PoseTrack,
    old: TestCase,
    stop_sign: bool,
    wait: bool = False,
) -> CarPlan:
    """The knots of one symbolic car; with ``wait``, a car without a stop sign stands
    before the line (yielding needs no sign; no rule counts that stand)."""
    knots: list[Knot] = []
    arrival = entry = None
    used = {str(s) for _, a, b in ordering.relations for s in (a, b)}
    for timed in timed_events(car):
        symbol = str(timed.symbol)
        if knots and knots[-1].symbol == symbol:
            continue
        if timed.event.kind is EventKind.ARRIVED:
            arrival = len(knots)
        if timed.event.kind is EventKind.ENTERED:
            stops = car.car in ordering.stops
            if stops or (wait and not stop_sign):
                stand = max(
                    timed.event.distance - STOP_BEFORE_ENTRY,
                    knots[-1].distance + 0.1 if knots else 0.1,
                )
                knots.append(Knot(str(stop_symbol(car.car)) if stops else None, stand, stop=True))
                knots.append(Knot(None, stand, stop=True))
            entry = len(knots)
        if symbol in used or timed.event.kind in (EventKind.ARRIVED, EventKind.ENTERED):
            knots.append(Knot(symbol, timed.event.distance))
        elif timed.event.kind is EventKind.LEFT_LANE and timed.event.lane == car.lane:
            knots.append(Knot(symbol, timed.event.distance))  # leaving its own lane: exit
    runs = None
    if stop_sign and car.car not in ordering.stops and arrival is not None and entry is not None:
        runs = (arrival, entry)
    start_speed = old.ego.start.speed if car.kind is CarKind.CERTIFICATE else None
    return CarPlan(
        car.car,
        tuple(knots),
        track.samples[-1].distance,
        start_speed,
        runs,
    )


def _timing_problem(
    old: TestCase,
    junction: Intersection,
    cars: Sequence[OrderingCar],
    ordering: Ordering,
    tracks: dict[str, PoseTrack],
    waiting: frozenset[str] = frozenset(),
) -> TimingProblem:
    plans = []
    fixed = []
    for car in cars:
        if car.kind is CarKind.OLD:
            fixed += [(str(t.symbol), t.event.time) for t in timed_events(car)]
            continue
        track = tracks["ego" if car.kind is CarKind.CERTIFICATE else car.car]
        sign = junction.forks[car.fork].stop_sign
        plans.append(_plan(car, ordering, track, old, sign, car.car in waiting))
    gaps = _headways(plans, cars)
    return TimingProblem(
        cars=tuple(plans),
        fixed=tuple(fixed),
        relations=tuple((kind, str(a), str(b)) for kind, a, b in ordering.relations),
        gaps=tuple(gaps),
        duration=old.duration,
        m=old.params.m,
        margin=max(2 * old.timestep, 0.1),
        a_min=old.params.a_min,
        a_max=old.params.a_max,
        v_stop=old.params.v_stop,
        v_run=old.params.v_run,
        v_max=old.params.v_max,
    )


def _headways(
    plans: Sequence[CarPlan], cars: Sequence[OrderingCar]
) -> list[tuple[str, str, float]]:
    """New cars of one fork drive the same path: at every event both have a knot for, the
    one behind comes HEADWAY seconds after the one ahead."""
    by_fork: dict[str, list[OrderingCar]] = {}
    for car in cars:
        if car.kind is CarKind.NEW:
            by_fork.setdefault(car.fork, []).append(car)
    knots = {p.car: {k.symbol for k in p.knots if k.symbol} for p in plans}
    gaps = []
    for group in by_fork.values():
        for leader, follower in itertools.pairwise(group):
            for timed in timed_events(leader):
                ahead = str(timed.symbol)
                behind = ahead.replace(f'"{leader.car}"', f'"{follower.car}"', 1)
                if ahead in knots[leader.car] and behind in knots[follower.car]:
                    gaps.append((ahead, behind, HEADWAY))
    return gaps


def _sample(
    at: Callable[[float], tuple[float, float]], track: PoseTrack, duration: float, timestep: float
) -> list[PoseSample]:
    samples = []
    for k in range(round(duration / timestep) + 1):
        t = round(k * timestep, 9)
        distance, speed = at(t)
        x, y, heading = track.pose_at(distance)
        samples.append(PoseSample(t, x, y, heading, speed, distance))
    return samples


def _candidate(
    old: TestCase,
    junction: Intersection,
    ordering: Ordering,
    samples: dict[str, list[PoseSample]],
    routes: Sequence[Route],
    ids: Sequence[str],
    seed: int,
    method: str,
    tried: int,
) -> TestCase:
    document: dict[str, Any] = old.model_dump(mode="json", by_alias=True, exclude_none=True)
    level = 1 + max((n.added_in for n in old.nonegos), default=0)
    for car_id, route in zip(ids, routes, strict=True):
        trajectory = samples[car_id]
        events = _events(trajectory, old.ego.length, old.ego.width, junction, route.fork, old)
        document["nonegos"].append(
            {
                "id": car_id,
                "route": {"fork": route.fork, "exit": route.exit},
                "length": old.ego.length,
                "width": old.ego.width,
                "trajectory": [_rounded(s) for s in trajectory],
                "events": [
                    {
                        "kind": e.kind.value,
                        "lane": e.lane,
                        "t": round(e.time, 6),
                        "distance": round(e.distance, 6),
                    }
                    for e in events
                ],
                "added_in": level,
            }
        )
    document["certificates"] = {
        "complexity": [_rounded(s) for s in samples["illegal"]],
        "solvability": [_rounded(s) for s in samples["ego"]],
    }
    document["provenance"] = {
        "parent": hashlib.sha256(dump_testcase(old).encode()).hexdigest(),
        "level": level,
        "new_nonegos": list(ids),
        "seed": seed,
        "answer_sets_tried": tried,
        "timing": method,
        "complexity_certificate_violates": [
            {"car": car, "rule": rule} for car, rule in ordering.violated if car in ids
        ],
        "order": ordering.describe(),
        "stops": sorted(ordering.stops),
    }
    return parse_testcase(document)


def _rounded(sample: PoseSample) -> dict[str, float]:
    data = asdict(sample)
    data["heading"] = round(data["heading"], 6) % 360.0
    return {key: round(value, 6) for key, value in data.items()}


def verify_extension(
    old: TestCase, new: TestCase, junction: Intersection, ids: Sequence[str]
) -> str | None:
    """None when the candidate is verified, else what is wrong."""
    assert new.certificates is not None
    solvability = [PoseSample(**s.model_dump()) for s in new.certificates.solvability]
    complexity = [PoseSample(**s.model_dump()) for s in new.certificates.complexity]
    verdict = check_testcase(new, solvability, "solvability", junction)
    if not verdict.passed:
        return "solvability certificate fails the new test-case: " + "; ".join(verdict.reasons)
    verdict = check_testcase(old, complexity, "complexity", junction)
    if not verdict.passed:
        return "complexity certificate fails the old test-case: " + "; ".join(verdict.reasons)
    verdict = check_testcase(new, complexity, "complexity", junction)
    if verdict.passed:
        return "complexity certificate passes the new test-case"
    if not verdict.goal_reached or verdict.collisions:
        return "complexity certificate fails the new test-case otherwise: " + "; ".join(
            verdict.reasons
        )
    if any(v.other not in ids for v in verdict.violations):
        return "complexity certificate breaks a rule besides a new car's right-of-way"
    motions = {
        n.id: Motion([PoseSample(**s.model_dump()) for s in n.trajectory], n.length, n.width)
        for n in new.nonegos
    }
    for car_id in ids:
        for other, motion in motions.items():
            if other == car_id or (other in ids and other < car_id):
                continue
            hit = first_collision(motions[car_id], motion)
            if hit is not None:
                return f"{car_id} collides with {other} at {hit.time:.2f} s"
    return None
