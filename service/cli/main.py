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

from service.cli import campaigns, exports, judging, networks, servers, testcases
from service.cli.output import EXIT_BAD_INPUT, EXIT_OK, exit_code
from service.cli.table import Command, build_parser
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
    exports.export,
    exports.plot,
    servers.serve,
    servers.worker,
    servers.submit,
    campaigns.campaign,
    campaigns.report,
)


def parser() -> argparse.ArgumentParser:
    return build_parser(
        COMMANDS,
        prog="scengen",
        description="Intersection test-cases of increasing complexity for autonomous vehicles.",
    )


def main(argv: Sequence[str] | None = None) -> int:
    args = parser().parse_args(argv)
    try:
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


if __name__ == "__main__":
    sys.exit(main())
