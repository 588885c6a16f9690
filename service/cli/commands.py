"""The ``scengen`` command line: the table of its commands, and ``main``.

Each command is declared with its arguments beside its handler, in the module of its
group; this table puts them in the order ``scengen --help`` lists them. Errors of the
domain become one line on stderr and an exit code (service.cli.output).
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence
from typing import Any

from service.cli import (
    budgeted,
    campaigns,
    cosim,
    exports,
    judging,
    networks,
    servers,
    testcases,
)
from service.cli.output import (
    EXIT_BAD_INPUT,
    EXIT_INTERRUPTED,
    EXIT_OK,
    check_writable,
    exit_code,
)
from service.cli.table import Command, Parser, build_parser
from service.core.errors import ScengenError

COMMANDS: tuple[Command, ...] = (
    networks.networks,
    networks.intersection,
    testcases.new,
    testcases.drive,
    judging.check,
    testcases.extend,
    testcases.example,
    judging.evaluate,
    cosim.cosim,
    exports.export,
    exports.plot,
    servers.serve,
    servers.worker,
    servers.submit,
    campaigns.campaign,
    campaigns.report,
)


def parser() -> argparse.ArgumentParser:
    table = build_parser(
        COMMANDS,
        prog="scengen",
        description="Intersection test-cases of increasing complexity for autonomous vehicles.",
    )
    table.add_argument(
        "--version", action=ShowVersion, help="show program's version number and exit"
    )
    return table


class ShowVersion(argparse.Action):
    """``--version``, as argparse's own action prints it, but looked up (the package's
    metadata) only when asked for: not on every command's start."""

    def __init__(self, option_strings: Sequence[str], dest: str, **options: Any) -> None:
        super().__init__(option_strings, dest=argparse.SUPPRESS, default=argparse.SUPPRESS,
                         nargs=0, **options)  # fmt: skip

    def __call__(
        self,
        parser: argparse.ArgumentParser,
        namespace: argparse.Namespace,
        values: Any,
        option_string: str | None = None,
    ) -> None:
        print(f"{parser.prog} {version()}")
        parser.exit()


def version() -> str:
    """The installed package's version (and SUMO's, whose drivers and netconvert matter)."""
    from importlib.metadata import PackageNotFoundError
    from importlib.metadata import version as installed

    from service.core.version import package_version

    ours = package_version()
    try:
        return f"{ours} (SUMO {installed('eclipse-sumo')})"
    except PackageNotFoundError:
        return ours


def main(argv: Sequence[str] | None = None) -> int:
    Parser.given = list(sys.argv[1:] if argv is None else argv)
    args = parser().parse_args(argv)
    try:
        for destination, what in args.writes:  # before any work: nothing computed in vain
            if getattr(args, destination) is not None:
                check_writable(getattr(args, destination), what)
        if args.limit is not None and not budgeted.in_command_child():
            return budgeted.run_in_child(Parser.given, args, run_command)
        code: int = args.run(args)
        return code
    except BrokenPipeError:  # the reader (head, less) went away: not an error
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return EXIT_OK
    except ScengenError as exc:
        code = exit_code(exc)
        label = "error" if code == EXIT_BAD_INPUT else "failed"
        print(f"scengen: {label}: {exc}", file=sys.stderr)
        return code
    except KeyboardInterrupt:  # Ctrl-C: a normal way to stop, not a fault
        again = (
            "run the same command to go on where it stopped"
            if args.run.__name__ == "campaign"
            else "nothing half-written is left; run the same command to start again"
        )
        print(f"scengen: stopped (Ctrl-C); {again}", file=sys.stderr)
        return EXIT_INTERRUPTED


def run_command(request: dict[str, Any]) -> tuple[int, bool]:
    """The command's child runs the command here (service.cli.budgeted)."""
    return budgeted.as_the_command(request, main)


if __name__ == "__main__":
    sys.exit(main())
