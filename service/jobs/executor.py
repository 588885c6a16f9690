"""Where long work runs: a pool of worker processes, each call in a killable child.

The server never runs a solver or SUMO in its own process. ``LocalExecutor.run`` hands each
call to a warm child (``python -m service.core.budget --many``, the framed protocol of
``WarmWorker``) at a lower CPU priority, so the event loop stays responsive, and waits for
its answer without blocking. A child serves calls one after another, so its imports (half a
second: more than most requests' own work) are paid once; a call that outlives its
deadline, is cancelled, crashes or runs out of memory takes its child (the whole process
group) with it, and the next call starts a fresh one. A child also retires after
``CALLS_PER_CHILD`` calls, giving its memory back. A semaphore sized by the worker count
bounds how many calls run at once, and so how many children there are; the rest wait their
turn, and the time they wait counts against their budget.
"""

from __future__ import annotations

import asyncio
import contextlib
import os
import shutil
import signal
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from service.core.budget import (
    CALLS_PER_CHILD,
    CHILD_COMMAND,
    FRAME,
    STDERR_KEPT,
    child_environment,
    encode_call,
    leaves_child_sound,
    outcome_of,
    read_answer,
    scratch_folder,
)
from service.core.errors import BudgetExceeded

NICENESS = 19  # worker children yield the CPU to the server's event loop
# Every worker call, here and in a job item (service.jobs.runner): a child at the lowest
# CPU priority.
WORKER_COMMAND = ["nice", "-n", str(NICENESS), *CHILD_COMMAND]
CLOSE_SECONDS = 5.0  # for a killed child to be collected


@dataclass
class ExecutorStats:
    """What ``/metrics`` reports about the pool."""

    workers: int
    running: int = 0
    waiting: int = 0
    finished: dict[str, int] = field(default_factory=dict)  # outcome -> count
    seconds: float = 0.0  # summed wall time of finished calls


class LocalExecutor:
    """Runs calls in child processes on this machine, at most ``workers`` at a time."""

    def __init__(self, workers: int) -> None:
        if workers < 1:
            raise ValueError(f"workers must be at least 1, got {workers}")
        self.stats = ExecutorStats(workers)
        self._slots: asyncio.Semaphore | None = None
        self._idle: list[_WarmChild] = []
        self._busy: set[_WarmChild] = set()

    async def run(
        self,
        function: Callable[..., Any],
        args: tuple[Any, ...],
        budget: float,
        what: str,
        started: float | None = None,
        grace: float = 0.0,
    ) -> Any:
        """``function(*args)`` in a worker; BudgetExceeded when ``budget`` seconds (plus
        ``grace`` once it runs), counted from ``started`` (default: now, a monotonic time),
        pass before it answers."""
        deadline = (time.monotonic() if started is None else started) + budget
        if self._slots is None:
            self._slots = asyncio.Semaphore(self.stats.workers)
        self.stats.waiting += 1
        try:
            await asyncio.wait_for(self._slots.acquire(), max(0.0, deadline - time.monotonic()))
        except TimeoutError:
            self._count("budget")
            if self.stats.running < self.stats.workers:  # a budget too small to start at all
                raise BudgetExceeded(
                    f"{what} did not finish within its budget of {budget:g} s and was stopped "
                    "before it started; raise the budget"
                ) from None
            raise BudgetExceeded(
                f"{what} waited {budget:g} s for a free worker (all {self.stats.workers} were "
                "busy) and was not started; retry later, raise the budget or SCENGEN_WORKERS"
            ) from None
        finally:
            self.stats.waiting -= 1
        self.stats.running += 1
        clock = time.monotonic()
        outcome = "error"
        try:
            result = await self._call(function, args, deadline + grace, budget, what)
            outcome = "ok"
            return result
        except BudgetExceeded:
            outcome = "budget"
            raise
        finally:
            self.stats.running -= 1
            self.stats.seconds += time.monotonic() - clock
            self._count(outcome)
            self._slots.release()

    async def _call(
        self,
        function: Callable[..., Any],
        args: tuple[Any, ...],
        deadline: float,
        budget: float,
        what: str,
    ) -> Any:
        if deadline <= time.monotonic():  # spent waiting for a worker: no child is asked
            raise BudgetExceeded(
                f"{what} did not finish within its budget of {budget:g} s and was stopped"
            )
        child = self._idle_child() or await _WarmChild.start()
        self._busy.add(child)
        keep = False
        try:
            answer = await child.answer(encode_call(function, args), deadline, budget, what)
            keep = leaves_child_sound(answer)
            return outcome_of(answer, what)
        finally:
            self._busy.discard(child)
            if keep and child.calls < CALLS_PER_CHILD:
                self._idle.append(child)
            else:  # collected even when this call is being cancelled
                await asyncio.shield(child.close())

    def _idle_child(self) -> _WarmChild | None:
        """A warm child that is still alive (one may have been killed while it waited)."""
        while self._idle:
            child = self._idle.pop()
            if child.process.returncode is None:
                return child
            child.stop()  # collected already: nothing to wait for
        return None

    async def shutdown(self) -> None:
        """Stop every child, running or idle (the server is going away)."""
        children, self._idle = [*self._busy, *self._idle], []
        await asyncio.gather(*(child.close() for child in children))

    def _count(self, outcome: str) -> None:
        self.stats.finished[outcome] = self.stats.finished.get(outcome, 0) + 1


class _WarmChild:
    """One warm child in its own process group (killed with its grandchildren), with the
    last of what it wrote to stderr, and a temporary folder removed with it."""

    def __init__(self, process: asyncio.subprocess.Process, scratch: str) -> None:
        self.process = process
        self.scratch = scratch
        self.calls = 0
        self.stderr = bytearray()
        self._drain = asyncio.create_task(self._keep_stderr())

    @classmethod
    async def start(cls) -> _WarmChild:
        scratch = scratch_folder("worker")
        process = await asyncio.create_subprocess_exec(
            *WORKER_COMMAND,
            "--many",
            stdin=asyncio.subprocess.PIPE,
            stdout=asyncio.subprocess.PIPE,
            stderr=asyncio.subprocess.PIPE,
            start_new_session=True,
            env=child_environment(scratch),
        )
        return cls(process, scratch)

    async def answer(
        self, request: bytes, deadline: float, budget: float, what: str
    ) -> tuple[str, Any]:
        """The child's (status, payload) for one framed call; BudgetExceeded at the deadline
        (the caller stops the child)."""
        self.calls += 1
        self.stderr.clear()
        process = self.process
        assert process.stdin is not None and process.stdout is not None
        stdin, stdout = process.stdin, process.stdout

        async def exchange() -> bytes:
            stdin.write(FRAME.pack(len(request)) + request)
            await stdin.drain()
            (size,) = FRAME.unpack(await stdout.readexactly(FRAME.size))
            return await stdout.readexactly(size)

        try:
            reply = await asyncio.wait_for(exchange(), deadline - time.monotonic())
        except TimeoutError:
            raise BudgetExceeded(
                f"{what} did not finish within its budget of {budget:g} s and was stopped"
            ) from None
        except (asyncio.IncompleteReadError, ConnectionError):  # it died: say what it said
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(asyncio.shield(self._drain), 5.0)
            return read_answer(b"", bytes(self.stderr), what)
        return read_answer(reply, b"", what)

    async def _keep_stderr(self) -> None:
        assert self.process.stderr is not None
        while chunk := await self.process.stderr.read(65536):
            self.stderr += chunk
            del self.stderr[:-STDERR_KEPT]

    async def close(self) -> None:
        """``stop``, then collect the child and its pipes (before the event loop ends)."""
        self.stop()
        if self.process.stdin is not None:
            self.process.stdin.close()
        with contextlib.suppress(TimeoutError):
            await asyncio.wait_for(self.process.wait(), CLOSE_SECONDS)
            await asyncio.wait_for(asyncio.shield(self._drain), CLOSE_SECONDS)

    def stop(self) -> None:
        """Kill the child's process group and remove its temporary folder."""
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(self.process.pid, signal.SIGKILL)
        shutil.rmtree(self.scratch, ignore_errors=True)
