"""Pictures of an intersection, its routes and a car's drive (matplotlib, no display)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from matplotlib.axes import Axes
from shapely.geometry import Polygon

from service.core.events import rectangles
from service.core.network import Intersection
from service.core.poses import PoseSample

TURN_COLOURS = {"left": "tab:red", "right": "tab:green", "straight": "tab:blue"}


def _fill(axes: Axes, polygon: Polygon, **style: Any) -> None:
    for part in getattr(polygon, "geoms", [polygon]):
        xs, ys = part.exterior.xy
        axes.fill(xs, ys, **style)


def plot_intersection(
    intersection: Intersection,
    path: Path,
    highlight: Sequence[str] = (),
    track: Sequence[PoseSample] = (),
    car: tuple[float, float] = (5.0, 1.8),
) -> None:
    """Draw the junction, every connecting lane (coloured by turn), forks with their names,
    the highlighted routes, and optionally a car's rectangles every second."""
    figure, axes = plt.subplots(figsize=(8, 8))
    _fill(axes, intersection.polygon, color="0.85", zorder=0)
    for fork in intersection.forks.values():
        _fill(axes, fork.approach.buffer(fork.width / 2, cap_style="flat"), color="0.9", zorder=0)
    for exit_lane in intersection.exits.values():
        road = exit_lane.departure.buffer(exit_lane.width / 2, cap_style="flat")
        _fill(axes, road, color="0.93", zorder=0)
    for route in intersection.routes.values():
        lane = intersection.connecting_lanes[route.connecting_lane]
        chosen = route.id in highlight
        xs, ys = lane.centreline.xy
        axes.plot(
            xs, ys, color=TURN_COLOURS[route.turn.value],
            linewidth=2.5 if chosen else 0.8, alpha=1.0 if chosen else 0.5, zorder=2,
        )  # fmt: skip
        if chosen:
            _fill(axes, lane.polygon, color=TURN_COLOURS[route.turn.value], alpha=0.15, zorder=1)
    for fork in intersection.forks.values():
        x, y = fork.stop_line
        sign = " (stop)" if fork.stop_sign else ""
        axes.annotate(f"{fork.lane}{sign}", (x, y), fontsize=7, zorder=4)
        axes.plot([x], [y], marker="s" if fork.stop_sign else "o", color="black", zorder=4)
    if track:
        step = max(1, round(1.0 / max(track[1].t - track[0].t, 1e-9))) if len(track) > 1 else 1
        shown = list(track[::step])
        rects = rectangles(
            np.array([s.x for s in shown]), np.array([s.y for s in shown]),
            np.array([s.heading for s in shown]), car[0], car[1],
        )  # fmt: skip
        for rect in rects:
            xs, ys = rect.exterior.xy
            axes.plot(xs, ys, color="black", linewidth=0.6, zorder=3)
        axes.plot([s.x for s in track], [s.y for s in track], "k:", linewidth=0.8, zorder=3)
    minx, miny, maxx, maxy = intersection.polygon.bounds
    margin = 20.0
    axes.set_xlim(minx - margin, maxx + margin)
    axes.set_ylim(miny - margin, maxy + margin)
    axes.set_aspect("equal")
    axes.set_title(
        f"junction {intersection.junction} ({intersection.control.value}): "
        "left red, right green, straight blue"
    )
    figure.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(figure)
