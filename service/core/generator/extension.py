"""extend(): add new non-egos to a test-case so that it becomes strictly more complex.

Steps: poses of the ego and the new cars (Step 1, one SUMO process), their events, the
order of events with event times (Step 2, clingo and clingo-dl, answer sets drawn one at a
time), speed curves for every symbolic car (Step 3, z3), trajectories sampled from the
curves and checked against the motion invariants, and verification by the checker: the
solvability certificate passes the new test-case; the complexity certificate passes the
old one and fails the new one only by a new non-ego's right-of-way; no new car collides
with anything. Only a verified test-case is returned.

The search is limited by counts (answer sets, and the solvers' own work limits), never by
a clock: the same request gives the same bytes on an idle and on a saturated machine. The
budget in seconds only stops a call that runs too long, with an error that says so.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any

from service.core.checker.check import Car, Judge, check_testcase
from service.core.checker.rules import people_laws
from service.core.checker.verdict import REAR_END, Verdict, Violation
from service.core.errors import (
    BudgetExceeded,
    InvalidInput,
    InvalidTestCase,
    NoMoreComplexTestCase,
    NoneFound,
)
from service.core.generator.following import CERTIFICATES, QueueMember, queue_bounds
from service.core.generator.linear import GRID
from service.core.generator.merging import exit_followings
from service.core.generator.ordering import (
    CarKind,
    Limits,
    Ordering,
    OrderingCar,
    OrderingSearch,
    QueueBounds,
    SearchLimitReached,
    event_groups,
    stand_distance,
    stop_symbol,
    timed_events,
)
from service.core.generator.timing import (
    SHARES,
    TICK,
    CarPlan,
    Following,
    Knot,
    TimingFailure,
    TimingProblem,
    TimingSolution,
    entry_window,
    plan_times,
)
from service.core.generator.timing_solve import solve_timing
from service.core.generator.variety import (
    AIMS,
    DISTINCT_GAP,
    Signature,
    is_new,
    seed_aim,
    signature,
    test_relations,
)
from service.core.generator.walkers import (
    NewPedestrians,
    new_pedestrian_cars,
    new_pedestrian_ids,
    old_pedestrian_cars,
    pedestrian_rows,
    pedestrian_tracks,
    validate_walks,
    walker_plan,
)
from service.core.motion.collisions import Motion, first_collision
from service.core.motion.events import EventKind, LaneEvent, compute_events
from service.core.motion.invariants import ROUNDING, motion_fault
from service.core.motion.kinematics import Bounds
from service.core.motion.poses import (
    DRIVE_BUDGET,
    PoseSample,
    PoseTrack,
    check_start_speed,
    generate_poses,
    longest_start,
    plan_drive,
)
from service.core.motion.queues import (
    Follow,
    Places,
    QueueCar,
    follows,
    gap_fault,
    line_distance,
    needed_gap,
)
from service.core.network import Intersection, Route, Walk
from service.core.testcase import (
    SCHEMA_WITH_PEDESTRIANS,
    TestCase,
    document_sha256,
    load_testcase_intersection,
    parse_testcase,
    testcase_level,
)

STEP1_SPEED = 8.0  # m/s: Step 1 drives at this speed; it sets only how dense the poses are
QUEUE_SPACING = 5.0  # metres a new car starts behind the room it needs on a fork in use
MAX_ORDERS = 60  # answer sets one extension tries at most: a count, the same on any machine
# Step 2 first proposes orders that 70 % of the bounds can time (they leave the curves room),
# then, when those are exhausted, every order the full bounds allow.
SEARCH_SHARES = (0.7, 1.0)
TIMINGS_PER_WANTED = 3  # other timings extend_testcases tries per extension still wanted

Progress = Callable[[str], None]
StartDistances = float | Sequence[float | None] | None


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


class _Deadline:
    """The wall-clock budget of one call: it only ever stops the call, with a clear error."""

    def __init__(self, budget: float, routes: Sequence[str], seed: int) -> None:
        self.budget = budget
        self.end = time.monotonic() + budget
        self.routes = list(routes)
        self.seed = seed

    def left(self) -> float:
        return self.end - time.monotonic()

    def check(self, tried: Sequence[Attempt], where: str, expired: bool = False) -> None:
        if self.left() > 0 and not expired:
            return
        raise NoneFound(
            f"budget exhausted: the budget of {self.budget:g} s ran out during {where}, "
            f"after {len(tried)} answer sets; the same request with a larger budget gives "
            "the result it would have given (the search does not depend on the clock)",
            routes=self.routes,
            seed=self.seed,
            budget_exhausted=True,
        )


def extend_testcase(
    old: TestCase,
    routes: Sequence[str],
    seed: int = 0,
    budget: float = 60.0,
    start_distance: StartDistances = None,
    progress: Progress | None = None,
    intersection: Intersection | None = None,
    max_orders: int = MAX_ORDERS,
    judge: Judge | None = None,
    avoid: Sequence[TestCase] = (),
    walks: Sequence[str] = (),
) -> Extension:
    """A strictly more complex, solvable test-case with new non-egos on ``routes``, each
    starting ``start_distance`` before its stop line (one number for all, one per route,
    or None: automatic, behind the cars already on its fork or ahead of the ego).

    At most ``max_orders`` answer sets of Step 2 are tried; ``budget`` (seconds) only
    stops a call that takes longer (NoneFound with ``budget_exhausted``). ``judge``: the
    checker of ``old`` from ``checked_judge`` (a chain tries many routes on one test-case
    and makes it once). The seed draws the order Step 2 tries first and where in its
    timings Step 3 aims (variety.seed_aim: seed 0 takes the smoothest). ``avoid``:
    test-cases the result must differ from (variety.Signature). ``walks``: new pedestrians,
    one on each walk (docs/pedestrians.md)."""
    return extend_testcases(
        old, routes, 1, seed, budget, start_distance, progress, intersection, max_orders,
        judge, avoid, walks,
    ).found[0]  # fmt: skip


@dataclass
class Extensions:
    """Distinct extensions of one test-case on the same routes, and how far the search went."""

    found: list[Extension]
    orders_tried: int  # answer sets drawn
    exhausted: bool  # every order of events was drawn
    timings_tried: int  # other timings of verified orders

    def shortfall(self, wanted: int) -> str | None:
        """Why fewer than ``wanted`` came back (None when that many did)."""
        have = len(self.found)
        if have >= wanted:
            return None
        timings = f", and {self.timings_tried} other timings of the verified ones"
        if self.exhausted:
            return (
                f"{have} distinct extensions exist for these routes: all orders of events "
                f"tried ({self.orders_tried}){timings if self.timings_tried else ''}"
            )
        return (
            f"{have} distinct extensions found within the search's count of "
            f"{self.orders_tried} answer sets{timings if self.timings_tried else ''}"
        )


def extend_testcases(
    old: TestCase,
    routes: Sequence[str],
    count: int = 1,
    seed: int = 0,
    budget: float = 60.0,
    start_distance: StartDistances = None,
    progress: Progress | None = None,
    intersection: Intersection | None = None,
    max_orders: int = MAX_ORDERS,
    judge: Judge | None = None,
    avoid: Sequence[TestCase] = (),
    walks: Sequence[str] = (),
) -> Extensions:
    """Up to ``count`` verified extensions (as ``extend_testcase`` makes one) that differ
    from each other and from ``avoid`` (variety.Signature): different orders of events
    first, each answer set at most once; then other timings of the verified orders, aimed
    at the points of variety.AIMS of the new cars' entry windows. Raises what
    ``extend_testcase`` raises when there is none; fewer than ``count`` is not an error
    (``Extensions.shortfall`` says why). ``walks``: new pedestrians, one on each walk
    (docs/pedestrians.md), with the new cars or without them."""
    if count < 1:
        raise InvalidInput(f"count must be at least 1, not {count}")
    deadline = _Deadline(budget, [*routes, *walks], seed)
    say = progress or (lambda _: None)
    seconds: dict[str, float] = {}
    junction = intersection or load_testcase_intersection(old)
    old_judge = judge or checked_judge(old, junction)
    new_walks = validate_walks(junction, walks)
    new_routes = _validate(old, junction, routes, new_walks)
    ego_route = junction.route(old.ego.route.id)
    ids = _new_ids(old, len(new_routes))
    people = NewPedestrians(tuple(new_walks), tuple(new_pedestrian_ids(old, len(new_walks))))
    starts, shortened = automatic_starts(old, old_judge, new_routes, start_distance, junction)
    for cut in shortened:
        say(
            f"{ids[cut.index]} ({cut.route}): the road before its fork is {cut.start:g} m "
            f"long, so its automatic start is {cut.start:g} m before the line, not "
            f"{cut.automatic:g} m"
        )

    clock = time.monotonic()
    attempts: list[Attempt] = []
    drive_budget = min(DRIVE_BUDGET, deadline.left())
    try:
        tracks = generate_poses(
            junction,
            [(ego_route, old.ego.start.distance), *list(zip(new_routes, starts, strict=True))],
            STEP1_SPEED,
            old.duration,
            old.timestep,
            old.ego.length,
            old.ego.width,
            budget=max(drive_budget, 0.01),
            reach=old.params.v_max * old.duration,  # the farthest any car can travel
        )
    except BudgetExceeded:
        if drive_budget < DRIVE_BUDGET:  # the call's own budget ran out, not SUMO's
            deadline.check(attempts, "Step 1", expired=True)
        raise
    ego_track, new_tracks = tracks[0], dict(zip(ids, tracks[1:], strict=True))
    try:
        walked = pedestrian_tracks(junction, people, old, max(drive_budget, 0.01))
    except BudgetExceeded:
        if drive_budget < DRIVE_BUDGET:
            deadline.check(attempts, "Step 1", expired=True)
        raise
    tracks_of = {**new_tracks, **walked, "ego": ego_track, "illegal": ego_track}
    seconds["poses"] = time.monotonic() - clock
    say(f"step 1 poses: {len(tracks)} drives in {seconds['poses']:.2f} s")
    deadline.check(attempts, "Step 1")

    cars = _ordering_cars(old, old_judge, junction, ego_track, new_tracks, new_routes, ids)
    cars += old_pedestrian_cars(old_judge, junction)
    cars += new_pedestrian_cars(junction, people, walked, old)
    queue = _queue(old, old_judge, junction, cars, tracks_of, ids)
    added = _Added(tuple(new_routes), tuple(ids), people)
    search = _Search(
        old, junction, cars, queue, tracks_of, added, seed, old_judge, deadline, say, seconds,
        attempts,
    )  # fmt: skip
    taken = [signature(t) for t in avoid]
    found: list[Extension] = []
    verified: list[Ordering] = []
    for ordering, candidate in search.orders(max_orders):
        verified.append(ordering)
        mark = signature(candidate)
        if not is_new(mark, taken):
            say(f"step 2/3 answer set {len(attempts)}: the same test-case as one before")
            continue
        taken.append(mark)
        _note_shortened(candidate, shortened, ids)
        found.append(Extension(candidate, list(attempts), dict(seconds), search.problem))
        if len(found) >= count:
            break
    if len(found) < count and verified:
        for _, candidate in search.timings(verified, taken, count - len(found)):
            taken.append(signature(candidate))
            _note_shortened(candidate, shortened, ids)
            found.append(Extension(candidate, list(attempts), dict(seconds), search.problem))
    if not found and verified:
        raise NoneFound(
            f"every extension found ({len(verified)} orders of events"
            + (f", {len(search.variants)} other timings" if search.variants else "")
            + ") is the same test-case as one already taken",
            routes=list(routes),
            seed=seed,
            search_exhausted=search.exhausted,
        )
    if not found:
        raise _not_found(
            old, junction, cars, queue.bounds, seed, routes, attempts, search.exhausted
        )
    return Extensions(found, len(search.tried), search.exhausted, len(search.variants))


class _Search:
    """Step 2 and 3 over one extension's cars: verified candidates, order by order
    (``orders``), then other timings of the verified orders (``timings``). Each answer set
    is drawn once; the seed's aim (variety.seed_aim) is tried first for every order."""

    def __init__(
        self,
        old: TestCase,
        junction: Intersection,
        cars: list[OrderingCar],
        queue: _Queue,
        tracks: dict[str, PoseTrack],
        added: _Added,
        seed: int,
        judge: Judge,
        deadline: _Deadline,
        say: Progress,
        seconds: dict[str, float],
        attempts: list[Attempt],
    ) -> None:
        self.old, self.junction, self.cars, self.queue = old, junction, cars, queue
        self.tracks, self.added, self.seed, self.judge = tracks, added, seed, judge
        self.deadline, self.say, self.seconds, self.attempts = deadline, say, seconds, attempts
        self.tried: list[Ordering] = []
        self.exhausted = False
        self.problem: TimingProblem | None = None  # of the last verified candidate
        self.variants: list[tuple[int, float]] = []  # (answer set, aim) of every timing tried
        self.keys: dict[tuple[tuple[str, ...], frozenset[str]], int] = {}  # verified: number
        # by order (not by its number: each round of SEARCH_SHARES numbers its answer sets
        # from 0 again, so a number names different orders in the two rounds)
        self.windows: dict[Ordering, list[tuple[str, tuple[float, float], float | None]]] = {}
        self.problems: dict[Ordering, TimingProblem] = {}
        for stage in ("ordering", "timing", "verification"):
            seconds[stage] = 0.0

    def orders(self, max_orders: int) -> Iterator[tuple[Ordering, TestCase]]:
        """Every verified order with its candidate, at most ``max_orders`` answer sets:
        first those that SEARCH_SHARES[0] of the bounds can time, then the rest."""
        attempts, seconds = self.attempts, self.seconds
        ruled_out: list[Sequence[tuple[str, Any, Any]]] = []
        aim = seed_aim(self.seed)
        for share in SEARCH_SHARES:
            clock = time.monotonic()
            search = OrderingSearch(
                self.junction, self.cars, self.old.params.m, self.seed,
                _limits(self.old, share=share), self.queue.bounds,
            )  # fmt: skip
            for ordering in self.tried:
                search.block(ordering)
            for relations in ruled_out:
                search.forbid(relations)
            seconds["ordering"] += time.monotonic() - clock
            self.exhausted = False
            while len(attempts) < max_orders:
                self.deadline.check(attempts, "Step 2")
                clock = time.monotonic()
                try:
                    drawn = search.next_ordering()
                except SearchLimitReached as limit:
                    attempts.append(Attempt(len(attempts), f"ordering: {limit}"))
                    break
                seconds["ordering"] += time.monotonic() - clock
                if drawn is None:
                    self.exhausted = True
                    break
                ordering = drawn
                self.tried.append(ordering)
                number = len(attempts)
                same = self.keys.get(self._key(ordering))
                if same is not None:  # nothing new for the test-case, only for a certificate
                    attempts.append(Attempt(number, f"the same test-case order as #{same}"))
                    continue
                outcome, candidate, core = self.attempt(ordering, aim, number + 1, apart=True)
                if candidate is None and aim is not None:  # the order's own plan may still
                    self.say(f"step 2/3 answer set {number + 1}, aimed: {outcome}")
                    outcome, candidate, core = self.attempt(ordering, None, number + 1)
                if core is not None:  # given the phases chosen: their bounds are part of it
                    ruled_out.append([*core, *ordering.phases])
                    search.forbid(ruled_out[-1])
                attempts.append(Attempt(number, outcome))
                self.say(f"step 2/3 answer set {number + 1}: {outcome}")
                if candidate is not None:
                    self.keys[self._key(ordering)] = number + 1
                    yield ordering, candidate
            if not self.exhausted:
                return

    def _key(self, ordering: Ordering) -> tuple[tuple[str, ...], frozenset[str]]:
        """What of an order the test-case keeps (variety.Signature): the relations among
        its cars and which new cars stop; orders alike in these differ only in how the
        certificates drive, and Step 3 plans the new cars alike for them."""
        ids = self.added.everyone
        return tuple(test_relations(ordering.describe())), ordering.stops & set(ids)

    def timings(
        self, verified: Sequence[Ordering], taken: list[Signature], wanted: int
    ) -> Iterator[tuple[Ordering, TestCase]]:
        """Up to ``wanted`` more candidates from the verified orders, aimed at the points
        of variety.AIMS in turn (each point in every order before the next point), those
        that differ from ``taken`` (which the caller extends with every one it keeps); at
        most TIMINGS_PER_WANTED x ``wanted`` timings are tried (a count). A point whose
        entry times are close to those of one taken is passed over without solving."""
        given, tried = 0, 0
        for aim in AIMS:
            for ordering in verified:
                if given >= wanted or tried >= TIMINGS_PER_WANTED * wanted:
                    return
                aims = self._aims(ordering, aim)
                if not aims or _near(aims, taken):
                    continue
                number = self.keys[self._key(ordering)]
                self.variants.append((number, aim))
                tried += 1
                outcome, candidate, _ = self.attempt(ordering, aim, number)
                self.say(f"step 3 answer set {number} at {aim:g} of its timings: {outcome}")
                if candidate is None or not is_new(signature(candidate), taken):
                    continue
                given += 1
                yield ordering, candidate

    def _aims(
        self, ordering: Ordering, aim: float, apart: bool = False
    ) -> tuple[tuple[str, float], ...]:
        """Each new car's junction entry aimed at ``aim`` of its window of entry times
        (timing.entry_window, worked out once an order); empty when a car has none. With
        ``apart`` (a seed's aim), an aim within DISTINCT_GAP of where the smoothest plan
        enters (seed 0's test-case) moves DISTINCT_GAP away from it, to the side nearer
        the aim that stays in the window."""
        if ordering not in self.windows:
            self.windows[ordering] = self._windows(ordering)
        aims = []
        for symbol, (lo, hi), smoothest in self.windows[ordering]:
            target = lo + aim * (hi - lo)
            if apart and smoothest is not None and abs(target - smoothest) < DISTINCT_GAP:
                sides = [t for t in (smoothest - DISTINCT_GAP, smoothest + DISTINCT_GAP)
                         if lo <= t <= hi]  # fmt: skip
                target = min(sides, key=lambda t: abs(t - target), default=target)
            aims.append((symbol, round(target, 4)))
        return tuple(aims)

    def _problem(self, ordering: Ordering) -> TimingProblem:
        """Step 3's problem of an order (made once: the windows and every timing use it)."""
        if ordering not in self.problems:
            self.problems[ordering] = _timing_problem(
                self.old, self.junction, self.cars, ordering, self.tracks, self.queue
            )
        return self.problems[ordering]

    def _windows(self, ordering: Ordering) -> list[tuple[str, tuple[float, float], float | None]]:
        """Each new car's entry symbol, its window of entry times, and its entry in the
        smoothest plan (None when there is none); empty when a car has no window."""
        problem = self._problem(ordering)
        smooth = plan_times(problem, SHARES[0])
        windows = []
        for plan in problem.cars:
            if plan.car not in self.added.everyone:
                continue
            symbol = _entry_symbol(plan)
            window = entry_window(problem, symbol) if symbol is not None else None
            if symbol is None or window is None:
                return []
            index = next(k for k, knot in enumerate(plan.knots) if knot.symbol == symbol)
            windows.append((symbol, window, smooth[plan.car][index] if smooth else None))
        return windows

    def attempt(
        self, ordering: Ordering, aim: float | None, number: int, apart: bool = False
    ) -> tuple[str, TestCase | None, list[tuple[str, Any, Any]] | None]:
        """The outcome of timing and judging one order, aimed at ``aim`` of the new cars'
        entry windows (None: the smoothest plan): what happened, the verified candidate
        (or None), and the relations that cannot hold together (a core, or None)."""
        old, seconds = self.old, self.seconds
        self.deadline.check(self.attempts, "Step 3")
        clock = time.monotonic()
        aims = self._aims(ordering, aim, apart) if aim is not None else ()
        if aim is not None and not aims:
            seconds["timing"] += time.monotonic() - clock
            return "no window of entry times to aim in", None, None
        problem = self._problem(ordering)
        result = solve_timing(dataclasses.replace(problem, aims=aims))
        seconds["timing"] += time.monotonic() - clock
        if isinstance(result, TimingFailure):
            core = [ordering.relations[i] for i in result.core] if result.core else None
            return f"timing: {result.reason}", None, core
        clock = time.monotonic()
        outcome, candidate = _judge(
            old, ordering, result, self.tracks, self.junction, self.added, self.seed,
            number, self.judge,
        )  # fmt: skip
        seconds["verification"] += time.monotonic() - clock
        if candidate is None:
            return outcome, None, None
        if aims:
            assert candidate.provenance is not None
            candidate.provenance["timing_aim"] = {
                "share": aim, "entries": {s: round(t, 3) for s, t in aims}
            }  # fmt: skip
        self.problem = problem
        return f"verified ({result.method})", candidate, None


def _near(aims: Sequence[tuple[str, float]], taken: Sequence[Signature]) -> bool:
    """Whether the first aimed entry is within half of DISTINCT_GAP of the entry of a
    test-case taken (of any order: its signature tells the orders apart after solving)."""
    _, target = aims[0]
    return any(abs(mark.cars[0].entry - target) < DISTINCT_GAP / 2 for mark in taken if mark.cars)


def _entry_symbol(plan: CarPlan) -> str | None:
    """The time symbol of the car entering its lane in the junction (else its first)."""
    if plan.inside is not None:
        return plan.knots[plan.inside[0]].symbol
    return next((k.symbol for k in plan.knots if k.symbol is not None), None)


def _note_shortened(
    testcase: TestCase, shortened: Sequence[ShortenedStart], ids: Sequence[str]
) -> None:
    """Say in the provenance which automatic starts the road made shorter."""
    if shortened and testcase.provenance is not None:
        testcase.provenance["shortened_starts"] = [
            {"car": ids[cut.index], "route": cut.route, "automatic": cut.automatic,
             "start": cut.start}
            for cut in shortened
        ]  # fmt: skip


def _limits(old: TestCase, margin: float | None = None, share: float = 1.0) -> Limits:
    """What Step 2 bounds the timing with: ``share`` of the test-case's speed and
    acceleration bounds, the safety margin of every relation, and the least average speed
    through the junction (v_run: a car the generator plans does not stall inside). Without
    a margin (the proof that nothing exists), any crossing speed."""
    params, walk = old.params, old.params.walk
    return Limits(
        old.duration,
        Bounds(params.v_max, params.a_max, params.a_min).scaled(share),
        params.v_run,
        _margin(old) if margin is None else margin,
        None if margin == 0.0 else params.v_run,
        Bounds(walk.v_max, walk.a_max, walk.a_min).scaled(share),
    )


def _margin(old: TestCase) -> float:
    """The safety margin of every order relation: two time steps, at least 0.1 s."""
    return max(2 * old.timestep, 0.1)


def _not_found(
    old: TestCase,
    junction: Intersection,
    cars: Sequence[OrderingCar],
    bounds: QueueBounds,
    seed: int,
    routes: Sequence[str],
    attempts: Sequence[Attempt],
    exhausted: bool,
) -> NoMoreComplexTestCase | NoneFound:
    """Why the search ended without a result. "No more complex test-case exists" only when
    even without any safety margin no order of events has consistent times: the whole
    search space is then empty."""
    tried = "; ".join(f"#{a.index + 1}: {a.outcome}" for a in attempts[:8])
    detail = f" ({tried})" if tried else ""
    if not exhausted:
        return NoneFound(
            f"none found among the first {len(attempts)} answer sets{detail}",
            routes=list(routes),
            seed=seed,
            search_exhausted=False,
        )
    bare = OrderingSearch(junction, cars, old.params.m, seed, _limits(old, margin=0.0), bounds)
    if not bare.satisfiable():
        return NoMoreComplexTestCase(
            f"no more complex test-case exists for these routes: {bare.explain_unsatisfiable()}",
            routes=list(routes),
        )
    if not attempts:
        return NoneFound(
            "none found: orders of events exist only without the safety margin of "
            f"{_margin(old):g} s on every relation, too close to call",
            routes=list(routes),
            seed=seed,
            search_exhausted=True,
        )
    return NoneFound(
        f"none found among all {len(attempts)} orders of events{detail}",
        routes=list(routes),
        seed=seed,
        search_exhausted=True,
    )


def _judge(
    old: TestCase,
    ordering: Ordering,
    timing: TimingSolution,
    tracks: dict[str, PoseTrack],
    junction: Intersection,
    added: _Added,
    seed: int,
    tried: int,
    old_judge: Judge,
) -> tuple[str, TestCase | None]:
    """The candidate of one answer set, when its samples keep the motion invariants and the
    checker verifies it; else what is wrong with it."""
    samples = {
        car: [_rounded(s) for s in _sample(curve.at, tracks[car], old.duration, old.timestep)]
        for car, curve in timing.curves.items()
    }
    for car, rows in samples.items():
        start = old.ego.start.speed if car in ("ego", "illegal") else None
        limits = old.params.walk if car in added.people.ids else old.params
        fault = motion_fault(rows, limits, old.timestep, start)
        if fault is not None:
            return f"curves: {car} {fault}", None
    try:
        candidate = _candidate(old, junction, ordering, samples, added, seed, timing.method, tried)
    except InvalidTestCase as error:  # our own fault, never the caller's input
        return f"internal: the candidate is not a valid test-case ({error})", None
    problem, verdict = _verify(old, candidate, junction, added.everyone, old_judge)
    if problem is not None:
        return f"verification: {problem}", None
    assert candidate.provenance is not None and verdict is not None
    candidate.provenance["complexity_certificate"] = _kind_of(verdict)
    return "verified", candidate


@dataclass(frozen=True)
class _Added:
    """What an extension adds: cars on routes, and pedestrians on walks."""

    routes: tuple[Route, ...]
    ids: tuple[str, ...]  # the new cars'
    people: NewPedestrians

    @property
    def everyone(self) -> tuple[str, ...]:
        """The ids of every new road user: the cars, then the pedestrians."""
        return (*self.ids, *self.people.ids)


def _validate(
    old: TestCase, junction: Intersection, routes: Sequence[str], walks: Sequence[Walk] = ()
) -> list[Route]:
    if not routes and not walks:
        raise InvalidInput(
            "name at least one new route (FORK_LANE:EXIT_LANE) or walk (a crossing and its "
            "direction, as scengen intersection lists them) to add"
        )
    chosen = [junction.route(r) for r in routes]
    ego = junction.route(old.ego.route.id)
    for route in chosen:
        if not junction.conflicts[route.id]:
            raise InvalidInput(
                f"route {route.id} conflicts with no route at junction {junction.junction}: "
                "a car on it can never matter to anyone"
            )
    if not any(ego.id in junction.conflicts[route.id] or route.fork == ego.fork
               for route in chosen) and not any(ego.id in w.conflicts for w in walks):  # fmt: skip
        raise NoMoreComplexTestCase(
            "no more complex test-case exists for these routes: none of them crosses or "
            f"merges with the ego's route {ego.id} or starts ahead of the ego on its fork, "
            "and no walk crosses it, so no ego behaviour can violate a new road user's "
            "right-of-way or drive into it",
            routes=[*routes, *(w.id for w in walks)],
        )
    return chosen


def checked_judge(old: TestCase, junction: Intersection) -> Judge:
    """The checker of ``old``, once its own solvability certificate passed it and its ego
    starts within its lane's speed limit, where SUMO can insert it (InvalidTestCase if
    not)."""
    ego = old.ego
    plan = plan_drive(
        junction, junction.route(ego.route.id), ego.start.distance, max(ego.start.speed, 1.0),
        old.duration, old.timestep, ego.length, ego.width,
    )  # fmt: skip
    check_start_speed(junction, plan, ego.start.speed)
    judge = Judge(old, junction)
    _check_old(old, judge)
    return judge


def _check_old(old: TestCase, judge: Judge) -> None:
    if old.certificates is None:
        return
    samples = [PoseSample(**s.model_dump()) for s in old.certificates.solvability]
    verdict = judge.verdict(samples, "solvability certificate")
    if not verdict.passed:
        raise InvalidTestCase(
            "the old test-case fails its own checks: its solvability certificate "
            + "; ".join(verdict.reasons)
        )


def _new_ids(old: TestCase, count: int) -> list[str]:
    taken = {n.id for n in old.road_users}
    ids: list[str] = []
    k = 1
    while len(ids) < count:
        if f"car{k}" not in taken:
            ids.append(f"car{k}")
        k += 1
    return ids


@dataclass(frozen=True)
class ShortenedStart:
    """An automatic start that did not fit on the road before its fork: the new car (by
    its place among the new routes) starts at the road's far end instead."""

    index: int
    route: str
    automatic: float  # where the car would have started on a longer road
    start: float  # where it starts: the whole road before its fork


def automatic_starts(
    old: TestCase,
    judge: Judge,
    routes: Sequence[Route],
    start: StartDistances,
    junction: Intersection,
) -> tuple[list[float], list[ShortenedStart]]:
    """Each new car's start distance: the one given, else automatic, and the automatic
    starts that were shortened. Automatically, a car on a fork no one uses starts where the
    ego does; on the ego's fork, ahead of the first car there; on a fork with other cars,
    behind the last one; with room for the gap and the headway at the start speed, and
    QUEUE_SPACING more; and never further back than the road before its fork goes (the
    longest start up to that which fits). InvalidInput when a car would start behind the
    ego or too close to a car already on its fork (for an automatic start: when the road
    has no room for it)."""
    given = _given_starts(routes, start)
    ego, params = old.ego, old.params
    ego_fork = ego.route.fork
    on_fork: dict[str, list[_Placed]] = {
        ego_fork: [_Placed(ego.start.distance, ego.length, "the ego", ego.start.speed)]
    }
    for car in judge.nonegos:
        speed = car.samples[0].speed if car.samples else 0.0
        on_fork.setdefault(car.fork, []).append(
            _Placed(car.in_queue.start, car.length, car.id, speed)
        )
    starts: list[float] = []
    shortened: list[ShortenedStart] = []
    for k, (route, wanted) in enumerate(zip(routes, given, strict=True)):
        there = on_fork.setdefault(route.fork, [])
        name = f"new car {k + 1} ({route.id})"
        cut = False
        if wanted is None:
            wanted = _automatic(old, there, route.fork == ego_fork)
            if wanted is None:
                first = min(p.start for p in there)
                raise InvalidInput(
                    f"{name}: no room ahead of the cars on the ego's fork {route.fork} (the "
                    f"first starts {first:g} m before the line); give its start distance"
                )
            wanted = round(wanted, 6)
            fitted = longest_start(junction, route, wanted)
            if fitted < wanted:
                shortened.append(ShortenedStart(k, route.id, wanted, fitted))
                wanted, cut = fitted, True
        wanted = round(wanted, 6)
        if route.fork == ego_fork and wanted > ego.start.distance:
            raise InvalidInput(
                f"{name} would start {wanted:g} m before the line, behind the ego "
                f"({ego.start.distance:g} m): a non-ego behind the ego would drive into any "
                "ego that waits longer than it does, so new cars on the ego's fork start "
                "ahead of it (a smaller start distance)"
            )
        placed = _Placed(wanted, ego.length, name, 0.0)
        for other in there:
            ahead, behind = (other, placed) if other.start < wanted else (placed, other)
            room = ahead.length + needed_gap(params.gap, params.headway, behind.speed)
            if behind.start - ahead.start >= room:
                continue
            if cut:
                raise InvalidInput(
                    f"{name}: no room on the road before fork {route.fork} ({wanted:g} m "
                    f"long) behind {other.name} ({other.start:g} m before the line): the car "
                    f"behind needs a car length plus its gap ({room:g} m) to the one ahead"
                )
            raise InvalidInput(
                f"{name} would start {wanted:g} m before the line, "
                f"{abs(wanted - other.start):g} m from {other.name} ({other.start:g} m) "
                f"on fork {route.fork}: the car behind needs a car length plus its gap "
                f"({room:g} m) to the one ahead"
            )
        there.append(placed)
        starts.append(wanted)
    return starts, shortened


@dataclass(frozen=True)
class _Placed:
    """A car on a fork at the start: metres before the line, length, name, speed."""

    start: float
    length: float
    name: str
    speed: float


def _automatic(old: TestCase, there: Sequence[_Placed], ego_fork: bool) -> float | None:
    """The automatic start of a new car on a fork with ``there`` on it."""
    params, length = old.params, old.ego.length
    if not there:
        return old.ego.start.distance
    if ego_fork:
        first = min(there, key=lambda p: p.start)
        room = length + needed_gap(params.gap, params.headway, first.speed)
        ahead = first.start - room - QUEUE_SPACING
        return ahead if ahead >= 0 else None
    last = max(there, key=lambda p: p.start)
    return last.start + last.length + params.gap + QUEUE_SPACING


def _given_starts(routes: Sequence[Route], start: StartDistances) -> list[float | None]:
    if start is None or isinstance(start, int | float):
        return [None if start is None else float(start)] * len(routes)
    given = list(start)
    if len(given) != len(routes):
        raise InvalidInput(
            f"give one start distance per new route: {len(routes)} routes, "
            f"{len(given)} start distances"
        )
    for value in given:
        if value is not None and (not math.isfinite(value) or value < 0):
            raise InvalidInput(f"start distances must be >= 0 m, got {value:g}")
    return given


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
    judge: Judge,
    junction: Intersection,
    ego_track: PoseTrack,
    new_tracks: dict[str, PoseTrack],
    new_routes: Sequence[Route],
    ids: Sequence[str],
) -> list[OrderingCar]:
    """The cars of Step 2; old cars with their events as the checker sees them (arrivals
    in a queue included)."""
    cars = [
        OrderingCar(car.id, CarKind.OLD, car.fork, car.lane, car.events) for car in judge.nonegos
    ]
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


@dataclass(frozen=True)
class _Queue:
    """The queues of an extension: who follows whom, and what that asks of the times."""

    follows: tuple[Follow, ...]
    members: dict[str, QueueMember]
    bounds: QueueBounds


def _queue(
    old: TestCase,
    judge: Judge,
    junction: Intersection,
    cars: Sequence[OrderingCar],
    tracks: dict[str, PoseTrack],
    ids: Sequence[str],
) -> _Queue:
    cars = [car for car in cars if not car.walker]  # people on foot keep no queue
    by_name = {car.car: car for car in cars}
    members: dict[str, QueueMember] = {}
    queue_cars: list[QueueCar] = []
    for old_car in judge.nonegos:
        members[old_car.id] = QueueMember(
            by_name[old_car.id],
            old_car.length,
            old_car.line,
            Places.of(old_car.samples, old_car.in_queue),
        )
        queue_cars.append(old_car.in_queue)
    for name in ("ego", *ids):
        car, track = by_name[name], tracks[name]
        line = line_distance(track.samples, track.length, junction.fork(car.fork), car.events)
        queue_cars.append(QueueCar(name, car.fork, car.lane, track.length, track.width, line,
                                   track.samples[0].distance))  # fmt: skip
        members[name] = QueueMember(car, track.length, line)
    members["illegal"] = QueueMember(by_name["illegal"], members["ego"].length,
                                     members["ego"].line)  # fmt: skip
    found = tuple(follows(queue_cars, junction))
    limits = Bounds(old.params.v_max, old.params.a_max, old.params.a_min)
    bounds = queue_bounds(found, members, old.params.gap, limits, old.duration)
    at_start = tuple(  # events where a car starts (a queue's first car may have arrived)
        (t.symbol, TICK)
        for car in cars
        if car.kind is not CarKind.OLD
        for t in timed_events(car)
        if t.event.distance <= ROUNDING
    )
    bounds = dataclasses.replace(bounds, latest=bounds.latest + at_start)
    return _Queue(found, members, bounds)


def _plan(car: OrderingCar, ordering: Ordering, track: PoseTrack, stop_sign: bool) -> CarPlan:
    """The knots of one symbolic car: the points (time symbols) the order speaks of, where
    it arrives, enters and leaves its own lane, and a stand just before the point where it
    enters when it stops at its sign."""
    knots: list[Knot] = []
    arrival = entry = leaves = None
    used = {s for _, a, b in ordering.named for s in (a, b)}
    stops = car.car in ordering.stops
    for group in event_groups(car):
        symbol, kinds = str(group[0].symbol), {t.event.kind for t in group}
        if EventKind.ENTERED in kinds:
            stand = stand_distance(car)
            if stops and stand is not None:
                knots.append(Knot(str(stop_symbol(car.car)), _on_grid(stand), stop=True))
                knots.append(Knot(None, _on_grid(stand), stop=True))
            entry = len(knots)
        if EventKind.ARRIVED in kinds:
            arrival = len(knots)
        own_exit = any(
            t.event.kind is EventKind.LEFT_LANE and t.event.lane == car.lane for t in group
        )
        if own_exit:
            leaves = len(knots)
        if group[0].event.distance <= ROUNDING:  # an event at the start: at t = 0
            arrival = None if EventKind.ARRIVED in kinds else arrival
            continue
        if symbol in used or kinds & {EventKind.ARRIVED, EventKind.ENTERED} or own_exit:
            knots.append(Knot(symbol, _on_grid(group[0].event.distance)))
    runs = None
    if stop_sign and not stops and arrival is not None and entry is not None:
        runs = (arrival, entry)
    inside = (entry, leaves) if entry is not None and leaves is not None else None
    # No end of the road here: a car's trajectory ends where it leaves the map (_sample).
    return CarPlan(car.car, tuple(knots), math.inf, car.start_speed, runs, inside)


def _on_grid(distance: float) -> float:
    """A knot distance on Step 3's micrometre grid, rounded up: the curve passes the event
    (at most a micrometre earlier) when the knot says."""
    return math.ceil(distance * GRID - 1e-6) / GRID


def _timing_problem(
    old: TestCase,
    junction: Intersection,
    cars: Sequence[OrderingCar],
    ordering: Ordering,
    tracks: dict[str, PoseTrack],
    queue: _Queue,
) -> TimingProblem:
    plans = []
    fixed = []
    for car in cars:
        if car.kind is CarKind.OLD:
            fixed += [(str(t.symbol), t.event.time) for t in timed_events(car)]
            continue
        if car.walker:
            plans.append(walker_plan(_plan(car, ordering, tracks[car.car], False), old))
        else:
            sign = junction.forks[car.fork].stop_sign
            plans.append(_plan(car, ordering, tracks[car.car], sign))
        fixed += [  # events where the car starts happen at t = 0
            (str(group[0].symbol), 0.0)
            for group in event_groups(car)
            if group[0].event.distance <= ROUNDING
        ]
    rows = {n.id: tuple((s.t, s.distance, s.speed) for s in n.trajectory) for n in old.nonegos}
    lines = {name: (member.line, member.length) for name, member in queue.members.items()}
    params = old.params
    follows = _followings(old, queue, rows) + exit_followings(
        junction, cars, ordering, lines, rows, params.gap, params.headway + _margin(old)
    )
    plans = _leaders_first(plans, follows)
    knotted = {k.symbol for p in plans for k in p.knots}
    bounds = queue.bounds
    return TimingProblem(
        cars=tuple(plans),
        fixed=tuple(fixed),
        relations=ordering.named,
        gaps=tuple(
            (str(a), str(b), gap)
            for a, b, gap in bounds.headways
            if str(a) in knotted and str(b) in knotted
        ),
        earliest=tuple((str(s), t) for s, t in bounds.earliest if str(s) in knotted)
        + tuple((s, start + _margin(old)) for s, start, _ in ordering.spans if s in knotted),
        latest=tuple((str(s), t) for s, t in bounds.latest if str(s) in knotted)
        + tuple((s, end - 0.001 - _margin(old)) for s, _, end in ordering.spans if s in knotted),
        follows=follows,
        timestep=old.timestep,
        duration=old.duration,
        m=old.params.m,
        margin=_margin(old),
        a_min=old.params.a_min,
        a_max=old.params.a_max,
        v_stop=old.params.v_stop,
        v_run=old.params.v_run,
        crossing=old.params.v_run,
        v_max=old.params.v_max,
    )


def _leaders_first(plans: Sequence[CarPlan], follows: Sequence[Following]) -> list[CarPlan]:
    """The plans in an order that puts every symbolic leader before its followers (Step 3
    fits a follower's curve behind its leader's), else in the order given."""
    names = [plan.car for plan in plans]
    ahead = {name: {f.leader for f in follows if f.follower == name and f.leader in names}
             for name in names}  # fmt: skip
    placed: list[str] = []
    while len(placed) < len(names):
        ready = [n for n in names if n not in placed and ahead[n] <= set(placed)]
        if not ready:  # leaders in a circle: no curves can keep them all; any order
            ready = [n for n in names if n not in placed]
        placed.append(ready[0])
    by_name = {plan.car: plan for plan in plans}
    return [by_name[name] for name in placed]


def _followings(
    old: TestCase, queue: _Queue, rows: dict[str, tuple[tuple[float, float, float], ...]]
) -> tuple[Following, ...]:
    """Step 3's pairs: every follow with a symbolic car (the ego's stands for both
    certificates), except the complexity certificate behind a new car (it may hit it)."""
    found = []
    for follow in queue.follows:
        for leader in CERTIFICATES if follow.leader == "ego" else (follow.leader,):
            for follower in CERTIFICATES if follow.follower == "ego" else (follow.follower,):
                a, b = queue.members[leader], queue.members[follower]
                if a.places is not None and b.places is not None:
                    continue
                if follower == "illegal" and a.car.kind is CarKind.NEW:
                    continue
                found.append(
                    Following(
                        leader,
                        follower,
                        a.line,
                        b.line,
                        a.length,
                        follow.parting,
                        old.params.gap,
                        old.params.headway + _margin(old),
                        rows.get(leader) or rows.get(follower) or (),
                    )
                )
    return tuple(found)


def _sample(
    at: Callable[[float], tuple[float, float]], track: PoseTrack, duration: float, timestep: float
) -> list[PoseSample]:
    """The curve at every time step while the car is on the map: a car whose front reaches
    the end of its road leaves there (as SUMO removes it), and its trajectory ends."""
    samples: list[PoseSample] = []
    for k in range(round(duration / timestep) + 1):
        t = round(k * timestep, 9)
        distance, speed = at(t)
        if distance > track.road and len(samples) >= 2:
            break
        if -ROUNDING < speed < 0:
            speed = 0.0  # float noise of a standing car
        if samples and samples[-1].distance - ROUNDING < distance < samples[-1].distance:
            distance = samples[-1].distance  # float noise, not a car backing up
        x, y, heading = track.pose_at(distance)
        samples.append(PoseSample(t, x, y, heading, speed, distance))
    return samples


def _candidate(
    old: TestCase,
    junction: Intersection,
    ordering: Ordering,
    samples: dict[str, list[PoseSample]],
    added: _Added,
    seed: int,
    method: str,
    tried: int,
) -> TestCase:
    document: dict[str, Any] = old.model_dump(mode="json", by_alias=True, exclude_none=True)
    level = 1 + testcase_level(old)
    ids = added.everyone
    for car_id, route in zip(added.ids, added.routes, strict=True):
        trajectory = samples[car_id]
        events = _events(trajectory, old.ego.length, old.ego.width, junction, route.fork, old)
        document["nonegos"].append(
            {
                "id": car_id,
                "route": {"fork": route.fork, "exit": route.exit},
                "length": old.ego.length,
                "width": old.ego.width,
                "trajectory": [_row(s) for s in trajectory],
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
    if added.people:
        document["schema"] = SCHEMA_WITH_PEDESTRIANS
        document.setdefault("pedestrians", []).extend(
            pedestrian_rows(old, junction, added.people, samples, level, _row)
        )
    document["certificates"] = {
        "complexity": [_row(s) for s in samples["illegal"]],
        "solvability": [_row(s) for s in samples["ego"]],
    }
    document["provenance"] = {
        "parent": document_sha256(old),
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


def _rounded(sample: PoseSample) -> PoseSample:
    """The sample as it is stored: six decimals (a micrometre), heading in [0, 360)."""
    t, x, y, heading, speed, distance = (round(v, 6) + 0.0 for v in _fields_of(sample))  # no -0.0
    return PoseSample(t, x, y, heading % 360.0, speed, distance)


def _fields_of(sample: PoseSample) -> tuple[float, float, float, float, float, float]:
    """The sample's fields in their order (dataclasses.astuple deep-copies: slow here)."""
    return sample.t, sample.x, sample.y, sample.heading, sample.speed, sample.distance


def _row(sample: PoseSample) -> dict[str, float]:
    """The sample as a document's row (dataclasses.asdict, without its deep copies)."""
    return dict(zip(_SAMPLE_FIELDS, _fields_of(sample), strict=True))


_SAMPLE_FIELDS = tuple(f.name for f in dataclasses.fields(PoseSample))


def _binds_new(violation: Violation, junction: Intersection) -> bool:
    """Whether Step 2 holds a new road user to the rule it broke: at a signal every rule
    (a new car obeys its light), elsewhere those of people on foot (theirs, and 21951 of
    the cars): at a sign a new car stops or does not, Step 2's choice, as without them."""
    return junction.signals is not None or violation.rule in people_laws(junction.control)


def verify_extension(
    old: TestCase,
    new: TestCase,
    junction: Intersection,
    ids: Sequence[str],
    old_judge: Judge | None = None,
) -> str | None:
    """None when the candidate is verified, else what is wrong (``old_judge``: the
    checker of ``old``, when the caller has it)."""
    return _verify(old, new, junction, ids, old_judge)[0]


def _verify(
    old: TestCase,
    new: TestCase,
    junction: Intersection,
    ids: Sequence[str],
    old_judge: Judge | None,
) -> tuple[str | None, Verdict | None]:
    """What is wrong with the candidate (None: verified), and the verdict of its
    complexity certificate in it once that was judged."""
    assert new.certificates is not None
    old_judge = old_judge or Judge(old, junction)
    new_judge = Judge(new, junction, known=old_judge)
    solvability = new_judge.ego_car(
        [PoseSample(**s.model_dump()) for s in new.certificates.solvability]
    )
    verdict = new_judge.verdict(solvability, "solvability")
    if not verdict.passed:
        reasons = "; ".join(verdict.reasons)
        return f"solvability certificate fails the new test-case: {reasons}", None
    if late := _after_goal(verdict):
        return f"solvability certificate {late} in the new test-case", None
    complexity = old_judge.ego_car(
        [PoseSample(**s.model_dump()) for s in new.certificates.complexity]
    )
    verdict = old_judge.verdict(complexity, "complexity")
    if not verdict.passed:
        reasons = "; ".join(verdict.reasons)
        return f"complexity certificate fails the old test-case: {reasons}", None
    if late := _after_goal(verdict):
        return f"complexity certificate {late} in the old test-case", None
    verdict = new_judge.verdict(complexity, "complexity")
    if verdict.passed:
        return "complexity certificate passes the new test-case", verdict
    if not verdict.goal_reached:
        reasons = "; ".join(verdict.reasons)
        return f"complexity certificate fails the new test-case otherwise: {reasons}", verdict
    if any(c.other not in ids or c.kind != REAR_END for c in verdict.collisions):
        problem = "complexity certificate collides with a car other than a new car ahead of it"
        return problem, verdict
    if late := _after_goal(verdict):
        return f"complexity certificate {late} in the new test-case", verdict
    if any(v.other not in ids for v in verdict.violations):
        return "complexity certificate breaks a rule besides a new car's right-of-way", verdict
    people = {p.id for p in new.pedestrians}
    for car_id in ids:  # new road users obey the rules Step 2 holds them to
        broken = [v for v in new_judge.rules_broken_by(car_id) if _binds_new(v, junction)]
        if broken:
            laws = ", ".join(f"{v.rule} ({v.law})" for v in broken)
            return f"{car_id} breaks {laws}", verdict
    motions = {
        n.id: Motion([PoseSample(**s.model_dump()) for s in n.trajectory], n.length, n.width)
        for n in new.road_users
    }
    for car_id in ids:
        for other, motion in motions.items():
            if other == car_id or (other in ids and other < car_id):
                continue
            if car_id in people and other in people:  # people on foot step round each other
                continue
            hit = first_collision(motions[car_id], motion)
            if hit is not None:
                return f"{car_id} collides with {other} at {hit.time:.2f} s", verdict
    return _gaps_kept(new, new_judge, solvability, junction, ids), verdict


def _after_goal(verdict: Verdict) -> str | None:
    """What a certificate does after its goal that a certificate must not, in words (None:
    nothing). The pass-fail criteria end with the goal, so the verdict only keeps it as
    information; a certificate still collides with no car and breaks no rule over its
    whole trajectory (design, section 2), and the complexity certificate's one binding
    rear-end collision is judged: before its goal."""
    if verdict.after_goal_collisions:
        first = verdict.after_goal_collisions[0]
        return f"collides with {first.other} at {first.t:.2f} s, after its goal"
    if verdict.after_goal_violations:
        return f"breaks {verdict.after_goal_violations[0].rule} after its goal"
    return None


def _gaps_kept(
    new: TestCase, judge: Judge, solvability: Car, junction: Intersection, ids: Sequence[str]
) -> str | None:
    """What is wrong with the gaps in the queues that a new car or the solvability
    certificate is in (None: every follower keeps its gap)."""
    cars = {car.id: car for car in (solvability, *judge.nonegos)}
    checked = {*ids, solvability.id}
    for follow in follows([car.in_queue for car in cars.values()], junction):
        if not checked & {follow.leader, follow.follower}:
            continue
        leader, follower = cars[follow.leader], cars[follow.follower]
        fault = gap_fault(
            follow,
            Places.of(leader.samples, leader.in_queue),
            Places.of(follower.samples, follower.in_queue),
            new.params.gap,
            new.params.headway,
        )
        if fault is not None:
            name = "the solvability certificate" if follower.id == solvability.id else None
            return f"{name or follower.id} does not keep its gap: {fault}"
    return None


def complexity_kind(new: TestCase, junction: Intersection) -> dict[str, Any]:
    """How the complexity certificate fails the new test-case: "right-of-way" (it violates
    a new car's) or "rear-end" (it drives into a new car ahead of it), and the cars."""
    assert new.certificates is not None
    verdict = check_testcase(
        new, [PoseSample(**s.model_dump()) for s in new.certificates.complexity],
        "complexity", junction, criticality=False,
    )  # fmt: skip
    return _kind_of(verdict)


def _kind_of(verdict: Verdict) -> dict[str, Any]:
    """The kind of complexity certificate its verdict in the new test-case shows."""
    hit = sorted({c.other for c in verdict.collisions})
    return {
        "kind": "rear-end" if hit else "right-of-way",
        "right_of_way": sorted({v.other for v in verdict.violations if v.other}),
        "rear_end": hit,
    }
