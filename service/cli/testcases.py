"""Making test-cases: ``new`` (ego only), ``drive`` (Step 1 alone), ``extend`` (one more
complex) and ``example`` (the paper's chains)."""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from service.cli.arguments import (
    COMMAND_BUDGET,
    NETWORK,
    NETWORK_FILE,
    SIGNALS,
    TESTCASE,
    budget,
    by_budget,
    distance_or_auto,
    locate_network,
    output,
    read_input,
    signals_program,
    testcase_intersection,
)
from service.cli.examples import (
    EXAMPLES,
    WORKER_SLACK,
    evaluate_levels,
    run_example,
    write_testcase,
)
from service.cli.output import EXIT_OK, StepProgress, emit, output_file, print_table, progress
from service.cli.table import arg, command
from service.core.campaign.paper_table import PAPER_CONTROLLERS
from service.core.names import (
    DEFAULT_START_DISTANCE,
    DEFAULT_START_SPEED,
    MAX_COUNT,
    REPLAY_BUDGET,
    bundled_networks,
)

if TYPE_CHECKING:  # the generator, Step 1 and the test-case's models load in the handlers
    from service.core.generator.additions import StartDistances
    from service.core.generator.extension import Extension
    from service.core.network import Intersection
    from service.core.testcase import TestCase


@command(
    "new",
    "write an ego-only test-case",
    NETWORK,
    SIGNALS,
    arg("--ego", required=True, metavar="FORK_LANE:EXIT_LANE", help="ego route"),
    arg(
        "--start-distance",
        type=float,
        metavar="M",
        help=f"ego front bumper before the stop line (default {DEFAULT_START_DISTANCE:g} m, or "
        "the whole road before the fork where it is shorter)",
    ),
    arg(
        "--start-speed",
        type=float,
        metavar="V",
        help=f"ego speed at t = 0 (default {DEFAULT_START_SPEED:g} m/s, or the speed limit of "
        "the lane it starts on where that is lower; at most that limit and v_max)",
    ),
    arg("--duration", type=float, default=20.0, help="seconds (default 20)"),
    arg("--timestep", type=float, default=0.1, help="seconds (default 0.1)"),
    arg(
        "--name",
        default="",
        help="a name for the test-case (default: network, junction, ego route and level, "
        "as in '4way-stop C S2C_1:C2W_1 level 0')",
    ),
    output("FILE", "write here, not stdout"),
    budget(COMMAND_BUDGET, "time for the whole command"),
    limit=by_budget,
)
def new(args: argparse.Namespace) -> int:
    from service.core.testcase import new_testcase, readable_name, renamed

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
        major_road=args.major,
        signals=signals_program(args),
        guess_crossings=args.guess_crossings,
    )
    if args.signals is None and testcase.signals is not None and testcase.signals.note:
        print(f"scengen: note: {testcase.signals.note}", file=sys.stderr)
    start = testcase.ego.start.distance
    if args.start_distance is None and start < DEFAULT_START_DISTANCE:
        print(
            f"ego start: {start:g} m before the stop line, the whole road before fork "
            f"{testcase.ego.route.fork} (the default {DEFAULT_START_DISTANCE:g} m does not fit)",
            file=sys.stderr,
        )
    if not args.name:
        testcase = renamed(testcase, readable_name(testcase))
    network_file = None if args.network in bundled_networks() else Path(args.network)
    return emit(testcase, args.output, network_file)


@command(
    "drive",
    "Step 1: drive a car alone along a route in SUMO and list its events",
    TESTCASE,
    arg("--route", metavar="FORK_LANE:EXIT_LANE", help="route to drive (default: the ego's)"),
    arg(
        "--start-distance",
        type=float,
        metavar="M",
        help="front bumper before the stop line (default: the ego's start)",
    ),
    arg("--speed", type=float, default=8.0, help="cruise speed (default 8 m/s)"),
    arg("--json", action="store_true", help="print samples and events as JSON"),
    arg("--plot", type=Path, metavar="FILE", writes="file", help="draw the drive to FILE"),
    NETWORK_FILE,
    budget(COMMAND_BUDGET, "time for the whole command"),
    limit=by_budget,
)
def drive(args: argparse.Namespace) -> int:
    from service.core.motion.events import compute_events
    from service.core.motion.poses import generate_poses

    testcase = read_input(args.testcase)
    intersection = testcase_intersection(testcase, args)
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
    samples = track.at_time_steps(testcase.timestep)
    if args.plot:
        from service.pictures.junction import plot_intersection

        with output_file(args.plot) as picture:
            plot_intersection(intersection, picture, [route.id], samples)
    if args.json:
        print(
            json.dumps(
                {
                    "route": route.id,
                    "samples": [vars(s) for s in samples],
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
        f"route {route.id} ({route.turn.value}), {len(samples)} samples, "
        f"{samples[-1].distance:.1f} m in {samples[-1].t:.1f} s"
    )
    rows = [["t (s)", "distance (m)", "event", "lane"]]
    for e in events:
        rows.append([f"{e.time:.3f}", f"{e.distance:.3f}", e.kind.value, e.lane])
    print_table(rows)
    return EXIT_OK


def extension_count(text: str) -> int:
    """``--count``: a whole number from 1 to MAX_COUNT."""
    try:
        count = int(text)
    except ValueError:
        count = 0
    if not 1 <= count <= MAX_COUNT:
        raise argparse.ArgumentTypeError(
            f"{text!r}: a whole number of extensions from 1 to {MAX_COUNT}"
        )
    return count


@command(
    "extend",
    "add new non-egos so that the test-case becomes strictly more complex",
    arg("testcase", type=Path, metavar="OLD", help="the test-case to extend"),
    arg(
        "--add",
        action="append",
        default=[],
        metavar="FORK_LANE:EXIT_LANE",
        help="route of a new car (repeat to add several in one extension)",
    ),
    arg(
        "--add-pedestrian",
        action="append",
        default=[],
        metavar="WALK",
        help="walk of a new pedestrian: a crossing and its direction, as `scengen "
        "intersection` lists them (C_c0+; repeatable, mixable with --add)",
    ),
    arg("--seed", type=int, default=0, help="seed of the search (default 0)"),
    budget(60.0, "time for the search, after which the whole command is stopped within 2 s"),
    arg(
        "--start-distance",
        action="append",
        type=distance_or_auto,
        metavar="M",
        help="a new car's front before its stop line at t = 0 (m), or 'auto'; once for every "
        "new car, or once per --add in the same order (default auto: behind the last car on "
        "its fork, ahead of the ego on the ego's fork, where the ego starts on a free fork; "
        "never further back than the road before the fork goes)",
    ),
    arg(
        "--count",
        type=extension_count,
        default=1,
        metavar="N",
        help=f"up to N distinct extensions (1 to {MAX_COUNT}; default 1), written as "
        "FILE-1.json ... FILE-N.json for -o FILE.json and named '... variant K level N'",
    ),
    arg(
        "--name",
        help="the new test-case's name (default: the old one's with the new level, "
        "'... level 1' after '... level 0')",
    ),
    output("FILE", "write here"),
    NETWORK_FILE,
    limit=by_budget,
)
def extend(args: argparse.Namespace) -> int:
    from service.core.generator.extension import extend_testcase
    from service.core.network import load_intersection
    from service.core.testcase import name_stem, readable_name, renamed, under_testcase_signals

    if not args.add and not args.add_pedestrian:
        args.usage.error(
            "name what to add: --add FORK_LANE:EXIT_LANE (a car) or --add-pedestrian WALK "
            "(a pedestrian), each repeatable"
        )
    start_distance = start_distances(args)
    if args.count > 1 and args.output is None:
        args.usage.error(
            f"--count {args.count} writes {args.count} files: give -o FILE.json "
            "(they are written as FILE-1.json, FILE-2.json, ...)"
        )
    old = read_input(args.testcase)
    if args.name is not None:
        renamed(old, args.name)  # a name that cannot be stored fails before the search
    network_file = locate_network(old, args)
    intersection = under_testcase_signals(
        load_intersection(
            network_file,
            old.junction,
            old.control,
            major_road=old.major_road,
            guess_crossings=old.crossings_guessed,
        ),
        old,
    )
    started = time.monotonic()
    if args.count > 1:
        return _extend_variants(args, old, start_distance, intersection, network_file, started)
    extension = extend_testcase(
        old, args.add, args.seed, args.budget, start_distance, progress(started), intersection,
        walks=args.add_pedestrian,
    )  # fmt: skip
    name = args.name or readable_name(extension.testcase, name_stem(old.name))
    extended = renamed(extension.testcase, name)
    provenance = extended.provenance or {}
    print(
        f"extended in {time.monotonic() - started:.1f} s after {len(extension.attempts)} "
        f"answer sets: added {', '.join(provenance.get('new_nonegos', []))}; the complexity "
        f"certificate {_what_certificate_breaks(provenance)}",
        file=sys.stderr,
    )
    return emit(extended, args.output, network_file)


def _extend_variants(
    args: argparse.Namespace,
    old: TestCase,
    start_distance: StartDistances,
    intersection: Intersection,
    network_file: Path,
    started: float,
) -> int:
    """``extend --count N`` (N > 1): up to N distinct extensions, each written to
    ``FILE-K.json`` and named as variant K, with a line on stderr saying what tells it from
    the others, and why fewer came back when they did."""
    from service.core.generator.extension import extend_testcases
    from service.core.generator.variety import describe_variants

    extensions = extend_testcases(
        old, args.add, args.count, args.seed, args.budget, start_distance, progress(started),
        intersection, walks=args.add_pedestrian,
    )  # fmt: skip
    found = extensions.found
    print(
        f"extended in {time.monotonic() - started:.1f} s after {extensions.orders_tried} "
        f"answer sets: {len(found)} distinct extensions of {args.count} asked for",
        file=sys.stderr,
    )
    differences = describe_variants([e.testcase for e in found])
    for number, (extension, difference) in enumerate(zip(found, differences, strict=True), 1):
        path = _variant_path(args.output, number)
        print(f"{path.name}: {difference}", file=sys.stderr)
        emit(_variant(extension, old, args.name, number), path, network_file)
    shortfall = extensions.shortfall(args.count)
    if shortfall is not None:
        print(shortfall, file=sys.stderr)
    return EXIT_OK


def _variant_path(output: Path, number: int) -> Path:
    """Where variant ``number`` of ``-o FILE.json`` goes: ``FILE-K.json`` beside it."""
    return output.with_name(f"{output.stem}-{number}{output.suffix}")


def _variant(extension: Extension, old: TestCase, name: str | None, number: int) -> TestCase:
    """Variant ``number`` of the extensions, named as ``variety.variant_name`` says after
    ``--name`` or the default (the old name with the new level)."""
    from service.core.generator.variety import variant_name
    from service.core.testcase import name_stem, readable_name, renamed

    chosen = name or readable_name(extension.testcase, name_stem(old.name))
    return renamed(extension.testcase, variant_name(chosen, number))


def start_distances(args: argparse.Namespace) -> StartDistances:
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


def controller_list(text: str) -> tuple[str, ...]:
    """``A,B``: controllers named once each (a name is checked when the work starts)."""
    names = tuple(name.strip() for name in text.split(","))
    if not all(names) or len(set(names)) != len(names):
        raise argparse.ArgumentTypeError(f"{text!r}: controllers separated by commas, each once")
    return names


def example_limit(args: argparse.Namespace) -> tuple[float, str]:
    """``example``'s budget: each extension's ``--budget``, and each replay's."""
    chosen = EXAMPLES[args.name]
    controllers = () if args.no_evaluate else (args.controllers or chosen.controllers)
    replays = (len(chosen.steps) + 1) * len(controllers)
    replay = REPLAY_BUDGET + WORKER_SLACK
    seconds = args.budget * len(chosen.steps) + replay * replays
    return seconds, (f"--budget {args.budget:g} s for each of {len(chosen.steps)} extensions "
                     f"and {replay:g} s for each of {replays} replays")  # fmt: skip


@command(
    "example",
    "run one of the paper's experiments: a chain of extensions, then the paper's table",
    arg(
        "name",
        choices=sorted(EXAMPLES),
        metavar="NAME",
        help=f"one of {', '.join(sorted(EXAMPLES))}",
    ),
    output("DIR", "folder for the test-cases (default examples-out)", default=Path("examples-out")),
    arg("--seed", type=int, default=0),
    budget(120.0, "time for each extension"),
    arg(
        "--controllers",
        type=controller_list,
        default=None,
        metavar="A,B",
        help=f"who drives the ego on every level (default {','.join(PAPER_CONTROLLERS)}: "
        "the paper's autopilot and autopilot-plus-RSS; crosswalk adds sumo-aggressive)",
    ),
    arg("--no-evaluate", action="store_true", help="write the levels only, evaluate none"),
    arg("--markdown", action="store_true", help="print the table as Markdown"),
    description="Writes every level of the example's chain to DIR as it is verified, then "
    "replays every level (the ego-only one included) with each controller and prints the "
    "paper's table: a row per controller, a column per level, each cell pass or why it "
    "failed (FAIL LAW CAR for a rule, FAIL collision CAR, FAIL goal, FAIL error). Exit 0 "
    "when the chain was made and judged, whatever the verdicts: they are the experiment's "
    "findings.",
    limit=example_limit,
)
def example(args: argparse.Namespace) -> int:
    from service.core.sim.controllers import resolve_driver

    chosen = EXAMPLES[args.name]
    controllers = () if args.no_evaluate else (args.controllers or chosen.controllers)
    for name in controllers:
        resolve_driver(name)  # a bad name fails before any work
    print(f"{chosen.name}: {chosen.about}", file=sys.stderr)
    count = len(chosen.steps) + 1
    levels = StepProgress(count * (1 + len(controllers)), "step")

    def keep(testcase: TestCase) -> None:  # each level is written as soon as it is verified
        levels.print(str(write_testcase(testcase, args.output)))
        levels.step(f"{testcase.name} written")

    try:
        chain = run_example(chosen, args.seed, args.budget, levels.note, keep)
        table = evaluate_levels(chain, controllers, on_verdict=levels.step) if controllers else None
    finally:
        levels.close()
    if table is not None:
        print(f"{chosen.name}, the paper's table (seed {args.seed}):")
        sys.stdout.write(table.markdown() if args.markdown else table.text())
    return EXIT_OK
