"""The command's child (service.core.attached): its output is the caller's, in order and
before its answer; its budget kills it with every process it started; Ctrl-C is passed on
and the child's own answer to it comes back; a crash retires it and the next call works."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from service.core.attached import AttachedWorker
from service.core.errors import BudgetExceeded, ScengenError
from tests.processes import alive


def talk(lines: int) -> str:
    for number in range(lines):
        print(f"out {number}")
        print(f"err {number}", file=sys.stderr)
    sys.stdout.write("no newline, ä")  # written before the answer: it comes first
    return "done"


def sleep_with_a_grandchild(pid_file: str) -> None:
    sleeper = subprocess.Popen(["sleep", "60"])
    Path(pid_file).write_text(str(sleeper.pid))
    time.sleep(60)


def wait_for_ctrl_c(ready: str) -> str:
    Path(ready).touch()
    try:
        time.sleep(60)
    except KeyboardInterrupt:
        print("stopping as asked", file=sys.stderr)
        return "interrupted"
    return "slept"


def die_on_ctrl_c(ready: str) -> None:
    print("working", file=sys.stderr)
    Path(ready).touch()
    try:
        time.sleep(60)
    except KeyboardInterrupt:
        print("terminate called inside a native library", file=sys.stderr, flush=True)
        os._exit(134)


def crash() -> None:
    raise RuntimeError("boom")


def test_the_childs_output_is_the_callers_in_order_before_its_answer(
    capsys: pytest.CaptureFixture[str],
) -> None:
    worker = AttachedWorker()
    try:
        assert worker.call(talk, (500,), 30, "talk") == "done"
        captured = capsys.readouterr()
        assert captured.out.splitlines() == [f"out {n}" for n in range(500)] + ["no newline, ä"]
        assert captured.err.splitlines() == [f"err {n}" for n in range(500)]
        assert worker.call(talk, (1,), 30, "talk") == "done"  # the same child, warm
        assert capsys.readouterr().out == "out 0\nno newline, ä"
    finally:
        worker.close()


def test_a_call_over_its_budget_is_killed_with_what_it_started(tmp_path: Path) -> None:
    worker = AttachedWorker()
    pid_file = tmp_path / "pid"
    try:
        with pytest.raises(BudgetExceeded, match=r"sleeper did not finish within its budget"):
            worker.call(sleep_with_a_grandchild, (str(pid_file),), 2, "sleeper")
        grandchild = int(pid_file.read_text())
        deadline = time.monotonic() + 5
        while time.monotonic() < deadline and alive(grandchild):
            time.sleep(0.05)
        assert not alive(grandchild)
    finally:
        worker.close()


@contextlib.contextmanager
def ctrl_c_once(ready: Path) -> Iterator[None]:
    """Ctrl-C to this process as soon as the child has made ``ready``."""

    def press_ctrl_c() -> None:
        while not ready.exists():
            time.sleep(0.02)
        os.kill(os.getpid(), signal.SIGINT)

    presser = threading.Thread(target=press_ctrl_c)
    presser.start()
    try:
        yield
    finally:
        presser.join()


def test_ctrl_c_is_passed_on_and_the_childs_answer_comes_back(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert threading.current_thread() is threading.main_thread()
    worker = AttachedWorker()
    ready = tmp_path / "ready"
    try:
        with ctrl_c_once(ready):
            assert worker.call(wait_for_ctrl_c, (str(ready),), 30, "waiter") == "interrupted"
        assert "stopping as asked" in capsys.readouterr().err
        assert worker.call(talk, (0,), 30, "talk") == "done"  # a fresh child
    finally:
        worker.close()


def test_a_child_that_dies_of_ctrl_c_leaves_no_last_words(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """What it wrote before Ctrl-C is kept; what a library says as Ctrl-C ends the process
    (clingo's "going to terminate") is not the command's to say."""
    worker = AttachedWorker()
    ready = tmp_path / "ready"
    try:
        with ctrl_c_once(ready), pytest.raises(KeyboardInterrupt):
            worker.call(die_on_ctrl_c, (str(ready),), 30, "dier")
    finally:
        worker.close()
    assert capsys.readouterr().err == "working\n"


def test_a_crash_retires_the_child_and_the_next_call_works() -> None:
    worker = AttachedWorker()
    try:
        with pytest.raises(ScengenError, match="crashed: RuntimeError: boom"):
            worker.call(crash, (), 30, "crasher")
        assert worker.call(talk, (0,), 30, "talk") == "done"
    finally:
        worker.close()
