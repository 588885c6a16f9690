"""A job item's calls run in warm child processes that budgets and cancellation kill."""

from __future__ import annotations

import math
import os
import sys
import threading
import time

import pytest

from service.core.errors import BudgetExceeded, MemoryExceeded, ScengenError, UnknownNetwork
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


def test_calls_share_a_warm_child_until_one_is_stopped() -> None:
    """A job's calls run one after another in one warm child; a stopped call takes its
    child (killed at once), and the next call gets a fresh one."""
    never = threading.Event()
    first = run_stoppable(os.getpid, (), 30, "pid", never)
    assert run_stoppable(os.getpid, (), 30, "pid", never) == first != os.getpid()
    stop = threading.Event()
    threading.Timer(0.5, stop.set).start()
    with pytest.raises(Stopped):
        run_stoppable(time.sleep, (60,), 120, "sleeping", stop)
    with pytest.raises(Stopped):  # stopped before it starts: no child is asked
        run_stoppable(os.getpid, (), 30, "pid", stop)
    assert run_stoppable(os.getpid, (), 30, "pid", never) != first
    with pytest.raises(ProcessLookupError):
        os.kill(first, 0)


def give_up_for_lack_of_memory() -> None:
    """In a child: what a native library prints when it cannot allocate, then its end."""
    sys.stderr.write("terminate called after throwing an instance of 'std::bad_alloc'\n")
    sys.stderr.flush()
    os._exit(134)


def test_a_native_allocation_failure_in_a_warm_child_is_a_memory_failure() -> None:
    """The child's last words (its stderr) tell a memory failure from a crash."""
    with pytest.raises(MemoryExceeded, match=r"SCENGEN_WORKER_MEMORY_MB\): terminate called"):
        run_stoppable(give_up_for_lack_of_memory, (), 30, "the drive", threading.Event())
    with pytest.raises(ScengenError, match="the exit died without an answer: no output"):
        run_stoppable(os._exit, (1,), 30, "the exit", threading.Event())
