"""A job item's calls run in child processes that budgets and cancellation kill."""

from __future__ import annotations

import math
import threading
import time

import pytest

from service.core.errors import BudgetExceeded, UnknownNetwork
from service.core.network import resolve_network
from service.jobs.runner import Stopped, run_stoppable


def test_a_call_returns_its_result() -> None:
    assert run_stoppable(math.factorial, (10,), 30, "factorial", threading.Event()) == 3628800


def test_domain_errors_cross_back() -> None:
    with pytest.raises(UnknownNetwork, match="nope"):
        run_stoppable(resolve_network, ("nope",), 30, "resolve", threading.Event())


def test_the_budget_kills_a_hanging_call() -> None:
    clock = time.monotonic()
    with pytest.raises(BudgetExceeded, match="within its budget of 1 s"):
        run_stoppable(time.sleep, (60,), 1, "sleeping", threading.Event())
    assert time.monotonic() - clock < 10


def test_cancelling_kills_the_call() -> None:
    stop = threading.Event()
    threading.Timer(0.5, stop.set).start()
    clock = time.monotonic()
    with pytest.raises(Stopped):
        run_stoppable(time.sleep, (60,), 120, "sleeping", stop)
    assert time.monotonic() - clock < 10
