"""The ``scengen`` command line: a thin adapter over ``service.core``.

Exit codes: 0 success (for ``check``: the ego passed), 1 the ego failed (``check``), 2 bad
input (one line on stderr), 3 the work could not be done (SUMO, netconvert or a budget
failed).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any
from urllib.parse import quote

from service.cli.examples import EXAMPLES, run_example, write_testcase
from service.core.checker.check import check_testcase
from service.core.checker.verdict import Verdict, junit_report
from service.core.errors import (
    InvalidInput,
    ScengenError,
    UnknownNetwork,
    UnsupportedIntersection,
)
from service.core.export import FLAVOURS
from service.core.export.bundle import export_bundle
from service.core.generator.extension import StartDistances, extend_testcase
from service.core.motion.events import compute_events
from service.core.motion.poses import PoseSample, generate_poses
from service.core.motion.trajectory import read_trajectory
from service.core.network import ControlType, Intersection, bundled_networks, load_intersection
from service.core.network.describe import describe_intersection
from service.core.sim.controllers import CertificateDriver, controller_names, resolve_driver
from service.core.sim.replay import evaluate as evaluate_controller
from service.core.testcase import (
    TestCase,
    dump_testcase,
    find_network_file,
    name_stem,
    new_testcase,
    read_testcase,
    readable_name,
    renamed,
)

EXIT_OK, EXIT_FAILED_CHECK, EXIT_BAD_INPUT, EXIT_FAILED = 0, 1, 2, 3
CONTROLS = [c.value for c in ControlType]


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="scengen",
        description="Intersection test-cases of increasing complexity for autonomous vehicles.",
    )
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    networks = commands.add_parser("networks", help="list the bundled networks")
    networks.set_defaults(run=_run_networks)

    inter = commands.add_parser(
        "intersection", help="describe a junction: forks, routes, conflicts, right-of relations"
    )
    _network_arguments(inter)
    inter.add_argument("--json", action="store_true", help="print one JSON object")
    inter.add_argument("--plot", type=Path, metavar="FILE", help="also draw it to FILE (.png/.svg)")
    inter.set_defaults(run=_run_intersection)

    new = commands.add_parser("new", help="write an ego-only test-case")
    _network_arguments(new)
    new.add_argument("--ego", required=True, metavar="FORK_LANE:EXIT_LANE", help="ego route")
    new.add_argument(
        "--start-distance",
        type=float,
        default=30.0,
        metavar="M",
        help="ego front bumper before the stop line (default 30 m)",
    )
    new.add_argument(
        "--start-speed",
        type=float,
        default=8.0,
        metavar="V",
        help="ego speed at t = 0 (default 8 m/s)",
    )
    new.add_argument("--duration", type=float, default=20.0, help="seconds (default 20)")
    new.add_argument("--timestep", type=float, default=0.1, help="seconds (default 0.1)")
    new.add_argument(
        "--name",
        default="",
        help="a name for the test-case (default: network, junction, ego route and level, "
        "as in '4way-stop C S2C_1:C2W_1 level 0')",
    )
    new.add_argument("-o", "--output", type=Path, metavar="FILE", help="write here, not stdout")
    new.set_defaults(run=_run_new)

    drive = commands.add_parser(
        "drive", help="Step 1: drive a car alone along a route in SUMO and list its events"
    )
    drive.add_argument("testcase", type=Path, metavar="TESTCASE", help="a test-case JSON file")
    drive.add_argument(
        "--route", metavar="FORK_LANE:EXIT_LANE", help="route to drive (default: the ego's)"
    )
    drive.add_argument(
        "--start-distance",
        type=float,
        metavar="M",
        help="front bumper before the stop line (default: the ego's start)",
    )
    drive.add_argument("--speed", type=float, default=8.0, help="cruise speed (default 8 m/s)")
    drive.add_argument("--json", action="store_true", help="print samples and events as JSON")
    drive.add_argument("--plot", type=Path, metavar="FILE", help="draw the drive to FILE")
    _network_file_argument(drive)
    drive.set_defaults(run=_run_drive)

    check = commands.add_parser(
        "check", help="judge an ego trajectory against a test-case (exit 0 pass, 1 fail)"
    )
    check.add_argument("testcase", type=Path, metavar="TESTCASE", help="a test-case JSON file")
    check.add_argument(
        "--ego",
        required=True,
        type=Path,
        metavar="TRAJECTORY",
        help="the ego's trajectory: JSON samples or a SUMO FCD file (sumo --fcd-output)",
    )
    check.add_argument(
        "--vehicle", default="ego", metavar="ID", help="the ego's id in an FCD file (default ego)"
    )
    check.add_argument(
        "--controller", metavar="NAME", help="name of what drove the ego (default: file name)"
    )
    check.add_argument("--junit", type=Path, metavar="FILE", help="also write JUnit XML here")
    check.add_argument("--json", action="store_true", help="print the verdict as JSON")
    _network_file_argument(check)
    check.set_defaults(run=_run_check)

    extend = commands.add_parser(
        "extend", help="add new non-egos so that the test-case becomes strictly more complex"
    )
    extend.add_argument("testcase", type=Path, metavar="OLD", help="the test-case to extend")
    extend.add_argument(
        "--add",
        action="append",
        required=True,
        metavar="FORK_LANE:EXIT_LANE",
        help="route of a new non-ego (repeat to add several in one extension)",
    )
    extend.add_argument("--seed", type=int, default=0, help="seed of the search (default 0)")
    extend.add_argument(
        "--budget",
        type=float,
        default=60.0,
        metavar="SECONDS",
        help="total time for the extension (default 60 s)",
    )
    extend.add_argument(
        "--start-distance",
        action="append",
        type=_distance_or_auto,
        metavar="M",
        help="a new car's front before its stop line at t = 0 (m), or 'auto'; once for every "
        "new car, or once per --add in the same order (default auto: behind the last car on "
        "its fork, ahead of the ego on the ego's fork, where the ego starts on a free fork)",
    )
    extend.add_argument(
        "--name",
        help="the new test-case's name (default: the old one's with the new level, "
        "'... level 1' after '... level 0')",
    )
    extend.add_argument("-o", "--output", type=Path, metavar="FILE", help="write here")
    _network_file_argument(extend)
    extend.set_defaults(run=_run_extend, usage=extend)

    example = commands.add_parser(
        "example", help="run one of the paper's experiments: a chain of extensions"
    )
    example.add_argument(
        "name",
        choices=sorted(EXAMPLES),
        metavar="NAME",
        help=f"one of {', '.join(sorted(EXAMPLES))}",
    )
    example.add_argument(
        "-o",
        "--output",
        type=Path,
        default=Path("examples-out"),
        metavar="DIR",
        help="folder for the test-cases (default examples-out)",
    )
    example.add_argument("--seed", type=int, default=0)
    example.add_argument(
        "--budget",
        type=float,
        default=120.0,
        metavar="SECONDS",
        help="budget of each extension (default 120 s)",
    )
    example.set_defaults(run=_run_example)

    evaluate = commands.add_parser(
        "evaluate",
        help="replay test-cases in SUMO with ego controllers and judge them",
        description="Replays each test-case in SUMO (non-egos exactly as recorded) with each "
        "controller driving the ego, and judges the ego with the checker. Controllers: "
        + ", ".join(controller_names())
        + ", or a user controller as module:attribute.",
    )
    evaluate.add_argument(
        "testcases",
        type=Path,
        nargs="+",
        metavar="TESTCASE",
        help="test-case JSON files, or folders of them",
    )
    evaluate.add_argument(
        "--controller",
        action="append",
        metavar="NAME",
        help="who drives the ego (repeatable; default sumo)",
    )
    evaluate.add_argument("--junit", type=Path, metavar="FILE", help="also write JUnit XML here")
    evaluate.add_argument("--json", action="store_true", help="print the verdicts as JSON")
    evaluate.add_argument(
        "--budget",
        type=float,
        default=60.0,
        metavar="SECONDS",
        help="time budget of each replay (default 60 s)",
    )
    _network_file_argument(evaluate)
    evaluate.set_defaults(run=_run_evaluate)

    export = commands.add_parser(
        "export",
        help="write a test-case as a SUMO bundle or as OpenSCENARIO + OpenDRIVE",
        description="--format sumo (default): writes into DIR the network, the test-case "
        "JSON, a README, run.py (the replay of `scengen evaluate`: python run.py --controller "
        "NAME writes the ego's FCD) with its plan, vehicle types and routes, and a .sumocfg "
        "for the plain sumo binary (the non-egos' trajectories as FCD for SUMO's fcd-replay "
        "device). --format openscenario: testcase.xodr (ASAM OpenDRIVE), testcase.xosc (ASAM "
        "OpenSCENARIO XML: the non-egos on their trajectories, the ego left to the system "
        "under test), one .xosc per certificate and verdict-rules.md; --flavour carla for "
        "CARLA's ScenarioRunner.",
    )
    export.add_argument("testcase", type=Path, metavar="TESTCASE", help="a test-case JSON file")
    export.add_argument(
        "-o", "--output", type=Path, required=True, metavar="DIR", help="folder to write"
    )
    export.add_argument(
        "--format", choices=("sumo", "openscenario"), default="sumo", help="default: sumo"
    )
    export.add_argument(
        "--flavour",
        choices=FLAVOURS,
        default="asam",
        help="OpenSCENARIO only: asam (1.2, one vertex per time step; default) or carla "
        "(1.0, 20 Hz, the CARLA town by name)",
    )
    _network_file_argument(export)
    export.set_defaults(run=_run_export)

    plot = commands.add_parser(
        "plot",
        help="draw a test-case (and optionally an evaluation) to PNG or SVG, or animate it to GIF",
        description="Draws the intersection with every car's path, the certificates (green "
        "solvability, red complexity) and a time-distance panel with the events. With "
        "--controller, the ego's path from that evaluation and its verdict instead.",
    )
    plot.add_argument("testcase", type=Path, metavar="TESTCASE", help="a test-case JSON file")
    plot.add_argument(
        "-o", "--output", type=Path, required=True, metavar="FILE", help="a .png or .svg file"
    )
    plot.add_argument("--controller", metavar="NAME", help="evaluate this controller and draw it")
    plot.add_argument(
        "--animate",
        action="store_true",
        help="write an animated GIF of the cars moving instead (FILE must end in .gif)",
    )
    _network_file_argument(plot)
    plot.set_defaults(run=_run_plot)

    serve = commands.add_parser(
        "serve",
        help="run the HTTP API (OpenAPI UI at /docs); settings from SCENGEN_* variables",
        description="Runs the HTTP API with uvicorn. With no settings it keeps its state in "
        "./scengen-data (SQLite) and runs work in local worker processes; see the README for "
        "SCENGEN_DATA_DIR, SCENGEN_DATABASE_URL, SCENGEN_WORKERS, SCENGEN_API_TOKEN and more.",
    )
    serve.add_argument("--host", default="127.0.0.1", help="address to bind (default 127.0.0.1)")
    serve.add_argument("--port", type=int, default=8000, help="port (default 8000)")
    serve.add_argument("--data-dir", type=Path, metavar="DIR", help="sets SCENGEN_DATA_DIR")
    serve.add_argument("--workers", type=int, metavar="N", help="sets SCENGEN_WORKERS")
    serve.set_defaults(run=_run_serve)

    worker = commands.add_parser(
        "worker",
        help="run a Celery worker for batch jobs (SCENGEN_EXECUTOR=celery on the server)",
        description="Runs job items sent by a server whose SCENGEN_EXECUTOR is celery. It "
        "reads SCENGEN_BROKER_URL and SCENGEN_DATABASE_URL (the server's database). Each "
        "task runs in a fresh process; a killed worker's items are retried elsewhere.",
    )
    worker.add_argument(
        "--concurrency", type=int, default=1, metavar="N", help="tasks at once (default 1)"
    )
    worker.add_argument("--name", metavar="NAME", help="worker name (default: host and pid)")
    worker.set_defaults(run=_run_worker)

    submit = commands.add_parser(
        "submit",
        help="submit a batch job to a server; with --wait follow it and fetch the results",
        description="Exit codes: 0 every evaluation passed, 1 some evaluation failed, 2 bad "
        "input, 3 the job failed or was cancelled (or the server could not be reached).",
    )
    submit.add_argument("batch", type=Path, metavar="BATCH", help="a .json or .yaml batch file")
    submit.add_argument("--server", required=True, metavar="URL", help="e.g. http://127.0.0.1:8000")
    submit.add_argument("--token", metavar="T", help="the server's API token (or SCENGEN_TOKEN)")
    submit.add_argument("--wait", action="store_true", help="follow the job until it finishes")
    submit.add_argument("--junit", type=Path, metavar="FILE", help="write the JUnit report (waits)")
    submit.add_argument(
        "--out", type=Path, metavar="DIR", help="download every result into DIR (waits)"
    )
    submit.add_argument(
        "--idempotency-key", metavar="KEY", help="resubmitting with the same key is safe"
    )
    submit.set_defaults(run=_run_submit)

    campaign = commands.add_parser(
        "campaign",
        help="grow chains of test-cases and judge every level with controllers: where they fail",
        description="Grows CHAINS chains per ego route to DEPTH levels (one new car per level, "
        "on a route chosen as `extend`'s automatic choice does, steered towards rules no "
        "level has covered yet), and evaluates every level, the ego-only start included, "
        "with every controller. Writes campaign.json, junit.xml, report.html and testcases/ "
        "into DIR; run the same command again to resume after a crash or Ctrl-C. Exit "
        "codes: 0 every evaluation passed, 1 some failed, 2 bad input, 3 the campaign "
        "could not run.",
    )
    _network_arguments(campaign)
    egos = campaign.add_mutually_exclusive_group(required=True)
    egos.add_argument(
        "--ego", action="append", metavar="FORK_LANE:EXIT_LANE", help="an ego route (repeatable)"
    )
    egos.add_argument("--all-egos", action="store_true", help="every route of the junction")
    campaign.add_argument("--depth", type=int, required=True, metavar="K", help="levels (1-10)")
    campaign.add_argument(
        "--chains", type=int, required=True, metavar="N", help="chains per ego route (1-20)"
    )
    campaign.add_argument(
        "--controller", action="append", required=True, metavar="NAME",
        help="who drives the ego (repeatable): " + ", ".join(controller_names())
        + ", or module:attribute",
    )  # fmt: skip
    campaign.add_argument("--seed", type=int, default=0, help="chain c has seed SEED + c")
    campaign.add_argument(
        "--duration", type=float, default=20.0, metavar="SECONDS",
        help="how long each test-case lasts (default 20 s; deep chains need room: try 45)",
    )  # fmt: skip
    campaign.add_argument(
        "--budget-per-level", type=float, metavar="SECONDS",
        help="budget of growing one level (default: SCENGEN_EXTEND_BUDGET, 60 s)",
    )  # fmt: skip
    campaign.add_argument(
        "--budget", type=float, metavar="SECONDS",
        help="budget of each replay (default: SCENGEN_EVALUATE_BUDGET, 60 s)",
    )  # fmt: skip
    campaign.add_argument("-o", "--output", type=Path, required=True, metavar="DIR")
    campaign.set_defaults(run=_run_campaign)

    report = commands.add_parser(
        "report",
        help="write a campaign's report as one self-contained HTML file",
        description="SOURCE is a folder `scengen campaign` wrote, or a job id on a server "
        "(--server): the report is the results browser with the campaign's data inside; "
        "it opens offline.",
    )
    report.add_argument("source", metavar="DIR|JOB", help="a campaign folder or a job id")
    report.add_argument("--server", metavar="URL", help="the server of JOB")
    report.add_argument("--token", metavar="T", help="the server's API token (or SCENGEN_TOKEN)")
    report.add_argument("-o", "--output", type=Path, required=True, metavar="FILE")
    report.set_defaults(run=_run_report)
    return parser


def _network_file_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--network",
        type=Path,
        metavar="FILE",
        help="the .net.xml of a test-case made on a network uploaded to a server (its "
        "network.ref is the server's id; GET /networks/{id}/file downloads it)",
    )


def _intersection(
    testcase: TestCase, args: argparse.Namespace, read_from: Path | None = None
) -> Intersection:
    """The test-case's intersection; its network found next to the file it was read from
    (``read_from``, default the command's TESTCASE), with --network, or among the bundled
    ones. Says on stderr which file it used when it is not a bundled network."""
    source = read_from or getattr(args, "testcase", None)
    near = source.parent if isinstance(source, Path) else None
    try:
        path, how = find_network_file(testcase, args.network, near)
    except UnknownNetwork as error:
        if args.network is not None or testcase.network.ref.endswith((".net.xml", ".xodr", ".osm")):
            raise
        raise UnknownNetwork(
            f"{error}; a test-case from a server names the server's network id: pass the "
            "network's file with --network FILE (GET /networks/{id}/file)"
        ) from None
    if how != "bundled":
        print(f"network {testcase.network.ref}: {path} ({how})", file=sys.stderr)
    return load_intersection(path, testcase.junction, testcase.control)  # hash checked above


def _network_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "network",
        metavar="NET",
        help=f"bundled network ({', '.join(bundled_networks())}), a SUMO .net.xml, or a map "
        "netconvert converts: OpenDRIVE .xodr, OpenStreetMap .osm (lane ids that start with "
        "'-', as OpenDRIVE's right lanes do, go after '=': --ego=-5_0:-7_0)",
    )
    parser.add_argument(
        "--junction",
        metavar="J",
        help="junction id (default: the only junction of a supported type)",
    )
    parser.add_argument(
        "--control",
        choices=CONTROLS,
        metavar="TYPE",
        help=f"override the control type, rebuilt with netconvert: {', '.join(CONTROLS)}",
    )


def _run_serve(args: argparse.Namespace) -> int:
    import uvicorn
    from pydantic import ValidationError

    from service.api import create_app
    from service.settings import Settings

    overrides: dict[str, Any] = {}
    if args.data_dir is not None:
        overrides["data_dir"] = args.data_dir
    if args.workers is not None:
        overrides["workers"] = args.workers
    try:
        settings = Settings(**overrides)
    except ValidationError as error:
        raise InvalidInput(
            f"settings: {error.errors()[0]['loc']}: {error.errors()[0]['msg']}"
        ) from None
    print(
        f"scengen: serving on http://{args.host}:{args.port} (UI at /docs), data in "
        f"{settings.data_dir.resolve()}, {settings.workers} worker(s)",
        file=sys.stderr,
    )
    uvicorn.run(create_app(settings), host=args.host, port=args.port, log_level="info")
    return EXIT_OK


def _run_worker(args: argparse.Namespace) -> int:
    import socket

    from service.jobs.celery_app import start_worker
    from service.settings import get_settings

    settings = get_settings()
    name = args.name or f"scengen-{socket.gethostname()}-{os.getpid()}"
    if settings.database.startswith("sqlite"):
        print(
            f"scengen: warning: the worker uses the SQLite file {settings.database}; it must be "
            "the server's own file (same machine and SCENGEN_DATA_DIR), or set "
            "SCENGEN_DATABASE_URL to the server's PostgreSQL",
            file=sys.stderr,
        )
    print(
        f"scengen: worker {name} on {settings.broker_url}, database {settings.database}",
        file=sys.stderr,
    )
    start_worker(settings, args.concurrency, name)
    return EXIT_OK


def _run_submit(args: argparse.Namespace) -> int:
    from service.cli import submit

    batch = submit.read_batch(args.batch)
    client = submit.Client(args.server, args.token or os.environ.get("SCENGEN_TOKEN"))
    try:
        job = submit.submit(client, batch, args.idempotency_key)
        print(f"scengen: job {job['id']}: {args.server.rstrip('/')}/jobs/{job['id']}",
              file=sys.stderr)  # fmt: skip
        if not (args.wait or args.junit or args.out):
            return EXIT_OK
        job = submit.follow(client, job, sys.stderr)
    except submit.ServerUnreachable as error:
        print(f"scengen: failed: {error}", file=sys.stderr)
        return EXIT_FAILED
    submit.print_failures(job)
    code = submit.outcome(job)  # decided before the downloads, which cannot change it
    try:
        submit.download(client, job, args.junit, args.out)
    except (ScengenError, OSError) as error:
        print(f"scengen: failed: the job {job['state']}, but its results could not be "
              f"fetched: {error}", file=sys.stderr)  # fmt: skip
        return EXIT_FAILED
    return code


def _run_campaign(args: argparse.Namespace) -> int:
    from service.cli.campaign_folder import elapsed_printer, run_folder_campaign
    from service.core.campaign import failure_table

    for name in args.controller:
        resolve_driver(name)  # a bad name fails before any work
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
    outcome = run_folder_campaign(spec, args.output, elapsed_printer(time.monotonic()))
    print("failed test-cases per level (failed/test-cases):")
    _print_table(failure_table(outcome))
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
    covered = [c["rule"] for c in outcome["coverage"] if c["covered"]]
    missing = [c["rule"] for c in outcome["coverage"] if c["coverable"] and not c["covered"]]
    print(f"rules covered by complexity certificates: {', '.join(covered) or 'none'}; "
          f"not covered: {', '.join(missing) or 'none'}")  # fmt: skip
    for chain in outcome["chains"]:
        if chain["end"]:
            print(f"{chain['ego']} chain {chain['chain'] + 1} ended at {chain['end']}")
    print(f"written: {args.output}/campaign.json, junit.xml, report.html, testcases/")
    return EXIT_FAILED_CHECK if failed else EXIT_OK


def _run_report(args: argparse.Namespace) -> int:
    if args.server is None:
        from service.cli.campaign_folder import folder_report

        page = folder_report(Path(args.source))
    else:  # the server writes it (GET /jobs/{id}/campaign/report)
        from service.cli import submit

        client = submit.Client(args.server, args.token or os.environ.get("SCENGEN_TOKEN"))
        path = f"/jobs/{quote(args.source, safe='')}/campaign/report"
        page = client.call("GET", path)[2].decode()
    args.output.write_text(page)
    print(f"written: {args.output}", file=sys.stderr)
    return EXIT_OK


def _run_networks(args: argparse.Namespace) -> int:
    for name, path in bundled_networks().items():
        print(f"{name}\t{path}")
    return EXIT_OK


def _run_intersection(args: argparse.Namespace) -> int:
    intersection = load_intersection(args.network, args.junction, args.control)
    description = describe_intersection(intersection)
    if args.plot:
        from service.pictures.plot import plot_intersection

        plot_intersection(intersection, args.plot)
    if args.json:
        print(json.dumps(description, indent=2))
    else:
        _print_intersection(description)
    return EXIT_OK


def _print_intersection(d: dict[str, Any]) -> None:
    overridden = " (overridden)" if d["control_overridden"] else ""
    print(f"junction {d['junction']}  control {d['control']}{overridden}  network {d['network']}")
    print()
    rows = [["fork", "heading", "stop", "to its right", "opposite"]]
    for f in d["forks"]:
        rows.append(
            [
                f["lane"],
                f"{f['heading']:.1f}",
                "yes" if f["stop_sign"] else "no",
                " ".join(f["to_its_right"]) or "-",
                " ".join(f["opposite"]) or "-",
            ]
        )
    _print_table(rows)
    print()
    rows = [["route", "turn", "conflicts"]]
    for r in d["routes"]:
        rows.append([r["id"], r["turn"], " ".join(r["conflicts"]) or "-"])
    _print_table(rows)


def _print_table(rows: Sequence[Sequence[str]]) -> None:
    widths = [max(len(row[i]) for row in rows) for i in range(len(rows[0]))]
    for row in rows:
        print(
            "  ".join(cell.ljust(width) for cell, width in zip(row, widths, strict=True)).rstrip()
        )


def _run_new(args: argparse.Namespace) -> int:
    testcase = new_testcase(
        args.network,
        args.ego,
        args.junction,
        args.control,
        args.start_distance,
        args.start_speed,
        args.duration,
        args.timestep,
        name=args.name,
    )
    if not args.name:
        testcase = renamed(testcase, readable_name(testcase))
    return _emit(testcase, args.output)


def _emit(testcase: TestCase, output: Path | None) -> int:
    """Write a test-case to ``output``, or to stdout without one."""
    text = dump_testcase(testcase)
    if output:
        output.write_text(text)
        print(f"wrote {output}", file=sys.stderr)
    else:
        sys.stdout.write(text)
    return EXIT_OK


def _run_drive(args: argparse.Namespace) -> int:
    testcase = read_testcase(args.testcase)
    intersection = _intersection(testcase, args)
    route = intersection.route(args.route or testcase.ego.route.id)
    start = testcase.ego.start.distance if args.start_distance is None else args.start_distance
    track = generate_poses(
        intersection,
        [(route, start)],
        args.speed,
        testcase.duration,
        testcase.timestep,
        testcase.ego.length,
        testcase.ego.width,
    )[0]
    events = compute_events(
        track.samples,
        track.length,
        track.width,
        intersection,
        route.fork,
        testcase.params.arrival_distance,
        testcase.params.v_stop,
    )
    if args.plot:
        from service.pictures.plot import plot_intersection

        plot_intersection(intersection, args.plot, [route.id], track.samples)
    if args.json:
        print(
            json.dumps(
                {
                    "route": route.id,
                    "samples": [vars(s) for s in track.samples],
                    "events": [
                        {"kind": e.kind.value, "lane": e.lane, "t": e.time, "distance": e.distance}
                        for e in events
                    ],
                },
                indent=2,
            )
        )
        return EXIT_OK
    print(
        f"route {route.id} ({route.turn.value}), {len(track.samples)} samples, "
        f"{track.samples[-1].distance:.1f} m in {track.samples[-1].t:.1f} s"
    )
    rows = [["t (s)", "distance (m)", "event", "lane"]]
    for e in events:
        rows.append([f"{e.time:.3f}", f"{e.distance:.3f}", e.kind.value, e.lane])
    _print_table(rows)
    return EXIT_OK


def _run_check(args: argparse.Namespace) -> int:
    testcase = read_testcase(args.testcase)
    ego = read_trajectory(args.ego, args.vehicle, testcase.ego.length)
    verdict = check_testcase(
        testcase, ego, args.controller or args.ego.stem, _intersection(testcase, args)
    )
    if args.junit:
        args.junit.write_text(verdict.to_junit())
    if args.json:
        sys.stdout.write(verdict.to_json())
    else:
        _print_verdict(verdict)
    return EXIT_OK if verdict.passed else EXIT_FAILED_CHECK


def _progress(started: float) -> Callable[[str], None]:
    def say(message: str) -> None:
        print(f"[{time.monotonic() - started:6.2f} s] {message}", file=sys.stderr)

    return say


def _distance_or_auto(text: str) -> float | None:
    """A --start-distance value: metres, or None for 'auto'."""
    if text.strip().lower() == "auto":
        return None
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value) or value < 0:
        raise argparse.ArgumentTypeError(f"a distance >= 0 (m) or 'auto', not {text!r}")
    return value


def _start_distances(args: argparse.Namespace) -> StartDistances:
    """--start-distance as extend_testcase takes it: none given, automatic for all; one, for
    every new car; one per --add, for each car in turn. Other counts are a usage error."""
    given: list[float | None] = args.start_distance or []
    if len(given) <= 1:
        return given[0] if given else None
    if len(given) != len(args.add):
        args.usage.error(
            "give --start-distance once (for every new car) or once per --add: "
            f"{len(args.add)} --add, {len(given)} --start-distance"
        )
    return given


def _run_extend(args: argparse.Namespace) -> int:
    start_distance = _start_distances(args)
    old = read_testcase(args.testcase)
    if args.name is not None:
        renamed(old, args.name)  # a name that cannot be stored fails before the search
    started = time.monotonic()
    extension = extend_testcase(
        old,
        args.add,
        args.seed,
        args.budget,
        start_distance,
        _progress(started),
        _intersection(old, args),
    )
    new = extension.testcase
    name = args.name or readable_name(new, name_stem(old.name))
    new = renamed(new, name)
    provenance = new.provenance or {}
    print(
        f"extended in {time.monotonic() - started:.1f} s after {len(extension.attempts)} "
        f"answer sets: added {', '.join(provenance.get('new_nonegos', []))}; the complexity "
        f"certificate {_what_certificate_breaks(provenance)}",
        file=sys.stderr,
    )
    return _emit(new, args.output)


def _what_certificate_breaks(provenance: dict[str, Any]) -> str:
    """How the complexity certificate fails the new test-case: a right-of-way it violates,
    or, for a new car ahead of the ego, the car it drives into."""
    violated = ", ".join(
        f"{v['car']} ({v['rule']})" for v in provenance.get("complexity_certificate_violates", [])
    )
    rear_end = ", ".join(provenance.get("complexity_certificate", {}).get("rear_end", []))
    broken = [f"violates the right-of-way of {violated}"] if violated else []
    broken += [f"drives into {rear_end} (rear-end)"] if rear_end else []
    return " and ".join(broken) or "fails the new test-case"


def _run_example(args: argparse.Namespace) -> int:
    example = EXAMPLES[args.name]
    print(f"{example.name}: {example.about}", file=sys.stderr)
    levels = StepProgress(len(example.steps) + 1, "level")

    def keep(testcase: TestCase) -> None:  # each level is written as soon as it is verified
        print(write_testcase(testcase, args.output), flush=True)
        levels.step(f"{testcase.name} written")

    try:
        run_example(example, args.seed, args.budget, levels.note, keep)
    finally:
        levels.close()
    return EXIT_OK


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


def _run_evaluate(args: argparse.Namespace) -> int:
    controllers = args.controller or ["sumo"]
    drivers = [resolve_driver(name) for name in controllers]  # bad names fail before any replay
    files = _testcase_files(args.testcases)
    if len(files) == 1 and len(controllers) == 1:  # one verdict: errors are the command's
        testcase = read_testcase(files[0])
        junction = _intersection(testcase, args, files[0])
        verdict = evaluate_controller(testcase, controllers[0], junction,
                                      args.budget).verdict  # fmt: skip
        verdict = dataclasses.replace(verdict, testcase=files[0].stem)
        return _report_evaluations(args, [verdict], [], [], [])
    rows = [["test-case", *controllers]]
    verdicts: list[Verdict] = []
    skipped: list[tuple[str, str]] = []  # (test-case, controller): a certificate it lacks
    problems: list[tuple[str, str, ScengenError]] = []  # (test-case, controller, why)
    steps = StepProgress(len(files) * len(controllers), "evaluations")
    for path in files:
        try:
            testcase = read_testcase(path)
            junction = _intersection(testcase, args, path)
        except ScengenError as error:  # this file cannot be evaluated: its row says why
            rows.append([path.stem, *(["ERROR (below)"] * len(controllers))])
            problems.append((path.stem, "", error))
            for name in controllers:
                steps.step(f"{path.stem} / {name}: error")
            continue
        row = [path.stem]
        for name, driver in zip(controllers, drivers, strict=True):
            if isinstance(driver, CertificateDriver) and testcase.certificates is None:
                row.append("(none)")
                skipped.append((path.stem, name))
                steps.step(f"{path.stem} / {name}: (none)")
                continue
            try:
                verdict = evaluate_controller(testcase, name, junction, args.budget).verdict
            except ScengenError as error:
                row.append("ERROR (below)")
                problems.append((path.stem, name, error))
                steps.step(f"{path.stem} / {name}: error")
                continue
            verdict = dataclasses.replace(verdict, testcase=path.stem)
            verdicts.append(verdict)
            row.append("pass" if verdict.passed else "FAIL: " + _short(verdict))
            steps.step(f"{path.stem} / {name}: {'pass' if verdict.passed else 'FAIL'}")
        rows.append(row)
    steps.close()
    return _report_evaluations(args, verdicts, skipped, problems, rows)


def _report_evaluations(
    args: argparse.Namespace,
    verdicts: Sequence[Verdict],
    skipped: Sequence[tuple[str, str]],
    problems: Sequence[tuple[str, str, ScengenError]],
    rows: Sequence[Sequence[str]],
) -> int:
    """Print the verdicts (one, a table, or JSON), write JUnit, and the overall exit code:
    0 all passed (cells without a certificate to replay do not count), 1 some failed, and,
    when some could not be evaluated at all, 2 if each of those was bad input, else 3."""
    if args.junit:
        errors = [(f"{t} / {c}" if c else t, str(e)) for t, c, e in problems]
        skips = [f"{t} / {c}" for t, c in skipped]
        args.junit.write_text(junit_report(verdicts, errors=errors, skipped=skips))
    if args.json:
        json.dump([v.to_dict() for v in verdicts], sys.stdout, indent=2)
        print()
    elif not rows:
        _print_verdict(verdicts[0])
    else:
        _print_table(rows)
    for testcase, controller, error in problems:  # after the table (stderr with --json)
        where = f"{testcase} / {controller}" if controller else testcase
        print(f"ERROR {where}: {error}", file=sys.stderr if args.json else sys.stdout)
    if rows:
        failed = sum(1 for v in verdicts if not v.passed)
        print(f"{len(verdicts) - failed} passed, {failed} failed, {len(skipped)} without a "
              f"certificate to replay, {len(problems)} could not be evaluated",
              file=sys.stderr)  # fmt: skip
    if problems:
        codes = {exit_code(error) for _, _, error in problems}
        return EXIT_BAD_INPUT if codes == {EXIT_BAD_INPUT} else EXIT_FAILED
    return EXIT_OK if all(v.passed for v in verdicts) else EXIT_FAILED_CHECK


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


def _run_export(args: argparse.Namespace) -> int:
    testcase = read_testcase(args.testcase)
    if args.format == "openscenario":
        from service.core.export.openscenario import (
            export_openscenario,  # scenariogeneration: 0.5 s
        )

        for path in export_openscenario(
            testcase, args.output, _intersection(testcase, args), args.flavour
        ):
            print(path)
        print(
            f"play it: esmini --window 60 60 800 400 --osc {args.output}/testcase.xosc; "
            f"the verdict rules: {args.output}/verdict-rules.md",
            file=sys.stderr,
        )
        return EXIT_OK
    for path in export_bundle(testcase, args.output, _intersection(testcase, args)):
        print(path)
    print(
        f"run it: cd {args.output} && python run.py --controller sumo "
        "(or plain sumo: sumo -c testcase.sumocfg; see its README.md)",
        file=sys.stderr,
    )
    return EXIT_OK


def _run_plot(args: argparse.Namespace) -> int:
    suffixes = (".gif",) if args.animate else (".png", ".svg")
    if args.output.suffix.lower() not in suffixes:
        raise InvalidInput(
            f"plot file must end in {' or '.join(suffixes)}, got {args.output.name!r}"
        )
    from service.pictures.plot import (  # matplotlib only when drawing
        animate_testcase,
        plot_testcase,
    )

    testcase = read_testcase(args.testcase)
    junction = _intersection(testcase, args)
    if args.animate:
        trajectory: list[PoseSample] = []
        label = ""
        if args.controller:
            trajectory = evaluate_controller(testcase, args.controller, junction).trajectory
            label = f"ego: {args.controller}"
        frames: list[StepProgress] = []

        def drawn(frame: int, total: int) -> None:  # matplotlib counts the frames it saves
            if not frames:
                frames.append(StepProgress(total, "frames", lines_every=10))
            frames[0].step(f"frame {frame + 1} of {total}")

        animate_testcase(testcase, junction, args.output, trajectory, label, progress=drawn)
        for bar in frames:
            bar.close()
    elif args.controller:
        evaluation = evaluate_controller(testcase, args.controller, junction)
        plot_testcase(testcase, junction, args.output, evaluation.trajectory,
                      f"ego: {args.controller}", evaluation.verdict)  # fmt: skip
    else:
        plot_testcase(testcase, junction, args.output)
    print(args.output)
    return EXIT_OK


def _short(verdict: Verdict) -> str:
    """The first reason of a failed verdict, in a few words."""
    if verdict.errors:
        return "controller error"
    if verdict.collisions:
        return f"collides with {verdict.collisions[0].other}"
    if verdict.violations:
        v = verdict.violations[0]
        return f"{v.rule}" + (f" of {v.other}" if v.other else "")
    return "did not reach its exit"


def _print_verdict(verdict: Verdict) -> None:
    status = "PASS" if verdict.passed else "FAIL"
    print(f"{status}  {verdict.testcase} / {verdict.controller}")
    if verdict.goal_time is not None:
        print(f"  reached its exit at {verdict.goal_time:.2f} s")
    for reason in verdict.reasons:
        print(f"  {reason}")


def exit_code(error: ScengenError) -> int:
    """The exit code for a domain error: the one place where errors become exit codes."""
    if isinstance(error, InvalidInput | UnsupportedIntersection):
        return EXIT_BAD_INPUT
    return EXIT_FAILED


def main(argv: Sequence[str] | None = None) -> int:
    parser = _parser()
    args = parser.parse_args(argv)
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
