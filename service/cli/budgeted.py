"""Every command's work inside its budget.

``main`` parses the command line, then hands a command that works on the user's input to a
child process (service.core.attached) that runs the same command there and is stopped when
the command's budget runs out: a limit on the whole command, whatever its work is made of
(a solver's grounding that never looks at the clock, a picture of thousands of frames, a
map that takes minutes to read). The child's output is the command's output, as it comes;
Ctrl-C still does what the command does on Ctrl-C.

The budget of a command is its ``--budget`` (for ``evaluate``, ``example`` and ``cosim``,
what their budgets add up to: ``Command.limit``), counted from the command's start. The
child, with every process it started, is killed ``KILL_GRACE`` after it, so that the
command's own stops (the generator's budget, with its message) come first. No signal is
raised inside the child's work: a solver's callback that raises ends the process (clingo
does). A stopped command leaves no half-written file: the parent removes the partial
files (``files.replacing``) of the paths the command writes.
"""

from __future__ import annotations

import argparse
import io
import os
import shutil
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from service.core.attached import AttachedWorker
from service.core.budget import memory_exceeded
from service.core.errors import BudgetExceeded, MemoryExceeded

KILL_GRACE = 2.0  # s after the budget: the command's own stops come first (budget + 2 s)

COMMANDS = AttachedWorker()
_in_child = False  # true while this process runs a command for run_in_child


def run_in_child(
    argv: Sequence[str], args: argparse.Namespace, run_command: Callable[..., tuple[int, bool]]
) -> int:
    """The command ``argv`` (parsed as ``args``) run in the command child by
    ``run_command(request)`` (``as_the_command`` with ``main``, a module-level function the
    child can import); its exit code. BudgetExceeded when it ran out of its budget."""
    limit, how = args.limit(args)
    what = f"scengen {args.command}"
    request = {
        "argv": list(argv),
        "cwd": str(Path.cwd()),
        "environ": dict(os.environ),
        "ttys": (_isatty(sys.stdout), _isatty(sys.stderr)),
        "columns": shutil.get_terminal_size().columns,
        "what": what,
    }
    try:
        code, exits = COMMANDS.call(run_command, (request,), limit + KILL_GRACE, what)
    except MemoryExceeded:  # the child ran out of its memory cap (said as the command's)
        _remove_partial_files(args)
        raise
    except BudgetExceeded:  # killed at the budget, whatever it was doing
        _remove_partial_files(args)
        raise BudgetExceeded(over_budget(what, limit, how)) from None
    if exits:  # a usage error found after parsing: argparse's exit, as without a child
        raise SystemExit(code)
    return code


def over_budget(what: str, limit: float, how: str) -> str:
    return (f"{what} did not finish within its budget of {limit:g} s ({how}) and was "
            "stopped; a larger --budget gives it more time")  # fmt: skip


def as_the_command(
    request: dict[str, Any], main: Callable[[Sequence[str]], int]
) -> tuple[int, bool]:
    """Child side: the command of ``request`` as ``main`` runs it, in the caller's folder
    and environment, its output the caller's; its exit code, and whether it exited
    (SystemExit: argparse's usage errors)."""
    global _in_child

    os.chdir(request["cwd"])
    scratch = os.environ.get("TMPDIR")
    os.environ.clear()
    os.environ.update(request["environ"])
    if scratch is not None:
        os.environ["TMPDIR"] = scratch  # the child's own, removed with it
    os.environ["COLUMNS"] = str(request["columns"])
    _in_child = True
    streams = sys.stdout, sys.stderr
    tty_out, tty_err = request["ttys"]
    sys.stdout, sys.stderr = _Stream(sys.stdout, tty_out), _Stream(sys.stderr, tty_err)
    try:
        return main(request["argv"]), False
    except SystemExit as exit:
        return exit.code if isinstance(exit.code, int) else 1, True
    except MemoryError:  # not the domain's: main lets it through
        raise memory_exceeded(request["what"]) from None
    finally:
        sys.stdout.flush()
        sys.stderr.flush()
        sys.stdout, sys.stderr = streams
        _in_child = False


def in_command_child() -> bool:
    """Whether this process runs a command for ``run_in_child`` (its work runs here)."""
    return _in_child


class _Stream(io.TextIOBase):
    """The child's stdout or stderr as the command sees it: a terminal when the caller's is
    one (progress bars), written at once (the caller shows it as it comes)."""

    def __init__(self, stream: Any, tty: bool) -> None:
        self._stream, self._tty = stream, tty

    def write(self, text: str) -> int:
        written: int = self._stream.write(text)
        self._stream.flush()
        return written

    def flush(self) -> None:
        self._stream.flush()

    def isatty(self) -> bool:
        return self._tty

    def fileno(self) -> int:
        return int(self._stream.fileno())

    @property
    def encoding(self) -> str:  # type: ignore[override]
        return str(self._stream.encoding)


def _isatty(stream: Any) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):
        return False


def _remove_partial_files(args: argparse.Namespace) -> None:
    """The partial files a killed command left beside the files it writes
    (``files.replacing`` names them ``.NAME.*.partial*``)."""
    for destination, what in args.writes:
        path = getattr(args, destination, None)
        if path is None:
            continue
        folder, pattern = (Path(path), ".*.partial*") if what == "folder" else (
            Path(path).parent, f".{Path(path).name[:200]}.*.partial*")  # fmt: skip
        for partial in folder.glob(pattern) if folder.is_dir() else ():
            partial.unlink(missing_ok=True)
