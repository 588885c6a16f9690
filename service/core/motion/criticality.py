"""How close a drive came to a crash: time-to-collision, post-encroachment time, the
deceleration needed to avoid a crash and the distance, of one car (the ego) against each
other car, from the cars' trajectories and the junction's geometry.

The definitions are those of SUMO's SSM device (``--device.ssm``, src/microsim/devices/
MSDevice_SSM.cpp), so that the values can be checked against it:

- A car's *path* is its route's centreline: the road before its fork, the connecting lane,
  the road after its exit (``route_path``). Its place on the path is where its front bumper
  projects onto it; its speed is the trajectory's.
- A *conflict area* of two cars whose routes cross or merge (``Intersection.conflicts``) is
  where the strips they sweep along their connecting lanes' centrelines overlap, each strip
  as wide as its car (SUMO: the foe's width around the crossing point). A car is in it from
  the moment its rectangle, placed along its path, first overlaps the area until it no
  longer does (its back has left it). The area is named ``EGO_LANE|OTHER_LANE``. At a
  merge the conflict is the *merge point*, the end of the connecting lanes where the two
  lanes have become one (SUMO's merge point, the start of the common lane): a car is in it
  from its front reaching that point until its back has passed it. The overlap of the
  strips runs along the lanes as they converge, and two cars one behind the other are in
  it at once without coming close to a crash (measured as the area, a pair 3.9 m apart
  going the same way had a PET of 0 and a TTC predicted where SUMO predicts none).
- TTC (time-to-collision) at a sample time, with both cars holding their current speeds
  along their paths: at a conflict area (a merge point), the time until the second car
  to arrive enters it, if it arrives before the first has left (SUMO's crossing and
  merging TTC; at a merge only while neither has reached the merge point: once one has,
  the pair is following, as in SUMO); a car behind another on its path (the other's back
  within half their widths of its path, heading within 45 degrees of it: one fork, one
  exit lane, a merge): gap / (v_behind - v_ahead) while it is faster (SUMO's following
  TTC). The smallest over the drive, at the sample where it occurred.
- DRAC (deceleration rate to avoid a crash): behind another car, (v_behind - v_ahead)^2 /
  (2 gap); at a conflict area (a merge point) where a crash is predicted, the smaller of
  the two decelerations that let one car reach the area just as the other leaves it,
  2 (v - d / T) / T (d its distance to the area, T the other's time to leave it), or
  v^2 / (2 d) when the other stands in the area (SUMO's ``computeDRAC`` at crossings; at a
  merge SUMO takes the follower's v^2 / (2 d), a stop at the merge point). The largest
  over the drive.
- PET (post-encroachment time) at each conflict area (merge point) both cars went
  through: the time from the first car leaving it to the second entering it (0 when both
  were in it at once), at the time the second entered; entries and exits interpolated
  between samples.
- Distance: the smallest gap between the two rectangles (0 when they overlap) at the ego's
  samples.

Where this differs from SUMO: SUMO orders two cars at a crossing by entry times estimated
with their current deceleration and the lane's speed limit; here both hold their speeds.
SUMO finds conflict areas from the junction's foe links and approximates an oblique
crossing with the crossing point plus the foe's width; here the strips' overlap is used,
so oblique crossings get their exact area. At a merge both take the merge point; SUMO
also predicts a rear-end collision after it (the first car's exit time plus the gap left
over the closing speed), here only a car already behind another is measured as following;
two cars that would touch side by side where the lanes converge are predicted to meet at
the merge point, up to that stretch's length over the speed later. PET is computed at
merges too (SUMO only at crossings). SUMO logs a value only below its thresholds, within its range;
here the extreme of each measure is kept whatever its size.

The records are in service.core.motion.criticality_records; the measures against people on
foot, which SUMO's device does not take, in service.core.motion.pedestrian_criticality.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
import shapely
from shapely.geometry import LineString
from shapely.geometry.base import BaseGeometry

from service.core.motion.criticality_records import AreaPet, Criticality, Measure, PairCriticality
from service.core.motion.events import overlapping, rectangles
from service.core.motion.poses import PoseSample
from service.core.network import Intersection, Route, parsed_network
from service.core.network.lanes import approach_polyline, dedupe, departure_polyline

PATH_REACH = 200.0  # metres of road kept before the fork's stop line and after the exit
EXTENSION = 1000.0  # metres straight on beyond them: a projection never lands on an end
AREA_STEP = 0.05  # metres between the places where a conflict area's bounds are looked for
FOLLOWING_ANGLE = 45.0  # degrees: a car ahead heads at most this far off the path
TANGENT = 0.5  # metres either side of a place over which the path's heading is taken
RANGE = 50.0  # metres between the centres within which TTC and DRAC apply (SUMO's default)
DIGITS = 3  # values and times are rounded to ms, mm, mm/s^2


@dataclass(frozen=True)
class Mover:
    """A car as the measures see it: its route, its size and its trajectory."""

    id: str
    route: Route
    length: float
    width: float
    samples: Sequence[PoseSample]


def measure_criticality(junction: Intersection, ego: Mover, others: Sequence[Mover]) -> Criticality:
    """The measures of ``ego`` against each of ``others`` (module docstring)."""
    ego_view = CarView(junction, ego)
    return Criticality(tuple(_pair(junction, ego_view, CarView(junction, o)) for o in others))


@dataclass(frozen=True)
class CarPath:
    """A route's centreline, straight on beyond its ends; ``stop_line``: the place (m along
    it) of the fork's stop line, where the connecting lane starts."""

    line: LineString
    stop_line: float


def route_path(junction: Intersection, route: Route) -> CarPath:
    """The path of ``route`` (module docstring), made once per junction and route."""
    key = (str(junction.network_file), junction.junction, route.id)
    if key not in _PATHS:
        net = parsed_network(junction.network_file)
        before = approach_polyline(net, net.getLane(route.fork), junction.junction, PATH_REACH)
        inside = list(junction.connecting_lanes[route.connecting_lane].centreline.coords)
        after = departure_polyline(net, net.getLane(route.exit), junction.junction, PATH_REACH)
        points = dedupe([*before, *[(float(x), float(y)) for x, y in inside], *after])
        start = _beyond(points[1], points[0])
        end = _beyond(points[-2], points[-1])
        stop_line = EXTENSION + LineString(dedupe(before)).length if len(before) > 1 else EXTENSION
        _PATHS[key] = CarPath(LineString([start, *points, end]), stop_line)
    return _PATHS[key]


_PATHS: dict[tuple[str, str, str], CarPath] = {}


def _beyond(a: tuple[float, float], b: tuple[float, float]) -> tuple[float, float]:
    """The point EXTENSION metres past ``b`` on the line from ``a`` through ``b``."""
    share = EXTENSION / math.dist(a, b)
    return b[0] + (b[0] - a[0]) * share, b[1] + (b[1] - a[1]) * share


def conflict_area(junction: Intersection, first: Mover, second: Mover) -> BaseGeometry | None:
    """Where the strips the two cars sweep along their connecting lanes overlap (None:
    their routes neither cross nor merge)."""
    if second.route.id not in junction.conflicts.get(first.route.id, frozenset()):
        return None
    key = (str(junction.network_file), junction.junction, first.route.id, first.width,
           second.route.id, second.width)  # fmt: skip
    if key not in _AREAS:
        strips = [
            junction.connecting_lanes[car.route.connecting_lane].centreline.buffer(
                car.width / 2.0, cap_style="flat"
            )
            for car in (first, second)
        ]
        area = strips[0].intersection(strips[1])
        _AREAS[key] = None if area.is_empty or area.area <= 0.0 else area
    return _AREAS[key]


_AREAS: dict[tuple[str, str, str, float, str, float], BaseGeometry | None] = {}


def area_bounds(
    junction: Intersection, car: Mover, area: BaseGeometry
) -> tuple[float, float] | None:
    """The places of the car's front (m along its path) where its rectangle, placed along
    its path, starts and stops overlapping ``area`` (None: it never does)."""
    key = (str(junction.network_file), junction.junction, car.route.id, car.length,
           car.width, shapely.to_wkb(area))  # fmt: skip
    if key not in _BOUNDS:
        path = route_path(junction, car.route)
        inside = junction.connecting_lanes[car.route.connecting_lane].length
        places = np.arange(
            path.stop_line, path.stop_line + inside + car.length + 2 * AREA_STEP, AREA_STEP
        )
        front = shapely.line_interpolate_point(path.line, places)
        back = shapely.line_interpolate_point(path.line, places - car.length)
        centre = shapely.line_interpolate_point(path.line, places - car.length / 2.0)
        heading = _heading(back, front)
        rects = rectangles(shapely.get_x(centre), shapely.get_y(centre), heading,
                           car.length, car.width)  # fmt: skip
        shapely.prepare(area)
        inside_area = np.flatnonzero(overlapping(rects, area))
        _BOUNDS[key] = (
            None
            if inside_area.size == 0
            else (float(places[inside_area[0]]), float(places[inside_area[-1]] + AREA_STEP))
        )
    return _BOUNDS[key]


_BOUNDS: dict[tuple[Any, ...], tuple[float, float] | None] = {}


def merging(first: Mover, second: Mover) -> bool:
    """Whether the two cars' routes merge: they leave the junction by one lane."""
    return first.route.exit == second.route.exit


def merge_bounds(junction: Intersection, car: Mover) -> tuple[float, float]:
    """The places of the car's front (m along its path) where it reaches the merge point,
    the end of its connecting lane, where the two merging lanes have become one, and where
    its back has passed it (SUMO's merge point: the start of the common lane)."""
    key = (str(junction.network_file), junction.junction, car.route.id, car.length)
    if key not in _MERGES:
        path = route_path(junction, car.route)
        end = junction.connecting_lanes[car.route.connecting_lane].centreline.coords[-1]
        place = float(path.line.project(shapely.Point(end)))
        _MERGES[key] = (place, place + car.length)
    return _MERGES[key]


_MERGES: dict[tuple[str, str, str, float], tuple[float, float]] = {}


def conflict_bounds(
    junction: Intersection, first: Mover, second: Mover, area: BaseGeometry
) -> tuple[tuple[float, float], tuple[float, float]] | None:
    """Where each car's front enters the conflict and where it has left it (m along its
    path): at a crossing the area's bounds (``area_bounds``); at a merge the merge point's
    (``merge_bounds``): the strips overlap all along where the lanes converge, and two cars
    one behind the other are in that overlap at once without coming close to a crash, so
    only the place where the lanes have become one is one neither may hold while the other
    does (None: a car never enters the area)."""
    if merging(first, second):
        return merge_bounds(junction, first), merge_bounds(junction, second)
    bounds = area_bounds(junction, first, area), area_bounds(junction, second, area)
    if bounds[0] is None or bounds[1] is None:
        return None
    return bounds[0], bounds[1]


def _heading(start: np.ndarray, end: np.ndarray) -> np.ndarray:
    """Headings (degrees clockwise from north) from ``start`` to ``end`` points."""
    dx = shapely.get_x(end) - shapely.get_x(start)
    dy = shapely.get_y(end) - shapely.get_y(start)
    return np.degrees(np.arctan2(dx, dy)) % 360.0  # type: ignore[no-any-return]


class CarView:
    """A car's samples as arrays, with its place on its path at each."""

    def __init__(self, junction: Intersection, car: Mover) -> None:
        self.car = car
        self.path = route_path(junction, car.route)
        self.t = np.array([s.t for s in car.samples])
        self.x = np.array([s.x for s in car.samples])
        self.y = np.array([s.y for s in car.samples])
        self.heading = np.unwrap(np.radians([s.heading for s in car.samples]))
        self.speed = np.array([s.speed for s in car.samples])
        fx, fy = _ahead(self.x, self.y, self.heading, car.length / 2.0)
        # a car never backs up: noise in the projection must not make it
        self.place = np.maximum.accumulate(
            shapely.line_locate_point(self.path.line, shapely.points(fx, fy))
        )

    def at(self, times: np.ndarray) -> Poses:
        """Pose, speed and place at ``times`` (within the samples), interpolated."""
        return Poses(
            np.interp(times, self.t, self.x),
            np.interp(times, self.t, self.y),
            np.interp(times, self.t, self.heading),
            np.interp(times, self.t, self.speed),
            np.interp(times, self.t, self.place),
        )


@dataclass(frozen=True)
class Poses:
    x: np.ndarray
    y: np.ndarray
    heading: np.ndarray  # radians, clockwise from north
    speed: np.ndarray
    place: np.ndarray  # the front's place on the car's path


def _ahead(
    x: np.ndarray, y: np.ndarray, heading: np.ndarray, metres: float
) -> tuple[np.ndarray, np.ndarray]:
    """Points ``metres`` ahead of (x, y) along ``heading`` (radians; negative: behind)."""
    return x + np.sin(heading) * metres, y + np.cos(heading) * metres


def measure_series(
    junction: Intersection, ego: Mover, other: Mover
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(times, TTC, DRAC) of ``ego`` against ``other`` at the ego's samples while both
    drive (inf TTC and 0 DRAC where none applies): what the extremes are taken from."""
    ego_view, other_view = CarView(junction, ego), CarView(junction, other)
    times = _shared_times(ego_view, other_view)
    mine, theirs = ego_view.at(times), other_view.at(times)
    return (times, *_ttc_drac(junction, ego_view, other_view, mine, theirs))


def _shared_times(ego: CarView, other: CarView) -> np.ndarray:
    return ego.t[(ego.t >= other.t[0]) & (ego.t <= other.t[-1])]  # type: ignore[no-any-return]


def _pair(junction: Intersection, ego: CarView, other: CarView) -> PairCriticality:
    area = conflict_area(junction, ego.car, other.car)
    pets = () if area is None else tuple(filter(None, [_pet(junction, ego, other, area)]))
    times = _shared_times(ego, other)
    if not times.size:
        return PairCriticality(other.car.id, None, pets, None, None)
    mine, theirs = ego.at(times), other.at(times)
    ttc, drac = _ttc_drac(junction, ego, other, mine, theirs)
    return PairCriticality(
        other.car.id,
        extreme_at(times, ttc, np.isfinite(ttc), smallest=True),
        pets,
        extreme_at(times, drac, drac > 0.0, smallest=False),
        closest(times, mine, theirs, ego.car, other.car),
    )


def _ttc_drac(
    junction: Intersection, ego: CarView, other: CarView, mine: Poses, theirs: Poses
) -> tuple[np.ndarray, np.ndarray]:
    """TTC and DRAC at each time: at the conflict area, and behind the other either way."""
    ttc = np.full(mine.x.shape, math.inf)
    drac = np.zeros(mine.x.shape)
    area = conflict_area(junction, ego.car, other.car)
    if area is not None:
        bounds = conflict_bounds(junction, ego.car, other.car, area)
        if bounds is not None:
            ttc, drac = _crossing(mine, theirs, *bounds, merging(ego.car, other.car))
    apart = np.hypot(mine.x - theirs.x, mine.y - theirs.y)
    for behind, ahead, view, car in (
        (mine, theirs, ego, other.car),
        (theirs, mine, other, ego.car),
    ):
        near = (apart <= RANGE) & (behind.speed > ahead.speed)
        if near.any():
            following = _following(behind, ahead, view, car, near)
            ttc, drac = np.minimum(ttc, following[0]), np.maximum(drac, following[1])
    return np.where(apart <= RANGE, ttc, math.inf), np.where(apart <= RANGE, drac, 0.0)


def extreme_at(
    times: np.ndarray, values: np.ndarray, valid: np.ndarray, smallest: bool
) -> Measure | None:
    """The smallest (largest) valid value and its time, the first where it repeats."""
    if not valid.any():
        return None
    candidates = np.where(valid, values if smallest else -values, math.inf)
    k = int(np.argmin(candidates))
    return Measure(round(float(values[k]), DIGITS), round(float(times[k]), DIGITS))


class Body(Protocol):
    """A road user's rectangle: its length (along its heading) and width."""

    @property
    def length(self) -> float: ...

    @property
    def width(self) -> float: ...


def closest(times: np.ndarray, mine: Poses, theirs: Poses, ego: Body, other: Body) -> Measure:
    """The smallest gap between the rectangles. It is at most the centres' distance and at
    least that less half of both diagonals, so only the samples that can hold the
    smallest are measured."""
    apart = np.hypot(mine.x - theirs.x, mine.y - theirs.y)
    reach = (math.hypot(ego.length, ego.width) + math.hypot(other.length, other.width)) / 2.0
    candidates = np.flatnonzero(apart - reach <= apart.min())
    gaps = shapely.distance(
        _rectangles(mine, ego, candidates), _rectangles(theirs, other, candidates)
    )
    k = int(np.argmin(gaps))
    return Measure(round(float(gaps[k]), DIGITS), round(float(times[candidates[k]]), DIGITS))


def _rectangles(poses: Poses, car: Body, chosen: np.ndarray) -> np.ndarray:
    return rectangles(poses.x[chosen], poses.y[chosen], np.degrees(poses.heading[chosen]) % 360.0,
                      car.length, car.width)  # fmt: skip


def _time_to(distance: np.ndarray, speed: np.ndarray) -> np.ndarray:
    """Time to cover ``distance`` at ``speed`` (0 when already there, inf when standing)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(distance <= 0.0, 0.0, np.where(speed > 0.0, distance / speed, math.inf))


def _crossing(
    mine: Poses, theirs: Poses, my_bounds: tuple[float, float],
    their_bounds: tuple[float, float], at_merge: bool,
) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """(TTC, DRAC) at each time at one conflict (inf and 0 where none applies), entered and
    left at the bounds given (``conflict_bounds``). At a merge (both routes leave by one
    lane) only while neither car has reached the merge point: once one has, the other
    follows it (SUMO's SSM device: a merging conflict becomes a following one), measured
    behind it on its path (``_following``)."""
    to_in = (my_bounds[0] - mine.place, their_bounds[0] - theirs.place)
    to_out = (my_bounds[1] - mine.place, their_bounds[1] - theirs.place)
    speeds = (mine.speed, theirs.speed)
    # both still to leave the area, not both in it already (SUMO: a collision, no measure)
    active = (to_out[0] > 0) & (to_out[1] > 0) & ((to_in[0] > 0) | (to_in[1] > 0))
    if at_merge:
        active &= (to_in[0] > 0) & (to_in[1] > 0)
    entry = [_time_to(np.maximum(d, 0.0), v) for d, v in zip(to_in, speeds, strict=True)]
    leave = [_time_to(d, v) for d, v in zip(to_out, speeds, strict=True)]
    first = entry[0] < entry[1]
    second_entry = np.maximum(entry[0], entry[1])
    first_leaves = np.where(first, leave[0], leave[1])
    crash = active & np.isfinite(second_entry) & (second_entry <= first_leaves)
    ttc = np.where(crash, second_entry, math.inf)
    needed = [
        _delay(to_in[k], speeds[k], leave[1 - k], to_in[1 - k]) for k in (0, 1)
    ]  # fmt: skip
    least = np.minimum(needed[0], needed[1])
    drac = np.where(active & np.isfinite(least) & (least > 0.0), least, 0.0)
    return ttc, drac


def _delay(
    to_in: np.ndarray, speed: np.ndarray, other_leaves: np.ndarray, other_to_in: np.ndarray
) -> np.ndarray:
    """The deceleration that brings a car to the area just as the other leaves it: 2 (v -
    d / T) / T; v^2 / (2 d) when the other stands in it; inf when it cannot brake for it
    (already in the area) or the other stands before the area."""
    with np.errstate(divide="ignore", invalid="ignore"):
        timed = 2.0 * (speed - to_in / other_leaves) / other_leaves
        stop = speed * speed / (2.0 * to_in)
    standing_inside = ~np.isfinite(other_leaves) & (other_to_in <= 0.0)
    found = np.where(np.isfinite(other_leaves), timed, np.where(standing_inside, stop, math.inf))
    return np.where(to_in > 0.0, found, math.inf)


def _following(
    behind: Poses, ahead: Poses, view: CarView, car_ahead: Mover, near: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(TTC, DRAC) at each time of a car (``view``: the one ``behind``) closing in on the
    back of ``car_ahead`` on its path, looked for where ``near``."""
    ttc = np.full(near.shape, math.inf)
    drac = np.zeros(near.shape)
    chosen = np.flatnonzero(near)
    heading = ahead.heading[chosen]
    bx, by = _ahead(ahead.x[chosen], ahead.y[chosen], heading, -car_ahead.length / 2.0)
    backs = shapely.points(bx, by)
    line = view.path.line
    place = shapely.line_locate_point(line, backs)
    gap = place - behind.place[chosen]
    lateral = (view.car.width + car_ahead.width) / 2.0
    candidate = (gap > 0.0) & (shapely.distance(line, backs) < lateral)
    chosen, place, gap, heading = (a[candidate] for a in (chosen, place, gap, heading))
    tangent = _heading(
        shapely.line_interpolate_point(line, place - TANGENT),
        shapely.line_interpolate_point(line, place + TANGENT),
    )
    turn = np.abs((np.degrees(heading) - tangent + 180.0) % 360.0 - 180.0)
    chosen, gap = chosen[turn < FOLLOWING_ANGLE], gap[turn < FOLLOWING_ANGLE]
    closing = behind.speed[chosen] - ahead.speed[chosen]
    ttc[chosen] = gap / closing
    drac[chosen] = closing * closing / (2.0 * gap)
    return ttc, drac


def _pet(
    junction: Intersection, ego: CarView, other: CarView, area: BaseGeometry
) -> AreaPet | None:
    """The PET at ``area``, when both cars went into it."""
    both = conflict_bounds(junction, ego.car, other.car, area)
    if both is None:
        return None
    passes = []
    for view, bounds in zip((ego, other), both, strict=True):
        entered = _first_time(view, bounds[0])
        if entered is None:
            return None
        passes.append((entered, _first_time(view, bounds[1]), view))
    (_, first_left, first), (second_entered, _, _) = sorted(
        passes, key=lambda p: (p[0], p[2].car.id)
    )
    if first_left is None and second_entered > first.t[-1]:
        return None  # the first car's trajectory ended inside: no exit to measure from
    gap = 0.0 if first_left is None else max(0.0, second_entered - first_left)
    name = f"{ego.car.route.connecting_lane}|{other.car.route.connecting_lane}"
    return AreaPet(name, round(gap, DIGITS), round(second_entered, DIGITS))


def _first_time(view: CarView, place: float) -> float | None:
    """When the car's front first reached ``place`` on its path (interpolated), if it did."""
    k = int(np.searchsorted(view.place, place, side="left"))
    if k >= len(view.place):
        return None
    if k == 0:
        return float(view.t[0])
    a, b = view.place[k - 1], view.place[k]
    share = (place - a) / (b - a)
    return float(view.t[k - 1] + share * (view.t[k] - view.t[k - 1]))
