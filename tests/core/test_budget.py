"""Killable child processes under a time budget."""

from __future__ import annotations

import math
import os
import subprocess
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from service.core.budget import WarmWorker, decode_outcome, kill_and_reap, run_with_budget
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


def spawning(function: Callable[..., Any], args: tuple[Any, ...]) -> tuple[Any, int, list[str]]:
    """``function(*args)`` (run in a budget child), this process's pid, and the command line
    of every process it started meanwhile."""
    started: list[str] = []
    original = subprocess.Popen.__init__

    def recording(self: subprocess.Popen[Any], command: Any, *rest: Any, **named: Any) -> None:
        started.append(command if isinstance(command, str) else " ".join(map(str, command)))
        original(self, command, *rest, **named)

    subprocess.Popen.__init__ = recording  # type: ignore[method-assign]
    try:
        return function(*args), os.getpid(), started
    finally:
        subprocess.Popen.__init__ = original  # type: ignore[method-assign]


def test_a_call_inside_a_budget_child_runs_in_that_child() -> None:
    """A nested call (an evaluation's replay, Step 1's drive) starts no grandchild: the
    workers a server or a job runs are all the processes that compute."""
    inner, child, started = run_with_budget(
        spawning, (run_with_budget, (os.getpid, (), 30.0, "inner")), 60.0, "outer"
    )
    assert inner == child != os.getpid()
    assert started == []


def test_a_nested_call_over_its_budget_is_stopped_in_the_child() -> None:
    """The nested call's own budget (an alarm), not the outer one, stops it."""
    with pytest.raises(BudgetExceeded, match="sleep did not finish within its budget of 1 s"):
        run_with_budget(run_with_budget, (time.sleep, (60,), 1.0, "sleep"), 120.0, "outer")


def test_a_nested_crash_is_reported_as_a_child_would() -> None:
    with pytest.raises(ScengenError, match=r"inner sqrt crashed: ValueError: math domain error"):
        run_with_budget(run_with_budget, (math.sqrt, (-1.0,), 30.0, "inner sqrt"), 60.0, "outer")


def test_a_child_is_reaped_even_when_popens_lock_was_left_held() -> None:
    # A Ctrl-C inside Popen.poll() can leave Popen's private waitpid lock held (CPython's
    # subprocess); Popen.wait() would then block forever, as it once did in CI.
    process = subprocess.Popen(["sleep", "60"])
    assert process._waitpid_lock.acquire(blocking=False)  # type: ignore[attr-defined]
    kill_and_reap(process, reap_seconds=0.2)
    assert process.returncode == -9
    with pytest.raises(ProcessLookupError):
        os.kill(process.pid, 0)


def leave_a_file_and_hang(marker: str) -> None:
    """In a budget child: a temporary folder (as SUMO runs make), its path in ``marker``,
    then a call that never ends."""
    folder = tempfile.mkdtemp(prefix="half-done-")
    Path(marker).write_text(folder)
    time.sleep(60)


def overrun_inside() -> None:
    """In a budget child: a nested call whose alarm interrupts it (BudgetExceeded)."""
    run_with_budget(time.sleep, (30,), 0.2, "the nested call")


def test_a_warm_child_goes_with_a_crash_or_a_budget_run_out_inside_it() -> None:
    """A domain error keeps the warm child; a crash, or a nested call's alarm (which may
    have interrupted an import half way), retires it: the next call gets a fresh one."""
    worker = WarmWorker()
    first = worker.call(os.getpid, (), 30.0, "pid")
    with pytest.raises(UnknownNetwork):
        worker.call(resolve_network, ("nowhere",), 30.0, "lookup")
    assert worker.call(os.getpid, (), 30.0, "pid") == first
    with pytest.raises(BudgetExceeded, match="the nested call did not finish"):
        worker.call(overrun_inside, (), 30.0, "outer")
    second = worker.call(os.getpid, (), 30.0, "pid")
    with pytest.raises(ScengenError, match="crashed: ValueError"):
        worker.call(math.sqrt, (-1.0,), 30.0, "sqrt")
    third = worker.call(os.getpid, (), 30.0, "pid")
    worker.close()
    assert len({first, second, third}) == 3


@pytest.mark.parametrize("warm", [False, True], ids=["one-call child", "warm child"])
def test_a_child_killed_at_its_budget_leaves_no_temporary_files(warm: bool, tmp_path: Path) -> None:
    marker = tmp_path / "folder.txt"
    worker = WarmWorker()
    call = worker.call if warm else run_with_budget
    with pytest.raises(BudgetExceeded):
        call(leave_a_file_and_hang, (str(marker),), 3.0, "hang")
    left = Path(marker.read_text())
    assert left.name.startswith("half-done-") and not left.exists() and not left.parent.exists()
    worker.close()


def test_the_scratch_of_a_process_that_is_gone_is_removed_by_the_next(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A Celery pool process leaves by os._exit (and a kill -9 runs no exit handler): its
    children's folders stay; the next child's start removes them, not a living one's."""
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    ended = subprocess.Popen(["true"])  # a process that has ended: its pid is free
    ended.wait()
    stale = tmp_path / f"scengen-worker-{ended.pid}-abc"
    (stale / "inner").mkdir(parents=True)
    living = tmp_path / f"scengen-call-{os.getpid()}-def"
    living.mkdir()
    other = tmp_path / "not-ours"
    other.mkdir()
    worker = WarmWorker()
    try:
        assert worker.call(math.sqrt, (4.0,), 30, "sqrt") == 2.0
    finally:
        worker.close()
    assert not stale.exists() and living.exists() and other.exists()


@pytest.mark.parametrize("warm", [False, True], ids=["fresh", "warm"])
def test_what_native_code_writes_to_stdout_does_not_corrupt_the_answer(warm: bool) -> None:
    """ad-rss logs to file descriptor 1 ("[info] restrictToLimits ... -nan value out of
    range"): in a warm child that was the answer pipe, and the parent read the log line as
    a frame's size and waited out the replay's budget."""
    line = b"[2026-12-08 02:33:00.837] [info] a native library's log line\\n"
    if warm:
        worker = WarmWorker()
        try:
            assert worker.call(os.write, (1, line), 30.0, "a native write") == len(line)
            assert worker.call(math.hypot, (3.0, 4.0), 30.0, "hypot") == 5.0  # still in step
        finally:
            worker.close()
    else:
        assert run_with_budget(os.write, (1, line), 30.0, "a native write") == len(line)
