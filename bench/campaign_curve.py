"""The paper's curve: how often drivers fail as test-cases grow more complex.

Runs `scengen campaign` (the command a user runs) with SUMO's four drivers and the user
controller of docs/controllers.md (`careful:Careful`, written from the docs into the run
folder) on two groups of junctions, then draws the failure share by level per junction
and writes the tables into docs/campaigns.md, each group in its own block:

- `stops`: the bundled stop-sign and uncontrolled junctions and CARLA's Town05 junction
  396 made an all-way stop (docs/images/campaign-failure-rate.png); three ego routes each
  (a left turn, a straight and a right turn where it has them, else the first routes by
  id);
- `signals`: the bundled signalized four-way and CARLA's Town05 junction 1126 under its
  own fixed-time program (docs/images/campaign-failure-rate-signals.png); three ego routes
  each, named below: a left turn on a permissive green against oncoming traffic, a straight
  on green, and at the four-way a left that starts on red (green after 25 s), at 1126 a
  right turn.

Three chains per ego route, depth 5, seed 0, test-cases of 45 s (room for deep chains, as
in bench_chains). Run with `make campaign-curve` (both groups, about an hour on two cores)
or `python -m bench.campaign_curve signals` (one group; the other's block is kept).
Campaign folders go to build/campaigns/; run it again and finished campaigns are read
back, not grown again (the criticality's trend is judged anew from their levels).
"""

from __future__ import annotations

import json
import os
import platform
import re
import subprocess
import sys
from datetime import date
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "build" / "campaigns"
DOCS = ROOT / "docs"
CONTROLLERS = ["sumo", "sumo-cautious", "sumo-rolling-stop", "sumo-aggressive", "careful:Careful"]
TOWN05 = str(ROOT / "tests/data/carla/Town05.net.xml")
Junction = tuple[str, str, str | None, str | None, list[str] | None]
# (label, network, junction, control, ego routes: None for three_egos)
GROUPS: dict[str, list[Junction]] = {
    "stops": [
        ("4way-stop", "4way-stop", None, None, None),
        ("t-stop", "t-stop", None, None, None),
        ("y-uncontrolled", "y-uncontrolled", None, None, None),
        ("Town05 396 as allway_stop", TOWN05, "396", "allway_stop", None),
    ],
    "signals": [
        # S2C_1:C2W_1 turns left on a permissive green (0-20 s), S2C_0:C2N_0 goes straight
        # on green, E2C_1:C2S_1 turns left from the arm that is red until 25 s
        ("4way-signal", "4way-signal", None, None, ["S2C_1:C2W_1", "S2C_0:C2N_0", "E2C_1:C2S_1"]),
        # the -6 arm is green 0-42 s: a permissive left against the oncoming 7 arm, a
        # straight that crosses seven routes, a right turn
        (
            "Town05 1126 (traffic_light)",
            TOWN05,
            "1126",
            None,
            ["-6_1:-47_1", "-6_1:-7_1", "-6_0:46_0"],
        ),
    ],
}
PICTURES = {"stops": "campaign-failure-rate.png", "signals": "campaign-failure-rate-signals.png"}
DEPTH, CHAINS, SEED, DURATION = 5, 3, 0, 45.0


def careful_source() -> str:
    """The user controller exactly as docs/controllers.md prints it."""
    text = (DOCS / "controllers.md").read_text()
    found = re.search(r"```python\n(import math\n\n\nclass Careful:.*?)```", text, re.S)
    assert found, "docs/controllers.md no longer holds the Careful example"
    return found.group(1)


def three_egos(network: str, junction: str | None, control: str | None) -> list[str]:
    from service.core.network import load_intersection

    intersection = load_intersection(network, junction, control)
    chosen: list[str] = []
    for turn in ("left", "straight", "right"):
        of_turn = sorted(r.id for r in intersection.routes.values() if r.turn.value == turn)
        if of_turn:
            chosen.append(of_turn[0])
    for route in sorted(intersection.routes):
        if len(chosen) >= 3:
            break
        if route not in chosen:
            chosen.append(route)
    return chosen


def run(
    label: str, network: str, junction: str | None, control: str | None, egos: list[str] | None
) -> dict[str, Any]:
    folder = OUT / re.sub(r"[^A-Za-z0-9]+", "-", label).strip("-")
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "careful.py").write_text(careful_source())
    command = [sys.executable, "-m", "service", "campaign", network, "--depth", str(DEPTH),
               "--chains", str(CHAINS), "--seed", str(SEED), "--duration", str(DURATION),
               "-o", str(folder)]  # fmt: skip
    if junction:
        command += ["--junction", junction]
    if control:
        command += ["--control", control]
    for ego in egos or three_egos(network, junction, control):
        command.append(f"--ego={ego}")
    for controller in CONTROLLERS:
        command += ["--controller", controller]
    if not (folder / "campaign.json").exists():
        print(f"{label}: {' '.join(command)}", flush=True)
        subprocess.run(command, cwd=folder, check=False)  # exit 1: some evaluation failed
    return dict(json.loads((folder / "campaign.json").read_text()))


def table(outcome: dict[str, Any]) -> list[str]:
    lines = ["| level | test-cases | " + " | ".join(CONTROLLERS) + " |",
             "|---|---|" + "---|" * len(CONTROLLERS)]  # fmt: skip
    for level in outcome["levels"]:
        cells = []
        for name in CONTROLLERS:
            share = level["controllers"][name]
            rules = ", ".join(f"{r} {n}" for r, n in share["rules"].items())
            extra = f" ({rules})" if rules else ""
            extra += f" {share['collisions']} coll." if share["collisions"] else ""
            cells.append(f"{share['failed']}/{share['evaluated']}{extra}")
        lines.append(f"| {level['level']} | {level['testcases']} | " + " | ".join(cells) + " |")
    return lines


def criticality_table(outcome: dict[str, Any]) -> list[str]:
    """Each controller's median of each criticality measure by level, and whether it grows
    (nothing when no verdict was measured: a campaign stored before verdicts had it)."""
    from service.core.campaign.criticality_by_level import (
        LABELS,
        MEASURES,
        UNITS,
        criticality_trend,
    )

    levels = outcome["levels"]
    if not any(lv["controllers"][c].get("criticality", {}).get("measured")
               for lv in levels for c in CONTROLLERS):  # fmt: skip
        return []
    head = " | ".join(f"L{lv['level']}" for lv in levels)
    lines = [f"| controller | median of | {head} | grows with the level |",
             "|---|---|" + "---:|" * len(levels) + "---|"]  # fmt: skip
    for name in CONTROLLERS:
        trend = criticality_trend([(lv["level"], lv["controllers"][name]["criticality"])
                                   for lv in levels])  # fmt: skip
        for measure in MEASURES:
            spreads = [lv["controllers"][name]["criticality"][measure] for lv in levels]
            cells = ["—" if s is None else f"{s['median']:g}" for s in spreads]
            said = trend["measures"][measure]
            grows = {True: "yes", False: "no", None: "—"}[said["grows"]]
            where = [f"{how} " + ", ".join(f"L{a}→L{b}" for a, b in said[key])
                     for key, how in (("breaks", "less critical"), ("flat", "unchanged"))
                     if said[key]]  # fmt: skip
            if where:
                grows += f" ({'; '.join(where)})"
            lines.append(f"| {name} | {LABELS[measure]} ({UNITS[measure]}) | "
                         + " | ".join(cells) + f" | {grows} |")  # fmt: skip
    return lines


def overview(outcomes: list[tuple[str, dict[str, Any]]]) -> list[str]:
    """One row per junction and controller: the share failed at each level (%)."""
    depth = max(len(outcome["levels"]) for _, outcome in outcomes)
    lines = ["| junction | controller | " + " | ".join(f"L{k}" for k in range(depth)) + " |",
             "|---|---|" + "---:|" * depth]  # fmt: skip
    for label, outcome in outcomes:
        for name in CONTROLLERS:
            shares = [f"{100 * (lv['controllers'][name]['share'] or 0):.0f}"
                      for lv in outcome["levels"]]  # fmt: skip
            lines.append(f"| {label} | {name} | " + " | ".join(shares) + " |")
    return lines


def plot(outcomes: list[tuple[str, dict[str, Any]]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(1, len(outcomes), figsize=(4.2 * len(outcomes), 3.9),
                                sharey=True)  # fmt: skip
    styles = ["-o", "--s", ":^", "-.v", "-D"]  # drivers that coincide stay visible
    for axis, (label, outcome) in zip(axes, outcomes, strict=True):
        for k, name in enumerate(CONTROLLERS):
            shift = (k - 2) * 0.05  # a nudge sideways, for the same reason
            levels = [lv["level"] + shift for lv in outcome["levels"]]
            shares = [100 * (lv["controllers"][name]["share"] or 0) for lv in outcome["levels"]]
            axis.plot(levels, shares, styles[k], label=name, markersize=5, linewidth=1.6)
        axis.set_title(label, fontsize=10)
        axis.set_xlabel("level (cars added)")
        axis.set_ylim(-5, 105)
        axis.grid(alpha=0.3)
    axes[0].set_ylabel("test-cases failed (%)")
    handles, labels = axes[0].get_legend_handles_labels()
    columns = len(CONTROLLERS) if len(outcomes) > 2 else 3  # two panels: two rows of names
    figure.legend(handles, labels, loc="lower center", ncol=columns, fontsize=9)
    figure.tight_layout(rect=(0, 0.08 if columns == len(CONTROLLERS) else 0.14, 1, 1))
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path, dpi=110)


def block(group: str, outcomes: list[tuple[str, dict[str, Any]]]) -> list[str]:
    """The group's block of docs/campaigns.md, between its markers."""
    picture = PICTURES[group]
    lines = [
        f"<!-- campaign-curve: {group} -->",
        f"Measured {date.today()} on {platform.node()} ({platform.machine()}, "
        f"{os.cpu_count()} cores, Python {platform.python_version()}) by `python -m "
        f"bench.campaign_curve {group}` (`make campaign-curve`): depth {DEPTH}, {CHAINS} "
        f"chains per ego route, seed {SEED}, test-cases of {DURATION:g} s; each cell is "
        "failed / test-cases at that level, with the rules broken and collisions.",
        "",
        f"![failure rate by level]({'images/' + picture})",
        "",
        "Share of test-cases failed at each level (%), L0 the ego-only test-cases:",
        "",
        *overview(outcomes),
        "",
    ]
    for label, outcome in outcomes:
        covered = [c["rule"] for c in outcome["coverage"] if c["covered"]]
        open_rules = [c["rule"] for c in outcome["coverage"] if c["coverable"] and not c["covered"]]
        ends = [f"{c['ego']} chain {c['chain'] + 1}: {c['end']}" for c in outcome["chains"]
                if c["end"]]  # fmt: skip
        lines += [f"### {label}", "", f"Ego routes: {', '.join(outcome['plan']['egos'])}.", ""]
        lines += table(outcome)
        measured = criticality_table(outcome)
        if measured:
            lines += ["", "Criticality by level (the median over the level's test-cases "
                      "that have the measure; — none had it):", "", *measured]  # fmt: skip
        lines += ["", f"Rules covered: {', '.join(covered) or 'none'}; not covered: "
                  f"{', '.join(open_rules) or 'none'}.", ""]  # fmt: skip
        if ends:
            lines += ["Chains that ended early:", "", *[f"- {e}" for e in ends], ""]
    return [*lines, f"<!-- /campaign-curve: {group} -->"]


def replace_block(text: str, group: str, lines: list[str]) -> str:
    """``text`` with the group's block replaced (or added at the end)."""
    pattern = re.compile(
        rf"<!-- campaign-curve: {group} -->.*?<!-- /campaign-curve: {group} -->", re.S
    )
    new = "\n".join(lines)
    if pattern.search(text):
        return pattern.sub(lambda _: new, text)
    return text.rstrip("\n") + "\n\n" + new + "\n"


def main(argv: list[str]) -> None:
    groups = argv or list(GROUPS)
    unknown = [g for g in groups if g not in GROUPS]
    if unknown:
        sys.exit(f"unknown group {', '.join(unknown)}; groups: {', '.join(GROUPS)}")
    path = DOCS / "campaigns.md"
    text = path.read_text() if path.exists() else "# Campaigns: failure rate by level\n"
    for group in groups:
        outcomes = [(j[0], run(*j)) for j in GROUPS[group]]
        plot(outcomes, DOCS / "images" / PICTURES[group])
        lines = block(group, outcomes)
        text = replace_block(text, group, lines)
        path.write_text(text)
        print("\n".join(lines))


if __name__ == "__main__":
    main(sys.argv[1:])
