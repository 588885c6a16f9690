"""A command's process under a budget: a warm child whose output is its caller's own.

The command line runs each command's work in such a child (service.cli.budgeted), so that
the command stops at its budget however the work is made up: a grounding that never looks
at the clock, a picture of thousands of frames, a map that takes minutes to read. The child
is the command's process moved one level down, nothing more: its solver and SUMO calls still
run in children of their own (``budget.INSIDE_CHILD`` stays false), as they did in the
command's process. What it prints on stdout and stderr appears on the caller's as it comes;
its answer comes back on a pipe of its own (``python -m service.core.attached FD``).

A call that overruns kills the child's process group (its grandchildren die with it, or
with their parent), and Ctrl-C in the caller is passed on to the child as SIGINT: what the
command does on Ctrl-C (a table of what was judged, a note on how to go on) still happens,
and its answer is waited for up to ``INTERRUPT_WAIT`` seconds. The child serves the next
call warm unless the last one left it unsound (``budget.leaves_child_sound``) or was
interrupted.
"""

from __future__ import annotations

import atexit
import codecs
import contextlib
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from typing import Any, TypeVar

from service.core.budget import (
    CALLS_PER_CHILD,
    FRAME,
    REAP_SECONDS,
    STDERR_KEPT,
    Echo,
    answer_call,
    child_environment,
    die_with_parent,
    encode_call,
    kill_and_reap,
    leaves_child_sound,
    limit_memory,
    outcome_of,
    read_answer,
    read_frame,
    scratch_folder,
)
from service.core.errors import BudgetExceeded

T = TypeVar("T")
INTERRUPT_WAIT = 10.0  # seconds a child may take to answer after Ctrl-C was passed on


class _ReaderGone(Exception):
    """The caller's own stdout or stderr is closed (``scengen ... | head``)."""


class AttachedWorker:
    """One warm child serving calls one after another, each under its budget, its output
    passed on to this process's ``sys.stdout`` and ``sys.stderr`` as it comes."""

    def __init__(self, command: tuple[str, ...] = ()) -> None:
        self._command = list(command or (sys.executable, "-m", "service.core.attached"))
        self._process: subprocess.Popen[bytes] | None = None
        self._answers = -1  # the read end of the child's answer pipe
        self._scratch: str | None = None  # the child's TMPDIR, removed with the child
        self._tail = bytearray()  # the end of what the call wrote on stderr
        self._calls = 0
        self._owner = os.getpid()
        self._lock = threading.Lock()
        atexit.register(self.close)

    def call(self, function: Callable[..., T], args: tuple[Any, ...], budget: float,
             what: str) -> T:  # fmt: skip
        """``function(*args)`` in the child; BudgetExceeded after ``budget`` seconds."""
        with self._lock:
            process = self._child()
            assert process.stdin is not None
            request = encode_call(function, args)
            self._tail.clear()
            self._calls += 1
            echo = self._echo(process)
            try:
                process.stdin.write(FRAME.pack(len(request)) + request)
                process.stdin.flush()
                reply = read_frame(self._answers, time.monotonic() + budget, None, echo)
            except TimeoutError:
                self._stop()
                raise BudgetExceeded(
                    f"{what} did not finish within its budget of {budget:g} s and was stopped"
                ) from None
            except _ReaderGone:
                self._stop()
                raise BrokenPipeError from None
            except (OSError, EOFError):  # the child died: out of memory, or a crash
                with contextlib.suppress(subprocess.TimeoutExpired):
                    process.wait(REAP_SECONDS)
                said = bytes(self._tail)
                self._stop()
                read_answer(b"", said, what)  # raises
                raise  # (not reached)
            except KeyboardInterrupt:
                reply = self._interrupted(process, echo)
            except BaseException:
                self._stop()
                raise
            answer = read_answer(reply, b"", what)
            if not leaves_child_sound(answer) or self._calls >= CALLS_PER_CHILD:
                self._stop()
        return outcome_of(answer, what)  # type: ignore[no-any-return]

    def _interrupted(self, process: subprocess.Popen[bytes], echo: Echo) -> bytes:
        """Ctrl-C during a call: passed on to the child's process group; the child's answer,
        after which it retires (the interrupt may have landed anywhere in its work). A second
        Ctrl-C, or no answer in ``INTERRUPT_WAIT`` seconds, kills it. What the child writes
        on stderr from here on is passed on only with its answer: a native library the
        interrupt ended inside (clingo's callbacks terminate the process) says so on its
        way out, and that is not the command's to say."""
        assert process.stderr is not None
        errors, held = process.stderr.fileno(), bytearray()
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(process.pid, signal.SIGINT)
        try:
            reply = read_frame(self._answers, time.monotonic() + INTERRUPT_WAIT, None,
                               {**echo, errors: held.extend})  # fmt: skip
        except BaseException:
            self._stop()
            raise KeyboardInterrupt from None
        self._stop()
        echo[errors](bytes(held))
        return reply

    def _echo(self, process: subprocess.Popen[bytes]) -> Echo:
        """Where the child's stdout and stderr go: this process's, looked up at each write
        (a test's capture replaces them), decoded as UTF-8 across chunk boundaries."""
        assert process.stdout is not None and process.stderr is not None

        def to(name: str, keep: bool) -> Callable[[bytes], None]:
            decoder = codecs.getincrementaldecoder("utf-8")(errors="replace")

            def write(chunk: bytes) -> None:
                if keep:
                    self._tail += chunk
                    del self._tail[:-STDERR_KEPT]
                stream = getattr(sys, name)
                try:
                    stream.write(decoder.decode(chunk))
                    stream.flush()
                except BrokenPipeError:
                    raise _ReaderGone from None

            return write

        return {process.stdout.fileno(): to("stdout", False),
                process.stderr.fileno(): to("stderr", True)}  # fmt: skip

    def _child(self) -> subprocess.Popen[bytes]:
        if self._owner != os.getpid():  # a forked copy of a parent's worker is not ours
            self._process, self._scratch, self._owner = None, None, os.getpid()
        if self._process is None or self._process.poll() is not None:
            self._stop()
            self._scratch = scratch_folder("command")
            self._calls = 0
            answers, written = os.pipe()
            try:
                self._process = subprocess.Popen(
                    [*self._command, str(written)],
                    stdin=subprocess.PIPE,
                    stdout=subprocess.PIPE,
                    stderr=subprocess.PIPE,
                    pass_fds=(written,),
                    env=child_environment(self._scratch),
                    start_new_session=True,  # the terminal's Ctrl-C is ours to pass on
                )
            except BaseException:
                os.close(answers)
                raise
            finally:
                os.close(written)
            self._answers = answers
        return self._process

    def _stop(self) -> None:
        if self._process is not None:
            with contextlib.suppress(ProcessLookupError, PermissionError):
                os.killpg(self._process.pid, signal.SIGKILL)
            kill_and_reap(self._process)
            for pipe in (self._process.stdin, self._process.stdout, self._process.stderr):
                if pipe is not None:
                    with contextlib.suppress(OSError):
                        pipe.close()
            self._process = None
            with contextlib.suppress(OSError):
                os.close(self._answers)
            self._answers = -1
        if self._scratch is not None:
            shutil.rmtree(self._scratch, ignore_errors=True)
            self._scratch = None

    def close(self) -> None:
        """End the child (it also ends when this process does)."""
        if self._process is not None and self._owner == os.getpid():
            self._stop()


def _serve(answers: int) -> None:
    """Child side: answer framed calls from stdin on the ``answers`` pipe until stdin
    closes; stdout and stderr are the caller's (line-buffered: they come as they are
    written, and all of a call's output comes before its answer)."""
    die_with_parent()
    limit_memory()
    out = os.fdopen(answers, "wb")
    source = sys.stdin.buffer
    sys.stdout.reconfigure(line_buffering=True)  # type: ignore[union-attr]
    while True:
        signal.signal(signal.SIGINT, signal.SIG_IGN)  # between calls: nothing to stop
        header = source.read(FRAME.size)
        if not header:
            return
        (size,) = FRAME.unpack(header)
        request = source.read(size)
        signal.signal(signal.SIGINT, signal.default_int_handler)
        answer = answer_call(request)
        sys.stdout.flush()
        sys.stderr.flush()
        out.write(FRAME.pack(len(answer)) + answer)
        out.flush()


if __name__ == "__main__":
    _serve(int(sys.argv[1]))
