"""Growing a chain one car at a time, the way a test engineer would.

Each level adds one new car on a route that conflicts with the ego's, from a fork no car
uses yet (following in one lane is not modelled), trying such routes in an order drawn
from the seed. Every choice depends only on the test-case and the seed: first every route
gets up to ROUTE_ORDERS answer sets (a count, not a clock), in that order; when none of
them gave an extension, those whose search was cut short get the generator's full MAX_ORDERS
(starting over: the search is deterministic, so the first ROUTE_ORDERS are tried again).
The time budget only stops the call.
"""

from __future__ import annotations

import random
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from service.core.errors import NoMoreComplexTestCase, NoneFound
from service.core.generate import MAX_ORDERS, Extension, Progress, extend_testcase
from service.core.network import Intersection
from service.core.testcase import TestCase, load_testcase_intersection

ROUTE_ORDERS = 20  # answer sets one route gets in the first round (a count)


def candidate_routes(old: TestCase, intersection: Intersection) -> list[str]:
    """Routes a new car may take: they conflict with the ego's and start on a fork that
    neither the ego nor any non-ego uses, sorted by id."""
    used = {old.ego.route.fork, *(car.route.fork for car in old.nonegos)}
    return sorted(
        route
        for route in intersection.conflicts[old.ego.route.id]
        if intersection.routes[route].fork not in used
    )


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
) -> Growth:
    """The next level of a chain: one new car on the first candidate route (in the seed's
    order) that has an extension. NoMoreComplexTestCase when none can have one; NoneFound
    when some were not found (with ``budget_exhausted`` when the budget stopped it)."""
    junction = intersection or load_testcase_intersection(old)
    candidates = candidate_routes(old, junction)
    random.Random(seed).shuffle(candidates)
    end = time.monotonic() + budget
    outcomes: list[str] = []
    proven = True
    for orders in (ROUTE_ORDERS, MAX_ORDERS):
        retry = []
        for route in candidates:
            left = end - time.monotonic()
            if left <= 0:
                raise _exhausted(budget, outcomes, seed)
            try:
                extension = extend_testcase(
                    old, [route], seed, left, None, progress, junction, max_orders=orders
                )
            except NoMoreComplexTestCase as error:
                outcomes.append(f"{route}: {error}")
                continue
            except NoneFound as error:
                if error.context.get("budget_exhausted"):
                    raise _exhausted(budget, outcomes, seed) from None
                if orders < MAX_ORDERS and not error.context.get("search_exhausted"):
                    retry.append(route)  # a longer search may find one; a finished one not
                    continue
                proven = False
                outcomes.append(f"{route}: {error}")
                continue
            return Growth(extension, route, tuple(outcomes))
        candidates = retry
    tried = "; ".join(outcomes) or "no route conflicts with the ego's from a free fork"
    if proven:
        raise NoMoreComplexTestCase(f"no new car makes this test-case more complex ({tried})")
    raise NoneFound(f"no route gave a more complex test-case ({tried})", seed=seed)


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
