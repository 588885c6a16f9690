"""Campaigns: ``campaign`` (chains grown and judged on this machine) and ``report`` (a
campaign's self-contained HTML report)."""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path
from urllib.parse import quote

from service.cli.arguments import (
    COMMAND_BUDGET,
    NETWORK,
    SIGNALS,
    TOKEN,
    budget,
    by_budget,
    controllers_named,
    output,
    signals_program,
)
from service.cli.output import EXIT_FAILED_CHECK, EXIT_OK, print_table, write_output
from service.cli.table import OneOf, arg, command
from service.core.campaign import CAMPAIGN_DURATION


@command(
    "campaign",
    "grow chains of test-cases and judge every level with controllers: where they fail",
    NETWORK,
    SIGNALS,
    OneOf(
        (
            arg(
                "--ego",
                action="append",
                metavar="FORK_LANE:EXIT_LANE",
                help="an ego route (repeatable)",
            ),
            arg(
                "--all-egos",
                action="store_true",
                help="every route the junction offers (side lanes left out)",
            ),
        ),
        required=True,
    ),
    arg("--depth", type=int, required=True, metavar="K", help="levels (1-10)"),
    arg("--chains", type=int, required=True, metavar="N", help="chains per ego route (1-100)"),
    arg(
        "--controller",
        action="append",
        required=True,
        metavar="NAME",
        help=lambda: f"who drives the ego (repeatable): {controllers_named()}, or module:attribute",
    ),
    arg("--seed", type=int, default=0, help="chain c has seed SEED + c"),
    arg(
        "--duration",
        type=float,
        default=CAMPAIGN_DURATION,
        metavar="SECONDS",
        help=f"how long each test-case lasts (default {CAMPAIGN_DURATION:g} s: room for a "
        "deep chain's ego to wait for the cars added and still leave; 20 s is too short for "
        "SUMO's own driver at a T-junction)",
    ),
    arg(
        "--budget-per-level",
        type=float,
        metavar="SECONDS",
        help="budget of growing one level (default: SCENGEN_EXTEND_BUDGET, 60 s)",
    ),
    arg(
        "--budget",
        type=float,
        metavar="SECONDS",
        help="budget of each replay (default: SCENGEN_EVALUATE_BUDGET, 60 s)",
    ),
    arg(
        "--table",
        choices=("levels", "paper"),
        default="levels",
        help="the failure table printed at the end: a row per level (default), or the "
        "paper's form, a row per controller, each cell the share failed and its most "
        "common cause",
    ),
    arg("--markdown", action="store_true", help="print the paper's table as Markdown"),
    arg(
        "--workers",
        type=int,
        metavar="N",
        help="steps (levels grown, verdicts) run at once, each in a process of its own "
        "(1-64; default: the machine's cores, or SCENGEN_WORKERS); the outcome is the "
        "same for any N",
    ),
    output("DIR", required=True),
    description="Grows CHAINS chains per ego route to DEPTH levels (one new car per level, "
    "on a route chosen as `extend`'s automatic choice does, steered towards rules no "
    "level has covered yet), and evaluates every level, the ego-only start included, "
    "with every controller. Writes campaign.json, junit.xml, report.html and testcases/ "
    "into DIR; run the same command again to resume after a crash or Ctrl-C. Exit "
    "codes: 0 every evaluation passed, 1 some failed, 2 bad input, 3 the campaign "
    "could not run.",
)
def campaign(args: argparse.Namespace) -> int:
    from service.cli.campaign_folder import elapsed_printer, run_folder_campaign
    from service.core.campaign.outcome import (
        campaign_paper_table,
        criticality_table,
        diversity_table,
        failure_table,
    )
    from service.core.sim.controllers import resolve_driver

    if args.major is not None:
        args.usage.error(
            "--major: a campaign takes the junction's own major road (or scengen's choice); "
            "to choose it, make the test-cases with `scengen new --major` and `extend`"
        )
    if args.guess_crossings:
        args.usage.error(
            "--guess-crossings: a campaign grows cars only; to add crossings, make the "
            "test-cases with `scengen new --guess-crossings` and `extend`"
        )
    for name in args.controller:
        resolve_driver(name)  # a bad name fails before any work
    program = signals_program(args)  # so does a program that does not fit the junction
    spec = {
        "network": args.network,
        "junction": args.junction,
        "control": args.control,
        "egos": args.ego,
        "all_egos": args.all_egos,
        "depth": args.depth,
        "chains": args.chains,
        "controllers": args.controller,
        "seed": args.seed,
        "duration": args.duration,
        "budget_per_level": args.budget_per_level,
        "budget": args.budget,
    }
    if program is not None:
        spec["signals"] = program.to_document()
    if args.workers is not None and not 1 <= args.workers <= 64:
        args.usage.error(f"--workers: give 1 to 64 steps at once, not {args.workers}")
    outcome = run_folder_campaign(
        spec, args.output, elapsed_printer(time.monotonic()), args.workers
    )
    if args.markdown:
        sys.stdout.write(campaign_paper_table(outcome).markdown())
    elif args.table == "paper":
        print("the paper's table (failed/test-cases and the most common cause):")
        sys.stdout.write(campaign_paper_table(outcome).text())
    else:
        print("failed test-cases per level (failed/distinct test-cases, share (Wilson 95% "
              "interval)):")  # fmt: skip
        print_table(failure_table(outcome))
    diversity = diversity_table(outcome)
    if diversity is not None:
        print(
            "diversity per level (distinct test-cases, grown, orders of events, routes, "
            "rules the certificates break, new cars' arrival and entry: median (min–max)):"
        )
        print_table(diversity)
    failed = False
    for controller in outcome["plan"]["controllers"]:
        shares = [level["controllers"][controller] for level in outcome["levels"]]
        count, total = sum(s["failed"] for s in shares), sum(s["evaluated"] for s in shares)
        firsts = [c["first_failure"][controller] for c in outcome["chains"]]
        failing = [level for level in firsts if level is not None]
        if not count:
            print(f"{controller}: passed all {total} test-cases")
            continue
        failed = True
        print(f"FAIL {controller}: failed {count} of {total} test-cases; first at level "
              f"{min(failing)}, in {len(failing)} of {len(firsts)} chains")  # fmt: skip
    for controller in outcome["plan"]["controllers"]:
        rows = criticality_table(outcome, controller)
        if rows is None:
            continue
        print(f"criticality of {controller} by level (median (min–max) n=test-cases that "
              "have it):")  # fmt: skip
        print_table(rows)
        print(f"criticality of {controller} "
              f"{outcome['criticality_trend'][controller]['summary']}")  # fmt: skip
    covered = [c["rule"] for c in outcome["coverage"] if c["covered"]]
    missing = [c["rule"] for c in outcome["coverage"] if c["coverable"] and not c["covered"]]
    print(f"rules covered by complexity certificates: {', '.join(covered) or 'none'}; "
          f"not covered: {', '.join(missing) or 'none'}")  # fmt: skip
    for chain in outcome["chains"]:
        if chain["end"]:
            print(f"{chain['ego']} chain {chain['chain'] + 1} ended at {chain['end']}")
    print(f"written: {args.output}/campaign.json, junit.xml, report.html, testcases/")
    return EXIT_FAILED_CHECK if failed else EXIT_OK


@command(
    "report",
    "write a campaign's report as one self-contained HTML file",
    arg("source", metavar="DIR|JOB", help="a campaign folder or a job id"),
    arg("--server", metavar="URL", help="the server of JOB"),
    TOKEN,
    output("FILE", required=True),
    budget(COMMAND_BUDGET, "time for the whole command"),
    description="SOURCE is a folder `scengen campaign` wrote, or a job id on a server "
    "(--server): the report is the results browser with the campaign's data inside; "
    "it opens offline.",
    limit=by_budget,
)
def report(args: argparse.Namespace) -> int:
    if args.server is None:
        from service.cli.campaign_folder import folder_report

        page = folder_report(Path(args.source))
    else:  # the server writes it (GET /jobs/{id}/campaign/report)
        from service.cli import submit

        client = submit.Client(args.server, args.token or os.environ.get("SCENGEN_TOKEN"))
        path = f"/jobs/{quote(args.source, safe='')}/campaign/report"
        page = client.call("GET", path)[2].decode()
    write_output(args.output, page)
    print(f"written: {args.output}", file=sys.stderr)
    return EXIT_OK
