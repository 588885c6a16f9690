"""Traffic lights in pictures: a head for each signalized link (a bar just past its fork's
stop line, and a pedestrian signal's bar at each end of its crossing, inside the strip:
service.core.network.geometry) in the colour its program shows at a moment, and a strip
under the time-distance panel with each road user's signal over the test-case.

Colours of SUMO's signal states: ``G`` (protected green) dark green, ``g`` (permissive
green) light green, ``y`` amber, ``r`` and ``u`` (red-yellow: still red) red, ``s`` (right
on red after a stop) red with a white dot. The results browser (ui/ui.js,
SIGNAL_COLOURS) draws the same colours; a test holds the two tables equal.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from matplotlib.artist import Artist
from matplotlib.axes import Axes
from matplotlib.lines import Line2D
from matplotlib.patches import Circle, Patch
from matplotlib.patches import Polygon as PolygonPatch

from service.core.checker.check import EGO
from service.core.motion.events import EventKind, compute_events
from service.core.motion.poses import PoseSample
from service.core.network import Intersection, SignalProgram
from service.core.network.geometry import HEAD_DEPTH, pedestrian_heads, signal_heads
from service.core.network.model import Point
from service.core.network.signals import COLOUR_WORDS
from service.core.testcase import TestCase

SIGNAL_COLOURS = {
    "G": "#0a7d2c",
    "g": "#7ddc72",
    "y": "#f2a600",
    "Y": "#f2a600",
    "r": "#d42020",
    "u": "#d42020",
    "s": "#d42020",
    "O": "#1fa6b8",
    "o": "#9a6a1c",
}
MARKED = "s"  # the colour drawn with a dot on it
MARK = "#ffffff"
UNKNOWN = "#8c8c8c"  # a head whose junction has no program (the network's was refused)
COLOUR_ORDER = "GgyYrusOo"  # the legend's order
HEAD_EDGE = "#3c3c3c"


def signalized(intersection: Intersection) -> bool:
    """Some route of ``intersection`` has a signal: its pictures draw heads."""
    return any(route.link_index >= 0 for route in intersection.routes.values())


def legend_words(colour: str) -> str:
    """A colour's name in a legend: SUMO's letter and what it means."""
    return f"{colour} {COLOUR_WORDS[colour]}"


@dataclass
class _Head:
    link_index: int
    corners: tuple[Point, Point, Point, Point]
    bar: PolygonPatch
    dot: Circle


class SignalHeads:
    """The heads of ``intersection``'s signalized links on a map, recoloured by ``show``:
    drawn once, as the animation needs (``animated``: drawn only when a frame asks). Each
    bar's SVG id is ``signal-head-FORK-LINK``, its dot's ``signal-dot-FORK-LINK``; a
    pedestrian signal's ``pedestrian-head-WALK`` and ``pedestrian-dot-WALK`` (the walk that
    starts at it, its + or - as ``plus`` or ``minus``: ``C_c0-plus``)."""

    def __init__(self, axes: Axes, intersection: Intersection, animated: bool = False) -> None:
        self.program: SignalProgram | None = intersection.signals
        self.heads: list[_Head] = []
        found = [(f"signal-%s-{h.fork}-{h.link_index}", h.link_index, h.corners)
                 for h in signal_heads(intersection)]  # fmt: skip
        found += [(f"pedestrian-%s-{walk_name(h.walk)}", h.link_index, h.corners)
                  for h in pedestrian_heads(intersection)]  # fmt: skip
        for name, link, corners in found:
            bar = PolygonPatch(
                corners, closed=True, facecolor=UNKNOWN, edgecolor=HEAD_EDGE, linewidth=0.4,
                zorder=4.5, animated=animated, gid=name % "head",
            )  # fmt: skip
            xs, ys = zip(*corners, strict=True)
            centre = (sum(xs) / 4.0, sum(ys) / 4.0)
            width = min(_side(corners[0], corners[1]), _side(corners[1], corners[2]), HEAD_DEPTH)
            dot = Circle(centre, width * 0.3, facecolor=MARK, edgecolor="none", zorder=4.6,
                         visible=False, animated=animated, gid=name % "dot")  # fmt: skip
            axes.add_patch(bar)
            axes.add_patch(dot)
            self.heads.append(_Head(link, corners, bar, dot))

    def show(self, t: float) -> list[Artist]:
        """Every head in its colour at time ``t`` (s); the artists, dots after bars."""
        for drawn in self.heads:
            colour = None if self.program is None else self.program.colour(drawn.link_index, t)
            drawn.bar.set_facecolor(SIGNAL_COLOURS.get(colour or "", UNKNOWN))
            drawn.dot.set_visible(colour == MARKED)
        return [h.bar for h in self.heads] + [h.dot for h in self.heads]

    def points(self) -> np.ndarray:
        """Points that cover the heads (corners and centres): labels keep off them."""
        found = [(x, y) for h in self.heads for x, y in (*h.corners, h.dot.center)]
        return np.array(found, dtype=float).reshape(-1, 2)

    def colours_used(self) -> list[str]:
        """The colours any of the heads shows at some time, in the legend's order."""
        if self.program is None:
            return []
        links = {h.link_index for h in self.heads}
        seen = {p.state[link] for p in self.program.phases for link in links}
        return [c for c in COLOUR_ORDER if c in seen]


def walk_name(walk: str) -> str:
    """A walk's id as an SVG id takes it: ``C_c0+`` as ``C_c0-plus``."""
    return walk[:-1] + ("-plus" if walk.endswith("+") else "-minus")


def _side(a: tuple[float, float], b: tuple[float, float]) -> float:
    return float(((a[0] - b[0]) ** 2 + (a[1] - b[1]) ** 2) ** 0.5)


def colour_handles(colours: Sequence[str]) -> tuple[list[Any], list[str]]:
    """Legend handles and labels for ``colours``: a swatch each, the marked one dotted."""
    handles: list[Any] = []
    for colour in colours:
        swatch = Patch(facecolor=SIGNAL_COLOURS[colour], edgecolor=HEAD_EDGE, linewidth=0.4)
        if colour == MARKED:
            dot = Line2D([], [], marker="o", color=MARK, linestyle="none", markersize=3)
            handles.append((swatch, dot))
        else:
            handles.append(swatch)
    return handles, [legend_words(c) for c in colours]


@dataclass(frozen=True)
class StripRow:
    """One row of the signal strip: a car, its colour, its route's link, and the times
    it entered the junction (a triangle each, in ``marks``' colours); or a pedestrian, her
    crossing's link, and the times she stepped onto it."""

    label: str
    colour: str
    link: int
    entries: tuple[tuple[float, str], ...]  # (time, colour of the triangle)
    walker: bool = False  # a pedestrian's row: her crossing's signal


STRIP_ROW = 0.26  # inches a row of the strip takes
STRIP_DOTS = 40  # an s run has a dot every 1/STRIP_DOTS of the duration


def draw_signal_strip(
    strip: Axes, program: SignalProgram, rows: Sequence[StripRow], duration: float
) -> None:
    """Each row's signal over [0, ``duration``] as bars in its colours (top row first),
    a triangle where the car entered the junction."""
    for k, row in enumerate(rows):
        y = len(rows) - 1 - k
        for start, end, colour in program.timeline(row.link, duration):
            strip.broken_barh(
                [(start, end - start)], (y - 0.35, 0.7), facecolors=SIGNAL_COLOURS[colour],
                edgecolor="none",
            )  # fmt: skip
            if colour == MARKED:  # dotted along its run
                every = duration / STRIP_DOTS
                dots = np.arange(start + every / 2.0, end, every)
                strip.plot(dots, np.full(len(dots), float(y)), "o", color=MARK, ms=2.2)
        for t, colour in row.entries:
            strip.plot([t], [y], "^", mfc=colour, mec="black", mew=0.6, ms=6, zorder=3)
    strip.set_yticks(range(len(rows)), [row.label for row in reversed(rows)], fontsize=8)
    for tick, row in zip(strip.get_yticklabels(), reversed(rows), strict=True):
        tick.set_color(row.colour)
    strip.set_ylim(-0.6, len(rows) - 0.4)
    strip.tick_params(axis="y", length=0)
    strip.set_xlabel("time (s)")
    if any(row.walker for row in rows):
        title = ("each road user's signal (colours: the map's legend); ▲ entered the junction "
                 "or stepped onto the crossing")  # fmt: skip
    else:
        title = "each car's signal (colours: the map's legend); ▲ entered the junction"
    strip.set_title(title, fontsize=8, loc="left")


def signal_rows(
    testcase: TestCase,
    intersection: Intersection,
    egos: Sequence[tuple[str, Sequence[PoseSample]]],
    colours: Sequence[str],
    walker_colours: Sequence[str] = (),
) -> list[StripRow]:
    """The strip's rows: the ego, then each non-ego (in ``colours``) whose route has a
    signal, with the times they entered the junction: each drawn ego path's (``egos``:
    its colour and samples), computed as the checker computes events; the non-egos' from
    their events; then each pedestrian (in ``walker_colours``) whose crossing has a signal,
    with the times she stepped onto it. None without a program."""
    if intersection.signals is None:
        return []
    rows = []
    ego = testcase.ego
    route = intersection.route(ego.route.id)
    if route.link_index >= 0:
        entries = []
        for colour, samples in egos:
            events = compute_events(
                samples, ego.length, ego.width, intersection, route.fork,
                testcase.params.arrival_distance, testcase.params.v_stop,
            )  # fmt: skip
            entries += [(e.time, colour) for e in events if e.kind is EventKind.ENTERED][:1]
        rows.append(StripRow(EGO, "black", route.link_index, tuple(entries)))
    for nonego, colour in zip(testcase.nonegos, colours, strict=True):
        link = intersection.route(nonego.route.id).link_index
        if link >= 0:
            entered = [(e.t, colour) for e in nonego.events if e.kind.value == EventKind.ENTERED]
            rows.append(StripRow(nonego.id, colour, link, tuple(entered)))
    for person, colour in zip(testcase.pedestrians, walker_colours, strict=True):
        walk = intersection.walks.get(person.walk)
        link = -1 if walk is None else intersection.crossings[walk.crossing].link_index
        if link >= 0:
            entered = [(e.t, colour) for e in person.events if e.kind.value == EventKind.ENTERED]
            rows.append(StripRow(person.id, colour, link, tuple(entered), walker=True))
    return rows
