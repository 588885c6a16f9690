"""The ``scengen`` command line: a thin adapter over ``service.core`` and the service.

``main`` runs the table of commands (service.cli.commands); each command group has a module
(networks, testcases, judging, exports, servers, campaigns) with its commands' arguments
beside their handlers; the arguments they share are defined once (service.cli.arguments).
``submit``, ``campaign_folder`` and ``examples`` do the work behind some of them.

Building the parser imports no heavy library (SUMO's, numpy, shapely, the solvers, pydantic,
the web stack): each handler imports what its work needs, so ``--version``, ``--help`` and
usage errors answer at once and a command pays only for what it uses (issue 49; the check is
tests/cli/test_startup.py). Help texts that need the core name it from light modules
(service.core.names) or are written when shown (service.cli.table.Later).
"""

from __future__ import annotations

import sys
from collections.abc import Sequence

__all__ = ["main"]


def main(argv: Sequence[str] | None = None) -> int:
    """The ``scengen`` command. Its table of commands is imported here, not when this
    package is, so that Ctrl-C while it loads stops it as quietly as Ctrl-C later does
    (service.cli.commands, which also catches it while a handler imports its libraries)."""
    try:
        from service.cli.commands import main as run
    except KeyboardInterrupt:
        print("scengen: stopped (Ctrl-C) while starting", file=sys.stderr)
        return 130  # service.cli.output.EXIT_INTERRUPTED, not imported yet
    return run(argv)
