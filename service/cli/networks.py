"""``scengen networks`` and ``scengen intersection``: what there is to test on."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from service.cli.arguments import NETWORK
from service.cli.output import EXIT_OK, output_file, print_table
from service.cli.table import arg, command
from service.core.network import bundled_networks, load_intersection
from service.core.network.describe import describe_intersection


@command("networks", "list the bundled networks")
def networks(args: argparse.Namespace) -> int:
    for name, path in bundled_networks().items():
        print(f"{name}\t{path}")
    return EXIT_OK


@command(
    "intersection",
    "describe a junction: forks, routes, conflicts, right-of relations",
    NETWORK,
    arg("--json", action="store_true", help="print one JSON object"),
    arg(
        "--plot",
        type=Path,
        metavar="FILE",
        writes="file",
        help="also draw it to FILE (.png/.svg)",
    ),
)
def intersection(args: argparse.Namespace) -> int:
    junction = load_intersection(args.network, args.junction, args.control, major_road=args.major)
    description = describe_intersection(junction)
    if args.plot:
        from service.pictures.plot import plot_intersection

        with output_file(args.plot) as picture:
            plot_intersection(junction, picture)
    if args.json:
        print(json.dumps(description, indent=2))
    else:
        _print_intersection(description, major_given=args.major is not None)
    return EXIT_OK


def _print_intersection(d: dict[str, Any], major_given: bool) -> None:
    overridden = " (overridden)" if d["control_overridden"] else ""
    print(f"junction {d['junction']}  control {d['control']}{overridden}  network {d['network']}")
    if d["major_road"]:
        how = "given" if major_given else "the roads closest to straight across; --major to choose"
        print(f"major road {' '.join(d['major_road'])} ({how})")
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
    print_table(rows)
    print()
    rows = [["route", "turn", "conflicts"]]
    for r in d["routes"]:
        rows.append([r["id"], r["turn"], " ".join(r["conflicts"]) or "-"])
    print_table(rows)
    if d["side_lanes"]:
        print()
        print("side lanes, not offered (a route on one works when named):")
        print_table([[s["lane"], s["reason"]] for s in d["side_lanes"]])
