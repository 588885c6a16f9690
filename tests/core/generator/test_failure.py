"""A search that found nothing says, in a line per route tried, what its answer sets came to
(counted), and what to try: from real searches (SUMO, clingo, z3), no fakes."""

from __future__ import annotations

import pytest

from service.core.errors import NoMoreComplexTestCase, NoneFound
from service.core.generator.chain import grow
from service.core.generator.extension import extend_testcase
from service.core.generator.failure import outcomes_said
from service.core.generator.search import Attempt
from service.core.testcase import TestCase, new_testcase

PROFILE = "timing: no speed profile within 85 % of the bounds"
EGO = "S2C_1:C2W_1"  # 4way-stop: the ego turns left
ONCOMING = "N2C_0:C2S_0"  # the oncoming car it yields to


def test_outcomes_are_counted_in_words_not_repeated() -> None:
    assert outcomes_said([Attempt(n, PROFILE) for n in range(8)]) == (
        "8 orders of events found, none could be timed within 85 % of the speed bounds"
    )
    attempts = [Attempt(n, PROFILE) for n in range(8)]
    attempts += [Attempt(8, "verification: the certificate collides with car1")]
    assert outcomes_said(attempts) == (
        "9 orders of events found, none verified: 8 could not be timed within 85 % of the "
        "speed bounds, 1 failed verification (first: the certificate collides with car1)"
    )
    assert outcomes_said([]) == "no order of events found"


def test_past_four_kinds_of_outcome_the_rest_are_counted_together() -> None:
    attempts = [Attempt(n, f"verification: outcome {n}") for n in range(2)]
    attempts += [Attempt(2, "timing: no event times can realise this order"),
                 Attempt(3, "no window of entry times to aim in"),
                 Attempt(4, "the same test-case order as #1"),
                 Attempt(5, PROFILE), Attempt(6, PROFILE)]  # fmt: skip
    said = outcomes_said(attempts)
    assert said.startswith("7 orders of events found, none verified: 2 failed verification")
    assert said.endswith(", 2 other")


def test_a_duration_too_short_for_the_new_car_says_the_duration_limits() -> None:
    """10 s: the ego turning left cannot wait for the oncoming car and still leave in
    time (14 s has room: test_a_longer_test_case_has_the_room_it_named)."""
    old = new_testcase("4way-stop", EGO, duration=10.0)
    with pytest.raises(NoMoreComplexTestCase) as error:
        extend_testcase(old, [ONCOMING], budget=60)
    headline, route, to_try = str(error.value).split("\n")
    assert headline == "no more complex test-case exists for these routes"
    assert route.startswith(f"  car route {ONCOMING}: the duration is what limits: no order of "
                            "events fits within 10 s")  # fmt: skip
    assert "(the first found ends at 13.0 s)" in route
    assert to_try.startswith("  to try: a longer test-case (this one lasts 10 s; the first "
                             "order found needs 14 s; make it anew with a longer --duration); "
                             "another route (E2C_1:C2S_1, ")  # fmt: skip
    assert ONCOMING not in to_try
    assert error.value.context["longer"] == 14.0


def test_a_longer_test_case_has_the_room_it_named() -> None:
    old = new_testcase("4way-stop", EGO, duration=14.0)
    assert extend_testcase(old, [ONCOMING], budget=60).testcase.nonegos


@pytest.fixture(scope="module")
def level_one() -> TestCase:
    return extend_testcase(new_testcase("4way-stop", EGO), [ONCOMING], budget=60).testcase


def test_orders_that_cannot_be_timed_are_counted_on_the_routes_line(level_one: TestCase) -> None:
    """A left turn from the west behind the oncoming car: 6 orders of events, none timed."""
    with pytest.raises(NoneFound) as error:
        extend_testcase(level_one, ["W2C_1:C2N_1"], budget=60)
    assert str(error.value).split("\n") == [
        "none found",
        "  car route W2C_1:C2N_1: every order of events tried: 6 orders of events found, none "
        "could be timed within 85 % of the speed bounds",
        "  to try: another route (E2C_1:C2S_1, E2C_1:C2W_1, N2C_0:C2S_0, ...; scengen "
        "intersection lists them)",
    ]
    assert error.value.context["search_exhausted"] is True


def test_a_level_tried_route_by_route_says_each_on_its_own_line(level_one: TestCase) -> None:
    """A 10 s test-case with the oncoming car: every route the chain tries has a line."""
    old = new_testcase("4way-stop", EGO, duration=10.0)
    with pytest.raises((NoMoreComplexTestCase, NoneFound)) as error:
        grow(old, budget=120)
    lines = str(error.value).split("\n")
    assert lines[0].endswith(f"({len(lines) - 2} routes tried):")
    assert any(line.startswith(f"  car route {ONCOMING}: the duration is what limits")
               for line in lines)  # fmt: skip
    assert lines[-1].startswith("  to try: ") and "a longer test-case" in lines[-1]
