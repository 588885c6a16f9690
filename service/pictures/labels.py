"""Labels placed beside the things they name, none over another and none outside its axes:
a greedy placement in a fixed order, so the same picture comes out every time."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from matplotlib.axes import Axes
from matplotlib.text import Annotation

GAP = 1.5  # points between a label and what it is beside, and between two labels
RINGS = (0.0, 4.0, 9.0)  # points further out, tried in turn when nearer places are taken


@dataclass(frozen=True)
class Spot:
    """Where a label may go: ``anchor`` (data coordinates) is what it names; it is tried in
    each direction of ``directions`` (unit vectors, data axes, in the order of preference),
    its nearest side ``metres[k]`` (what it labels: a car's half extent that way) and
    ``points`` (a marker's radius, a gap) from the anchor in direction k."""

    anchor: tuple[float, float]
    directions: Sequence[tuple[float, float]]
    metres: Sequence[float]
    points: float = GAP


class LabelPlacer:
    """Places labels one by one on an axes whose limits and size are final: each takes the
    first free place (inside the axes, over no label placed before) that covers the fewest
    obstacle points (paths, markers), or none when no place is free."""

    def __init__(self, axes: Axes, obstacles: np.ndarray | None = None) -> None:
        axes.apply_aspect()
        self.axes = axes
        self.renderer = axes.figure.canvas.get_renderer()  # type: ignore[attr-defined]
        self.pixels_per_point = axes.figure.dpi / 72.0
        self.frame = axes.get_window_extent(self.renderer).extents  # x0, y0, x1, y1
        origin, east = axes.transData.transform([(0.0, 0.0), (1.0, 0.0)])
        self.points_per_metre = float(east[0] - origin[0]) / self.pixels_per_point
        self.boxes = np.empty((0, 4))
        points = np.empty((0, 2)) if obstacles is None else np.asarray(obstacles, float)
        self.obstacles = axes.transData.transform(points) if len(points) else np.empty((0, 2))

    def place(self, label: Annotation, spot: Spot) -> bool:
        """Move ``label`` (an annotation of ``spot.anchor``, its text offset in points) to
        its best free place and keep that place taken; False (the label untouched) when
        there is none."""
        box = label.get_window_extent(self.renderer)
        half = np.array([box.width, box.height]) / 2.0
        anchor = self.axes.transData.transform(spot.anchor)
        best: tuple[int, np.ndarray] | None = None
        for ring in RINGS:
            for direction, metres in zip(spot.directions, spot.metres, strict=True):
                clearance = metres * self.points_per_metre + spot.points + ring
                centre = self._centre(anchor, direction, clearance, half)
                covered = self._covered(centre, half)
                if covered is not None and (best is None or covered < best[0]):
                    best = (covered, centre)
                    if covered == 0:
                        break
            if best is not None and best[0] == 0:
                break
        if best is None:
            return False
        centre = best[1]
        label.xyann = tuple((centre - anchor) / self.pixels_per_point)
        label.set_horizontalalignment("center")
        label.set_verticalalignment("center")
        self.boxes = np.vstack([self.boxes, np.concatenate([centre - half, centre + half])])
        return True

    def _centre(
        self, anchor: np.ndarray, direction: tuple[float, float], points: float, half: np.ndarray
    ) -> np.ndarray:
        """The centre of a box whose side nearest to ``anchor`` is ``points`` away from it in
        ``direction`` (the box's half extent along the direction added)."""
        ux, uy = direction
        norm = math.hypot(ux, uy) or 1.0
        ux, uy = ux / norm, uy / norm
        out = points * self.pixels_per_point + abs(ux) * half[0] + abs(uy) * half[1]
        centre: np.ndarray = anchor + np.array([ux, uy]) * out
        return centre

    def _covered(self, centre: np.ndarray, half: np.ndarray) -> int | None:
        """How many obstacle points a box at ``centre`` covers; None where it may not go
        (outside the axes, or over a label placed before, with a gap)."""
        x0, y0 = centre - half
        x1, y1 = centre + half
        left, bottom, right, top = self.frame
        if x0 < left or y0 < bottom or x1 > right or y1 > top:
            return None
        gap = GAP * self.pixels_per_point
        placed = self.boxes
        if len(placed) and np.any(
            (placed[:, 0] < x1 + gap) & (placed[:, 2] > x0 - gap)
            & (placed[:, 1] < y1 + gap) & (placed[:, 3] > y0 - gap)
        ):  # fmt: skip
            return None
        points = self.obstacles
        if not len(points):
            return 0
        inside = (
            (points[:, 0] > x0) & (points[:, 0] < x1) & (points[:, 1] > y0) & (points[:, 1] < y1)
        )
        return int(np.count_nonzero(inside))
