"""Why a search for a more complex test-case found none, in words a user can act on.

"No more complex test-case exists" is said only when, even without any safety margin, no
order of events has consistent times (the search space is empty); "none found" says what
the answer sets it drew came to, each outcome once, and what to try (another seed, another
route, a longer test-case).
"""

from __future__ import annotations

from collections.abc import Sequence

from service.core.errors import NoMoreComplexTestCase, NoneFound
from service.core.generator.candidate import safety_margin
from service.core.generator.ordering import OrderingSearch
from service.core.generator.ordering_facts import OrderingCar, QueueBounds
from service.core.generator.search import Attempt, order_limits
from service.core.network import Intersection
from service.core.testcase import TestCase


def outcomes_said(attempts: Sequence[Attempt]) -> str:
    """What the attempts came to, each outcome once with the answer sets that had it
    ("#1-#8: timing: no speed profile within 85 % of the bounds; #9: ...")."""
    numbers: dict[str, list[int]] = {}
    for attempt in attempts:
        numbers.setdefault(attempt.outcome, []).append(attempt.index + 1)
    said = []
    for outcome, which in list(numbers.items())[:4]:
        runs = ", ".join(f"#{a}" if a == b else f"#{a}-#{b}" for a, b in _runs(which))
        said.append(f"{runs}: {outcome}")
    more = len(numbers) - 4
    return "; ".join(said) + (f"; {more} other outcome(s)" if more > 0 else "")


def _runs(numbers: Sequence[int]) -> list[tuple[int, int]]:
    """Consecutive numbers as (first, last) runs: 1, 2, 3, 5 -> (1, 3), (5, 5)."""
    runs: list[tuple[int, int]] = []
    for number in numbers:
        if runs and number == runs[-1][1] + 1:
            runs[-1] = (runs[-1][0], number)
        else:
            runs.append((number, number))
    return runs


def not_found(
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
    tried = outcomes_said(attempts)
    detail = f" ({tried})" if tried else ""
    if not exhausted:
        return NoneFound(
            f"none found among the first {len(attempts)} answer sets{detail}; the search's "
            "count of answer sets ran out: another seed draws others, another route or a "
            f"longer test-case (this one lasts {old.duration:g} s) gives more room",
            routes=list(routes),
            seed=seed,
            search_exhausted=False,
        )
    bare = OrderingSearch(junction, cars, old.params.m, seed, order_limits(old, margin=0.0), bounds)
    if not bare.satisfiable():
        return NoMoreComplexTestCase(
            f"no more complex test-case exists for these routes: {bare.explain_unsatisfiable()}",
            routes=list(routes),
        )
    if not attempts:
        return NoneFound(
            "none found: orders of events exist only without the safety margin of "
            f"{safety_margin(old):g} s on every relation, too close to call",
            routes=list(routes),
            seed=seed,
            search_exhausted=True,
        )
    return NoneFound(
        f"none found among all {len(attempts)} orders of events{detail}; another route or a "
        f"longer test-case (this one lasts {old.duration:g} s) gives more room",
        routes=list(routes),
        seed=seed,
        search_exhausted=True,
    )
