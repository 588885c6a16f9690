"""The server's pool of workers: its size is a true cap on the processes that compute; each
child stays warm between calls and goes with a call that overruns, crashes, runs out of
memory or is cancelled."""

from __future__ import annotations

import asyncio
import math
import os
import time
from collections.abc import Awaitable, Callable
from pathlib import Path
from typing import Any, TypeVar

import pytest

from service.core.errors import BudgetExceeded, MemoryExceeded, ScengenError, UnknownNetwork
from service.core.network import resolve_network
from service.core.testcase import dump_testcase, new_testcase
from service.jobs import executor as executor_module
from service.jobs import tasks
from service.jobs.executor import LocalExecutor
from tests.core.test_budget import leave_a_file_and_hang, overrun_inside, spawning

T = TypeVar("T")


def test_one_worker_is_one_process_with_a_controller_inside(tmp_path: Path) -> None:
    """With one worker, an evaluation, a picture with a controller and an extension (each of
    which replays or drives in SUMO inside) run one after another, each in one process that
    starts no other: at most one process computes at any time. The three share one warm
    child (its imports paid once)."""
    network = resolve_network("4way-stop")
    document = dump_testcase(new_testcase("4way-stop", "E2C_1:C2S_1", duration=20.0))
    calls: list[tuple[Any, tuple[Any, ...]]] = [
        (tasks.evaluate_controller, (document, network, tmp_path, "sumo", 60.0)),
        (tasks.plot_testcase, (document, network, tmp_path, "svg", "sumo", 60.0)),
        (tasks.extend, (document, network, tmp_path, ["S2C_1:C2N_1"], 0, 120.0, None)),
    ]
    executor = LocalExecutor(1)

    async def run_all() -> list[tuple[Any, int, list[str]]]:
        return await asyncio.gather(
            *(executor.run(spawning, call, 300.0, "a call") for call in calls)
        )

    answers = _on(executor, run_all)
    verdict, picture, extension = (answer for answer, _, _ in answers)
    assert verdict["verdict"]["controller"] == "sumo" and len(verdict["drive"]) > 2
    assert picture.startswith(b"<?xml") and b"<svg" in picture
    assert '"nonegos"' in extension["document"]
    assert [started for _, _, started in answers] == [[], [], []]
    assert len({pid for _, pid, _ in answers}) == 1  # one warm child, one call at a time
    assert executor.stats.finished == {"ok": 3}
    assert not _alive(answers[0][1])  # stopped with the executor


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    stat = Path(f"/proc/{pid}/stat").read_text()  # killed but not yet collected is gone too
    return stat.split(") ")[1][0] != "Z"


def _on(executor: LocalExecutor, work: Callable[[], Awaitable[T]]) -> T:
    """``work()`` on a new event loop, the executor's children stopped after it."""

    async def run() -> T:
        try:
            return await work()
        finally:
            await executor.shutdown()

    return asyncio.run(run())


def test_a_child_goes_with_a_call_that_overruns_crashes_or_runs_out_of_memory(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """A domain error keeps the warm child; a call over its budget, one whose process dies,
    one that crashes, one that needs more memory than a worker may use and one whose
    nested call ran out of its budget inside the child each take their child (killed, its
    temporary files removed), and the next call runs in a fresh one."""
    monkeypatch.setenv("SCENGEN_WORKER_MEMORY_MB", "256")  # read by children as they start
    executor = LocalExecutor(1)
    marker = tmp_path / "folder.txt"

    async def work() -> list[int]:
        pids = [await executor.run(os.getpid, (), 30.0, "pid")]
        with pytest.raises(UnknownNetwork):
            await executor.run(resolve_network, ("nowhere",), 30.0, "lookup")
        pids.append(await executor.run(os.getpid, (), 30.0, "pid"))
        with pytest.raises(BudgetExceeded, match="hang did not finish within its budget of 2 s"):
            await executor.run(leave_a_file_and_hang, (str(marker),), 2.0, "hang")
        pids.append(await executor.run(os.getpid, (), 30.0, "pid"))
        with pytest.raises(ScengenError, match="exit died without an answer"):
            await executor.run(os._exit, (3,), 30.0, "exit")
        pids.append(await executor.run(os.getpid, (), 30.0, "pid"))
        with pytest.raises(ScengenError, match="sqrt crashed: ValueError"):
            await executor.run(math.sqrt, (-1.0,), 30.0, "sqrt")
        pids.append(await executor.run(os.getpid, (), 30.0, "pid"))
        with pytest.raises(MemoryExceeded, match="256 MB, SCENGEN_WORKER_MEMORY_MB"):
            await executor.run(bytearray, (1024**3,), 30.0, "a gigabyte")
        pids.append(await executor.run(os.getpid, (), 30.0, "pid"))
        with pytest.raises(BudgetExceeded, match="the nested call did not finish"):
            await executor.run(overrun_inside, (), 30.0, "outer")  # an alarm inside the child
        pids.append(await executor.run(os.getpid, (), 30.0, "pid"))
        return pids

    pids = _on(executor, work)
    assert pids[0] == pids[1] and len(set(pids[1:])) == 6, pids
    assert not any(_alive(pid) for pid in pids)
    left = Path(marker.read_text())
    assert left.name.startswith("half-done-") and not left.parent.exists()
    assert executor.stats.finished == {"ok": 7, "error": 3, "budget": 3}  # memory is a budget


def test_a_cancelled_call_takes_its_child_and_a_child_retires_after_its_calls(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A request that goes away (its task cancelled) kills the call's child at once; a child
    that has served CALLS_PER_CHILD calls is replaced."""
    monkeypatch.setattr(executor_module, "CALLS_PER_CHILD", 2)
    executor = LocalExecutor(1)

    async def work() -> tuple[list[int], int]:
        pids = [await executor.run(os.getpid, (), 30.0, "pid") for _ in range(3)]
        sleeper = await executor.run(os.getpid, (), 30.0, "pid")
        call = asyncio.create_task(executor.run(time.sleep, (60,), 120.0, "sleep"))
        await asyncio.sleep(1.0)
        call.cancel()
        with pytest.raises(asyncio.CancelledError):
            await call
        return pids, sleeper

    (first, second, third), sleeper = _on(executor, work)
    assert first == second != third == sleeper
    deadline = time.monotonic() + 10
    while _alive(sleeper) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not _alive(sleeper)


def test_a_budget_too_small_to_start_does_not_blame_busy_workers() -> None:
    """With every worker free, a budget that runs out before the call starts says so."""
    executor = LocalExecutor(2)

    async def work() -> None:
        with pytest.raises(BudgetExceeded, match="budget of 0 s and was stopped before it"):
            await executor.run(os.getpid, (), 0.0, "the call")

    _on(executor, work)
