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

Here the entry points and Step 1; the method's other parts in the order they run:
additions.py (the new routes, walks, ids and starts checked; every car's events and the
queues for Step 2), search.py (Step 2's answer sets and their timings, why none was found),
candidate.py (Step 3's problem of an order, and the candidate from its solution) and
verification.py (the checker's verdicts on a candidate).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field

from service.core.checker.check import Judge
from service.core.errors import BudgetExceeded, InvalidInput, NoneFound
from service.core.generator.additions import (
    Added,
    ShortenedStart,
    StartDistances,
    automatic_starts,
    new_car_ids,
    ordering_cars,
    queue_of,
    validate_routes,
)
from service.core.generator.failure import not_found
from service.core.generator.ordering import Ordering
from service.core.generator.search import (
    MAX_TIMINGS,
    TIMINGS_PER_WANTED,
    Attempt,
    Deadline,
    ExtensionSearch,
    Progress,
)
from service.core.generator.timing import TimingProblem
from service.core.generator.variety import AIM_POINTS, ALIKE_POINTS, is_new, signature
from service.core.generator.verification import checked_judge
from service.core.generator.walkers import (
    NewPedestrians,
    new_pedestrian_cars,
    new_pedestrian_ids,
    old_pedestrian_cars,
    pedestrian_tracks,
    validate_walks,
)
from service.core.motion.poses import DRIVE_BUDGET, generate_poses
from service.core.network import Intersection
from service.core.testcase import TestCase, load_testcase_intersection

STEP1_SPEED = 8.0  # m/s: Step 1 drives at this speed; it sets only how dense the poses are
MAX_ORDERS = 60  # answer sets one extension tries at most: a count, the same on any machine


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
    timings_limited: bool = False  # their count (TIMINGS_PER_WANTED a wanted one) ran out
    alike_orders: int = 0  # orders alike to a verified one whose windows were aimed in too

    def shortfall(self, wanted: int) -> str | None:
        """Why fewer than ``wanted`` came back (None when that many did): which of the
        search's counts ran out, the answer sets of Step 2 or the other timings, or that
        every order was drawn and every point of its timings looked at."""
        have = len(self.found)
        if have >= wanted:
            return None
        if self.exhausted:
            orders = f"every order of events tried ({self.orders_tried} answer sets)"
        else:
            orders = f"the search's count of {self.orders_tried} answer sets ran out"
        timings = ""
        if self.timings_tried:
            alike = f" and of {self.alike_orders} orders alike" if self.alike_orders else ""
            why = (
                f"their count ({TIMINGS_PER_WANTED} per extension wanted, at most "
                f"{MAX_TIMINGS}) ran out"
                if self.timings_limited
                else f"all {AIM_POINTS} points of their entry and arrival windows looked at"
                + (f" ({ALIKE_POINTS} over the orders alike)" if self.alike_orders else "")
            )
            timings = (
                f"; {self.timings_tried} other timings of the verified orders{alike} tried, {why}"
            )
        return f"{have} distinct extensions found: {orders}{timings}"


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
    first, each answer set at most once (those alike in the test-case's cars ruled out
    once one of them is verified); then other timings of the verified orders, aimed at the
    points of variety.aim_points over the new cars' entry and arrival windows; when every
    point was looked at and fewer were found, the orders alike to the verified ones (the
    certificates drive otherwise, which opens other windows), aimed at the points of
    variety.joint_points. TIMINGS_PER_WANTED timings per extension still wanted after
    the orders (at most MAX_TIMINGS) are tried in all. Raises what
    ``extend_testcase`` raises when there is none; fewer than ``count`` is not an error
    (``Extensions.shortfall`` says why). ``walks``: new pedestrians, one on each walk
    (docs/pedestrians.md), with the new cars or without them."""
    if count < 1:
        raise InvalidInput(f"count must be at least 1, not {count}")
    deadline = Deadline(budget, [*routes, *walks], seed)
    say = progress or (lambda _: None)
    seconds: dict[str, float] = {}
    junction = intersection or load_testcase_intersection(old)
    old_judge = judge or checked_judge(old, junction)
    new_walks = validate_walks(junction, walks)
    new_routes = validate_routes(old, junction, routes, new_walks)
    ego_route = junction.route(old.ego.route.id)
    ids = new_car_ids(old, len(new_routes))
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

    cars = ordering_cars(old, old_judge, junction, ego_track, new_tracks, new_routes, ids)
    cars += old_pedestrian_cars(old_judge, junction)
    cars += new_pedestrian_cars(junction, people, walked, old)
    queue = queue_of(old, old_judge, junction, cars, tracks_of, ids)
    added = Added(tuple(new_routes), tuple(ids), people)
    search = ExtensionSearch(
        old, junction, cars, queue, tracks_of, added, seed, old_judge, deadline, say, seconds,
        attempts,
    )  # fmt: skip
    taken = [signature(t) for t in avoid]
    found: list[Extension] = []
    verified: list[Ordering] = []

    def keep(candidate: TestCase) -> None:
        taken.append(signature(candidate))
        _note_shortened(candidate, shortened, ids)
        found.append(Extension(candidate, list(attempts), dict(seconds), search.problem))

    for ordering, candidate in search.orders(max_orders):
        verified.append(ordering)
        if not is_new(signature(candidate), taken):
            say(f"step 2/3 answer set {len(attempts)}: the same test-case as one before")
            continue
        keep(candidate)
        if len(found) >= count:
            break
    limit = min(TIMINGS_PER_WANTED * (count - len(found)), MAX_TIMINGS)  # timings, in all
    alike: list[Ordering] = []
    if len(found) < count and verified:
        for _, candidate in search.timings(verified, taken, count - len(found), limit):
            keep(candidate)
    if len(found) < count and verified and not search.timings_limited:
        # every point of the verified orders looked at: the windows of the orders alike
        alike = search.alike_orders(max_orders)
        for _, candidate in search.timings(alike, taken, count - len(found), limit, joint=True):
            keep(candidate)
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
        raise not_found(old, junction, cars, queue.bounds, seed, routes, attempts,
                        search.exhausted, walks)  # fmt: skip
    return Extensions(
        found, len(search.tried), search.exhausted, len(search.variants), search.timings_limited,
        len(alike),
    )  # fmt: skip


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
