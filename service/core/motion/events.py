"""Lane events of a car from its sampled poses and its rectangle.

Events (design section 1), each with a time and a distance travelled:

- ``arrived``: the front bumper comes within the arrival distance of the fork's limit line
  (measured along the fork's approach heading), with no car ahead of it on its fork that
  has not entered the junction yet (a car still behind another has not arrived: the
  caller says when the last car ahead entered, service.core.motion.queues);
- ``stopped``: the speed first falls to ``v_stop`` or below between arriving and entering;
- ``entered``: the rectangle first overlaps the junction beyond the fork's limit line (the
  fork's entry area, service.core.network.forks: the junction polygon, without the road
  behind the limit line where the polygon reaches upstream of it, and with the lanes after
  the line where the limit line lies before a short fork);
- ``entered_lane`` / ``left_lane``: the rectangle starts / stops overlapping a connecting
  lane, for every connecting lane of the junction it touches, not only its own;
- ``exited``: the rectangle stops overlapping the junction for good.

"Overlap" means the interiors intersect; touching edges do not count. Between two samples
the pose is interpolated linearly in distance and the time linearly in distance (constant
speed within a step), and each event is placed to within ``TOLERANCE`` metres,
so event distances are not truncated to a time step (the flip is searched among 16 shares
at once, then again within the gap where it happens). The same function serves Step 1
(constant speed) and the checker (any trajectory, stops included).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from enum import StrEnum

import numpy as np
import shapely
from shapely.geometry import MultiPolygon, Polygon

from service.core.motion.poses import PoseSample, interpolate_heading
from service.core.network import Fork, Intersection

TOLERANCE = 1e-4  # metres
SPLIT = 16  # shares tried at once in each round of the refinement


class EventKind(StrEnum):
    ARRIVED = "arrived"
    STOPPED = "stopped"
    ENTERED = "entered"
    ENTERED_LANE = "entered_lane"
    LEFT_LANE = "left_lane"
    EXITED = "exited"


@dataclass(frozen=True)
class LaneEvent:
    """One event of a car: kind, the lane it concerns, time (s) and distance travelled (m).

    ``lane`` is the fork for arrived, stopped and entered, the connecting lane for
    entered_lane and left_lane, and the junction id for exited.
    """

    kind: EventKind
    lane: str
    time: float
    distance: float


def rectangles(
    xs: np.ndarray, ys: np.ndarray, headings: np.ndarray, length: float, width: float
) -> np.ndarray:
    """Car rectangles (shapely polygons) for arrays of centre poses."""
    rad = np.radians(headings)
    fx, fy = np.sin(rad) * length / 2.0, np.cos(rad) * length / 2.0
    rx, ry = np.cos(rad) * width / 2.0, -np.sin(rad) * width / 2.0
    corners = np.stack(
        [
            np.stack([xs + fx + rx, ys + fy + ry], axis=-1),
            np.stack([xs + fx - rx, ys + fy - ry], axis=-1),
            np.stack([xs - fx - rx, ys - fy - ry], axis=-1),
            np.stack([xs - fx + rx, ys - fy + ry], axis=-1),
        ],
        axis=1,
    )
    return shapely.polygons(corners)  # type: ignore[no-any-return]


def overlapping(rects: np.ndarray, region: Polygon | MultiPolygon) -> np.ndarray:
    """Whether each rectangle's interior meets the region's interior."""
    return shapely.intersects(rects, region) & ~shapely.touches(rects, region)  # type: ignore[no-any-return]


class _Track:
    """Samples as arrays, with the pose anywhere between two samples."""

    def __init__(self, samples: Sequence[PoseSample], length: float, width: float) -> None:
        self.samples = samples
        self.length = length
        self.width = width
        self.t = np.array([s.t for s in samples])
        self.x = np.array([s.x for s in samples])
        self.y = np.array([s.y for s in samples])
        self.heading = np.array([s.heading for s in samples])
        self.distance = np.array([s.distance for s in samples])
        self.rects = rectangles(self.x, self.y, self.heading, length, width)

    def between(self, k: int, share: float) -> tuple[float, float, float, float, float]:
        """(time, distance, x, y, heading) at ``share`` of the way from sample k to k+1."""
        a, b = self.samples[k], self.samples[k + 1]
        return (
            a.t + share * (b.t - a.t),
            a.distance + share * (b.distance - a.distance),
            a.x + share * (b.x - a.x),
            a.y + share * (b.y - a.y),
            interpolate_heading(a.heading, b.heading, share),
        )

    def poses_between(
        self, k: int, shares: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(x, y, heading) at ``shares`` of the way from sample k to k+1."""
        a, b = self.samples[k], self.samples[k + 1]
        delta = (b.heading - a.heading + 180.0) % 360.0 - 180.0
        return (a.x + shares * (b.x - a.x), a.y + shares * (b.y - a.y),
                (a.heading + shares * delta) % 360.0)  # fmt: skip

    def rects_between(self, k: int, shares: np.ndarray) -> np.ndarray:
        """The rectangles at ``shares`` of the way from sample k to k+1."""
        return rectangles(*self.poses_between(k, shares), self.length, self.width)

    def fronts(self, x: np.ndarray, y: np.ndarray, heading: np.ndarray) -> np.ndarray:
        """The middles of the front edges of the rectangles at these poses."""
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
        time, distance, *_ = self.between(k, high)
        return time, distance


def _region_events(
    track: _Track, region: Polygon | MultiPolygon, lane: str, enter: EventKind, leave: EventKind
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


def region_events(
    samples: Sequence[PoseSample],
    length: float,
    width: float,
    region: Polygon | MultiPolygon,
    name: str,
) -> list[LaneEvent]:
    """When the rectangle starts and stops overlapping ``region`` (``entered_lane`` and
    ``left_lane`` events named ``name``), placed as a lane's events are."""
    if len(samples) < 2:
        return []
    return _region_events(_Track(samples, length, width), region, name,
                          EventKind.ENTERED_LANE, EventKind.LEFT_LANE)  # fmt: skip


def _arrival(
    track: _Track, fork: Fork, arrival_distance: float, not_before: float
) -> LaneEvent | None:
    rad = math.radians(fork.heading)
    ux, uy = math.sin(rad), math.cos(rad)
    fx = track.x + np.sin(np.radians(track.heading)) * track.length / 2.0
    fy = track.y + np.cos(np.radians(track.heading)) * track.length / 2.0
    to_line = (fork.stop_line[0] - fx) * ux + (fork.stop_line[1] - fy) * uy
    near = np.flatnonzero(to_line <= arrival_distance)
    if near.size == 0:
        return None
    k = int(near[0])
    if not_before > track.t[k]:  # still behind a car that has not entered: not yet arrived
        if not_before > track.t[-1]:
            return None
        j = int(np.searchsorted(track.t, not_before, side="right")) - 1
        if j >= len(track.t) - 1:
            last = track.samples[-1]
            return LaneEvent(EventKind.ARRIVED, fork.lane, last.t, last.distance)
        share = (not_before - track.t[j]) / (track.t[j + 1] - track.t[j])
        time, distance, *_ = track.between(j, float(share))
        return LaneEvent(EventKind.ARRIVED, fork.lane, time, distance)
    if k == 0:
        return LaneEvent(EventKind.ARRIVED, fork.lane, float(track.t[0]), float(track.distance[0]))
    share = (to_line[k - 1] - arrival_distance) / (to_line[k - 1] - to_line[k])
    time, distance, *_ = track.between(k - 1, float(share))
    return LaneEvent(EventKind.ARRIVED, fork.lane, time, distance)


def _stop(
    track: _Track, fork: Fork, arrived: LaneEvent, entered_at: float, v_stop: float
) -> LaneEvent | None:
    return _stop_before(track, fork.lane, arrived, entered_at, v_stop)


def _stop_before(
    track: _Track, lane: str, arrived: LaneEvent, entered_at: float, v_stop: float
) -> LaneEvent | None:
    """The first moment at ``v_stop`` or below between arriving and entering."""
    speeds = [s.speed for s in track.samples]
    for k, sample in enumerate(track.samples):
        if sample.t < arrived.time or sample.t >= entered_at or sample.speed > v_stop:
            continue
        time, distance = sample.t, sample.distance
        if k > 0 and speeds[k - 1] > v_stop:
            share = (speeds[k - 1] - v_stop) / (speeds[k - 1] - speeds[k])
            time, distance, *_ = track.between(k - 1, share)
            if time < arrived.time:
                time, distance = arrived.time, arrived.distance
        return LaneEvent(EventKind.STOPPED, lane, time, distance)
    return None


def _entry(
    track: _Track, fork: Fork, intersection: Intersection, entries: list[LaneEvent]
) -> LaneEvent | None:
    """When the car first overlaps its fork's entry area (the junction beyond its limit
    line); ``entries``: its entries into the junction's polygon, the same where the fork's
    entry area is the polygon."""
    if fork.entry is intersection.polygon:
        return entries[0] if entries else None
    found = _region_events(track, fork.entry, fork.lane, EventKind.ENTERED, EventKind.EXITED)
    return next((e for e in found if e.kind is EventKind.ENTERED), None)


def compute_events(
    samples: Sequence[PoseSample],
    length: float,
    width: float,
    intersection: Intersection,
    fork: str,
    arrival_distance: float,
    v_stop: float,
    not_before: float = -math.inf,
) -> list[LaneEvent]:
    """All events of a car on a route from ``fork``, ordered by distance then kind.
    ``not_before``: when every car ahead of it on its fork has entered the junction (a car
    still behind another has not arrived, service.core.motion.queues)."""
    if len(samples) < 2:
        return []
    track = _Track(samples, length, width)
    events: list[LaneEvent] = []
    junction = _region_events(
        track, intersection.polygon, intersection.junction, EventKind.ENTERED, EventKind.EXITED
    )
    entries = [e for e in junction if e.kind is EventKind.ENTERED]
    exits = [e for e in junction if e.kind is EventKind.EXITED]
    the_fork = intersection.fork(fork)
    entered = _entry(track, the_fork, intersection, entries)
    if entered is not None:
        events.append(LaneEvent(EventKind.ENTERED, fork, entered.time, entered.distance))
    if exits and exits[-1].time >= entries[-1].time:
        events.append(exits[-1])
    arrived = _arrival(track, the_fork, arrival_distance, not_before)
    if arrived is not None and (entered is None or arrived.time <= entered.time):
        events.append(arrived)
        limit = entered.time if entered is not None else math.inf
        stopped = _stop(track, the_fork, arrived, limit, v_stop)
        if stopped is not None:
            events.append(stopped)
    events.extend(_lane_events(track, intersection))
    return _in_order(events)


def _lane_events(track: _Track, intersection: Intersection) -> list[LaneEvent]:
    """Entering and leaving every connecting lane and every crossing (its lane) the
    rectangle touches: the conflict areas of cars with cars and with people on foot."""
    regions = [(lane.polygon, lane.id) for lane in intersection.connecting_lanes.values()]
    regions += [(crossing.polygon, crossing.lane) for crossing in intersection.crossings.values()]
    events = []
    for region, lane in regions:
        events.extend(
            _region_events(track, region, lane, EventKind.ENTERED_LANE, EventKind.LEFT_LANE)
        )
    return events


def _in_order(events: list[LaneEvent]) -> list[LaneEvent]:
    order = list(EventKind)
    return sorted(events, key=lambda e: (e.distance, e.time, order.index(e.kind), e.lane))


def pedestrian_events(
    samples: Sequence[PoseSample],
    length: float,
    width: float,
    intersection: Intersection,
    walk: str,
    arrival_distance: float,
    v_stop: float,
) -> list[LaneEvent]:
    """All events of a pedestrian on ``walk`` (docs/pedestrians.md): at the curb
    (``arrived``: its front within ``arrival_distance`` of the crossing), waiting there
    (``stopped``), on the crossing (``entered``, then ``exited`` when it is off it for good;
    the lane of the three is the crossing's id), and entering and leaving every connecting
    lane and crossing lane it touches; ordered by distance then kind."""
    if len(samples) < 2:
        return []
    crossing = intersection.crossings[intersection.walk(walk).crossing]
    track = _Track(samples, length, width)
    on = _region_events(track, crossing.polygon, crossing.id, EventKind.ENTERED,
                        EventKind.EXITED)  # fmt: skip
    events = [e for e in on[:1] if e.kind is EventKind.ENTERED]
    if on and on[-1].kind is EventKind.EXITED:
        events.append(on[-1])
    arrived = _at_curb(track, crossing.polygon, crossing.id, arrival_distance)
    if arrived is not None and (not events or arrived.time <= events[0].time):
        events.append(arrived)
        limit = events[0].time if events and events[0].kind is EventKind.ENTERED else math.inf
        stopped = _stop_before(track, crossing.id, arrived, limit, v_stop)
        if stopped is not None:
            events.append(stopped)
    regions = [(lane.polygon, lane.id) for lane in intersection.connecting_lanes.values()]
    for region, lane in [*regions, (crossing.polygon, crossing.lane)]:
        events += _region_events(track, region, lane, EventKind.ENTERED_LANE, EventKind.LEFT_LANE)
    return _in_order(events)


def _at_curb(
    track: _Track, region: Polygon, lane: str, arrival_distance: float
) -> LaneEvent | None:
    """When the front first comes within ``arrival_distance`` of ``region``."""
    gaps = shapely.distance(track.fronts(track.x, track.y, track.heading), region)
    near = np.flatnonzero(gaps <= arrival_distance)
    if near.size == 0:
        return None
    k = int(near[0])
    if k == 0:
        return LaneEvent(EventKind.ARRIVED, lane, float(track.t[0]), float(track.distance[0]))

    def flips(shares: np.ndarray) -> np.ndarray:
        fronts = track.fronts(*track.poses_between(k - 1, shares))
        return shapely.distance(fronts, region) <= arrival_distance  # type: ignore[no-any-return]

    time, distance = track.refine(k - 1, flips)
    return LaneEvent(EventKind.ARRIVED, lane, time, distance)
