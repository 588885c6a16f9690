"""People on foot as the checker sees them: a pedestrian's events on its walk, and a car's
events at the crosswalks (docs/pedestrians.md, "Events of a pedestrian").

Events of a pedestrian, each with a time and the distance walked, ``lane`` the crossing's
id for the first four:

- ``arrived``: the front (the middle of the rectangle's leading edge) comes within the
  arrival distance of the crossing's polygon (at the curb);
- ``stopped``: the speed first falls to ``v_stop`` or below between arriving and entering;
- ``entered``: the rectangle first overlaps the crossing's polygon (steps onto it);
- ``entered_lane`` / ``left_lane``: the rectangle starts / stops overlapping a connecting
  lane of the junction (a car's), or its crossing's lane, for every one it touches;
- ``exited``: the rectangle stops overlapping the crossing for good.

A car's events gain ``entered_lane`` / ``left_lane`` for every crossing lane its rectangle
touches (``crossing_events``): when it reaches and leaves the crosswalk.

``pedestrian_events`` and ``crossing_events`` are the boundary with the events stage
(service.core.motion), written in parallel: until it computes them, they are computed here
with its geometry (service.core.motion.events: the same rectangles, "overlap" as interiors
meeting, the pose interpolated linearly between samples and each event refined between
them to ``TOLERANCE`` metres, ``SPLIT`` shares a round). A car lane that the car's own
events already name is not computed again, so the two never double an event.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TypeAlias

import numpy as np
import shapely
from shapely.geometry import MultiPolygon, Polygon

from service.core.motion.events import (
    SPLIT,
    TOLERANCE,
    EventKind,
    LaneEvent,
    overlapping,
    rectangles,
)
from service.core.motion.poses import PoseSample, interpolate_heading
from service.core.network import Intersection, Walk

Region: TypeAlias = Polygon | MultiPolygon
ORDER = list(EventKind)


@dataclass(frozen=True)
class Walker:
    """A pedestrian as the checker sees it: id, walk, crossing, size, samples and events."""

    id: str
    walk: str
    crossing: str  # the crossing's id (":C_c0"): its events' lane
    lane: str  # the crossing's lane (":C_c0_0"): what the rules name
    length: float
    width: float
    samples: Sequence[PoseSample]
    events: tuple[LaneEvent, ...]


def walker(
    junction: Intersection,
    person: str,
    walk_id: str,
    length: float,
    width: float,
    samples: Sequence[PoseSample],
    arrival_distance: float,
    v_stop: float,
) -> Walker:
    """The pedestrian ``person`` on walk ``walk_id`` (raises UnknownWalk naming the walks)."""
    walk = junction.walk(walk_id)
    crossing = junction.crossings[walk.crossing]
    events = pedestrian_events(
        junction, walk, samples, length, width, arrival_distance, v_stop
    )  # fmt: skip
    return Walker(person, walk.id, crossing.id, crossing.lane, length, width, samples,
                  tuple(events))  # fmt: skip


def pedestrian_events(
    junction: Intersection,
    walk: Walk,
    samples: Sequence[PoseSample],
    length: float,
    width: float,
    arrival_distance: float,
    v_stop: float,
) -> list[LaneEvent]:
    """Every event of a pedestrian on ``walk`` (module docstring), ordered by distance then
    kind. The boundary with the events stage: until it lands, computed here."""
    if len(samples) < 2:
        return []
    track = _Track(samples, length, width)
    crossing = junction.crossings[walk.crossing]
    on_it = _region_events(track, crossing.polygon, crossing.id, EventKind.ENTERED,
                           EventKind.EXITED)  # fmt: skip
    entries = [e for e in on_it if e.kind is EventKind.ENTERED]
    exits = [e for e in on_it if e.kind is EventKind.EXITED]
    events = entries[:1]
    if entries and exits and exits[-1].time >= entries[-1].time:
        events.append(exits[-1])
    arrived = _arrival(track, crossing.polygon, crossing.id, arrival_distance)
    entered = entries[0] if entries else None
    if arrived is not None and (entered is None or arrived.time <= entered.time):
        events.append(arrived)
        stopped = _stop(track, crossing.id, arrived, entered.time if entered else math.inf,
                        v_stop)  # fmt: skip
        if stopped is not None:
            events.append(stopped)
    regions = [(lane.id, lane.polygon) for lane in junction.connecting_lanes.values()]
    for lane_id, polygon in [*regions, (crossing.lane, crossing.polygon)]:
        events += _region_events(track, polygon, lane_id, EventKind.ENTERED_LANE,
                                 EventKind.LEFT_LANE)  # fmt: skip
    return _ordered(events)


def crossing_events(
    junction: Intersection,
    samples: Sequence[PoseSample],
    length: float,
    width: float,
    known: Sequence[LaneEvent] = (),
) -> list[LaneEvent]:
    """A car's ``entered_lane`` / ``left_lane`` for every crossing lane of the junction its
    rectangle touches, but those ``known`` already names (the events stage's own, once it
    computes them); none without crossings."""
    named = {e.lane for e in known if e.kind in (EventKind.ENTERED_LANE, EventKind.LEFT_LANE)}
    crossings = [c for c in junction.crossings.values() if c.lane not in named]
    if len(samples) < 2 or not crossings:
        return []
    track = _Track(samples, length, width)
    events: list[LaneEvent] = []
    for crossing in crossings:
        events += _region_events(track, crossing.polygon, crossing.lane, EventKind.ENTERED_LANE,
                                 EventKind.LEFT_LANE)  # fmt: skip
    return events


def with_crossing_events(
    junction: Intersection,
    samples: Sequence[PoseSample],
    length: float,
    width: float,
    events: Sequence[LaneEvent],
) -> list[LaneEvent]:
    """A car's ``events`` with its crossing lane events, in the events' order."""
    extra = crossing_events(junction, samples, length, width, events)
    return _ordered([*events, *extra]) if extra else list(events)


def _ordered(events: list[LaneEvent]) -> list[LaneEvent]:
    return sorted(events, key=lambda e: (e.distance, e.time, ORDER.index(e.kind), e.lane))


class _Track:
    """Samples as arrays, with the pose anywhere between two samples (as in
    service.core.motion.events)."""

    def __init__(self, samples: Sequence[PoseSample], length: float, width: float) -> None:
        self.samples = samples
        self.length = length
        self.width = width
        self.t = np.array([s.t for s in samples])
        self.distance = np.array([s.distance for s in samples])
        self.rects = rectangles(
            np.array([s.x for s in samples]), np.array([s.y for s in samples]),
            np.array([s.heading for s in samples]), length, width,
        )  # fmt: skip

    def between(self, k: int, share: float) -> tuple[float, float]:
        """(time, distance) at ``share`` of the way from sample k to k+1."""
        a, b = self.samples[k], self.samples[k + 1]
        return a.t + share * (b.t - a.t), a.distance + share * (b.distance - a.distance)

    def poses_between(
        self, k: int, shares: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(x, y, heading) at ``shares`` of the way from sample k to k+1."""
        a, b = self.samples[k], self.samples[k + 1]
        headings = np.array([interpolate_heading(a.heading, b.heading, s) for s in shares])
        return a.x + shares * (b.x - a.x), a.y + shares * (b.y - a.y), headings

    def rects_between(self, k: int, shares: np.ndarray) -> np.ndarray:
        x, y, heading = self.poses_between(k, shares)
        return rectangles(x, y, heading, self.length, self.width)

    def fronts(self, x: np.ndarray, y: np.ndarray, heading: np.ndarray) -> np.ndarray:
        rad = np.radians(heading)
        half = self.length / 2.0
        return shapely.points(x + np.sin(rad) * half, y + np.cos(rad) * half)  # type: ignore[no-any-return]

    def refine(self, k: int, flips: Callable[[np.ndarray], np.ndarray]) -> tuple[float, float]:
        """(time, distance) where the state flips between samples k and k+1: the first
        flip among SPLIT evenly spaced shares, then again within that gap, to TOLERANCE."""
        low, high = 0.0, 1.0
        span = max(abs(self.distance[k + 1] - self.distance[k]), TOLERANCE)
        while (high - low) * span > TOLERANCE:
            shares = low + (high - low) * np.arange(1, SPLIT + 1) / SPLIT
            flipped = np.flatnonzero(flips(shares))
            first = int(flipped[0]) if flipped.size else SPLIT - 1
            low, high = (float(shares[first - 1]) if first else low), float(shares[first])
        return self.between(k, high)


def _region_events(
    track: _Track, region: Region, lane: str, enter: EventKind, leave: EventKind
) -> list[LaneEvent]:
    shapely.prepare(region)
    inside = overlapping(track.rects, region)
    events = []
    if inside[0]:
        events.append(LaneEvent(enter, lane, float(track.t[0]), float(track.distance[0])))
    for k in np.flatnonzero(inside[1:] != inside[:-1]):
        was_inside = bool(inside[k])

        def flips(shares: np.ndarray, k: int = int(k), was: bool = was_inside) -> np.ndarray:
            return overlapping(track.rects_between(k, shares), region) != was  # type: ignore[no-any-return]

        time, distance = track.refine(int(k), flips)
        events.append(LaneEvent(leave if was_inside else enter, lane, time, distance))
    return events


def _arrival(
    track: _Track, region: Region, crossing: str, arrival_distance: float
) -> LaneEvent | None:
    """When the front first comes within ``arrival_distance`` of the crossing's polygon."""
    heading = np.array([s.heading for s in track.samples])
    x, y = np.array([s.x for s in track.samples]), np.array([s.y for s in track.samples])
    near = np.flatnonzero(shapely.distance(track.fronts(x, y, heading), region) <= arrival_distance)
    if near.size == 0:
        return None
    k = int(near[0])
    if k == 0:
        return LaneEvent(EventKind.ARRIVED, crossing, float(track.t[0]), float(track.distance[0]))

    def flips(shares: np.ndarray) -> np.ndarray:
        fronts = track.fronts(*track.poses_between(k - 1, shares))
        return shapely.distance(fronts, region) <= arrival_distance  # type: ignore[no-any-return]

    time, distance = track.refine(k - 1, flips)
    return LaneEvent(EventKind.ARRIVED, crossing, time, distance)


def _stop(
    track: _Track, crossing: str, arrived: LaneEvent, entered_at: float, v_stop: float
) -> LaneEvent | None:
    """The first moment at or below ``v_stop`` between arriving and entering (the speed
    interpolated linearly between samples)."""
    speeds = [s.speed for s in track.samples]
    for k, sample in enumerate(track.samples):
        if sample.t < arrived.time or sample.t >= entered_at or sample.speed > v_stop:
            continue
        time, distance = sample.t, sample.distance
        if k > 0 and speeds[k - 1] > v_stop:
            share = (speeds[k - 1] - v_stop) / (speeds[k - 1] - speeds[k])
            time, distance = track.between(k - 1, share)
            if time < arrived.time:
                time, distance = arrived.time, arrived.distance
        return LaneEvent(EventKind.STOPPED, crossing, time, distance)
    return None
