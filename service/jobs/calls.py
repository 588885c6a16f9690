"""Job work's calls: each in a killable child process, stopped when its budget runs out or
its lease is lost, and the heartbeat that renews a lease.

Both a job item (service.jobs.runner) and a campaign step a Celery worker runs
(service.jobs.step_runner) hold a lease in the database while they work; ``heartbeat``
renews it and sets ``stop`` when it is lost (the work was cancelled or given to another
worker), and ``run_stoppable`` kills the running child as soon as ``stop`` is set.
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import threading
import time
from collections.abc import Callable
from typing import Any

from service.core.budget import decode_outcome, encode_call
from service.core.errors import BudgetExceeded
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


def run_stoppable(
    function: Callable[..., Any], args: tuple[Any, ...], budget: float, what: str,
    stop: threading.Event,
) -> Any:  # fmt: skip
    """``function(*args)`` in a child process (lowest priority, own process group), killed
    when ``budget`` runs out (BudgetExceeded) or ``stop`` is set (Stopped)."""
    child = subprocess.Popen(
        WORKER_COMMAND,
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
        start_new_session=True,
    )  # fmt: skip
    answer: dict[str, bytes] = {}
    request = encode_call(function, args)

    def talk() -> None:
        answer["out"], answer["err"] = child.communicate(request)

    talker = threading.Thread(target=talk, daemon=True)
    talker.start()
    deadline = time.monotonic() + budget
    try:
        while talker.is_alive():
            talker.join(0.2)
            if stop.is_set():
                raise Stopped(what)
            if time.monotonic() > deadline:
                raise BudgetExceeded(
                    f"{what} did not finish within its budget of {budget:g} s and was stopped"
                )
    finally:
        if child.poll() is None:  # stopped early: its group is still ours to kill
            with contextlib.suppress(ProcessLookupError, PermissionError):
                os.killpg(child.pid, signal.SIGKILL)
        talker.join(5)
    return decode_outcome(answer.get("out", b""), answer.get("err", b""), what)
