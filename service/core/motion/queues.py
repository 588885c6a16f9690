"""Cars that share a fork: who is ahead of whom, where their paths part, the gap they keep.

A car's place on its fork is its distance along its own route from the stop line (the
fork's limit line), x = distance travelled - ``line``, where ``line`` is the distance at
which its front reaches the junction (its entered event; from the stop line's position
when it never enters). Every car from one fork drives the same path up to the stop line,
so these places compare directly there, and beyond it for as long as the two routes have
not parted.

Of two cars on one fork, the one with the larger place at the first sample is ahead. The
one behind follows it: while the leader's rear has not passed the point where their paths
part (``Follow.parting``; never on one route), the follower's front stays at least
``gap + headway x its speed`` behind the leader's rear. Every car follows every car ahead
of it on its fork, not only the next one: a car that turns off frees the road to the one
after it.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from shapely.geometry import Point

from service.core.motion.events import EventKind, LaneEvent
from service.core.motion.poses import PoseSample
from service.core.network import Fork, Intersection

PARTED = 0.3  # metres of clearance between two cars' outlines at which their paths have parted
PARTING_STEP = 0.25  # metres between the points where a parting is looked for
GAP_TOLERANCE = 1e-3  # metres: stored samples are rounded to a micrometre; the plans keep more


@dataclass(frozen=True)
class QueueCar:
    """A car as the queue rules see it."""

    id: str
    fork: str
    lane: str  # the connecting lane of its route
    length: float
    width: float
    line: float  # distance travelled at which its front reaches the junction
    first: float  # distance travelled at its first sample

    @property
    def start(self) -> float:
        """Metres from its front to the stop line at its first sample."""
        return self.line - self.first


@dataclass(frozen=True)
class Follow:
    """``follower`` drives behind ``leader`` on one fork until their paths part."""

    leader: str
    follower: str
    fork: str
    parting: float  # place (m past the stop line) where the paths part; inf on one route


def line_distance(
    samples: Sequence[PoseSample], length: float, fork: Fork, events: Sequence[LaneEvent]
) -> float:
    """The distance travelled at which the car's front reaches the junction: its entered
    event, or (a car that never enters) where it would be by the stop line's position."""
    entered = next((e for e in events if e.kind is EventKind.ENTERED), None)
    if entered is not None:
        return entered.distance
    last = samples[-1]
    rad, heading = math.radians(fork.heading), math.radians(last.heading)
    fx = last.x + math.sin(heading) * length / 2.0
    fy = last.y + math.cos(heading) * length / 2.0
    to_line = (fork.stop_line[0] - fx) * math.sin(rad) + (fork.stop_line[1] - fy) * math.cos(rad)
    return last.distance + to_line


def parting(
    junction: Intersection, lane_a: str, lane_b: str, width_a: float, width_b: float
) -> float:
    """Where (m past the fork's end, where the connecting lanes start) two routes from one
    fork part: the first point of ``lane_a``'s centreline from which two cars, one on
    each, no longer touch. Infinite for one connecting lane; the end of ``lane_a`` when
    they never part inside the junction (they merge into one exit: the checker's outlines
    decide beyond it)."""
    if lane_a == lane_b:
        return math.inf
    apart = round((width_a + width_b) / 2 + PARTED, 6)
    key = (str(junction.network_file), junction.junction, lane_a, lane_b, apart)
    if key not in _PARTINGS:
        _PARTINGS[key] = _parting(junction, lane_a, lane_b, apart)
    return _PARTINGS[key]


_PARTINGS: dict[tuple[str, str, str, str, float], float] = {}


def _parting(junction: Intersection, lane_a: str, lane_b: str, apart: float) -> float:
    a = junction.connecting_lanes[lane_a].centreline
    b = junction.connecting_lanes[lane_b].centreline
    steps = max(1, math.ceil(a.length / PARTING_STEP))
    for k in range(steps + 1):
        s = min(a.length, k * PARTING_STEP)
        point = a.interpolate(s)
        if b.distance(Point(point.x, point.y)) >= apart:
            return float(s)
    return float(a.length)


def follows(cars: Sequence[QueueCar], junction: Intersection) -> list[Follow]:
    """Every (leader, follower) pair of cars on one fork, the car ahead first."""
    found = []
    by_fork: dict[str, list[QueueCar]] = {}
    for car in cars:
        by_fork.setdefault(car.fork, []).append(car)
    for fork, group in by_fork.items():
        ordered = sorted(group, key=lambda c: (c.start, c.id))
        # places count from the limit line; connecting lanes start at the fork's end
        offset = junction.forks[fork].limit_offset
        for k, leader in enumerate(ordered):
            for follower in ordered[k + 1 :]:
                where = parting(junction, leader.lane, follower.lane, leader.width, follower.width)
                found.append(Follow(leader.id, follower.id, fork, where + offset))
    return found


def needed_gap(gap: float, headway: float, speed: float) -> float:
    """Metres a car at ``speed`` keeps between its front and the rear of the car ahead."""
    return gap + headway * max(speed, 0.0)


@dataclass(frozen=True)
class Places:
    """A car's place on its fork over time (x = distance - line) and its speed."""

    t: np.ndarray
    x: np.ndarray
    speed: np.ndarray
    length: float

    @staticmethod
    def of(samples: Sequence[PoseSample], car: QueueCar) -> Places:
        return Places(
            np.array([s.t for s in samples]),
            np.array([s.distance - car.line for s in samples]),
            np.array([s.speed for s in samples]),
            car.length,
        )

    def at(self, times: np.ndarray) -> np.ndarray:
        return np.asarray(np.interp(times, self.t, self.x))

    def first_time_at(self, place: float) -> float | None:
        """The first time the car's front reaches ``place`` (None: never)."""
        k = bisect.bisect_left(list(self.x), place)
        if k >= len(self.x):
            return None
        if k == 0:
            return float(self.t[0])
        x0, x1 = self.x[k - 1], self.x[k]
        share = (place - x0) / (x1 - x0) if x1 > x0 else 1.0
        return float(self.t[k - 1] + share * (self.t[k] - self.t[k - 1]))


def gap_fault(
    follow: Follow, leader: Places, follower: Places, gap: float, headway: float
) -> str | None:
    """What is wrong with the follower's distance to its leader (None: it keeps the gap at
    every sample of the follower while the leader's rear has not passed the parting)."""
    inside = (follower.t >= leader.t[0]) & (follower.t <= leader.t[-1])
    times = follower.t[inside]
    rear = leader.at(times) - leader.length
    ahead = rear - follower.x[inside]
    needed = gap + headway * np.maximum(follower.speed[inside], 0.0)
    short = (rear < follow.parting) & (ahead < needed - GAP_TOLERANCE)
    if not short.any():
        return None
    k = int(np.argmax(short))
    speed = float(follower.speed[inside][k])
    return (
        f"{follow.follower} is {ahead[k]:.2f} m behind {follow.leader} at {times[k]:.2f} s "
        f"(needs {gap:g} m + {headway:g} s x {speed:.1f} m/s = {needed[k]:.2f} m)"
    )
