"""Job work's calls: each in a killable child process, stopped when its budget runs out or
its lease is lost, and the heartbeat that renews a lease.

Both a job item (service.jobs.runner) and a campaign step a Celery worker runs
(service.jobs.step_runner) hold a lease in the database while they work; ``heartbeat``
renews it and sets ``stop`` when it is lost (the work was cancelled or given to another
worker), and ``run_stoppable`` kills the running child as soon as ``stop`` is set. The
children stay warm between calls (``JOB_CALLS``), as the server's do.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable
from typing import Any

from service.core.budget import CallStopped, WarmPool
from service.jobs.executor import WORKER_COMMAND


class Stopped(Exception):
    """The work was cancelled, or its lease was lost to another worker."""


def heartbeat(
    renew: Callable[[], bool], lease: float, stop: threading.Event, shutdown: threading.Event
) -> None:
    """Call ``renew`` often enough to see a cancellation within seconds, until ``stop``;
    set ``stop`` when it says the lease is lost or ``shutdown`` is set. After a failed
    renewal (the database is away) retry every second: the lease decides."""
    interval = min(lease / 3, 2.0)
    while not stop.wait(interval):
        if shutdown.is_set():
            stop.set()
            return
        try:
            if not renew():
                stop.set()  # cancelled, or given to another worker
            interval = min(lease / 3, 2.0)
        except Exception:
            interval = 1.0


# Warm children for job work, at the lowest CPU priority, each in its own process group; as
# many kept idle as there are cores (each holds about 200 MB once it has worked).
JOB_CALLS = WarmPool(keep=os.cpu_count() or 2, command=WORKER_COMMAND, group=True)


def run_stoppable(
    function: Callable[..., Any], args: tuple[Any, ...], budget: float, what: str,
    stop: threading.Event,
) -> Any:  # fmt: skip
    """``function(*args)`` in a warm child process (lowest priority, own process group),
    killed when ``budget`` runs out (BudgetExceeded) or soon after ``stop`` is set
    (Stopped); a call that overruns, crashes or is stopped takes its child with it."""
    if stop.is_set():
        raise Stopped(what)
    try:
        return JOB_CALLS.call(function, args, budget, what, stop)
    except CallStopped:
        raise Stopped(what) from None
