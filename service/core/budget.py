"""Run a call in a child process that is killed when its time budget runs out.

Solver and simulator libraries do not always honour their own timeouts, and libsumo is a
per-process singleton, so every long call runs here, never in the caller's process.
"""

from __future__ import annotations

import multiprocessing
import traceback
from collections.abc import Callable
from multiprocessing.connection import Connection
from typing import Any, TypeVar

from service.core.errors import BudgetExceeded, ScengenError

T = TypeVar("T")

_CONTEXT = multiprocessing.get_context("forkserver")


def _child(conn: Connection, function: Callable[..., Any], args: tuple[Any, ...]) -> None:
    try:
        conn.send(("ok", function(*args)))
    except ScengenError as exc:
        conn.send(("error", exc))
    except BaseException as exc:  # report anything, the parent decides
        conn.send(("crash", f"{type(exc).__name__}: {exc}\n{traceback.format_exc()}"))
    finally:
        conn.close()


def run_with_budget(
    function: Callable[..., T], args: tuple[Any, ...], budget: float, what: str
) -> T:
    """``function(*args)`` in a child process; BudgetExceeded after ``budget`` seconds.

    ``function`` must be a module-level function and its arguments and result picklable.
    Domain errors raised in the child are re-raised here as they were.
    """
    receiver, sender = _CONTEXT.Pipe(duplex=False)
    process = _CONTEXT.Process(target=_child, args=(sender, function, args), daemon=True)
    process.start()
    sender.close()
    try:
        if not receiver.poll(budget):
            raise BudgetExceeded(f"{what} did not finish within its budget of {budget:g} s")
        try:
            status, payload = receiver.recv()
        except EOFError:
            raise ScengenError(f"{what} died without an answer") from None
    finally:
        if process.is_alive():
            process.kill()
        process.join()
        receiver.close()
    if status == "error":
        raise payload
    if status == "crash":
        raise ScengenError(f"{what} crashed: {payload}")
    return payload  # type: ignore[no-any-return]
