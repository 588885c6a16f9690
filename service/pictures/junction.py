"""The junction in pictures: its roads and area, stop lines, the map's frame, a picture
of the junction with its connecting lanes by turn, and how every picture is saved
(matplotlib, no display)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from shapely.geometry import Polygon

from service.core.motion.events import rectangles
from service.core.motion.poses import PoseSample
from service.core.network import Intersection
from service.pictures.pedestrians import draw_crosswalks, draw_pavements
from service.pictures.signals import SignalHeads, colour_handles

TURN_COLOURS = {"left": "tab:red", "right": "tab:green", "straight": "tab:blue"}


def _fill(axes: Axes, polygon: Polygon, **style: Any) -> None:
    for part in getattr(polygon, "geoms", [polygon]):
        xs, ys = part.exterior.xy
        axes.fill(xs, ys, **style)


def draw_roads(axes: Axes, intersection: Intersection) -> None:
    _fill(axes, intersection.polygon, color="0.85", zorder=0)
    for fork in intersection.forks.values():
        _fill(axes, fork.approach.buffer(fork.width / 2, cap_style="flat"), color="0.9", zorder=0)
    for exit_lane in intersection.exits.values():
        road = exit_lane.departure.buffer(exit_lane.width / 2, cap_style="flat")
        _fill(axes, road, color="0.93", zorder=0)


STOP_LINE = "firebrick"  # a stop sign's line; other forks' lines are grey
YIELD_LINE = "darkorange"  # a yield sign's line (the minor road of a priority junction), dashed


def draw_stop_lines(axes: Axes, intersection: Intersection) -> None:
    """Each fork's line across its lane at the junction: red with a stop sign, dashed
    orange with a yield sign, else grey (lines, so that they clash with no event marker)."""
    for fork in intersection.forks.values():
        x, y = fork.stop_line
        heading = math.radians(fork.heading)  # degrees clockwise from north
        dx, dy = math.cos(heading) * fork.width / 2, -math.sin(heading) * fork.width / 2
        colour, width = (STOP_LINE, 2.2) if fork.stop_sign else ("0.45", 1.0)
        style: str | tuple[int, tuple[float, float]] = "-"
        if fork.yield_sign:
            colour, width, style = YIELD_LINE, 2.2, (0, (1.5, 1.0))
        axes.plot([x - dx, x + dx], [y - dy, y + dy], color=colour, linewidth=width,
                  linestyle=style, solid_capstyle="butt", zorder=4)  # fmt: skip


def sign_legend(axes: Axes, intersection: Intersection) -> None:
    """Legend entries for the stop and yield signs the junction has."""
    forks = intersection.forks.values()
    if any(fork.stop_sign for fork in forks):
        axes.plot([], [], color=STOP_LINE, linewidth=2.2, label="stop line (sign)")
    if any(fork.yield_sign for fork in forks):
        axes.plot([], [], color=YIELD_LINE, linewidth=2.2, linestyle=(0, (1.5, 1.0)),
                  label="yield line (sign)")  # fmt: skip


def _back_along(line: Any, metres: float, from_end: bool = True) -> tuple[float, float]:
    """The point ``metres`` from the end (or the start) of a line, along it."""
    length = line.length
    at = line.interpolate(max(length - metres, 0.0) if from_end else min(metres, length))
    return at.x, at.y


def plot_intersection(
    intersection: Intersection,
    path: Path,
    highlight: Sequence[str] = (),
    track: Sequence[PoseSample] = (),
    car: tuple[float, float] = (5.0, 1.8),
) -> None:
    """Draw the junction, every connecting lane (coloured by turn), forks with their names,
    the highlighted routes, the crosswalks, the signal heads at t = 0 s of the junction's
    program, and optionally a car's rectangles every second."""
    figure, axes = plt.subplots(figsize=(8, 8))
    draw_roads(axes, intersection)
    draw_pavements(axes, intersection)
    draw_crosswalks(axes, intersection)
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
        xs, ys = lane.centreline.xy
        axes.annotate("", xy=(xs[-1], ys[-1]), xytext=(xs[-2], ys[-2]), zorder=2,
                      arrowprops={"arrowstyle": "-|>", "color": TURN_COLOURS[route.turn.value],
                                  "lw": 0.8, "alpha": 1.0 if chosen else 0.6})  # fmt: skip
    draw_stop_lines(axes, intersection)
    heads = SignalHeads(axes, intersection)
    heads.show(0.0)
    if heads.heads and heads.program is not None:
        handles, labels = colour_handles(heads.colours_used())
        axes.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, -0.04), ncol=3,
                    fontsize=7, title="signals at t = 0 s", title_fontsize=7)  # fmt: skip
    for fork in intersection.forks.values():
        sign = " (stop)" if fork.stop_sign else " (yield)" if fork.yield_sign else ""
        _label_outward(axes, f"{fork.lane}{sign}", _back_along(fork.approach, 1.5), fork.approach)
    for exit_lane in intersection.exits.values():
        start = _back_along(exit_lane.departure, 1.5, from_end=False)
        _label_outward(axes, f"{exit_lane.lane} (exit)", start, exit_lane.departure, True)
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
        "left red, right green, straight blue" + _heads_title(heads)
    )
    save(figure, path)


def _heads_title(heads: SignalHeads) -> str:
    """What a junction's picture says of its signal heads (nothing without any)."""
    if not heads.heads:
        return ""
    if heads.program is None:
        return "\nsignal heads past the stop lines, grey: the network's program is not fixed-time"
    return "\nsignal heads past the stop lines at t = 0 s"


def save(figure: Figure, path: Path) -> None:
    """Write a figure (the legend below a map included) and close it: the same picture
    gives the same bytes (an SVG's ids from a fixed salt, no date in its metadata)."""
    metadata = {"Date": None} if path.suffix.lower() == ".svg" else None
    with matplotlib.rc_context({"svg.hashsalt": "scengen"}):
        figure.savefig(path, dpi=110, bbox_inches="tight", metadata=metadata)
    plt.close(figure)


def _label_outward(
    axes: Any, text: str, at: tuple[float, float], line: Any, outward: bool = False
) -> None:
    """A label that runs from ``at`` away from the junction along a lane (an approach ends
    at the junction; a departure, ``outward``, starts there): labels of lanes side by side
    on one arm stay apart, and none is upside down."""
    (x0, y0), (x1, y1) = line.coords[0], line.coords[-1]
    if outward:
        (x0, y0), (x1, y1) = (x1, y1), (x0, y0)
    angle = math.degrees(math.atan2(y0 - y1, x0 - x1))
    flipped = not -90.0 <= angle <= 90.0
    axes.text(
        at[0], at[1], text, fontsize=7, zorder=4,
        rotation=angle + 180.0 if flipped else angle, rotation_mode="anchor",
        ha="right" if flipped else "left", va="center",
    )  # fmt: skip


def frame_map(axes: Axes, intersection: Intersection, starts: Sequence[PoseSample]) -> None:
    """The junction with a margin, every start in view, metres on both axes."""
    minx, miny, maxx, maxy = intersection.polygon.bounds
    margin = 25.0
    low_x = min([minx - margin, *(s.x - 6.0 for s in starts)])  # every start in view
    low_y = min([miny - margin, *(s.y - 6.0 for s in starts)])
    high_x = max([maxx + margin, *(s.x + 6.0 for s in starts)])
    high_y = max([maxy + margin, *(s.y + 6.0 for s in starts)])
    axes.set_xlim(low_x, high_x)
    axes.set_ylim(low_y, high_y)
    axes.set_aspect("equal")
    axes.set_xlabel("x (m)")
    axes.set_ylabel("y (m)")
