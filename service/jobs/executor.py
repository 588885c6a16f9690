"""Where long work runs: a pool of worker processes, each call in its own killable child.

The server never runs a solver or SUMO in its own process. ``LocalExecutor.run`` starts
``python -m service.core.budget`` (the protocol of ``run_with_budget``) for each call, at a
lower CPU priority so the event loop stays responsive, waits for it without blocking, and
kills its whole process group when the call outlives its deadline. A semaphore sized by the
worker count bounds how many calls run at once; the rest wait their turn, and the time they
wait counts against their budget.
"""

from __future__ import annotations

import asyncio
import contextlib
import os
import signal
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from service.core.budget import CHILD_COMMAND, decode_outcome, encode_call
from service.core.errors import BudgetExceeded

NICENESS = 19  # worker children yield the CPU to the server's event loop
# Every worker call, here and in a job item (service.jobs.runner): a fresh child at the
# lowest CPU priority.
WORKER_COMMAND = ["nice", "-n", str(NICENESS), *CHILD_COMMAND]


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
        self._children: set[asyncio.subprocess.Process] = set()

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
        child = await asyncio.create_subprocess_exec(
            *WORKER_COMMAND,
            stdin=asyncio.subprocess.PIPE,
            stdout=asyncio.subprocess.PIPE,
            stderr=asyncio.subprocess.PIPE,
            start_new_session=True,  # its own process group: killed with its grandchildren
        )
        self._children.add(child)
        try:
            stdout, stderr = await asyncio.wait_for(
                child.communicate(encode_call(function, args)),
                max(0.1, deadline - time.monotonic()),
            )
        except TimeoutError:
            _kill_group(child)
            await child.wait()
            raise BudgetExceeded(
                f"{what} did not finish within its budget of {budget:g} s and was stopped"
            ) from None
        finally:
            if child.returncode is None:  # cancelled: its group is still ours to kill
                _kill_group(child)
            self._children.discard(child)
        return decode_outcome(stdout, stderr, what)

    async def shutdown(self) -> None:
        """Stop every running call (the server is going away)."""
        for child in list(self._children):
            _kill_group(child)

    def _count(self, outcome: str) -> None:
        self.stats.finished[outcome] = self.stats.finished.get(outcome, 0) + 1


def _kill_group(child: asyncio.subprocess.Process) -> None:
    with contextlib.suppress(ProcessLookupError, PermissionError):
        os.killpg(child.pid, signal.SIGKILL)
