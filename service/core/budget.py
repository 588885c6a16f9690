"""Run a call in a child Python process that is killed when its time budget runs out.

Solver and simulator libraries do not always honour their own timeouts, and libsumo is a
per-process singleton, so every long call runs here, never in the caller's process. The
child is a fresh interpreter (``python -m service.core.budget``) fed the call by pickle on
stdin: no fork of a threaded server, and no re-import of the caller's ``__main__``.

``WarmWorker`` keeps such a child alive between calls, so that its imports (libsumo, about
half a second) are paid once per process; each call still runs under its budget, and a call
that overruns kills the child (the next call starts a fresh one).

Inside such a child (an evaluation or a picture the server or a job started there), a nested
call runs in the child itself, under its own budget (an alarm, and the child's parent kills
the child at the outer budget): one child per call, so the number of workers is a true cap
on the processes that compute at once.
"""

from __future__ import annotations

import atexit
import contextlib
import importlib
import os
import pickle
import re
import select
import shutil
import signal
import struct
import subprocess
import sys
import tempfile
import threading
import time
import traceback
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, BinaryIO, TypeVar

from service.core.errors import BudgetExceeded, MemoryExceeded, ScengenError

MEMORY_VARIABLE = "SCENGEN_WORKER_MEMORY_MB"
DEFAULT_MEMORY_MB = 4096
# what a child's native libraries print when an allocation fails under the cap
OUT_OF_MEMORY = re.compile(
    r"MemoryError|Memory allocation|Cannot allocate memory|bad_alloc|out of memory", re.I
)

T = TypeVar("T")
INSIDE_CHILD = False  # set in a budget child: nested calls run there, not in a grandchild


def run_with_budget(
    function: Callable[..., T], args: tuple[Any, ...], budget: float, what: str
) -> T:
    """``function(*args)`` in a child process; BudgetExceeded after ``budget`` seconds.

    ``function`` must be a module-level function and its arguments and result picklable.
    Domain errors raised in the child are re-raised here as they were. Inside a budget
    child, the call runs in this process (``run_here``).
    """
    if INSIDE_CHILD:
        return run_here(function, args, budget, what)
    request = encode_call(function, args)
    scratch = scratch_folder("call")
    try:
        result = subprocess.run(
            CHILD_COMMAND,
            input=request,
            capture_output=True,
            timeout=budget,
            check=False,
            env=child_environment(scratch),
        )
    except subprocess.TimeoutExpired:
        raise BudgetExceeded(
            f"{what} did not finish within its budget of {budget:g} s and was stopped"
        ) from None
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
    return decode_outcome(result.stdout, result.stderr, what)  # type: ignore[no-any-return]


CHILD_COMMAND = [sys.executable, "-m", "service.core.budget"]


def scratch_folder(kind: str) -> str:
    """A new folder for a child's temporary files, named for its kind and this process
    (``scengen-KIND-PID-...``). The folders of the same kind whose process is gone are
    removed first: a process that ended without its exit handlers (a Celery pool process
    leaves by ``os._exit``, a kill -9) could not remove its children's."""
    base = Path(tempfile.gettempdir())
    for stale in base.glob(f"scengen-{kind}-*-*"):
        owner = stale.name.split("-")[2]
        if owner.isdigit() and not _runs(int(owner)):
            shutil.rmtree(stale, ignore_errors=True)
    return tempfile.mkdtemp(prefix=f"scengen-{kind}-{os.getpid()}-")


def _runs(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's: running
        return True
    return True


def child_environment(scratch: str) -> dict[str, str]:
    """The child's environment: its temporary files go into ``scratch``, a folder the
    parent removes once the child is gone, so that a child killed at its budget (or by
    Ctrl-C) leaves no files behind."""
    return {**os.environ, "TMPDIR": scratch}


REAP_SECONDS = 5.0  # how long a killed child may take to be collected through Popen


def kill_and_reap(process: subprocess.Popen[Any], reap_seconds: float = REAP_SECONDS) -> None:
    """Kill ``process`` (if it still runs) and collect its exit status.

    A Ctrl-C that lands inside ``Popen.poll()`` can leave Popen's internal waitpid lock
    held for good; ``Popen.wait()`` would then block forever (an interpreter that never
    exits after the KeyboardInterrupt). So the wait has a timeout, and when it runs out the
    child is collected here, without that lock.
    """
    with contextlib.suppress(OSError):
        process.kill()
    try:
        process.wait(timeout=reap_seconds)
    except subprocess.TimeoutExpired:
        with contextlib.suppress(ChildProcessError):  # someone else collected it
            _, status = os.waitpid(process.pid, 0)
            process.returncode = os.waitstatus_to_exitcode(status)


def run_here(function: Callable[..., T], args: tuple[Any, ...], budget: float, what: str) -> T:
    """``function(*args)`` in this process, as a child would answer it: BudgetExceeded when
    an alarm after ``budget`` seconds interrupts it (Python code between two native calls;
    a native call that never returns is ended by the parent, which kills this process at
    its own budget), anything but a domain error reported as a crash."""
    alarm = threading.current_thread() is threading.main_thread() and hasattr(signal, "setitimer")
    if alarm and signal.getitimer(signal.ITIMER_REAL)[0] > 0:
        alarm = False  # an outer call's alarm is running: it stays the one that stops us

    def expire(signum: int, frame: Any) -> None:
        raise BudgetExceeded(
            f"{what} did not finish within its budget of {budget:g} s and was stopped"
        )

    previous = signal.signal(signal.SIGALRM, expire) if alarm else None
    try:
        if alarm:
            signal.setitimer(signal.ITIMER_REAL, max(budget, 0.001))
        return function(*args)
    except ScengenError:
        raise
    except MemoryError:
        raise memory_exceeded(what) from None
    except Exception as exc:
        raise ScengenError(
            f"{what} crashed: {type(exc).__name__}: {exc}", traceback=traceback.format_exc()
        ) from exc
    finally:
        if alarm:
            signal.setitimer(signal.ITIMER_REAL, 0)
            signal.signal(signal.SIGALRM, previous)


def memory_exceeded(what: str) -> MemoryExceeded:
    """The error of ``what`` that failed to allocate under this worker's memory cap."""
    limit = os.environ.get(MEMORY_VARIABLE, str(DEFAULT_MEMORY_MB))
    return MemoryExceeded(
        f"{what} needed more memory than a worker may use ({limit} MB, {MEMORY_VARIABLE})"
    )


def encode_call(function: Callable[..., Any], args: tuple[Any, ...]) -> bytes:
    """What the child reads on stdin: a module-level function and its arguments."""
    return pickle.dumps((function.__module__, function.__qualname__, args))


def decode_outcome(stdout: bytes, stderr: bytes, what: str) -> Any:
    """The child's answer: its result, or the domain error it raised, re-raised here."""
    return outcome_of(read_answer(stdout, stderr, what), what)


def read_answer(stdout: bytes, stderr: bytes, what: str) -> tuple[str, Any]:
    """The child's answer as (status, payload): "ok" and the result, "error" and the domain
    error it raised, or "crash" and the traceback of anything else. A child that died
    without one is MemoryExceeded when its native libraries said they could not allocate
    (on ``stderr``), else ScengenError."""
    try:
        status, payload = pickle.loads(stdout)
    except Exception:
        text = stderr.decode(errors="replace")
        detail = text.strip().splitlines()[-1:] or ["no output"]
        if OUT_OF_MEMORY.search(text):  # a native library that could not allocate gave up
            limit = os.environ.get(MEMORY_VARIABLE, str(DEFAULT_MEMORY_MB))
            raise MemoryExceeded(
                f"{what} ran out of the memory a worker may use ({limit} MB, "
                f"{MEMORY_VARIABLE}): {detail[0]}"
            ) from None
        raise ScengenError(f"{what} died without an answer: {detail[0]}") from None
    return status, payload


def leaves_child_sound(answer: tuple[str, Any]) -> bool:
    """Whether a warm child that gave ``answer`` may serve another call. A result or a
    domain error leaves it as it was. A crash may not, nor a budget that ran out inside it:
    a nested call's alarm interrupts whatever Python code runs (an import half done leaves a
    module without its names), and a failed allocation can leave a library's state torn."""
    status, payload = answer
    return status == "ok" or (status == "error" and not isinstance(payload, BudgetExceeded))


def outcome_of(answer: tuple[str, Any], what: str) -> Any:
    """The result of ``read_answer``'s answer, or its error raised here."""
    status, payload = answer
    if status == "error":
        raise payload
    if status == "crash":
        summary = str(payload).splitlines()[0] if payload else "no detail"
        raise ScengenError(f"{what} crashed: {summary}", traceback=str(payload))
    return payload


def die_with_parent() -> None:
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


FRAME = struct.Struct(">Q")  # a length, then that many bytes of pickle


CALLS_PER_CHILD = 200  # then a warm child retires: caches and fragmentation do not pile up
STDERR_KEPT = 16384  # bytes of a warm child's last output: why it died, should it die


class CallStopped(Exception):
    """A warm call's ``stop`` event was set: the child was killed without an answer."""


class WarmWorker:
    """One child interpreter that serves calls one after another, each under its budget;
    ``command`` starts it (``CHILD_COMMAND`` behind a ``nice``, say), in a process group of
    its own when ``group`` (killed with its grandchildren)."""

    def __init__(self, command: Sequence[str] = (), group: bool = False) -> None:
        self._command = [*(command or CHILD_COMMAND), "--many"]
        self._group = group
        self._process: subprocess.Popen[bytes] | None = None
        self._scratch: str | None = None  # the child's TMPDIR, removed with the child
        self._stderr: Any = None  # where the child writes its stderr, in the scratch folder
        self._calls = 0
        self._owner = 0
        self._lock = threading.Lock()
        atexit.register(self.close)

    def call(self, function: Callable[..., T], args: tuple[Any, ...], budget: float,
             what: str, stop: threading.Event | None = None) -> T:  # fmt: skip
        """``function(*args)`` in the warm child; BudgetExceeded after ``budget`` seconds,
        CallStopped as soon as ``stop`` is set. Inside a budget child, in this process
        (``run_here``)."""
        if INSIDE_CHILD:
            return run_here(function, args, budget, what)
        with self._lock:
            process = self._child()
            assert process.stdin is not None and process.stdout is not None
            request = encode_call(function, args)
            self._stderr.truncate(0)  # the child appends: this call's output only
            self._calls += 1
            try:
                process.stdin.write(FRAME.pack(len(request)) + request)
                process.stdin.flush()
                reply = read_frame(process.stdout.fileno(), time.monotonic() + budget, stop)
            except TimeoutError:
                self._stop()
                raise BudgetExceeded(
                    f"{what} did not finish within its budget of {budget:g} s and was stopped"
                ) from None
            except (OSError, EOFError):
                with contextlib.suppress(subprocess.TimeoutExpired):
                    process.wait(REAP_SECONDS)  # its last words are all written
                self._stderr.seek(0)
                said = self._stderr.read()[-STDERR_KEPT:]
                self._stop()
                read_answer(b"", said, what)  # raises: out of memory, or died
                raise  # (not reached)
            except BaseException:  # Ctrl-C, a stop: an answer may still come, unread
                self._stop()
                raise
            answer = read_answer(reply, b"", what)
            if not leaves_child_sound(answer) or self._calls >= CALLS_PER_CHILD:
                self._stop()
        return outcome_of(answer, what)  # type: ignore[no-any-return]

    def _child(self) -> subprocess.Popen[bytes]:
        if self._owner != os.getpid():  # a forked copy of a parent's worker is not ours
            self._process, self._scratch, self._owner = None, None, os.getpid()
            self._stderr = None
        if self._process is None or self._process.poll() is not None:
            self._stop()
            self._scratch = scratch_folder("worker")
            self._stderr = Path(self._scratch, ".stderr").open("a+b")  # noqa: SIM115
            self._calls = 0
            self._process = subprocess.Popen(
                self._command,
                stdin=subprocess.PIPE,
                stdout=subprocess.PIPE,
                stderr=self._stderr,
                env=child_environment(self._scratch),
                start_new_session=self._group,
            )
        return self._process

    def _stop(self) -> None:
        if self._process is not None:
            if self._group:
                with contextlib.suppress(ProcessLookupError, PermissionError):
                    os.killpg(self._process.pid, signal.SIGKILL)
            kill_and_reap(self._process)
            self._process = None
        if self._stderr is not None:
            self._stderr.close()
            self._stderr = None
        if self._scratch is not None:
            shutil.rmtree(self._scratch, ignore_errors=True)
            self._scratch = None

    def close(self) -> None:
        """End the child (it also ends when this process does)."""
        if self._process is not None and self._owner == os.getpid():
            self._stop()


class WarmPool:
    """Warm children lent out one call at a time, for calls whose imports cost more than
    their work (a replay: a second of imports, a tenth of a second of SUMO). A caller
    borrows an idle child or, when every child is busy, starts another, so calls run at
    once as before; at most ``keep`` idle children are kept (each holds libsumo's memory).
    Each call runs under its budget, and a call that overruns or dies takes its child
    with it, as WarmWorker does."""

    def __init__(self, keep: int, command: Sequence[str] = (), group: bool = False) -> None:
        self._keep = keep
        self._command, self._group = command, group
        self._idle: list[WarmWorker] = []
        self._owner = os.getpid()
        self._lock = threading.Lock()
        atexit.register(self.close)

    def call(self, function: Callable[..., T], args: tuple[Any, ...], budget: float,
             what: str, stop: threading.Event | None = None) -> T:  # fmt: skip
        """``function(*args)`` in a warm child; BudgetExceeded after ``budget`` seconds,
        CallStopped as soon as ``stop`` is set."""
        if INSIDE_CHILD:
            return run_here(function, args, budget, what)
        with self._lock:
            if self._owner != os.getpid():  # a forked copy: the parent's children are not ours
                self._idle, self._owner = [], os.getpid()
            worker = self._idle.pop() if self._idle else WarmWorker(self._command, self._group)
        try:
            return worker.call(function, args, budget, what, stop)
        finally:
            self._give_back(worker)

    def _give_back(self, worker: WarmWorker) -> None:
        with self._lock:
            if len(self._idle) < self._keep and self._owner == os.getpid():
                self._idle.append(worker)
                return
        worker.close()
        atexit.unregister(worker.close)  # nothing left to end at exit

    def close(self) -> None:
        """End every idle child."""
        with self._lock:
            idle, self._idle = self._idle, []
        for worker in idle:
            worker.close()


STOP_POLL = 0.2  # seconds between looks at a call's stop event


Echo = dict[int, Callable[[bytes], None]]  # a child's output pipes, each to where it goes


def read_frame(
    fd: int, deadline: float, stop: threading.Event | None = None, echo: Echo | None = None
) -> bytes:
    """One frame from ``fd``; TimeoutError at the deadline, EOFError when the child is gone,
    CallStopped soon after ``stop`` is set. ``echo``: other pipes of the child, whose output
    is passed on as it comes, and all of it that was written before the frame."""
    echo = dict(echo or {})
    data = b""
    size: int | None = None
    while size is None or len(data) < FRAME.size + size:
        left = deadline - time.monotonic()
        if left <= 0:
            raise TimeoutError
        if stop is not None and stop.is_set():
            raise CallStopped
        wait = left if stop is None else min(left, STOP_POLL)
        ready = select.select([fd, *echo], [], [], wait)[0]
        _pass_on(echo, ready)
        if fd not in ready:
            continue
        chunk = os.read(fd, 1 << 20)
        if not chunk:
            raise EOFError
        data += chunk
        if size is None and len(data) >= FRAME.size:
            (size,) = FRAME.unpack(data[: FRAME.size])
    while echo and (ready := select.select(list(echo), [], [], 0)[0]):  # written before it
        _pass_on(echo, ready)
    return data[FRAME.size :]


def _pass_on(echo: Echo, ready: Sequence[int]) -> None:
    """What the ``ready`` pipes of ``echo`` hold, to where each goes; a closed one is
    dropped from ``echo``."""
    for pipe in [r for r in ready if r in echo]:
        chunk = os.read(pipe, 1 << 16)
        if chunk:
            echo[pipe](chunk)
        else:
            del echo[pipe]


def answer_call(request: bytes) -> bytes:
    """Run one pickled call; the pickled outcome."""
    module, name, args = pickle.loads(request)
    try:
        target: Any = importlib.import_module(module)
        for part in name.split("."):
            target = getattr(target, part)
        answer: tuple[str, Any] = ("ok", target(*args))
    except ScengenError as exc:
        answer = ("error", exc)
    except MemoryError:
        answer = ("error", memory_exceeded(f"{module}.{name}"))
    except BaseException as exc:  # report anything, the parent decides
        answer = ("crash", f"{type(exc).__name__}: {exc}\n{traceback.format_exc()}")
    return pickle.dumps(answer)


def limit_memory() -> None:
    """Cap this worker's data segment (heap and private mappings: what a huge allocation
    takes) at ``SCENGEN_WORKER_MEMORY_MB`` (default 4096; 0: no cap), so that one call that
    asks for gigabytes fails alone instead of taking the machine's memory."""
    try:
        megabytes = int(os.environ.get(MEMORY_VARIABLE, str(DEFAULT_MEMORY_MB)))
    except ValueError:
        megabytes = DEFAULT_MEMORY_MB
    if megabytes <= 0 or not hasattr(os, "fork"):  # POSIX only
        return
    import resource

    wanted = megabytes * 1024 * 1024
    _, hard = resource.getrlimit(resource.RLIMIT_DATA)
    if hard != resource.RLIM_INFINITY:
        wanted = min(wanted, hard)
    with contextlib.suppress(ValueError, OSError):
        resource.setrlimit(resource.RLIMIT_DATA, (wanted, hard))


def enter_child() -> None:
    """This process is a budget child: die with the parent, cap the memory, and run nested
    calls here (the flag is set on the importable module, which the calls import: this file
    runs as ``__main__``)."""
    die_with_parent()
    limit_memory()
    vars(importlib.import_module("service.core.budget"))["INSIDE_CHILD"] = True


def answer_pipe() -> BinaryIO:
    """The pipe the parent reads answers from (this child's stdout when it started), kept
    apart: stdout then goes where stderr goes, so that nothing the call prints, neither
    Python nor a native library writing to file descriptor 1 (ad-rss logs there), can
    corrupt an answer."""
    sys.stdout.flush()
    answers = os.fdopen(os.dup(1), "wb")
    os.dup2(2, 1)
    sys.stdout = sys.stderr
    return answers


def _serve() -> None:
    """Child side: read one pickled call from stdin, write the pickled outcome to stdout."""
    enter_child()
    request = sys.stdin.buffer.read()
    out = answer_pipe()
    out.write(answer_call(request))
    out.flush()


def _serve_many() -> None:
    """Warm child side: answer framed calls from stdin until it closes."""
    enter_child()
    source, out = sys.stdin.buffer, answer_pipe()
    while header := source.read(FRAME.size):
        (size,) = FRAME.unpack(header)
        answer = answer_call(source.read(size))
        out.write(FRAME.pack(len(answer)) + answer)
        out.flush()


if __name__ == "__main__":
    _serve_many() if "--many" in sys.argv[1:] else _serve()
