"""Growing a chain one car at a time, the way a test engineer would.

Each level adds one new car on a route that conflicts with the ego's or starts ahead of
the ego on its fork, trying such routes in an order drawn from the seed: those from forks
no car uses first; only when none of them gives an extension, those that join a queue
(service.core.motion.queues). Every choice depends only on the test-case and the seed: in each
group, first every route gets up to ROUTE_ORDERS answer sets (a count, not a clock), in
that order; when none of them gave an extension, those whose search was cut short get the
generator's full MAX_ORDERS (starting over: the search is deterministic, so the first
ROUTE_ORDERS are drawn again, and their Step 3 is remembered, timing_solve.solve_timing).
The time budget only stops the call.
"""

from __future__ import annotations

import random
import time
from collections.abc import Callable, Collection, Sequence
from dataclasses import dataclass

from service.core.checker.check import Judge
from service.core.errors import InvalidInput, NoMoreComplexTestCase, NoneFound, ScengenError
from service.core.generator.additions import candidate_routes
from service.core.generator.extension import MAX_ORDERS, Extension, extend_testcase
from service.core.generator.failure import longer_duration, route_label
from service.core.generator.search import Progress
from service.core.generator.verification import checked_judge
from service.core.network import Intersection
from service.core.testcase import TestCase, load_testcase_intersection

ROUTE_ORDERS = 20  # answer sets one route gets in the first round (a count)


def _by_free_fork(old: TestCase, intersection: Intersection, routes: list[str]) -> list[list[str]]:
    """Routes from forks no car uses and walks no pedestrian takes, then those that join a
    queue or a walk in use (each in the order given): the second group is tried only when
    the first gave nothing."""
    used = {old.ego.route.fork, *(car.route.fork for car in old.nonegos)}
    walked = {person.walk for person in old.pedestrians}
    taken = [r for r in routes if r in walked
             or (r in intersection.routes and intersection.routes[r].fork in used)]  # fmt: skip
    return [[r for r in routes if r not in taken], taken]


@dataclass(frozen=True)
class Growth:
    """One level more: the extension and the route it added, and the routes tried first."""

    extension: Extension
    route: str
    passed_over: tuple[str, ...]  # routes tried before, each with why it gave nothing


def grow(
    old: TestCase,
    seed: int = 0,
    budget: float = 60.0,
    intersection: Intersection | None = None,
    progress: Progress | None = None,
    last: Collection[str] = (),
    avoid: Sequence[TestCase] = (),
) -> Growth:
    """The next level of a chain: one new car on the first candidate route (in the seed's
    order, those in ``last`` after the others) that has an extension that differs from
    every test-case in ``avoid`` (another chain's level: service.core.generator.variety).
    NoMoreComplexTestCase when none can have one; NoneFound when some were not found (with
    ``budget_exhausted`` when the budget stopped it)."""
    junction = intersection or load_testcase_intersection(old)
    judge = checked_judge(old, junction)  # once for every route tried
    candidates = candidate_routes(old, junction)
    random.Random(seed).shuffle(candidates)
    held_back = set(last)
    candidates.sort(key=lambda route: route in held_back)  # stable: the seed's order stays
    end = time.monotonic() + budget
    outcomes: list[str] = []  # a line per route: its name and why it gave nothing
    needed: list[object] = []  # the durations with room, where the duration limits
    proven = True
    for group in _by_free_fork(old, junction, candidates):
        found, proven_here = _first_extension(old, group, seed, budget, end, (junction, judge),
                                              progress, (outcomes, needed), avoid)  # fmt: skip
        proven = proven and proven_here
        if found is not None:
            return found
    if not outcomes:
        raise NoMoreComplexTestCase("no new car makes this test-case more complex: no route "
                                    "conflicts with the ego's")  # fmt: skip
    tried = "".join(f"\n  {line}" for line in outcomes)
    longer = [n for n in needed if isinstance(n, float)]
    to_try = ["another seed (draws the routes in another order)" if not proven else "",
              longer_duration(old, max(longer)) if longer else ""]  # fmt: skip
    to_try = [t for t in to_try if t]
    advice = f"\n  to try: {'; '.join(to_try)}" if to_try else ""
    if proven:
        raise NoMoreComplexTestCase(
            f"no new car makes this test-case more complex ({len(outcomes)} routes tried):"
            f"{tried}{advice}"
        )
    raise NoneFound(
        f"no route gave a more complex test-case ({len(outcomes)} routes tried):{tried}{advice}",
        seed=seed,
    )


def _first_extension(
    old: TestCase,
    candidates: list[str],
    seed: int,
    budget: float,
    end: float,
    checker: tuple[Intersection, Judge],
    progress: Progress | None,
    said: tuple[list[str], list[object]],
    avoid: Sequence[TestCase] = (),
) -> tuple[Growth | None, bool]:
    """The first of ``candidates`` with an extension: each first gets ROUTE_ORDERS answer
    sets, then those cut short get MAX_ORDERS. Also whether every other one is proven to
    have none. ``said``: a line per route without one (its name and why), and the
    durations with room that their errors name."""
    proven = True
    junction, judge = checker
    outcomes, needed = said
    for orders in (ROUTE_ORDERS, MAX_ORDERS):
        retry = []
        for route in candidates:
            left = end - time.monotonic()
            if left <= 0:
                raise _exhausted(budget, outcomes, seed)
            try:
                walking = route in junction.walks  # a pedestrian's walk, not a car's route
                extension = extend_testcase(
                    old, [] if walking else [route], seed, left, None, progress, junction,
                    orders, judge, avoid, [route] if walking else [],
                )  # fmt: skip
            except (NoMoreComplexTestCase, InvalidInput) as error:  # no room on its fork
                outcomes.append(_route_said(route, walking, error))
                needed.append(error.context.get("longer"))
                continue
            except NoneFound as error:
                if error.context.get("budget_exhausted"):
                    raise _exhausted(budget, outcomes, seed) from None
                if orders < MAX_ORDERS and not error.context.get("search_exhausted"):
                    retry.append(route)  # a longer search may find one; a finished one not
                    continue
                proven = False
                outcomes.append(_route_said(route, walking, error))
                continue
            return Growth(extension, route, tuple(outcomes)), proven
        candidates = retry
    return None, proven


def _route_said(route: str, walking: bool, error: ScengenError) -> str:
    """A route's line: its name and why it gave nothing (the error's ``why`` where it has
    one: failure.not_found)."""
    label = route_label([], [route]) if walking else route_label([route])
    return f"{label}: {error.context.get('why', error.message)}"


def _exhausted(budget: float, outcomes: Sequence[str], seed: int) -> NoneFound:
    tried = f" after {len(outcomes)} routes without an extension" if outcomes else ""
    return NoneFound(
        f"budget exhausted: the budget of {budget:g} s ran out{tried}; the same request with "
        "a larger budget gives the result it would have given",
        seed=seed,
        budget_exhausted=True,
    )


def grow_chain(
    start: TestCase,
    levels: int,
    seed: int = 0,
    budget_per_level: float = 60.0,
    on_level: Callable[[int, Growth], None] | None = None,
    progress: Progress | None = None,
) -> list[Growth]:
    """Up to ``levels`` levels from ``start``; ``on_level`` hears of each as soon as it is
    verified. Stops at the first level that has no extension (its error is raised)."""
    junction = load_testcase_intersection(start)
    grown: list[Growth] = []
    current = start
    for level in range(1, levels + 1):
        growth = grow(current, seed, budget_per_level, junction, progress)
        grown.append(growth)
        current = growth.extension.testcase
        if on_level is not None:
            on_level(level, growth)
    return grown
