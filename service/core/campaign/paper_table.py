"""The seed paper's table: controllers against levels, each cell pass or why it failed.

The paper reports its experiment as a controller's verdict on each level of a chain
("both pass the first test-case, only autopilot-plus-RSS passes the second"). A cell here
holds one verdict (``pass``, ``FAIL 21800(a) car2``, ``FAIL collision car3``, ``FAIL goal``,
``FAIL error``) or, when a level holds several test-cases (a campaign's chains), how many
failed and their most common cause (``2/3 FAIL 21800(a)``; ``pass 3/3`` when none did).
A verdict fails for one shown cause: a collision first, then the first rule it broke, then
an error of its controller, then the goal it missed. A cell of one verdict also says how
close the run came (its smallest time-to-collision) and, for a guarded controller, at how
many of its steps the guard intervened: ``pass (TTC 2.6 s, RSS 8/199)``.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

# The paper's pair: its autopilot and autopilot-plus-RSS, here SUMO's driver and the same
# driver guarded by RSS (``scengen example`` evaluates with them unless told otherwise).
PAPER_CONTROLLERS = ("sumo", "sumo+rss")


def failure_cause(verdict: Mapping[str, Any]) -> dict[str, Any] | None:
    """The one cause the table shows for a failed verdict, None for a pass: ``{"kind":
    "collision", "car"}``, ``{"kind": "rule", "rule", "law", "car"}`` (car None for the
    ego's own rules), ``{"kind": "error"}`` or ``{"kind": "goal"}``. Reads a verdict
    (``Verdict.to_dict``) or a campaign's compact one: its ``cause``, or, in campaigns
    stored before causes were kept, its rules and counts (no law, no car)."""
    if verdict["passed"]:
        return None
    if "cause" in verdict:
        cause: dict[str, Any] | None = verdict["cause"]
        return cause
    collisions = verdict["collisions"]
    if isinstance(collisions, int):  # a compact verdict of an older campaign
        if collisions:
            return {"kind": "collision", "car": None}
        if verdict["rules"]:
            return {"kind": "rule", "rule": verdict["rules"][0], "law": None, "car": None}
    else:
        if collisions:
            first = min(collisions, key=lambda c: c["t"])
            return {"kind": "collision", "car": first["other"]}
        if verdict["violations"]:
            broken = verdict["violations"][0]
            return {"kind": "rule", "rule": broken["rule"], "law": broken.get("law"),
                    "car": broken.get("other")}  # fmt: skip
    if verdict["errors"]:
        return {"kind": "error"}
    return {"kind": "goal"}


def cause_text(cause: Mapping[str, Any], with_car: bool = True) -> str:
    """``21800(a) car2``, ``collision car3``, ``goal``, ``error`` (without the car:
    ``21800(a)``, ``collision``; a rule whose law is unknown by its name)."""
    kind = cause["kind"]
    if kind == "rule":
        text = cause.get("law") or cause["rule"]
    elif kind in ("collision", "goal", "error"):
        text = kind
    else:
        raise ValueError(f"unknown failure cause {kind!r}: collision, rule, error or goal")
    car = cause.get("car")
    return f"{text} {car}" if with_car and car else str(text)


def paper_cell(verdicts: Sequence[Mapping[str, Any]]) -> str:
    """One cell: a verdict's ``pass`` or ``FAIL CAUSE``; several: ``k/n FAIL CAUSE`` with
    the most common cause among the failed (cars left out: car2 of one chain is another
    car than car2 of the next), ``pass n/n`` when none failed, ``—`` for none."""
    if not verdicts:
        return "—"
    causes = [failure_cause(v) for v in verdicts]
    failed = [c for c in causes if c is not None]
    if len(verdicts) == 1:
        shown = "pass" if not failed else f"FAIL {cause_text(failed[0])}"
        return shown + closeness(verdicts[0])
    if not failed:
        return f"pass {len(verdicts)}/{len(verdicts)}"
    common = Counter(cause_text(c, with_car=False) for c in failed).most_common(1)[0][0]
    return f"{len(failed)}/{len(verdicts)} FAIL {common}"


def closeness(verdict: Mapping[str, Any]) -> str:
    """How close one run came and how often its guard stepped in, for a cell:
    `` (TTC 2.6 s, RSS 8/199)``; empty when the verdict has neither."""
    parts = []
    ttc = ((verdict.get("criticality") or {}).get("overall") or {}).get("ttc")
    if ttc is not None:
        parts.append(f"TTC {ttc['value']:.1f} s")
    guard = verdict.get("guard")
    if guard is not None:
        fallback = " time-gap" if guard.get("fallback") else ""
        parts.append(f"RSS{fallback} {guard['interventions']}/{guard['steps']}")
    return f" ({', '.join(parts)})" if parts else ""


@dataclass(frozen=True)
class PaperTable:
    """Controllers (rows) against levels (columns), as the paper states its results."""

    levels: tuple[int, ...]
    rows: tuple[tuple[str, tuple[str, ...]], ...]  # a controller and its cell per level

    def cells(self) -> list[list[str]]:
        """The header row, then a row per controller."""
        head = ["controller", *(f"level {level}" for level in self.levels)]
        return [head, *([controller, *cells] for controller, cells in self.rows)]

    def text(self) -> str:
        """Columns aligned with two spaces between them."""
        rows = self.cells()
        widths = [max(len(row[k]) for row in rows) for k in range(len(rows[0]))]
        lines = ["  ".join(cell.ljust(w) for cell, w in zip(row, widths, strict=True)).rstrip()
                 for row in rows]  # fmt: skip
        return "\n".join(lines) + "\n"

    def markdown(self) -> str:
        """A Markdown table (``|`` inside a cell escaped)."""
        rows = [[cell.replace("|", "\\|") for cell in row] for row in self.cells()]
        lines = ["| " + " | ".join(rows[0]) + " |", "|" + "---|" * len(rows[0])]
        lines += ["| " + " | ".join(row) + " |" for row in rows[1:]]
        return "\n".join(lines) + "\n"


def paper_table(
    levels: Mapping[int, Mapping[str, Sequence[Mapping[str, Any]]]], controllers: Sequence[str]
) -> PaperTable:
    """The table of ``levels``: level -> controller -> the verdicts of that level's
    test-cases (one for an example's chain, one per distinct test-case for a campaign)."""
    numbers = tuple(sorted(levels))
    rows = tuple(
        (controller, tuple(paper_cell(levels[n].get(controller, ())) for n in numbers))
        for controller in controllers
    )
    return PaperTable(numbers, rows)
