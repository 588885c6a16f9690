"""Necessary conditions on a car's timing: the least time between two points of its drive.

A car that starts at a given speed (or any speed up to v_max), accelerates at most a_max,
brakes at most -a_min, never exceeds v_max and stands still at given distances cannot reach
a point sooner than these bounds say, whatever its speed profile. Step 2 states them as
difference constraints over event times (so it never proposes an order that no profile can
realise) and Step 3 plans its knot times with them; both read them from here.

Points are given by distance travelled from the start (the start itself is distance 0 at
t = 0). Two consecutive points at the same distance are a stand: the car stands still there
for at least ``DWELL`` seconds.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

DWELL = 0.5  # seconds a car stands still at least where it stands
SAME = 1e-9  # metres: points closer than this are one distance (a stand)


@dataclass(frozen=True)
class Bounds:
    """The speed and acceleration bounds of every car (a_min is negative)."""

    v_max: float
    a_max: float
    a_min: float

    def scaled(self, share: float) -> Bounds:
        """The bounds a plan uses when it keeps ``share`` of them in reserve for the curves."""
        return Bounds(share * self.v_max, share * self.a_max, share * self.a_min)


def fastest(distance: float, start_speed: float, accel: float, top: float) -> float:
    """Least time to cover ``distance`` from ``start_speed`` accelerating at most ``accel``
    up to ``top`` (braking to a stand is the same, backwards in time)."""
    if distance <= 0:
        return 0.0
    if start_speed >= top:
        return distance / top
    ramp = (top * top - start_speed * start_speed) / (2 * accel)
    if distance <= ramp:
        return (-start_speed + math.sqrt(start_speed**2 + 2 * accel * distance)) / accel
    return (top - start_speed) / accel + (distance - ramp) / top


def stands(distances: Sequence[float]) -> list[float]:
    """The distances where the car stands (two consecutive points at one distance)."""
    return [b for a, b in itertools.pairwise(distances) if abs(b - a) <= SAME]


def speed_caps(
    distances: Sequence[float], start_speed: float | None, bounds: Bounds
) -> list[float]:
    """The highest speed the car can have at each point (``distances[0]`` is the start):
    v_max, what it can gain from its start speed or from a stand behind it, and what it can
    still brake away before a stand ahead of it. ``start_speed`` None: any speed."""
    halts = stands(distances)
    caps = []
    for j, distance in enumerate(distances):
        cap = bounds.v_max
        if start_speed is not None:
            cap = (
                start_speed
                if j == 0
                else min(cap, math.sqrt(start_speed**2 + 2 * bounds.a_max * distance))
            )
        for halt in halts:
            gap = distance - halt
            accel = bounds.a_max if gap >= 0 else -bounds.a_min
            cap = min(cap, math.sqrt(2 * accel * abs(gap)))
        caps.append(cap)
    return caps


def least_gaps(
    distances: Sequence[float], start_speed: float | None, bounds: Bounds
) -> list[float]:
    """``gaps[j - 1]``: the least time from point j - 1 to point j, for j >= 1. Covering the
    distance takes at least as long as from the highest speed the car can have at the first
    point (accelerating at most a_max) and as arriving no faster than it can have at the
    second (braking at most -a_min), never above v_max; a stand takes ``DWELL``, an event
    at the start (point 1 where point 0 is) none."""
    caps = speed_caps(distances, start_speed, bounds)
    gaps = []
    for j in range(1, len(distances)):
        gap = distances[j] - distances[j - 1]
        if gap <= SAME:
            gaps.append(0.0 if j == 1 else DWELL)  # an event at the start, or a stand
            continue
        gaps.append(
            max(
                fastest(gap, caps[j - 1], bounds.a_max, bounds.v_max),
                fastest(gap, caps[j], -bounds.a_min, bounds.v_max),
            )
        )
    return gaps


STOP_BEFORE_ENTRY = 0.5  # metres before entering the junction where a stopping car stands


def stand_before(entry: float, previous: float) -> float:
    """Where a car that stops before entering the junction at ``entry`` stands: half a
    metre before, or halfway from ``previous`` (its last point before) when that is closer."""
    return entry - min(STOP_BEFORE_ENTRY, (entry - previous) / 2.0)


def duration_range(
    distance: float, v0: float, v1: float, bounds: Bounds, floor: float = 0.0
) -> tuple[float, float] | None:
    """How long covering ``distance`` can take when the car passes its two ends at speeds
    v0 and v1 (accelerating at most a_max, braking at most -a_min, never above v_max, never
    below ``floor``): (shortest, longest), the longest infinite when it can stand in
    between; None when no motion connects the two speeds."""
    up, down, top = bounds.a_max, -bounds.a_min, bounds.v_max
    if distance <= SAME:
        return (DWELL, math.inf) if v0 <= SAME and v1 <= SAME else None
    if v1 * v1 - v0 * v0 > 2 * up * distance or v0 * v0 - v1 * v1 > 2 * down * distance:
        return None
    weights = 1 / (2 * up) + 1 / (2 * down)
    peak = math.sqrt((distance + v0 * v0 / (2 * up) + v1 * v1 / (2 * down)) / weights)
    if peak <= top:
        shortest = (peak - v0) / up + (peak - v1) / down
    else:
        ramps = (top * top - v0 * v0) / (2 * up) + (top * top - v1 * v1) / (2 * down)
        shortest = (top - v0) / up + (top - v1) / down + (distance - ramps) / top
    low_square = (v0 * v0 / (2 * down) + v1 * v1 / (2 * up) - distance) / weights
    if low_square > floor * floor:
        low = math.sqrt(low_square)
        return shortest, (v0 - low) / down + (v1 - low) / up
    if floor <= 0:
        return shortest, math.inf
    ramps = (v0 * v0 - floor * floor) / (2 * down) + (v1 * v1 - floor * floor) / (2 * up)
    return shortest, (v0 - floor) / down + (v1 - floor) / up + (distance - ramps) / floor


LINGER_LEVELS = (1.0, 2.0, 4.0)  # a segment lingers at c x D / sqrt(2 a D) seconds or more
LINGER_GAIN = 0.02  # seconds a lingering bound must add to the least gaps to be worth stating


@dataclass(frozen=True)
class Linger:
    """If segment ``segment`` (from point segment - 1 to point segment) takes at least
    ``seconds``, point ``other`` comes at least ``least`` after point ``segment`` (or, when
    ``other`` is earlier, point segment - 1 comes at least ``least`` after it)."""

    segment: int
    seconds: float
    other: int
    least: float


def lingering(distances: Sequence[float], bounds: Bounds) -> list[Linger]:
    """What a slow segment says about the points around it. A car that takes at least T to
    cover a segment of length D was at some point slower than its average D / T, so at the
    segment's end it is at most sqrt((D / T)^2 + 2 a_max D) fast, and at its start at most
    sqrt((D / T)^2 - 2 a_min D): a car that waited on the way cannot then be at full speed,
    nor have come at full speed. That bounds the time to the later points and from the
    earlier ones (``distances[0]`` is the start). Only bounds that add at least LINGER_GAIN
    to the least gaps are given."""
    gaps = least_gaps(distances, None, bounds)
    reached = [0.0, *itertools.accumulate(gaps)]  # least time from the start to each point
    found = []
    for j in range(1, len(distances)):
        length = distances[j] - distances[j - 1]
        if length <= SAME:
            continue
        crawl = math.sqrt(2 * bounds.a_max * length)
        for level in LINGER_LEVELS:
            seconds = level * length / crawl
            pace = length / seconds
            out = math.sqrt(pace * pace + 2 * bounds.a_max * length)
            into = math.sqrt(pace * pace - 2 * bounds.a_min * length)
            for k in range(j + 1, len(distances)):
                least = fastest(distances[k] - distances[j], out, bounds.a_max, bounds.v_max)
                if least >= reached[k] - reached[j] + LINGER_GAIN:
                    found.append(Linger(j, seconds, k, least))
            for k in range(j - 1):
                span = distances[j - 1] - distances[k]
                least = fastest(span, into, -bounds.a_min, bounds.v_max)
                if least >= reached[j - 1] - reached[k] + LINGER_GAIN:
                    found.append(Linger(j, seconds, k, least))
    return found
