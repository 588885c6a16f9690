"""Killable child processes under a time budget."""

from __future__ import annotations

import math
import time

import pytest

from service.core.budget import decode_outcome, run_with_budget
from service.core.errors import BudgetExceeded, MemoryExceeded, ScengenError, UnknownNetwork
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


def test_a_call_that_needs_too_much_memory_fails_alone(monkeypatch: pytest.MonkeyPatch) -> None:
    """Each worker's data segment is capped (SCENGEN_WORKER_MEMORY_MB): a call that asks for
    more fails with MemoryExceeded naming the limit; the next call runs as usual."""
    monkeypatch.setenv("SCENGEN_WORKER_MEMORY_MB", "256")
    with pytest.raises(MemoryExceeded, match=r"256 MB, SCENGEN_WORKER_MEMORY_MB"):
        run_with_budget(bytearray, (1024**3,), 60.0, "a gigabyte")
    assert len(run_with_budget(bytearray, (1024**2,), 60.0, "a megabyte")) == 1024**2


def test_a_native_library_that_cannot_allocate_is_a_memory_failure() -> None:
    """Under a low cap, OpenBLAS (numpy's) gives up and exits without a Python MemoryError:
    that is still the memory budget, not a crashed worker."""
    stderr = b"OpenBLAS error: Memory allocation still failed after 10 retries, giving up.\n"
    with pytest.raises(MemoryExceeded, match=r"SCENGEN_WORKER_MEMORY_MB\): OpenBLAS error"):
        decode_outcome(b"", stderr, "the picture")
    with pytest.raises(ScengenError, match="died without an answer: Segmentation fault"):
        decode_outcome(b"", b"Segmentation fault\n", "the picture")
