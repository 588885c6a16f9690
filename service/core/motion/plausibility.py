"""Trajectories no car can drive: a jump between two samples that no speed explains.

A stored trajectory that teleports (a hand-edited file, a broken converter, samples lost in
the middle) is still a valid document, and the checker judges it as written; but a test
engineer should hear of it before a suite is grown on top of it. The bound is generous:
the faster of the two sampled speeds for the whole step, one g of acceleration on top, and
half a metre for how the centre of a turning rectangle may move; and never faster than a
road car at all.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from typing import Protocol

STRONGEST_ACCELERATION = 9.81  # m/s^2: beyond any road car's pull-away or braking
FASTEST_CAR = 100.0  # m/s (360 km/h): no road car at an intersection is faster
TURN_SLACK = 0.5  # m a rectangle's centre may move beyond its speed on a tight turn


class Pose(Protocol):
    @property
    def t(self) -> float: ...
    @property
    def x(self) -> float: ...
    @property
    def y(self) -> float: ...
    @property
    def speed(self) -> float: ...


def first_jump(samples: Sequence[Pose]) -> str | None:
    """The first step in which the car moves further than any car could, in words, or
    None when every step is plausible."""
    for before, after in itertools.pairwise(samples):
        step = after.t - before.t
        moved = math.hypot(after.x - before.x, after.y - before.y)
        fastest = min(max(before.speed, after.speed), FASTEST_CAR)
        allowed = fastest * step + STRONGEST_ACCELERATION * step**2 + TURN_SLACK
        if moved > allowed:
            return (
                f"moves {moved:.1f} m between {before.t:.2f} s and {after.t:.2f} s, where its "
                f"speeds ({before.speed:.1f} and {after.speed:.1f} m/s) allow at most "
                f"{allowed:.1f} m"
            )
    return None
