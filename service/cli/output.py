"""What the commands print and how they end: exit codes, tables, verdicts, progress.

Exit codes: 0 success (for ``check``: the ego passed), 1 the ego failed (``check``), 2 bad
input (one line on stderr), 3 the work could not be done (SUMO, netconvert or a budget
failed).
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path

from service.core.checker.verdict import Verdict
from service.core.errors import InvalidInput, ScengenError, UnsupportedIntersection
from service.core.testcase import TestCase, dump_testcase

EXIT_OK, EXIT_FAILED_CHECK, EXIT_BAD_INPUT, EXIT_FAILED = 0, 1, 2, 3


def exit_code(error: ScengenError) -> int:
    """The exit code for a domain error: the one place where errors become exit codes."""
    if isinstance(error, InvalidInput | UnsupportedIntersection):
        return EXIT_BAD_INPUT
    return EXIT_FAILED


def print_table(rows: Sequence[Sequence[str]]) -> None:
    widths = [max(len(row[i]) for row in rows) for i in range(len(rows[0]))]
    for row in rows:
        print(
            "  ".join(cell.ljust(width) for cell, width in zip(row, widths, strict=True)).rstrip()
        )


def emit(testcase: TestCase, output: Path | None) -> int:
    """Write a test-case to ``output``, or to stdout without one."""
    text = dump_testcase(testcase)
    if output:
        output.write_text(text)
        print(f"wrote {output}", file=sys.stderr)
    else:
        sys.stdout.write(text)
    return EXIT_OK


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


def print_verdict(verdict: Verdict) -> None:
    status = "PASS" if verdict.passed else "FAIL"
    print(f"{status}  {verdict.testcase} / {verdict.controller}")
    if verdict.goal_time is not None:
        print(f"  reached its exit at {verdict.goal_time:.2f} s")
    for reason in verdict.reasons:
        print(f"  {reason}")


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
