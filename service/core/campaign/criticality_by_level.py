"""How close the runs came, level by level: the criticality measures of a level's verdicts
as distributions, and whether they grow more critical as the levels grow more complex.

A verdict's ``criticality`` (null when it was not measured, as in campaigns stored before
it existed) holds, overall, the smallest time-to-collision (``ttc``, s), post-encroachment
time (``pet``, s) and distance (``distance``, m) to any other road user, car or
pedestrian, and the largest deceleration needed to avoid a crash (``drac``, m/s²); each
is null when it never arose (no one on a collision course: no TTC). A level's
distribution of a measure is over the verdicts that have it: count, min, quartiles,
median, max and the values themselves.

A measure is more critical at one level than at another when its median is: TTC, PET and
distance smaller, DRAC larger. It grows with complexity, over the levels that have it (at
least two), when no step between consecutive levels makes it less critical and the last
level is more critical than the first; the steps where it falls back (``breaks``) and
those where it stays the same (``flat``: a new car that never came closer than the old
ones leaves the smallest TTC where it was) are named.
"""

from __future__ import annotations

import itertools
import statistics
from collections.abc import Mapping, Sequence
from typing import Any

MEASURES = ("ttc", "pet", "drac", "distance")
UNITS = {"ttc": "s", "pet": "s", "drac": "m/s²", "distance": "m"}
LABELS = {"ttc": "TTC", "pet": "PET", "drac": "DRAC", "distance": "distance"}
SMALLER_IS_CRITICAL = {"ttc": True, "pet": True, "drac": False, "distance": True}
DIGITS = 3  # values are rounded to the millimetre, millisecond


def overall_value(verdict: Mapping[str, Any], measure: str) -> float | None:
    """The verdict's overall ``measure``, None when not measured or when it never arose."""
    criticality = verdict.get("criticality")
    if not criticality:
        return None
    found = (criticality.get("overall") or {}).get(measure)
    return None if found is None else float(found["value"])


def distribution(values: Sequence[float]) -> dict[str, Any] | None:
    """count, min, q1, median, q3, max and the sorted values (None for no value); the
    quartiles are the inclusive ones (the median of a half, interpolated)."""
    if not values:
        return None
    ordered = sorted(values)
    if len(ordered) == 1:
        q1 = median = q3 = ordered[0]
    else:
        q1, median, q3 = statistics.quantiles(ordered, n=4, method="inclusive")
    summary = {"count": len(ordered), "min": ordered[0], "q1": q1, "median": median,
               "q3": q3, "max": ordered[-1]}  # fmt: skip
    rounded: dict[str, Any] = {k: round(v, DIGITS) for k, v in summary.items()}
    rounded["count"] = len(ordered)
    rounded["values"] = [round(v, DIGITS) for v in ordered]
    return rounded


def level_criticality(verdicts: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """A level's criticality for one controller: how many of its verdicts were measured,
    and each measure's distribution (None where no verdict has it)."""
    found: dict[str, Any] = {"measured": sum(1 for v in verdicts if v.get("criticality"))}
    for measure in MEASURES:
        values = [overall_value(v, measure) for v in verdicts]
        found[measure] = distribution([v for v in values if v is not None])
    return found


def _more_critical(measure: str, before: float, after: float) -> bool:
    return after < before if SMALLER_IS_CRITICAL[measure] else after > before


def measure_trend(measure: str, levels: Sequence[tuple[int, Mapping[str, Any]]]) -> dict[str, Any]:
    """One measure over ``levels`` (level, ``level_criticality``): the medians by level,
    ``grows`` (None with fewer than two levels measured) and the steps where it does not
    (``breaks``: [from level, to level], less critical) or where it stays (``flat``)."""
    medians = [[n, found[measure]["median"]] for n, found in levels if found.get(measure)]
    steps = list(itertools.pairwise(medians))
    breaks = [[a, b] for (a, before), (b, after) in steps if _more_critical(measure, after, before)]
    flat = [[a, b] for (a, before), (b, after) in steps if before == after]
    grows = None
    if len(medians) >= 2:
        grows = not breaks and _more_critical(measure, medians[0][1], medians[-1][1])
    return {"medians": medians, "grows": grows, "breaks": breaks, "flat": flat}


def criticality_trend(levels: Sequence[tuple[int, Mapping[str, Any]]]) -> dict[str, Any]:
    """Whether criticality grows with complexity for one controller: each measure's trend,
    ``grows`` (True when every measure with two levels grows, False when one does not,
    None when none has two) and a sentence that says it."""
    trends = {measure: measure_trend(measure, levels) for measure in MEASURES}
    judged = [t["grows"] for t in trends.values() if t["grows"] is not None]
    grows = None if not judged else all(judged)
    return {"grows": grows, "measures": trends, "summary": _summary(grows, trends)}


def _summary(grows: bool | None, trends: Mapping[str, Mapping[str, Any]]) -> str:
    if grows is None:
        return "not measured on two levels or more"
    parts = []
    for measure, trend in trends.items():
        if trend["grows"] is None:
            continue
        medians = " → ".join(f"{m:g}" for _, m in trend["medians"])
        levels = "–".join(str(trend["medians"][k][0]) for k in (0, -1))
        said = f"median {LABELS[measure]} {medians} {UNITS[measure]} (levels {levels})"
        for key, how in (("breaks", "less critical"), ("flat", "unchanged")):
            if trend[key]:
                steps = ", ".join(f"{a} → {b}" for a, b in trend[key])
                said += f", {how} from level {steps}"
        parts.append(said)
    return ("grows: " if grows else "does not grow: ") + "; ".join(parts)
