"""Arguments that several commands share, defined once, and what they mean.

``NETWORK`` names a junction (a network, ``--junction``, ``--control``); ``NETWORK_FILE``
(``--network``) finds the network of a test-case read from a file, which
``testcase_intersection`` loads.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import Any

from service.cli.table import Argument, arg
from service.core.errors import UnknownNetwork
from service.core.network import ControlType, Intersection, bundled_networks, load_intersection
from service.core.testcase import TestCase, find_network_file

CONTROLS = [c.value for c in ControlType]

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
        help="priority_stop: the two roads into the junction (edge ids) that keep the right "
        "of way, the others stop (default: the network's; for a junction made priority_stop "
        "whose roads all have the same priority, the two closest to straight across)",
    ),
)


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
    help="the .net.xml of a test-case made on a network uploaded to a server (its "
    "network.ref is the server's id; GET /networks/{id}/file downloads it)",
)
TESTCASE = arg("testcase", type=Path, metavar="TESTCASE", help="a test-case JSON file")
JUNIT = arg("--junit", type=Path, metavar="FILE", help="also write JUnit XML here")
TOKEN = arg("--token", metavar="T", help="the server's API token (or SCENGEN_TOKEN)")


def output(metavar: str, help: str | None = None, **options: Any) -> Argument:
    """``-o/--output``: the file or folder a command writes."""
    return arg("-o", "--output", type=Path, metavar=metavar, help=help, **options)


def testcase_intersection(
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
    return load_intersection(  # the hash was checked above
        path, testcase.junction, testcase.control, major_road=testcase.major_road
    )


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
