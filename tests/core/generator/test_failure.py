"""A search that found nothing says what its answer sets came to, each outcome once."""

from __future__ import annotations

from service.core.generator.failure import outcomes_said
from service.core.generator.search import Attempt

PROFILE = "timing: no speed profile within 85 % of the bounds"


def test_each_outcome_is_said_once_with_the_answer_sets_that_had_it() -> None:
    attempts = [Attempt(n, PROFILE) for n in range(8)]
    attempts += [Attempt(8, "checker: the certificate collides with car1"), Attempt(9, PROFILE)]
    assert outcomes_said(attempts) == (
        f"#1-#8, #10: {PROFILE}; #9: checker: the certificate collides with car1"
    )


def test_past_four_outcomes_the_rest_are_counted() -> None:
    attempts = [Attempt(n, f"outcome {n}") for n in range(6)]
    said = outcomes_said(attempts)
    assert said.startswith("#1: outcome 0; #2: outcome 1; #3: outcome 2; #4: outcome 3")
    assert said.endswith("; 2 other outcome(s)")
    assert outcomes_said([]) == ""
