"""Judging egos: ``check`` (a trajectory from a file) and ``evaluate`` (controllers driven
through test-cases in SUMO)."""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from service.cli.arguments import (
    COMMAND_BUDGET,
    JUNIT,
    NETWORK_FILE,
    TESTCASE,
    budget,
    by_budget,
    controllers_named,
    read_input,
    seconds,
    testcase_intersection,
)
from service.cli.output import (
    EXIT_BAD_INPUT,
    EXIT_FAILED,
    EXIT_FAILED_CHECK,
    EXIT_INTERRUPTED,
    EXIT_OK,
    StepProgress,
    exit_code,
    guard_note,
    print_table,
    print_verdict,
    report_verdict,
    short,
    write_output,
)
from service.cli.table import arg, command
from service.core.errors import InvalidInput, ScengenError
from service.core.names import REPLAY_BUDGET

if TYPE_CHECKING:
    from service.core.checker.verdict import Verdict

JUDGING = 10.0  # s an evaluation may take beside its replay (reading, loading, judging)


@command(
    "check",
    "judge an ego trajectory against a test-case (exit 0 pass, 1 fail)",
    TESTCASE,
    arg(
        "--ego",
        required=True,
        type=Path,
        metavar="TRAJECTORY",
        help="the ego's trajectory: JSON samples or a SUMO FCD file (sumo --fcd-output)",
    ),
    arg("--vehicle", default="ego", metavar="ID", help="the ego's id in an FCD file (default ego)"),
    arg("--controller", metavar="NAME", help="name of what drove the ego (default: file name)"),
    JUNIT,
    arg("--json", action="store_true", help="print the verdict as JSON"),
    NETWORK_FILE,
    budget(COMMAND_BUDGET, "time for the whole command"),
    limit=by_budget,
)
def check(args: argparse.Namespace) -> int:
    from service.core.checker.check import check_testcase
    from service.core.motion.trajectory import read_trajectory

    testcase = read_input(args.testcase)
    ego = read_trajectory(args.ego, args.vehicle, testcase.ego.length)
    verdict = check_testcase(
        testcase, ego, args.controller or args.ego.stem, testcase_intersection(testcase, args)
    )
    return report_verdict(verdict, args.json, args.junit)


def evaluate_limit(args: argparse.Namespace) -> tuple[float, str]:
    """``evaluate``'s budget: each replay's ``--budget`` and ``JUDGING`` for each."""
    evaluations = len(_testcase_files(args.testcases)) * len(args.controller or ["sumo"])
    return (args.budget + JUDGING) * evaluations, (
        f"--budget {args.budget:g} s and {JUDGING:g} s to judge for each of {evaluations} "
        "evaluations")  # fmt: skip


@command(
    "evaluate",
    "replay test-cases in SUMO with ego controllers and judge them",
    arg(
        "testcases",
        type=Path,
        nargs="+",
        metavar="TESTCASE",
        help="test-case JSON files, or folders of them",
    ),
    arg(
        "--controller",
        action="append",
        metavar="NAME",
        help="who drives the ego (repeatable; default sumo)",
    ),
    JUNIT,
    arg("--json", action="store_true", help="print the verdicts as JSON"),
    arg(
        "--budget",
        type=seconds,
        default=REPLAY_BUDGET,
        metavar="SECONDS",
        help=f"time budget of each replay (default {REPLAY_BUDGET:g} s; the command's: "
        f"{JUDGING:g} s more for each)",
    ),
    arg(
        "--rss-params",
        type=Path,
        metavar="FILE",
        help="RSS dynamics (JSON) for the NAME+rss controllers, overriding CARLA's defaults "
        "(docs/controllers.md)",
    ),
    NETWORK_FILE,
    description=lambda: (
        "Replays each test-case in SUMO (non-egos exactly as recorded) with "
        "each controller driving the ego, and judges the ego with the checker. Controllers: "
        f"{controllers_named()}, or a user controller as module:attribute (NAME+rss: under the "
        "RSS guard)."
    ),
    limit=evaluate_limit,
)
def evaluate(args: argparse.Namespace) -> int:
    from service.core.checker.check import testcase_label
    from service.core.sim.controllers import CertificateDriver, resolve_driver
    from service.core.sim.replay import evaluate as evaluate_controller

    controllers = args.controller or ["sumo"]
    drivers = [resolve_driver(name) for name in controllers]  # bad names fail before any replay
    rss_params = _rss_params(args.rss_params)
    files = _testcase_files(args.testcases)
    if len(files) == 1 and len(controllers) == 1:  # one verdict: errors are the command's
        testcase = read_input(files[0])
        junction = testcase_intersection(testcase, args, files[0])
        verdict = evaluate_controller(testcase, controllers[0], junction, args.budget,
                                      rss_params).verdict  # fmt: skip
        return _report_evaluations(args, [(verdict, files[0])], [], [], [])
    rows = [["test-case", "file", *controllers]]
    verdicts: list[tuple[Verdict, Path]] = []
    skipped: list[tuple[str, str]] = []  # (test-case, controller): a certificate it lacks
    problems: list[tuple[str, str, ScengenError]] = []  # (test-case, controller, why)
    not_run: list[tuple[str, str]] = []  # (test-case, controller): interrupted before it
    steps = StepProgress(len(files) * len(controllers), "evaluations")
    row: list[str] = []
    try:
        for path in files:
            row = ["-", str(path)]
            try:
                testcase = read_input(path)
                junction = testcase_intersection(testcase, args, path)
            except ScengenError as error:  # this file cannot be evaluated: its row says why
                rows.append([*row, *(["ERROR (below)"] * len(controllers))])
                row = []
                problems.append((str(path), "", error))
                for name in controllers:
                    steps.step(f"{path} / {name}: error")
                continue
            label = _label(testcase_label(testcase), path)
            row = [testcase_label(testcase), str(path)]
            for name, driver in zip(controllers, drivers, strict=True):
                if isinstance(driver, CertificateDriver) and testcase.certificates is None:
                    row.append("(none)")
                    skipped.append((label, name))
                    steps.step(f"{label} / {name}: (none)")
                    continue
                try:
                    verdict = evaluate_controller(
                        testcase, name, junction, args.budget, rss_params
                    ).verdict
                except ScengenError as error:
                    row.append("ERROR (below)")
                    problems.append((label, name, error))
                    steps.step(f"{label} / {name}: error")
                    continue
                verdicts.append((verdict, path))
                cell = "pass" if verdict.passed else "FAIL: " + short(verdict)
                row.append(cell + guard_note(verdict))
                steps.step(f"{label} / {name}: {'pass' if verdict.passed else 'FAIL'}")
            rows.append(row)
            row = []
    except KeyboardInterrupt:  # Ctrl-C: what was judged is reported, the rest is not run
        steps.close()
        _mark_not_run(rows, row, files, controllers, not_run)
        _report_evaluations(args, verdicts, skipped, problems, rows, not_run)
        print(f"scengen: stopped (Ctrl-C) after {len(verdicts)} of "
              f"{len(files) * len(controllers)} evaluations: the rest are not run; run the "
              "same command again for all", file=sys.stderr)  # fmt: skip
        return EXIT_INTERRUPTED
    steps.close()
    return _report_evaluations(args, verdicts, skipped, problems, rows)


def _mark_not_run(
    rows: list[list[str]], row: list[str], files: Sequence[Path], controllers: Sequence[str],
    not_run: list[tuple[str, str]],
) -> None:  # fmt: skip
    """The table's cells (and ``not_run``'s names) of the evaluations an interruption left
    out: the rest of the row it stopped in (``row``, empty when none was begun) and the
    files after it."""
    started = len(rows) - 1 + (1 if row else 0)
    if row:
        path = files[started - 1]
        label = str(path) if row[0] == "-" else _label(row[0], path)
        for name in controllers[len(row) - 2 :]:
            not_run.append((label, name))
        rows.append(row + ["not run"] * (len(controllers) - (len(row) - 2)))
    for path in files[started:]:
        rows.append(["-", str(path), *(["not run"] * len(controllers))])
        not_run += [(str(path), name) for name in controllers]


def _rss_params(path: Path | None) -> dict[str, Any] | None:
    """``--rss-params``: the RSS dynamics file, checked (InvalidInput names the problem)."""
    if path is None:
        return None
    from service.core.inputs import read_json_file
    from service.core.sumo.rss_guard import GuardError, dynamics_from

    params = read_json_file(path, "RSS parameters")  # at most 1 MB, 32 levels deep
    if not isinstance(params, dict):
        raise InvalidInput(f"RSS parameters {path}: expected a JSON object")
    try:
        dynamics_from(params)
    except GuardError as exc:
        raise InvalidInput(f"RSS parameters {path}: {exc}") from None
    return params


def _label(name: str, path: Path) -> str:
    """A test-case as the table's rows, JUnit and progress name it: by its name, its file
    beside it (``four-way level 1 (chain/four-way-1.json)``)."""
    return f"{name} ({path})"


def _testcase_files(paths: Sequence[Path]) -> list[Path]:
    files: list[Path] = []
    for path in paths:
        if path.is_dir():
            found = sorted(path.glob("*.json"))
            if not found:
                raise InvalidInput(f"folder {path} holds no test-case (*.json)")
            files += found
        elif path.exists():
            files.append(path)
        else:
            raise InvalidInput(f"no such test-case file or folder: {path}")
    return files


def _report_evaluations(
    args: argparse.Namespace,
    judged: Sequence[tuple[Verdict, Path]],
    skipped: Sequence[tuple[str, str]],
    problems: Sequence[tuple[str, str, ScengenError]],
    rows: Sequence[Sequence[str]],
    not_run: Sequence[tuple[str, str]] = (),
) -> int:
    """Print the verdicts (one, a table, or JSON), write JUnit, and the overall exit code:
    0 all passed (cells without a certificate to replay do not count), 1 some failed, and,
    when some could not be evaluated at all, 2 if each of those was bad input, else 3.
    Verdicts name their test-case by its name; JUnit and JSON give its file beside it.
    ``not_run``: the evaluations an interruption left out (JUnit: skipped, saying so)."""
    verdicts = [verdict for verdict, _ in judged]
    if args.junit:
        from service.core.checker.verdict import junit_report

        labelled = [dataclasses.replace(v, testcase=_label(v.testcase, path))
                    for v, path in judged]  # fmt: skip
        errors = [(f"{t} / {c}" if c else t, str(e)) for t, c, e in problems]
        skips = [f"{t} / {c}" for t, c in skipped]
        never = [f"{t} / {c}" for t, c in not_run]
        write_output(args.junit, junit_report(labelled, errors=errors, skipped=skips,
                                              not_run=never))  # fmt: skip
    if args.json:
        json.dump([{**v.to_dict(), "file": str(path)} for v, path in judged], sys.stdout,
                  indent=2)  # fmt: skip
        print()
    elif not rows:
        print_verdict(verdicts[0])
    else:
        print_table(rows)
    for testcase, controller, error in problems:  # after the table (stderr with --json)
        where = f"{testcase} / {controller}" if controller else testcase
        print(f"ERROR {where}: {error}", file=sys.stderr if args.json else sys.stdout)
    if rows:
        failed = sum(1 for v in verdicts if not v.passed)
        left = f", {len(not_run)} not run" if not_run else ""
        print(f"{len(verdicts) - failed} passed, {failed} failed, {len(skipped)} without a "
              f"certificate to replay, {len(problems)} could not be evaluated{left}",
              file=sys.stderr)  # fmt: skip
    if problems:
        codes = {exit_code(error) for _, _, error in problems}
        return EXIT_BAD_INPUT if codes == {EXIT_BAD_INPUT} else EXIT_FAILED
    return EXIT_OK if all(v.passed for v in verdicts) else EXIT_FAILED_CHECK
