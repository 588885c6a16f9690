"""Run a call in a child Python process that is killed when its time budget runs out.

Solver and simulator libraries do not always honour their own timeouts, and libsumo is a
per-process singleton, so every long call runs here, never in the caller's process. The
child is a fresh interpreter (``python -m service.core.budget``) fed the call by pickle on
stdin: no fork of a threaded server, and no re-import of the caller's ``__main__``.
"""

from __future__ import annotations

import contextlib
import importlib
import os
import pickle
import subprocess
import sys
import traceback
from collections.abc import Callable
from typing import Any, TypeVar

from service.core.errors import BudgetExceeded, ScengenError

T = TypeVar("T")


def run_with_budget(
    function: Callable[..., T], args: tuple[Any, ...], budget: float, what: str
) -> T:
    """``function(*args)`` in a child process; BudgetExceeded after ``budget`` seconds.

    ``function`` must be a module-level function and its arguments and result picklable.
    Domain errors raised in the child are re-raised here as they were.
    """
    request = encode_call(function, args)
    try:
        result = subprocess.run(
            CHILD_COMMAND,
            input=request,
            capture_output=True,
            timeout=budget,
            check=False,
        )
    except subprocess.TimeoutExpired:
        raise BudgetExceeded(
            f"{what} did not finish within its budget of {budget:g} s and was stopped"
        ) from None
    return decode_outcome(result.stdout, result.stderr, what)  # type: ignore[no-any-return]


CHILD_COMMAND = [sys.executable, "-m", "service.core.budget"]


def encode_call(function: Callable[..., Any], args: tuple[Any, ...]) -> bytes:
    """What the child reads on stdin: a module-level function and its arguments."""
    return pickle.dumps((function.__module__, function.__qualname__, args))


def decode_outcome(stdout: bytes, stderr: bytes, what: str) -> Any:
    """The child's answer: its result, or the domain error it raised, re-raised here."""
    try:
        status, payload = pickle.loads(stdout)
    except Exception:
        detail = stderr.decode(errors="replace").strip().splitlines()[-1:] or ["no output"]
        raise ScengenError(f"{what} died without an answer: {detail[0]}") from None
    if status == "error":
        raise payload
    if status == "crash":
        summary = str(payload).splitlines()[0] if payload else "no detail"
        raise ScengenError(f"{what} crashed: {summary}", traceback=str(payload))
    return payload


def _die_with_parent() -> None:
    """On Linux, be killed when the process that started this one dies (a server or worker
    killed with -9 must not leave its solver children running)."""
    if sys.platform.startswith("linux"):
        import ctypes
        import signal

        parent = os.getppid()
        pr_set_pdeathsig = 1
        with contextlib.suppress(OSError, AttributeError):
            ctypes.CDLL("libc.so.6", use_errno=True).prctl(pr_set_pdeathsig, int(signal.SIGKILL))
        if os.getppid() != parent:  # the parent died before the request took effect
            os._exit(1)


def _serve() -> None:
    """Child side: read one pickled call from stdin, write the pickled outcome to stdout."""
    _die_with_parent()
    module, name, args = pickle.loads(sys.stdin.buffer.read())
    out = sys.stdout.buffer
    sys.stdout = sys.stderr  # anything the call prints must not corrupt the answer
    try:
        target: Any = importlib.import_module(module)
        for part in name.split("."):
            target = getattr(target, part)
        answer: tuple[str, Any] = ("ok", target(*args))
    except ScengenError as exc:
        answer = ("error", exc)
    except BaseException as exc:  # report anything, the parent decides
        answer = ("crash", f"{type(exc).__name__}: {exc}\n{traceback.format_exc()}")
    out.write(pickle.dumps(answer))
    out.flush()


if __name__ == "__main__":
    _serve()
