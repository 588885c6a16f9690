"""``scengen networks`` and ``scengen intersection``: what there is to test on."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from service.cli.arguments import (
    COMMAND_BUDGET,
    NETWORK,
    SIGNALS,
    budget,
    by_budget,
    signals_program,
)
from service.cli.output import EXIT_OK, output_file, print_table
from service.cli.table import arg, command
from service.core.names import bundled_networks

WALK_WORDS = "G or g walk, y flashing don't walk (nobody starts), r don't walk"  # 21456


@command("networks", "list the bundled networks")
def networks(args: argparse.Namespace) -> int:
    for name, path in bundled_networks().items():
        print(f"{name}\t{path}")
    return EXIT_OK


@command(
    "intersection",
    "describe a junction: forks, routes, conflicts, right-of relations",
    NETWORK,
    SIGNALS,
    arg(
        "--duration",
        type=float,
        default=None,
        metavar="S",
        help="a signalized junction: show each route's signal over this many seconds "
        "(default: one cycle)",
    ),
    arg("--json", action="store_true", help="print one JSON object"),
    arg(
        "--plot",
        type=Path,
        metavar="FILE",
        writes="file",
        help="also draw it to FILE (.png/.svg)",
    ),
    budget(COMMAND_BUDGET, "time for the whole command"),
    limit=by_budget,
)
def intersection(args: argparse.Namespace) -> int:
    from service.core.network import load_intersection, with_signals
    from service.core.network.describe import describe_intersection

    junction = load_intersection(
        args.network,
        args.junction,
        args.control,
        major_road=args.major,
        guess_crossings=args.guess_crossings,
    )
    program = signals_program(args)
    if program is not None:
        junction = with_signals(junction, program)
    elif junction.signals_refused:  # shown, but no test-case can be made on it as it is
        print(f"scengen: note: {junction.signals_refused}", file=sys.stderr)
    elif junction.signals is not None and junction.signals.note:  # read, but not as given
        print(f"scengen: note: {junction.signals.note}", file=sys.stderr)
    description = describe_intersection(junction, args.duration)
    if args.plot:
        from service.pictures.junction import plot_intersection

        with output_file(args.plot) as picture:
            plot_intersection(junction, picture)
    if args.json:
        print(json.dumps(description, indent=2))
    else:
        _print_intersection(description, major_given=args.major is not None)
    return EXIT_OK


def _print_intersection(d: dict[str, Any], major_given: bool) -> None:
    overridden = " (overridden)" if d["control_overridden"] else ""
    guessed = "  crossings guessed" if d["crossings_guessed"] else ""
    print(
        f"junction {d['junction']}  control {d['control']}{overridden}{guessed}  "
        f"network {d['network']}"
    )
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
                "yes" if f["stop_sign"] else "yield" if f["yield_sign"] else "no",
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
    print()
    _print_walks(d["walks"])
    if d.get("signals"):
        _print_signals(d["signals"], {r["id"]: r for r in d["routes"]})
        if d["walks"]:
            _print_walk_signals(d["walks"])
    if d["side_lanes"]:
        print()
        print("side lanes, not offered (a route on one works when named):")
        print_table([[s["lane"], s["reason"]] for s in d["side_lanes"]])


def _print_walks(walks: list[dict[str, Any]]) -> None:
    if not walks:
        print(
            "no pedestrian crossings: add sidewalks and crossings with --guess-crossings "
            "(car lane indices then move up by one)"
        )
        return
    rows = [["walk", "crossing", "from", "to", "length", "width", "conflicts"]]
    for w in walks:
        rows.append(
            [
                w["id"],
                w["crossing"],
                f"{w['from']} ({w['before']})",
                f"{w['to']} ({w['after']})",
                f"{w['length']:.2f}",
                f"{w['width']:.2f}",
                " ".join(w["conflicts"]) or "-",
            ]
        )
    print_table(rows)
    print("from, to: the walking areas at its ends (the sidewalk lanes before and after it)")


def _print_walk_signals(walks: list[dict[str, Any]]) -> None:
    print()
    rows = [["walk", "link", "colours (from s: colour)"]]
    for w in walks:
        signal = w.get("signal")
        if signal is None:
            rows.append([w["id"], "-", "no signal"])
            continue
        runs = "  ".join(f"{start:g}: {colour}" for start, _, colour in signal["timeline"])
        rows.append([w["id"], str(signal["link_index"]), runs])
    print_table(rows)
    print(f"pedestrian signals: {WALK_WORDS}")


def _print_signals(signals: dict[str, Any], routes: dict[str, dict[str, Any]]) -> None:
    from service.core.network.signals import COLOUR_WORDS  # loaded with the junction

    print()
    print(
        f"traffic light {signals['tls']}  program {signals['program']}  offset "
        f"{signals['offset']:g} s  cycle {signals['cycle']:g} s  {len(signals['phases'])} "
        f"phases; colours over {signals['horizon']:g} s from t = 0"
    )
    rows = [["route", "link", "green", "colours (from s: colour)"]]
    for route_id, route in routes.items():
        signal = route.get("signal")
        if signal is None:
            rows.append([route_id, "-", "-", "no signal"])
            continue
        greens = {"G": "protected", "g": "permissive", "s": "on red after stop",
                  "O": "off, priority", "o": "off, yields"}  # fmt: skip
        kinds = sorted({greens[c] for _, _, c in signal["timeline"] if c in greens})
        runs = "  ".join(f"{start:g}: {colour}" for start, _, colour in signal["timeline"])
        rows.append([route_id, str(signal["link_index"]), ", ".join(kinds) or "never", runs])
    print_table(rows)
    print("colours: " + ", ".join(f"{c} {word}" for c, word in COLOUR_WORDS.items()))
