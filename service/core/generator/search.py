"""An extension's search: Steps 2 and 3 over the orders of events and their timings.

Step 2 draws answer sets one at a time (service.core.generator.ordering), first those that
SEARCH_SHARES[0] of the bounds can time, then the rest; each new order is timed by Step 3
(aimed where the seed says, variety.seed_aim) and made into a verified candidate
(service.core.generator.candidate); the relations a failed timing cannot keep are ruled out
of later answer sets. Then other timings of the verified orders, for distinct extensions.
The search is limited by counts; the wall-clock budget (``Deadline``) only stops a call
that runs too long. When it ends empty, ``not_found`` says why. Its place in the method:
service.core.generator.extension.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any

from service.core.checker.check import Judge
from service.core.errors import NoneFound
from service.core.generator.additions import Added, Queue
from service.core.generator.candidate import judged_candidate, safety_margin, timing_problem
from service.core.generator.ordering import (
    Ordering,
    OrderingSearch,
    SearchLimitReached,
)
from service.core.generator.ordering_facts import (
    Limits,
    OrderingCar,
)
from service.core.generator.timing import (
    SHARES,
    CarPlan,
    TimingFailure,
    TimingProblem,
    TimingSolution,
    entry_window,
    plan_times,
)
from service.core.generator.timing_solve import solve_timing
from service.core.generator.variety import (
    AIM_POINTS,
    ALIKE_POINTS,
    DISTINCT_GAP,
    LATTICE,
    Signature,
    aim_points,
    describe_aim,
    is_new,
    joint_points,
    seed_aim,
    signature,
    test_relations,
)
from service.core.motion.kinematics import Bounds
from service.core.motion.poses import PoseTrack
from service.core.network import Intersection
from service.core.testcase import TestCase

# Step 2 first proposes orders that 70 % of the bounds can time (they leave the curves room),
# then, when those are exhausted, every order the full bounds allow.
SEARCH_SHARES = (0.7, 1.0)
TIMINGS_PER_WANTED = 3  # other timings extend_testcases tries per extension still wanted
MAX_TIMINGS = 60  # ... and at most this many in one call (each costs a plan and a verdict)

Progress = Callable[[str], None]


@dataclass(frozen=True)
class Attempt:
    """What happened to one answer set."""

    index: int
    outcome: str


class Deadline:
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


Aims = tuple[tuple[str, float], ...]  # (time symbol, aimed time): see ExtensionSearch._aims


class ExtensionSearch:
    """Step 2 and 3 over one extension's cars: verified candidates, order by order
    (``orders``), then other timings of the verified orders (``timings``). Each answer set
    is drawn once; the seed's aim (variety.seed_aim) is tried first for every order that
    Step 3 can time at all (its own plan, without aims, solved first and kept: an order
    without curves is not aimed, and its core goes back to Step 2)."""

    def __init__(
        self,
        old: TestCase,
        junction: Intersection,
        cars: list[OrderingCar],
        queue: Queue,
        tracks: dict[str, PoseTrack],
        added: Added,
        seed: int,
        judge: Judge,
        deadline: Deadline,
        say: Progress,
        seconds: dict[str, float],
        attempts: list[Attempt],
    ) -> None:
        self.old, self.junction, self.cars, self.queue = old, junction, cars, queue
        self.tracks, self.added, self.seed, self.judge = tracks, added, seed, judge
        self.deadline, self.say, self.seconds, self.attempts = deadline, say, seconds, attempts
        self.tried: list[Ordering] = []
        self.verified: list[Ordering] = []  # of every test-case order, the first verified
        self.timings_limited = False  # timings() stopped at its count
        self.exhausted = False
        self.problem: TimingProblem | None = None  # of the last verified candidate
        self.variants: list[tuple[int, float]] = []  # (answer set, aim) of every timing tried
        self.own_plans: dict[Ordering, bool] = {}  # an alike order's own plan: timed?
        self.keys: dict[tuple[tuple[str, ...], frozenset[str]], int] = {}  # verified: number
        # by order (not by its number: each round of SEARCH_SHARES numbers its answer sets
        # from 0 again, so a number names different orders in the two rounds)
        self.windows: dict[Ordering, list[tuple[str, tuple[float, float], float | None]]] = {}
        self.problems: dict[Ordering, TimingProblem] = {}
        self.solved: dict[tuple[Ordering, Aims], TimingSolution | TimingFailure] = {}
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
                order_limits(self.old, share=share), self.queue.bounds,
            )  # fmt: skip
            for ordering in self.tried:
                search.block(ordering)
            for relations in ruled_out:
                search.forbid(relations)
            for ordering in self.verified:
                self._block_alike(search, ordering)
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
                if aim is not None and isinstance(self._solve(ordering, ()), TimingFailure):
                    aimed = False  # no curves even for the order's own plan: aims add none
                else:
                    aimed = aim is not None
                outcome, candidate, core = self.attempt(
                    ordering, aim if aimed else None, number + 1, apart=aimed
                )
                if candidate is None and aimed:  # the order's own plan may still
                    self.say(f"step 2/3 answer set {number + 1}, aimed: {outcome}")
                    outcome, candidate, core = self.attempt(ordering, None, number + 1)
                if core is not None:  # given the phases chosen: their bounds are part of it
                    ruled_out.append([*core, *ordering.phases])
                    search.forbid(ruled_out[-1])
                attempts.append(Attempt(number, outcome))
                self.say(f"step 2/3 answer set {number + 1}: {outcome}")
                if candidate is not None:
                    self.keys[self._key(ordering)] = number + 1
                    self.verified.append(ordering)
                    self._block_alike(search, ordering)
                    yield ordering, candidate
            if not self.exhausted:
                return

    def alike_orders(self, max_orders: int) -> list[Ordering]:
        """The orders alike in the test-case's cars to one verified (``_key``), drawn but
        not timed, within ``max_orders`` answer sets in all. They differ from it in how the
        certificates drive, and so in the windows of arrival (and entry) times their
        timings leave: ``--count`` aims in them (``timings`` over both windows) once the
        verified orders' timings fall short. Every other order was drawn before
        (``orders``): one drawn here is passed over."""
        clock = time.monotonic()
        search = OrderingSearch(
            self.junction, self.cars, self.old.params.m, self.seed,
            order_limits(self.old, share=SEARCH_SHARES[0]), self.queue.bounds,
        )  # fmt: skip
        for ordering in self.tried:
            search.block(ordering)
        alike: list[Ordering] = []
        while len(self.attempts) < max_orders:
            self.deadline.check(self.attempts, "Step 2")
            try:
                drawn = search.next_ordering()
            except SearchLimitReached:
                break
            if drawn is None:
                break
            self.tried.append(drawn)
            number = self.keys.get(self._key(drawn))  # the verified order it is alike to
            if number is not None:
                alike.append(drawn)
                outcome = f"alike to #{number}: --count aims in its windows"
            else:
                outcome = "not alike to a verified order: passed over"
            self.attempts.append(Attempt(len(self.attempts), outcome))
        self.seconds["ordering"] += time.monotonic() - clock
        return alike

    def _block_alike(self, search: OrderingSearch, ordering: Ordering) -> None:
        """Rule out the answer sets that differ from a verified order only in how the
        certificates drive (the same test-case: ``_key``), so that the search's count goes
        to other test-cases: for an order with relations among the test-case's cars, or
        where there are no two such cars to relate (else a constraint without relations
        would rule out orders with other relations too)."""
        test = [
            relation
            for relation, named in zip(ordering.relations, ordering.named, strict=True)
            if test_relations([" ".join(named)])
        ]
        if test or len(self.old.road_users) + len(self.added.everyone) < 2:
            cars = set(self.added.everyone)
            search.block_alike(test, ordering.stops & cars, cars)

    def _key(self, ordering: Ordering) -> tuple[tuple[str, ...], frozenset[str]]:
        """What of an order the test-case keeps (variety.Signature): the relations among
        its cars and which new cars stop; orders alike in these differ only in how the
        certificates drive, and Step 3 plans the new cars alike for them."""
        ids = self.added.everyone
        return tuple(test_relations(ordering.describe())), ordering.stops & set(ids)

    def timings(
        self, verified: Sequence[Ordering], taken: list[Signature], wanted: int, limit: int,
        joint: bool = False,
    ) -> Iterator[tuple[Ordering, TestCase]]:  # fmt: skip
        """Up to ``wanted`` more candidates from ``verified`` orders, aimed at the points
        of variety.aim_points in turn (``joint``: variety.joint_points, over the entry and
        arrival windows together, ALIKE_POINTS points in all the orders), each point in every
        order before the next point, those that differ from ``taken`` (which the caller
        extends with every one it keeps); at most ``limit`` timings are tried in all the
        calls of this search (a count). A point whose entry and arrival times are close to
        those of one taken is passed over without solving."""
        given = 0
        points = {
            ordering: joint_points() if joint else aim_points(self._lattice_step(ordering))
            for ordering in verified
        }
        looked = 0  # points looked at: the orders alike (``joint``) share ALIKE_POINTS
        for rank in range(AIM_POINTS):
            for ordering in verified:
                aim, arrival = points[ordering][rank]
                if given >= wanted or (joint and looked >= ALIKE_POINTS):
                    return
                looked += 1
                if len(self.variants) >= limit:
                    self.timings_limited = True
                    return
                if joint and not self._timeable(ordering):
                    continue
                aims = self._aims(ordering, aim)
                if not aims:
                    continue
                arrivals = self._arrival_aims(ordering, aims, arrival)
                if self._near(ordering, aims, arrivals, taken):
                    continue
                number = self.keys[self._key(ordering)]
                self.variants.append((number, aim))
                outcome, candidate, _ = self.attempt(ordering, aim, number, arrival=arrival)
                aimed = {"share": aim, "arrival_share": arrival}
                self.say(f"step 3 answer set {number}, {describe_aim(aimed)}: {outcome}")
                if candidate is None or not is_new(signature(candidate), taken):
                    continue
                given += 1
                yield ordering, candidate

    def _timeable(self, ordering: Ordering) -> bool:
        """Whether Step 3 times an order drawn but not timed (``alike_orders``) by its own
        plan: an order without curves is not aimed in (each aim would fail after every
        fall-back)."""
        if ordering not in self.own_plans:
            self.own_plans[ordering] = not isinstance(self._solve(ordering, ()), TimingFailure)
        return self.own_plans[ordering]

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

    def _lattice_step(self, ordering: Ordering) -> float | None:
        """The share of the first new car's entry window that LATTICE x DISTINCT_GAP
        seconds make (None without a window)."""
        if ordering not in self.windows:
            self.windows[ordering] = self._windows(ordering)
        if not self.windows[ordering]:
            return None
        _, (low, high), _ = self.windows[ordering][0]
        return LATTICE * DISTINCT_GAP / (high - low) if high > low else None

    def _arrival_aims(self, ordering: Ordering, aims: Aims, share: float | None) -> Aims:
        """Each new car's arrival at its line aimed at ``share`` of the window of arrival
        times that its aimed entry (in ``aims``) leaves; none without a share, for a car
        that arrives where it starts, or where the window is empty."""
        if share is None:
            return ()
        problem, entries = self._problem(ordering), dict(aims)
        found = []
        for plan in problem.cars:
            entry = _entry_symbol(plan)
            if plan.car not in self.added.everyone or plan.arrival is None or entry is None:
                continue
            arrival = plan.knots[plan.arrival].symbol
            if entry not in entries or arrival is None or arrival == entry:
                continue
            held = ((entry, entries[entry]),)
            given = dataclasses.replace(
                problem, earliest=problem.earliest + held, latest=problem.latest + held
            )
            window = entry_window(given, arrival)
            if window is not None:
                low, high = window
                found.append((arrival, round(low + share * (high - low), 4)))
        return tuple(found)

    def _near(
        self, ordering: Ordering, aims: Aims, arrivals: Aims, taken: Sequence[Signature]
    ) -> bool:
        """Whether a test-case taken (of any order: its signature tells the orders apart
        only after solving) has every new car within DISTINCT_GAP of the aimed entry and,
        where one is aimed, the aimed arrival: solving would give no new test-case."""
        owner = {k.symbol: plan.car for plan in self._problem(ordering).cars for k in plan.knots}
        entries = {owner[symbol]: t for symbol, t in aims}
        arrived = {owner[symbol]: t for symbol, t in arrivals}
        return any(
            mark.cars
            and all(
                car.car in entries
                and abs(car.entry - entries[car.car]) < DISTINCT_GAP
                and (car.car not in arrived or abs(car.arrival - arrived[car.car]) < DISTINCT_GAP)
                for car in mark.cars
            )
            for mark in taken
        )

    def _problem(self, ordering: Ordering) -> TimingProblem:
        """Step 3's problem of an order (made once: the windows and every timing use it)."""
        if ordering not in self.problems:
            self.problems[ordering] = timing_problem(
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

    def _solve(self, ordering: Ordering, aims: Aims) -> TimingSolution | TimingFailure:
        """Step 3 of an order with ``aims`` (none: the order's own plan), solved once."""
        key = (ordering, aims)
        if key not in self.solved:
            self.deadline.check(self.attempts, "Step 3")
            clock = time.monotonic()
            problem = dataclasses.replace(self._problem(ordering), aims=aims)
            self.solved[key] = solve_timing(problem)
            self.seconds["timing"] += time.monotonic() - clock
        return self.solved[key]

    def attempt(
        self,
        ordering: Ordering,
        aim: float | None,
        number: int,
        apart: bool = False,
        arrival: float | None = None,
    ) -> tuple[str, TestCase | None, list[tuple[str, Any, Any]] | None]:
        """The outcome of timing and judging one order, aimed at ``aim`` of the new cars'
        entry windows (None: the smoothest plan) and ``arrival`` of the arrival windows
        those entries leave (None: as the plan has it): what happened, the verified
        candidate (or None), and the relations that cannot hold together (a core, or
        None)."""
        old, seconds = self.old, self.seconds
        self.deadline.check(self.attempts, "Step 3")
        clock = time.monotonic()
        aims = self._aims(ordering, aim, apart) if aim is not None else ()
        arrivals = self._arrival_aims(ordering, aims, arrival)
        if aim is not None and not aims:
            seconds["timing"] += time.monotonic() - clock
            return "no window of entry times to aim in", None, None
        seconds["timing"] += time.monotonic() - clock
        problem = self._problem(ordering)
        result = self._solve(ordering, aims + arrivals)
        if isinstance(result, TimingFailure):
            core = [ordering.relations[i] for i in result.core] if result.core else None
            return f"timing: {result.reason}", None, core
        clock = time.monotonic()
        outcome, candidate = judged_candidate(
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
            if arrivals:
                candidate.provenance["timing_aim"] |= {
                    "arrival_share": arrival, "arrivals": {s: round(t, 3) for s, t in arrivals}
                }  # fmt: skip
        self.problem = problem
        return f"verified ({result.method})", candidate, None


def _entry_symbol(plan: CarPlan) -> str | None:
    """The time symbol of the car entering its lane in the junction (else its first)."""
    if plan.inside is not None:
        return plan.knots[plan.inside[0]].symbol
    return next((k.symbol for k in plan.knots if k.symbol is not None), None)


def order_limits(old: TestCase, margin: float | None = None, share: float = 1.0) -> Limits:
    """What Step 2 bounds the timing with: ``share`` of the test-case's speed and
    acceleration bounds, the safety margin of every relation, and the least average speed
    through the junction (v_run: a car the generator plans does not stall inside). Without
    a margin (the proof that nothing exists), any crossing speed."""
    params, walk = old.params, old.params.walk
    return Limits(
        old.duration,
        Bounds(params.v_max, params.a_max, params.a_min).scaled(share),
        params.v_run,
        safety_margin(old) if margin is None else margin,
        None if margin == 0.0 else params.v_run,
        Bounds(walk.v_max, walk.a_max, walk.a_min).scaled(share),
    )
