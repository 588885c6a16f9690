"""The paper's curve: how often drivers fail as test-cases grow more complex.

Runs `scengen campaign` (the command a user runs) on the bundled junctions and on CARLA's
Town05 junction 396 made an all-way stop, with SUMO's four drivers and the user controller
of docs/controllers.md (`careful:Careful`, written from the docs into the run folder),
then draws the failure share by level per junction (docs/images/campaign-failure-rate.png)
and writes the tables (docs/campaigns.md). Each junction gets three ego routes (a left
turn, a straight and a right turn where it has them, else the first routes by id), three
chains per ego route, depth 5, seed 0, test-cases of 45 s (room for deep chains, as in
bench_chains).

Run with `make campaign-curve` (about half an hour on two cores). Campaign folders go to
build/campaigns/; run it again and finished campaigns are read back, not grown again.
"""

from __future__ import annotations

import json
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
JUNCTIONS = [  # (label, network, junction, control)
    ("4way-stop", "4way-stop", None, None),
    ("t-stop", "t-stop", None, None),
    ("y-uncontrolled", "y-uncontrolled", None, None),
    ("Town05 396 as allway_stop", str(ROOT / "tests/data/carla/Town05.net.xml"), "396",
     "allway_stop"),
]  # fmt: skip
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


def run(label: str, network: str, junction: str | None, control: str | None) -> dict[str, Any]:
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
    for ego in three_egos(network, junction, control):
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
    figure.legend(handles, labels, loc="lower center", ncol=len(CONTROLLERS), fontsize=9)
    figure.tight_layout(rect=(0, 0.08, 1, 1))
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path, dpi=110)


def main() -> None:
    outcomes = [(label, run(label, *rest)) for label, *rest in JUNCTIONS]
    plot(outcomes, DOCS / "images" / "campaign-failure-rate.png")
    lines = [
        "# Campaigns: failure rate by level",
        "",
        f"Measured {date.today()} on {platform.node()} ({platform.machine()}, Python "
        f"{platform.python_version()}) by `make campaign-curve` (bench/campaign_curve.py): "
        f"depth {DEPTH}, {CHAINS} chains per ego route, seed {SEED}, test-cases of "
        f"{DURATION:g} s; each cell is failed / "
        "test-cases at that level, with the rules broken and collisions.",
        "",
        "![failure rate by level](images/campaign-failure-rate.png)",
        "",
        "What these figures show, and why, is in the README (`scengen campaign`).",
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
        lines += [f"## {label}", "", f"Ego routes: {', '.join(outcome['plan']['egos'])}.", ""]
        lines += table(outcome)
        lines += ["", f"Rules covered: {', '.join(covered) or 'none'}; not covered: "
                  f"{', '.join(open_rules) or 'none'}.", ""]  # fmt: skip
        if ends:
            lines += ["Chains that ended early:", "", *[f"- {e}" for e in ends], ""]
    (DOCS / "campaigns.md").write_text("\n".join(lines))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
