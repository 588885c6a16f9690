"""People on foot and crosswalks in pictures (docs/pedestrians.md): each crossing of the
junction as a zebra (its bars white on a dark strip, service.core.network.geometry), the
sidewalks and walking areas lightly, and each pedestrian of a test-case as a disc in a
colour of her own (PEDESTRIAN_COLOURS: none of them a car's), her path dotted.

The results browser (ui/ui.js, PEDESTRIAN_COLOURS) draws the same colours; a test holds
the two tables equal.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.collections import PolyCollection
from matplotlib.lines import Line2D
from matplotlib.patches import Patch
from shapely.geometry import LineString, Polygon

from service.core.motion.poses import PoseSample
from service.core.network import Intersection
from service.core.network.geometry import zebra_stripes
from service.core.network.load import parsed_network
from service.core.testcase import TestCase

# fuchsia, deep violet, navy, dark green: at least 30 apart (CIELAB delta E) from the
# cars' colours here and in the browser, the ego's, the certificates' and the roads', and
# from one another (tests/pictures/test_pedestrians.py)
PEDESTRIAN_COLOURS = ["#ff00ff", "#6200ea", "#000080", "#1b5e20"]
CROSSWALK = "#8a8d93"  # the strip under the zebra's bars
STRIPE = "#ffffff"
PAVEMENT = "#ebe6da"  # sidewalks and walking areas
DISC = 5.0  # points: a pedestrian's disc on the test-case's map (the GIF's: GIF_DISC)
GIF_DISC = 7.0
DOTTED = ":"  # a pedestrian's path and curve


@dataclass(frozen=True)
class Walker:
    """A pedestrian as the pictures draw her: id, what the legend and the panel call her,
    her colour, samples and size."""

    id: str
    label: str
    colour: str
    samples: Sequence[PoseSample]
    length: float
    width: float


def walkers(testcase: TestCase) -> list[Walker]:
    """Every pedestrian of ``testcase`` in order, each in her colour."""
    return [
        Walker(person.id, f"{person.id} (pedestrian, {person.walk}, level {person.added_in})",
               PEDESTRIAN_COLOURS[k % len(PEDESTRIAN_COLOURS)],
               [PoseSample(**s.model_dump()) for s in person.trajectory], person.length,
               person.width)
        for k, person in enumerate(testcase.pedestrians)
    ]  # fmt: skip


def draw_pavements(axes: Axes, intersection: Intersection) -> None:
    """The sidewalks of the junction's roads and the walking areas at its crossings' ends,
    lightly, under everything else; nothing at a junction without crossings."""
    if not intersection.crossings:
        return
    net = parsed_network(intersection.network_file)
    edges = {f.edge for f in intersection.forks.values()}
    edges |= {e.edge for e in intersection.exits.values()}
    shapes = []
    for edge in sorted(edges):
        for lane in net.getEdge(edge).getLanes():
            if lane.allows("pedestrian") and not lane.allows("passenger"):
                line = LineString([(x, y) for x, y, *_ in lane.getShape()])
                shapes.append(line.buffer(lane.getWidth() / 2.0, cap_style="flat"))
    areas = sorted({end for crossing in intersection.crossings.values() for end in crossing.ends})
    for area in areas:
        outline = [(x, y) for x, y, *_ in net.getEdge(area).getLanes()[0].getShape()]
        if len(outline) >= 3:
            shapes.append(Polygon(outline).buffer(0))
    rings = [np.array(part.exterior.coords) for shape in shapes
             for part in getattr(shape, "geoms", [shape]) if not part.is_empty]  # fmt: skip
    axes.add_collection(PolyCollection(rings, facecolors=PAVEMENT, edgecolors="none",
                                       zorder=0.2, gid="pavement"))  # fmt: skip


def draw_crosswalks(axes: Axes, intersection: Intersection) -> None:
    """Each crossing as a zebra over the junction's area and under the paths: its strip
    dark, its bars white; SVG ids ``crosswalk-CROSSING`` (the strip) and
    ``crosswalk-stripes-CROSSING`` (the bars), the crossing's id without SUMO's colon."""
    for crossing in sorted(intersection.crossings.values(), key=lambda c: c.id):
        name = crossing.id.lstrip(":")
        strip = [np.array(part.exterior.coords)
                 for part in getattr(crossing.polygon, "geoms", [crossing.polygon])]  # fmt: skip
        axes.add_collection(PolyCollection(strip, facecolors=CROSSWALK, edgecolors="none",
                                           zorder=0.5, gid=f"crosswalk-{name}"))  # fmt: skip
        bars = PolyCollection([np.array(bar) for bar in zebra_stripes(crossing)],
                              facecolors=STRIPE, edgecolors="none", zorder=0.6)  # fmt: skip
        bars.set_gid(f"crosswalk-stripes-{name}")
        axes.add_collection(bars)


def crosswalk_handles(intersection: Intersection) -> tuple[list[Any], list[str]]:
    """The legend's entries for what draw_pavements and draw_crosswalks drew (none without
    crossings)."""
    if not intersection.crossings:
        return [], []
    zebra = Patch(facecolor=CROSSWALK, edgecolor=STRIPE, hatch="||||", linewidth=0.0)
    pavement = Patch(facecolor=PAVEMENT, edgecolor="0.6", linewidth=0.4)
    return [zebra, pavement], ["crosswalk", "sidewalk, walking area"]


def draw_walker(axes: Axes, panel: Axes, walker: Walker, every: int) -> np.ndarray:
    """One pedestrian on the map, her path dotted and a disc every ``every`` samples (a
    hollow one at her start), and her distance walked over time on the panel, dotted. The
    points drawn on the map, which labels should not cover."""
    drawn = walker.samples
    xs, ys = [s.x for s in drawn], [s.y for s in drawn]
    axes.plot(xs, ys, linestyle=DOTTED, color=walker.colour, linewidth=1.5, zorder=3.2)
    shown = list(drawn[::every])
    axes.plot([s.x for s in shown[1:]], [s.y for s in shown[1:]], "o", ms=DISC,
              color=walker.colour, mec="white", mew=0.6, zorder=3.6)  # fmt: skip
    axes.plot([drawn[0].x], [drawn[0].y], "o", ms=DISC + 1.0, color=walker.colour,
              mfc="white", mew=1.2, zorder=5)  # fmt: skip
    axes.plot([], [], linestyle=DOTTED, marker="o", ms=DISC, color=walker.colour,
              mec="white", mew=0.6, label=walker.label)  # fmt: skip
    panel.plot([s.t for s in drawn], [s.distance for s in drawn], linestyle=DOTTED,
               color=walker.colour, linewidth=1.8, label=walker.label)  # fmt: skip
    return np.column_stack([xs, ys])


def walker_artist(axes: Axes, walker: Walker) -> Line2D:
    """The GIF's disc of a pedestrian, animated, at no place until a frame puts it."""
    (disc,) = axes.plot([], [], "o", ms=GIF_DISC, color=walker.colour, mec="white", mew=0.8,
                        zorder=3.5, animated=True, label=f"{walker.id} (pedestrian)")  # fmt: skip
    return disc
