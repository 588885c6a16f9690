"""A test-case as files: ``export`` (a SUMO bundle, or OpenSCENARIO and OpenDRIVE) and
``plot`` (a picture or an animation)."""

from __future__ import annotations

import argparse
import sys
import time
from typing import TYPE_CHECKING

from service.cli.arguments import (
    COMMAND_BUDGET,
    NETWORK_FILE,
    TESTCASE,
    budget,
    by_budget,
    output,
    read_input,
    testcase_intersection,
)
from service.cli.output import EXIT_OK, StepProgress, make_folder, output_file, progress
from service.cli.table import arg, command
from service.core.errors import InvalidInput
from service.core.export import FLAVOURS

if TYPE_CHECKING:  # Step 1's samples (libsumo's module) load when a picture is drawn
    from service.core.motion.poses import PoseSample


@command(
    "export",
    "write a test-case as a SUMO bundle or as OpenSCENARIO + OpenDRIVE",
    TESTCASE,
    output("DIR", "folder to write", required=True),
    arg("--format", choices=("sumo", "openscenario"), default="sumo", help="default: sumo"),
    arg(
        "--flavour",
        choices=FLAVOURS,
        default="asam",
        help="OpenSCENARIO only: asam (1.2, one vertex per time step; default) or carla "
        "(1.0, 20 Hz, the CARLA town by name)",
    ),
    NETWORK_FILE,
    budget(COMMAND_BUDGET, "time for the whole command"),
    description="--format sumo (default): writes into DIR the network, the test-case "
    "JSON, a README, run.py (the replay of `scengen evaluate`: python run.py --controller "
    "NAME writes the ego's FCD) with its plan, vehicle types and routes, and a .sumocfg "
    "for the plain sumo binary (the non-egos' trajectories as FCD for SUMO's fcd-replay "
    "device). --format openscenario: testcase.xodr (ASAM OpenDRIVE), testcase.xosc (ASAM "
    "OpenSCENARIO XML: the non-egos on their trajectories, the ego left to the system "
    "under test; at a signalized junction the signal program as a "
    "TrafficSignalController over the network's signal heads), one .xosc per certificate "
    "and verdict-rules.md; --flavour carla for CARLA's ScenarioRunner.",
    limit=by_budget,
)
def export(args: argparse.Namespace) -> int:
    from service.core.export.bundle import export_bundle

    testcase = read_input(args.testcase)
    make_folder(args.output)
    if args.format == "openscenario":
        from service.core.export.openscenario import export_openscenario  # scenariogeneration

        for path in export_openscenario(
            testcase, args.output, testcase_intersection(testcase, args), args.flavour
        ):
            print(path)
        print(
            f"play it: esmini --window 60 60 800 400 --osc {args.output}/testcase.xosc; "
            f"the verdict rules: {args.output}/verdict-rules.md",
            file=sys.stderr,
        )
        return EXIT_OK
    for path in export_bundle(testcase, args.output, testcase_intersection(testcase, args)):
        print(path)
    print(
        f"run it: cd {args.output} && python run.py --controller sumo "
        "(or plain sumo: sumo -c testcase.sumocfg; see its README.md)",
        file=sys.stderr,
    )
    return EXIT_OK


@command(
    "plot",
    "draw a test-case (and optionally an evaluation) to PNG or SVG, or animate it to GIF",
    TESTCASE,
    output("FILE", "a .png or .svg file", required=True),
    arg("--controller", metavar="NAME", help="evaluate this controller and draw it"),
    arg(
        "--animate",
        action="store_true",
        help="write an animated GIF of the cars moving instead (FILE must end in .gif)",
    ),
    NETWORK_FILE,
    budget(COMMAND_BUDGET, "time for the whole command, an evaluation with --controller included"),
    description="Draws the intersection with every car's path, the certificates (green "
    "solvability, red complexity) and a time-distance panel with the events. With "
    "--controller, the ego's path from that evaluation and its verdict instead.",
    limit=by_budget,
)
def plot(args: argparse.Namespace) -> int:
    suffixes = (".gif",) if args.animate else (".png", ".svg")
    if args.output.suffix.lower() not in suffixes:
        hint = {".gif": "; an animated GIF needs --animate",
                ".png": "; --animate writes a GIF", ".svg": "; --animate writes a GIF"}  # fmt: skip
        raise InvalidInput(
            f"plot file must end in {' or '.join(suffixes)}, got {args.output.name!r}"
            f"{hint.get(args.output.suffix.lower(), '')}"
        )
    say = progress(time.monotonic())
    from service.core.sim.replay import evaluate as evaluate_controller
    from service.pictures.animation import animate_testcase  # matplotlib: on use
    from service.pictures.junction import save
    from service.pictures.plot import draw_testcase

    testcase = read_input(args.testcase)
    junction = testcase_intersection(testcase, args)
    walkers = f" and {len(testcase.pedestrians)} pedestrians" if testcase.pedestrians else ""
    say(f"read {args.testcase.name}: junction {testcase.junction}, "
        f"{len(testcase.nonegos)} cars besides the ego{walkers}")  # fmt: skip
    trajectory: list[PoseSample] = []
    verdict = None
    if args.controller:
        say(f"evaluating {args.controller}")
        evaluation = evaluate_controller(testcase, args.controller, junction)
        trajectory, verdict = evaluation.trajectory, evaluation.verdict
        say(f"{args.controller}: {'PASS' if verdict.passed else 'FAIL'}")
    label = f"ego: {args.controller}" if args.controller else ""
    if args.animate:
        frames: list[StepProgress] = []

        def drawn(frame: int, total: int) -> None:  # matplotlib counts the frames it saves
            if not frames:
                frames.append(StepProgress(total, "frames", lines_every=10))
            frames[0].step(f"frame {frame + 1} of {total}")

        with output_file(args.output) as picture:
            animate_testcase(testcase, junction, picture, trajectory, label, progress=drawn)
        for bar in frames:
            bar.close()
    else:
        figure = draw_testcase(testcase, junction, trajectory, label, verdict, say)
        say(f"writing {args.output}")
        with output_file(args.output) as picture:
            save(figure, picture)
    print(args.output)
    return EXIT_OK
