"""``scengen cosim``: a test-case as a co-simulation over TraCI, the driving stack under test
connected as a second TraCI client and judged by the checker (docs/cosim.md)."""

from __future__ import annotations

import argparse
import math
import sys

from service.cli.arguments import JUNIT, NETWORK_FILE, TESTCASE, read_input, testcase_intersection
from service.cli.judging import JUDGING
from service.cli.output import report_verdict
from service.cli.table import arg, command
from service.core.names import COSIM_BUDGET, COSIM_WAIT


def cosim_limit(args: argparse.Namespace) -> tuple[float, str]:
    """``cosim``'s budget: the wait, the run and ``JUDGING`` (a value the command refuses
    counts as its default here: the refusal comes at once)."""

    def given(value: float, default: float) -> float:
        return value if math.isfinite(value) and value > 0 else default

    seconds = given(args.wait, COSIM_WAIT) + given(args.budget, COSIM_BUDGET) + JUDGING
    return seconds, f"--wait, --budget and {JUDGING:g} s to load and judge"


@command(
    "cosim",
    "run a test-case as a TraCI server for your driving stack and judge it (exit 0 pass, "
    "1 fail, 4 the client's fault)",
    TESTCASE,
    arg("--port", type=int, required=True, metavar="P", help="the port your TraCI client "
        "connects to (0: any free port, printed)"),
    arg("--host", default="127.0.0.1", metavar="H", help="the address to listen on (default "
        "127.0.0.1, this machine only; another address lets other machines drive the ego)"),
    arg("--wait", type=float, default=COSIM_WAIT, metavar="SECONDS", help="how long to wait "
        f"for the client (default {COSIM_WAIT:g} s)"),
    arg("--budget", type=float, default=COSIM_BUDGET, metavar="SECONDS", help="how long the "
        f"run may take once the client came (default {COSIM_BUDGET:g} s)"),
    arg("--json", action="store_true", help="print the verdict as JSON"),
    JUNIT,
    NETWORK_FILE,
    description="Runs the test-case in SUMO as a TraCI server for two clients: scengen (order "
    "1) moves every other road user along its recorded trajectory, your driving stack (order "
    "2) drives the vehicle 'ego' with TraCI commands (or leaves it to SUMO's driver). When "
    "the ego has passed its goal or the test-case's duration is over, SUMO closes the "
    "connection and the ego's trajectory is judged as `evaluate` judges it. Exit codes: 0 "
    "pass, 1 fail, 2 bad input, 3 SUMO failed or the budget ran out, 4 the client never came, "
    "left before the end or took the ego off its route (docs/cosim.md).",
    limit=cosim_limit,
)  # fmt: skip
def cosim(args: argparse.Namespace) -> int:
    from service.core.sim.cosim import cosimulate_testcase

    testcase = read_input(args.testcase)
    intersection = testcase_intersection(testcase, args)

    def say(line: str) -> None:
        print(f"scengen: {line}", file=sys.stderr, flush=True)

    evaluation = cosimulate_testcase(testcase, intersection, args.port, args.host, args.wait,
                                     args.budget, say)  # fmt: skip
    return report_verdict(evaluation.verdict, args.json, args.junit)
