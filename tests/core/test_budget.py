"""Killable child processes under a time budget."""

from __future__ import annotations

import math
import time

import pytest

from service.core.budget import run_with_budget
from service.core.errors import BudgetExceeded, ScengenError, UnknownNetwork
from service.core.network import resolve_network


def test_result_comes_back() -> None:
    assert run_with_budget(math.hypot, (3.0, 4.0), 30.0, "hypot") == 5.0


def test_a_call_over_budget_is_killed() -> None:
    started = time.monotonic()
    with pytest.raises(BudgetExceeded, match="sleep did not finish within its budget of 1 s"):
        run_with_budget(time.sleep, (60,), 1.0, "sleep")
    assert time.monotonic() - started < 30.0


def test_domain_errors_cross_the_process_boundary() -> None:
    with pytest.raises(UnknownNetwork, match="is neither a bundled network") as caught:
        run_with_budget(resolve_network, ("nowhere",), 30.0, "lookup")
    assert caught.value.context == {"network": "nowhere"}


def test_other_exceptions_are_reported_as_crashes() -> None:
    with pytest.raises(ScengenError, match=r"crashed: ValueError: math domain error"):
        run_with_budget(math.sqrt, (-1.0,), 30.0, "sqrt")
