"""Why a search for a more complex test-case found none, in words a user can act on.

The message has a headline, one line for the routes tried (their names and what their
answer sets came to, counted: "car route N2C_0:C2S_0: 8 orders of events found, none could
be timed within 85 % of the speed bounds") and a last line of what to try: another route
(a few that exist and were not tried), another seed (when the search's count ran out), a
longer test-case (when the duration is what limits).

"No more complex test-case exists" is said only when, even without any safety margin, no
order of events has consistent times (the search space is empty). Whether the duration is
what limits then costs one more search, on the same facts with a horizon of
``PAST_THE_END`` times the duration (the search itself is left as it was: its answer sets,
and so every test-case it gives, stay the same); its first answer set's latest event gives
a duration with room. A search that drew orders says so from its own outcomes: a certificate
that does not reach its exit before the end.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace

from service.core.checker.verdict import NOT_REACHED
from service.core.errors import NoMoreComplexTestCase, NoneFound
from service.core.generator.additions import candidate_routes
from service.core.generator.candidate import safety_margin
from service.core.generator.ordering import OrderingSearch
from service.core.generator.ordering_facts import OrderingCar, QueueBounds
from service.core.generator.search import Attempt, order_limits
from service.core.network import Intersection
from service.core.testcase import TestCase

PAST_THE_END = 3.0  # how far past the end the events may fall when it is asked whether
# the duration is what limits (times the duration)

OTHER_ROUTES = 3  # routes named in "what to try"
VERIFICATION = "failed verification"  # outcomes of the checker and the curves, counted together
KINDS_SAID = 4  # kinds of outcome said with their counts; the rest are counted together

# Step 3's reasons (timing_solve.solve_timing) in words: (some of the orders, all of them).
TIMING_WORDS = {
    "no event times can realise this order": (
        "have no event times that realise them",
        "none has event times that realise it",
    ),
    "no curves within the bounds for the planned event times": (
        "got event times but no speed curves within the bounds",
        "none got speed curves within the bounds for its event times",
    ),
}


def route_label(routes: Sequence[str], walks: Sequence[str] = ()) -> str:
    """What was tried, by name: "car route A", "car routes A + B", "pedestrian walk W"."""
    said = []
    if routes:
        said.append(("car route " if len(routes) == 1 else "car routes ") + " + ".join(routes))
    if walks:
        said.append(("pedestrian walk " if len(walks) == 1 else "pedestrian walks ")
                    + " + ".join(walks))  # fmt: skip
    return " with ".join(said) or "no route"


def in_words(outcome: str) -> tuple[str, str]:
    """An answer set's outcome as (what some orders did, what all of them did)."""
    if outcome.startswith("timing: "):
        reason = outcome.removeprefix("timing: ")
        if reason in TIMING_WORDS:
            return TIMING_WORDS[reason]
        if reason.startswith("no speed profile within "):
            share = reason.removeprefix("no speed profile within ").removesuffix(" of the bounds")
            return (f"could not be timed within {share} of the speed bounds",
                    f"none could be timed within {share} of the speed bounds")  # fmt: skip
        return f"could not be timed ({reason})", f"none could be timed ({reason})"
    if NOT_REACHED in outcome:
        late = "a certificate does not reach its exit before the end"
        return f"were timed, but {late}", f"each was timed, but {late}"
    if outcome.startswith("the same test-case order as"):
        return "repeated a test-case order already drawn", "each repeated an order already drawn"
    if outcome.startswith("no window of entry times"):
        return "left no window of entry times to aim in", "none left a window of entry times"
    return VERIFICATION, "none passed verification"


def outcomes_said(attempts: Sequence[Attempt]) -> str:
    """What the answer sets came to, each kind of outcome once with its count ("8 orders
    of events found, none could be timed within 85 % of the speed bounds"; "10 orders of
    events found, none verified: 8 could not be timed ..., 2 failed verification ...")."""
    orders = [a for a in attempts if not a.outcome.startswith("ordering: ")]
    limit = next((a.outcome for a in attempts if a.outcome.startswith("ordering: ")), None)
    counted: dict[str, int] = {}
    every: dict[str, str] = {}
    for attempt in orders:
        some, all_of_them = in_words(attempt.outcome)
        if some == VERIFICATION:  # outcomes told apart by their text: the first one's
            example = attempt.outcome.removeprefix("verification: ")
            some = next((k for k in counted if k.startswith(VERIFICATION)),
                        f"{some} (first: {example})")  # fmt: skip
            all_of_them += some.removeprefix(VERIFICATION)
        counted[some] = counted.get(some, 0) + 1
        every.setdefault(some, all_of_them)
    found = f"{len(orders)} order{'s' if len(orders) != 1 else ''} of events found"
    if len(counted) == 1:
        said = f"{found}, {every[next(iter(counted))]}"
    elif counted:
        kinds = [f"{count} {some}" for some, count in list(counted.items())[:KINDS_SAID]]
        rest = sum(list(counted.values())[KINDS_SAID:])
        said = f"{found}, none verified: " + ", ".join(kinds) + (f", {rest} other" if rest else "")
    else:
        said = "no order of events found"
    if limit is not None:  # SearchLimitReached: Step 2's work limit on one answer set
        said += f"; then Step 2 stopped: {limit.removeprefix('ordering: ')}"
    return said


def _other_routes(old: TestCase, junction: Intersection, tried: Sequence[str]) -> str:
    """A few routes (or walks) a new road user could take that were not tried."""
    others = [r for r in candidate_routes(old, junction) if r not in tried]
    if not others:
        return ""
    named = ", ".join(others[:OTHER_ROUTES]) + (", ..." if len(others) > OTHER_ROUTES else "")
    return f"another route ({named}; scengen intersection lists them)"


def longer_duration(old: TestCase, needed: float | None = None) -> str:
    """What to try when the duration is what limits: a longer test-case, made anew (the
    old cars' drives end with the old duration, and are driven anew in a longer one, so
    ``needed``, from the first order found with events after the end, is no promise)."""
    first = f"; the first order found needs {needed:g} s" if needed is not None else ""
    return (f"a longer test-case (this one lasts {old.duration:g} s{first}; make it anew "
            f"with a longer --duration)")  # fmt: skip


def failure_message(headline: str, label: str, why: str, to_try: Sequence[str]) -> str:
    """The message: the headline, the routes' line, what to try (each on its own line)."""
    tried = [t for t in to_try if t]
    return f"{headline}\n  {label}: {why}" + (f"\n  to try: {'; '.join(tried)}" if tried else "")


def not_found(
    old: TestCase,
    junction: Intersection,
    cars: Sequence[OrderingCar],
    bounds: QueueBounds,
    seed: int,
    routes: Sequence[str],
    attempts: Sequence[Attempt],
    exhausted: bool,
    walks: Sequence[str] = (),
) -> NoMoreComplexTestCase | NoneFound:
    """Why the search ended without a result. "No more complex test-case exists" only when
    even without any safety margin no order of events has consistent times: the whole
    search space is then empty. The error's context keeps ``why`` (the routes' line
    without their name) and ``longer`` (a duration with room, when the duration limits)
    for a caller that tries many routes (service.core.generator.chain)."""
    label = route_label(routes, walks)
    another = _other_routes(old, junction, [*routes, *walks])
    said = outcomes_said(attempts)
    late = any(NOT_REACHED in a.outcome for a in attempts)
    if not exhausted:
        why = f"the search's count ran out ({len(attempts)} answer sets): {said}"
        return NoneFound(
            failure_message(
                "none found", label, why,
                ["another seed (draws other orders first)", another,
                 longer_duration(old) if late else ""],
            ),
            routes=list(routes), seed=seed, search_exhausted=False, why=why,
        )  # fmt: skip
    bare_limits = order_limits(old, margin=0.0)
    bare = OrderingSearch(junction, cars, old.params.m, seed, bare_limits, bounds)
    if not bare.satisfiable():
        released = replace(bare_limits, duration=PAST_THE_END * old.duration)
        latest = OrderingSearch(junction, cars, old.params.m, seed, released, bounds).latest_event()
        if latest is not None:
            needed = float(math.ceil(latest + safety_margin(old)))
            why = (f"the duration is what limits: no order of events fits within "
                   f"{old.duration:g} s, and with events after the end orders exist (the "
                   f"first found ends at {latest:.1f} s)")  # fmt: skip
            to_try = [longer_duration(old, needed), another]
        else:
            why, to_try, needed = bare.explain_unsatisfiable(), [another], None
        return NoMoreComplexTestCase(
            failure_message("no more complex test-case exists for these routes", label, why,
                            to_try),
            routes=list(routes), why=why, longer=needed,
        )  # fmt: skip
    if not attempts:
        why = (f"orders of events exist only without the safety margin of "
               f"{safety_margin(old):g} s on every relation, too close to call")  # fmt: skip
        return NoneFound(
            failure_message("none found", label, why, [another]),
            routes=list(routes), seed=seed, search_exhausted=True, why=why,
        )  # fmt: skip
    why = f"every order of events tried: {said}"
    return NoneFound(
        failure_message(
            "none found", label, why,
            [another, longer_duration(old) if late else ""],
        ),
        routes=list(routes), seed=seed, search_exhausted=True, why=why,
    )  # fmt: skip
