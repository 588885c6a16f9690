"""What the commands print and how they end: exit codes, tables, verdicts, progress.

Exit codes: 0 success (for ``check``: the ego passed), 1 the ego failed (``check``), 2 bad
input (one line on stderr), 3 the work could not be done (SUMO, netconvert or a budget
failed).
"""

from __future__ import annotations

import contextlib
import os
import sys
import tempfile
import time
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from service.cli.table import Writes
from service.core.errors import ClientFault, InvalidInput, ScengenError, UnsupportedIntersection

if TYPE_CHECKING:  # loaded by the commands that use them, not by every command's start
    from service.core.checker.verdict import Verdict
    from service.core.motion.criticality_records import Criticality
    from service.core.testcase import TestCase

EXIT_OK, EXIT_FAILED_CHECK, EXIT_BAD_INPUT, EXIT_FAILED = 0, 1, 2, 3
EXIT_CLIENT = 4  # the co-simulated driving stack's fault (scengen cosim): no verdict
EXIT_INTERRUPTED = 130  # 128 + SIGINT, as shells report a command stopped by Ctrl-C


def exit_code(error: ScengenError) -> int:
    """The exit code for a domain error: the one place where errors become exit codes."""
    if isinstance(error, InvalidInput | UnsupportedIntersection):
        return EXIT_BAD_INPUT
    if isinstance(error, ClientFault):
        return EXIT_CLIENT
    return EXIT_FAILED


def print_table(rows: Sequence[Sequence[str]]) -> None:
    widths = [max(len(row[i]) for row in rows) for i in range(len(rows[0]))]
    for row in rows:
        print(
            "  ".join(cell.ljust(width) for cell, width in zip(row, widths, strict=True)).rstrip()
        )


def emit(testcase: TestCase, output: Path | None, network_file: Path | None = None) -> int:
    """Write a test-case to ``output`` (with its network's path from there), or to stdout
    without one."""
    from service.core.testcase import dump_testcase, with_network_path

    if output:
        placed = with_network_path(testcase, network_file, output.parent)
        write_output(output, dump_testcase(placed))
        print(f"wrote {output}", file=sys.stderr)
    else:
        sys.stdout.write(dump_testcase(testcase))
    return EXIT_OK


def check_writable(path: Path, what: Writes) -> None:
    """InvalidInput unless the command can write ``path`` (a file, or a folder it writes
    into): checked before the work, so that nothing is computed for a place that cannot
    take it. A missing folder on the way is fine (it is made when the result is written);
    a file on the way, a folder where a file goes, or a place that refuses a new file is
    not."""
    if what == "file" and path.is_dir():
        raise InvalidInput(f"cannot write {path}: it is a folder; give a file name")
    folder = path if what == "folder" else path.parent
    existing = folder
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    if not existing.is_dir():
        raise InvalidInput(f"cannot write {path}: {existing} is a file, not a folder")
    try:  # the only reliable test (as root, os.access says yes to /proc and read-only mounts)
        with tempfile.TemporaryFile(dir=existing):
            pass
    except OSError as error:
        raise InvalidInput(
            f"cannot write {path}: the folder {existing} takes no new file ({error.strerror})"
        ) from None
    if what == "file" and path.exists() and not os.access(path, os.W_OK):
        raise InvalidInput(f"cannot write {path}: permission denied")


def make_folder(folder: Path) -> None:
    """Make ``folder`` (and its parents) when missing, and say so."""
    if folder.is_dir():
        return
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise InvalidInput(f"cannot make the folder {folder}: {error.strerror}") from None
    print(f"scengen: made the folder {folder}", file=sys.stderr)


def write_output(path: Path, data: str | bytes) -> None:
    """Write a result to ``path`` whole or not at all, its folder made when missing."""
    from service.core.files import write_atomically

    make_folder(path.parent)
    try:
        write_atomically(path, data)
    except OSError as error:  # the disk filled up or the folder went away since the check
        raise ScengenError(f"cannot write {path}: {error.strerror}") from None


@contextlib.contextmanager
def output_file(path: Path) -> Iterator[Path]:
    """A temporary path for a writer that takes a path (a picture), renamed to ``path``
    when the writer is done; its folder made when missing."""
    from service.core.files import replacing

    make_folder(path.parent)
    with replacing(path) as temporary:
        yield temporary


def short(verdict: Verdict) -> str:
    """The first reason of a failed verdict, in a few words."""
    if verdict.errors:
        return "controller error"
    if verdict.collisions:
        return f"collides with {verdict.collisions[0].other}"
    if verdict.violations:
        v = verdict.violations[0]
        return f"{v.rule}" + (f" of {v.other}" if v.other else "")
    return "did not reach its exit"


def report_verdict(verdict: Verdict, as_json: bool, junit: Path | None) -> int:
    """One verdict as ``check`` and ``cosim`` give it: JUnit written when asked, JSON or
    text on stdout; the exit code (0 pass, 1 fail)."""
    if junit:
        write_output(junit, verdict.to_junit())
    if as_json:
        sys.stdout.write(verdict.to_json())
    else:
        print_verdict(verdict)
    return EXIT_OK if verdict.passed else EXIT_FAILED_CHECK


def print_verdict(verdict: Verdict) -> None:
    from service.core.sumo.run import guard_text

    status = "PASS" if verdict.passed else "FAIL"
    print(f"{status}  {verdict.testcase} / {verdict.controller}")
    if verdict.goal_time is not None:
        print(f"  reached its exit at {verdict.goal_time:.2f} s")
    for reason in verdict.reasons:
        print(f"  {reason}")
    for line in verdict.information:  # after the judgement ended: not a reason
        print(f"  {line}")
    if verdict.guard is not None:
        print(f"  {guard_text(verdict.guard)}")
    if verdict.criticality is not None:
        print(f"  {describe_criticality(verdict.criticality)}")


def describe_criticality(criticality: Criticality) -> str:
    """One line of the overall measures: the smallest TTC, PET and distance, the largest
    DRAC, each with the car and the time (``-`` where no car gives one)."""
    parts = []
    for name, unit, extreme in (
        ("TTC", "s", criticality.ttc),
        ("PET", "s", criticality.pet),
        ("DRAC", "m/s^2", criticality.drac),
        ("distance", "m", criticality.distance),
    ):
        if extreme is None:
            parts.append(f"{name} -")
        else:
            parts.append(f"{name} {extreme.value:.2f} {unit} ({extreme.car} at {extreme.t:.2f} s)")
    return "criticality: " + ", ".join(parts)


def guard_note(verdict: Verdict) -> str:
    """A guarded verdict's table cell suffix: how often the guard intervened."""
    if verdict.guard is None:
        return ""
    fallback = ", time-gap fallback" if verdict.guard.get("fallback") else ""
    return f" [RSS {verdict.guard['interventions']}/{verdict.guard['steps']}{fallback}]"


def progress(started: float) -> Callable[[str], None]:
    """Messages on stderr, each with the seconds since ``started``."""

    def say(message: str) -> None:
        print(f"[{time.monotonic() - started:6.2f} s] {message}", file=sys.stderr)

    return say


class StepProgress:
    """Progress of a known number of steps on stderr: a bar on a terminal, otherwise a line
    every ``lines_every`` steps and at the last (CI logs keep every line)."""

    def __init__(self, total: int, unit: str, lines_every: int = 1) -> None:
        self.total, self.done, self.started = total, 0, time.monotonic()
        self.lines_every = lines_every
        self.bar = None
        if sys.stderr.isatty():
            from tqdm import tqdm

            self.bar = tqdm(total=total, unit=f" {unit}", file=sys.stderr, leave=False)

    def step(self, message: str) -> None:
        self.done += 1
        if self.bar is not None:
            self.bar.set_postfix_str(message, refresh=False)
            self.bar.update()
        elif self.done % self.lines_every == 0 or self.done == self.total:
            elapsed = time.monotonic() - self.started
            print(f"[{elapsed:6.2f} s] {self.done}/{self.total} {message}", file=sys.stderr,
                  flush=True)  # fmt: skip

    def print(self, line: str) -> None:
        """A line of the command's output (stdout), above the bar on a terminal."""
        if self.bar is not None:
            self.bar.write(line, file=sys.stdout)
        else:
            print(line, flush=True)

    def note(self, message: str) -> None:
        """Something said between steps: beside the bar on a terminal, else its own line."""
        if self.bar is not None:
            self.bar.set_postfix_str(message)
        else:
            elapsed = time.monotonic() - self.started
            print(f"[{elapsed:6.2f} s] {message}", file=sys.stderr, flush=True)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
