"""Collisions between two cars' trajectories: rectangles overlapping at any moment.

Both trajectories are sampled (any times); between samples each car moves linearly in
position and heading. Every interval of the finer time grid is subdivided so that neither
car moves more than ``RESOLUTION`` metres between two checks: cars 1.8 m wide cannot pass
through each other unseen, however fast they drive or however coarse the samples.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import shapely

from service.core.motion.events import rectangles
from service.core.motion.poses import PoseSample

RESOLUTION = 0.2  # metres of travel between two overlap checks


@dataclass(frozen=True)
class Collision:
    """The first moment two cars overlap: time and the centre of the overlap."""

    time: float
    x: float
    y: float


class Motion:
    """A car's pose at any time within its samples (absent before the first, after the last)."""

    def __init__(self, samples: Sequence[PoseSample], length: float, width: float) -> None:
        self.length = length
        self.width = width
        self.t = np.array([s.t for s in samples])
        self.x = np.array([s.x for s in samples])
        self.y = np.array([s.y for s in samples])
        self.heading = np.unwrap(np.radians([s.heading for s in samples]))

    @property
    def start(self) -> float:
        return float(self.t[0])

    @property
    def end(self) -> float:
        return float(self.t[-1])

    def poses(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(x, y, heading in degrees) at ``times`` (within [start, end])."""
        return (
            np.interp(times, self.t, self.x),
            np.interp(times, self.t, self.y),
            np.degrees(np.interp(times, self.t, self.heading)) % 360.0,
        )

    def rectangles(self, times: np.ndarray) -> np.ndarray:
        x, y, heading = self.poses(times)
        return rectangles(x, y, heading, self.length, self.width)


def first_collision(first: Motion, second: Motion) -> Collision | None:
    """The first moment the two cars' rectangles overlap (interiors meet), if any."""
    start, end = max(first.start, second.start), min(first.end, second.end)
    if end < start:
        return None
    grid = np.union1d(first.t, second.t)
    grid = np.unique(np.concatenate([[start], grid[(grid > start) & (grid < end)], [end]]))
    reach = (math.hypot(first.length, first.width) + math.hypot(second.length, second.width)) / 2
    x1, y1, _ = first.poses(grid)
    x2, y2, _ = second.poses(grid)
    gap = np.hypot(x1 - x2, y1 - y2)
    move = np.maximum(np.hypot(np.diff(x1), np.diff(y1)), np.hypot(np.diff(x2), np.diff(y2)))
    for k in range(len(grid) - 1):
        if min(gap[k], gap[k + 1]) > reach + move[k]:
            continue  # too far apart to touch anywhere in this interval
        steps = max(1, math.ceil(move[k] / RESOLUTION))
        times = np.linspace(grid[k], grid[k + 1], steps + 1)
        rects_a, rects_b = first.rectangles(times), second.rectangles(times)
        touching = shapely.intersects(rects_a, rects_b) & ~shapely.touches(rects_a, rects_b)
        if touching.any():
            j = int(np.argmax(touching))
            centre = shapely.intersection(rects_a[j], rects_b[j]).centroid
            return Collision(float(times[j]), float(centre.x), float(centre.y))
    return None
