"""Arguments that several commands share, defined once, and what they mean.

``NETWORK`` names a junction (a network, ``--junction``, ``--control``, ``--major``,
``--guess-crossings``); ``NETWORK_FILE``
(``--network``) finds the network of a test-case read from a file, which
``testcase_intersection`` loads.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from service.cli.table import Argument, Writes, arg
from service.core.errors import UnknownNetwork
from service.core.names import ControlType, bundled_networks

if TYPE_CHECKING:  # the network and the test-case load sumolib, numpy and pydantic: on use
    from service.core.network import Intersection, SignalProgram
    from service.core.testcase import TestCase

CONTROLS = [c.value for c in ControlType]
COMMAND_BUDGET = 300.0  # s: the budget of a command whose work has no budget of its own

NETWORK = (
    arg(
        "network",
        metavar="NET",
        help=f"bundled network ({', '.join(bundled_networks())}), a SUMO .net.xml, or a map "
        "netconvert converts: OpenDRIVE .xodr, OpenStreetMap .osm (lane ids that start with "
        "'-', as OpenDRIVE's right lanes do, go after '=': --ego=-5_0:-7_0)",
    ),
    arg(
        "--junction",
        metavar="J",
        help="junction id (default: the only junction of a supported type)",
    ),
    arg(
        "--control",
        choices=CONTROLS,
        metavar="TYPE",
        help=f"override the control type, rebuilt with netconvert: {', '.join(CONTROLS)}",
    ),
    arg(
        "--major",
        type=lambda text: edge_pair(text),
        metavar="EDGE,EDGE",
        help="priority_stop, priority: the two roads into the junction (edge ids) that keep "
        "the right of way, the others stop or yield (default: the network's; for a junction "
        "made priority_stop or priority whose roads all have the same priority, the two "
        "closest to straight across)",
    ),
    arg(
        "--guess-crossings",
        action="store_true",
        help="add sidewalks and pedestrian crossings, rebuilt with netconvert "
        "(--sidewalks.guess --crossings.guess): the junction gets walks; every car lane's "
        "index moves up by one (S2C_1 becomes S2C_2), as the sidewalk becomes lane 0",
    ),
)


SIGNALS = arg(
    "--signals",
    type=Path,
    metavar="FILE",
    help="a traffic_light junction: its fixed-time program, replacing the network's: a SUMO "
    'file with a <tlLogic type="static"> (an additional file, a .tll.xml or a .net.xml: the '
    "junction's traffic light is taken where there are several) or scengen's JSON "
    '({"tls", "program", "offset", "phases": [{"duration", "state"}]}, the test-case\'s '
    "signals field)",
)


def signals_program(args: argparse.Namespace) -> SignalProgram | None:
    """The program of ``--signals FILE`` for the junction the command names (NETWORK):
    read for the junction's traffic light (a file with several, such as a network, gives
    that light's) and checked against the junction before any work (InvalidInput naming
    the problem). None without --signals."""
    if args.signals is None:
        return None
    from service.core.network import load_intersection, with_signals
    from service.core.network.signals import read_signals_file

    intersection = load_intersection(
        args.network,
        args.junction,
        args.control,
        major_road=args.major,
        guess_crossings=args.guess_crossings,
    )
    program = read_signals_file(args.signals, intersection.tls)
    with_signals(intersection, program)  # a program for another light or link count fails
    return program


def edge_pair(text: str) -> list[str]:
    """A --major value: two edge ids, comma-separated."""
    edges = [edge.strip() for edge in text.split(",")]
    if len(edges) != 2 or not all(edges):
        raise argparse.ArgumentTypeError(
            f"two edge ids separated by a comma (EDGE,EDGE), not {text!r}"
        )
    return edges


NETWORK_FILE = arg(
    "--network",
    type=Path,
    metavar="FILE",
    help="the test-case's network file, when the test-case cannot find it itself (see the "
    "README: where a test-case's network is found; a test-case from a server names the "
    "server's network id: GET /networks/{id}/file)",
)
TESTCASE = arg("testcase", type=Path, metavar="TESTCASE", help="a test-case JSON file")
JUNIT = arg("--junit", type=Path, metavar="FILE", writes="file", help="also write JUnit XML here")
TOKEN = arg("--token", metavar="T", help="the server's API token (or SCENGEN_TOKEN)")


def seconds(text: str) -> float:
    """A budget: a number of seconds above 0."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"{text!r}: a number of seconds above 0")
    return value


def budget(default: float, what: str) -> Argument:
    """``--budget SECONDS``: the time ``what`` may take (service.cli.budgeted)."""
    return arg(
        "--budget",
        type=seconds,
        default=default,
        metavar="SECONDS",
        help=f"{what} (default {default:g} s); exit 3 when it runs out",
    )


def by_budget(args: argparse.Namespace) -> tuple[float, str]:
    """A command's limit that is its ``--budget``."""
    return args.budget, "--budget"


def output(metavar: str, help: str | None = None, **options: Any) -> Argument:
    """``-o/--output``: the file (or, with ``DIR``, the folder) a command writes."""
    writes: Writes = "folder" if metavar == "DIR" else "file"
    return arg("-o", "--output", type=Path, metavar=metavar, help=help, writes=writes, **options)


def read_input(path: Path) -> TestCase:
    """A test-case file a command works on; a warning on stderr for each stored trajectory
    that no car can drive (the command goes on: the document is valid)."""
    from service.core.testcase import implausible_trajectories, read_testcase

    testcase = read_testcase(path)
    for problem in implausible_trajectories(testcase):
        print(f"scengen: warning: {path}: {problem}", file=sys.stderr)
    return testcase


def network_search_path() -> list[Path]:
    """The folders of ``SCENGEN_NETWORK_PATH`` (separated by ``os.pathsep``), in order."""
    value = os.environ.get("SCENGEN_NETWORK_PATH", "")
    return [Path(part) for part in value.split(os.pathsep) if part]


def locate_network(
    testcase: TestCase, args: argparse.Namespace, read_from: Path | None = None
) -> Path:
    """The file of the test-case's network (``find_network_file``), looked for from the
    folder of the file it was read from (``read_from``, default the command's TESTCASE),
    with --network and SCENGEN_NETWORK_PATH. Says on stderr which file it used when it is
    not the bundled network."""
    from service.core.testcase import find_network_file

    source = read_from or getattr(args, "testcase", None)
    near = source.parent if isinstance(source, Path) else None
    try:
        path, how = find_network_file(testcase, args.network, near, network_search_path())
    except UnknownNetwork as error:
        if args.network is not None or testcase.network.ref.endswith((".net.xml", ".xodr", ".osm")):
            raise
        raise UnknownNetwork(
            f"{error}; a test-case from a server names the server's network id: its file is "
            "at GET /networks/{id}/file"
        ) from None
    if how != "bundled":
        print(f"network {testcase.network.ref}: {path} ({how})", file=sys.stderr)
    return path


def testcase_intersection(
    testcase: TestCase, args: argparse.Namespace, read_from: Path | None = None
) -> Intersection:
    """The test-case's intersection, its network found by ``locate_network``."""
    from service.core.network import load_intersection
    from service.core.testcase import under_testcase_signals

    path = locate_network(testcase, args, read_from)
    intersection = load_intersection(  # the hash was checked above
        path,
        testcase.junction,
        testcase.control,
        major_road=testcase.major_road,
        guess_crossings=testcase.crossings_guessed,
    )
    return under_testcase_signals(intersection, testcase)


def controllers_named() -> str:
    """Every controller a NAME can be (built-in, registered, guarded), for a help text that
    is written when it is shown (service.cli.table.Later): finding the registered ones reads
    the installed packages' entry points."""
    from service.core.sim.controllers import controller_names

    return ", ".join(controller_names())


def distance_or_auto(text: str) -> float | None:
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
