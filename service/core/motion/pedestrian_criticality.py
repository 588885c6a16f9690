"""How close the ego came to a person on foot: time-to-collision, post-encroachment time,
the deceleration needed to avoid a crash and the distance, of the ego against each
pedestrian (docs/pedestrians.md), beside its measures against each car
(service.core.motion.criticality). SUMO's SSM device measures no people on foot; these
follow its definitions for cars, at constant speeds:

- The ego moves along its route's path at its current speed (its place on the path is
  where its front bumper projects, as against a car), its rectangle kept where it is
  relative to the path at the sample (so the prediction starts from its real pose). A
  pedestrian walks on in a straight line along her recorded heading (her walk's path on
  the crossing) at her current speed.
- TTC at a sample: the time until the two rectangles, so moved, first overlap; none when
  they never do, and none when they overlap already (a collision, which the verdict
  reports). A pedestrian standing at the curb is never on a collision course with a car
  that does not drive onto the curb; one who has walked past the ego's lane, or crosses
  behind it, is not either. The collision itself is predicted, not the two being in one
  conflict area at once: a lane-wide area holds a car and a pedestrian apart (she in its
  other half), so an area's TTC could predict a crash that cannot happen. Hence no TTC is
  ever smaller than the gap between the two rectangles over the speed at which they can
  close (the sum of their speeds). Looked for while the faster of the two covers at most
  ``AHEAD`` metres, and only while the centres are within ``RANGE`` (SUMO's default, as
  for cars). The smallest over the drive.
- DRAC: the deceleration that stops the ego short of where it would first touch her,
  v^2 / (2 v TTC) = v / (2 TTC) (SUMO's v^2 / (2 d) for a car standing in the conflict
  area): she has the right-of-way and is not counted on to hurry out of the way, and a
  pedestrian's own deceleration is no measure of danger. Only where a TTC is predicted and
  the ego moves; the largest over the drive.
- PET at the conflict area of the ego's route and her walk, where the ego's connecting
  lane and her crossing's polygon overlap (docs/pedestrians.md; only for a route among the
  walk's conflicts), named ``EGO_LANE|CROSSING_LANE``: from the first of the two leaving it
  to the second entering it (0 when both were in it at once), at the time the second
  entered. Each is in it while its rectangle overlaps it (the events' notion, placed
  between samples as the lane events are).
- Distance: the smallest gap between the two rectangles, at the ego's samples.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import shapely

from service.core.motion.criticality import (
    DIGITS,
    RANGE,
    CarView,
    Mover,
    Poses,
    closest,
    extreme_at,
)
from service.core.motion.criticality_records import AreaPet, PairCriticality
from service.core.motion.events import EventKind, region_events
from service.core.motion.poses import PoseSample
from service.core.network import Intersection

SEARCH_STEP = 0.05  # metres the two close in at most between two predicted poses
PLACE_STEP = 0.05  # metres between the places of the ego's path where its pose is tabled
AHEAD = 2 * RANGE  # metres the faster of the two is followed ahead at most
COARSE = 20  # search steps between the times first tried
REFINE = 32  # shares tried at once of the step in which the first overlap lies
ROUNDS = 2  # rounds of them: the overlap placed to 1/1024 of a step


@dataclass(frozen=True)
class PedestrianMover:
    """A pedestrian as the measures see her: her walk, her size and her trajectory."""

    id: str
    walk: str
    length: float
    width: float
    samples: Sequence[PoseSample]


def measure_pedestrians(
    junction: Intersection, ego: Mover, people: Sequence[PedestrianMover]
) -> tuple[PairCriticality, ...]:
    """The measures of ``ego`` against each of ``people`` (module docstring)."""
    if not people:
        return ()
    view = CarView(junction, ego)
    placed = _PlacedPath(view)
    return tuple(_pair(junction, view, placed, person) for person in people)


class _PlacedPath:
    """The ego's rectangle placed along its path, tabled by the place of its front: its
    centre (the middle of its front and its back on the path) and heading."""

    def __init__(self, view: CarView) -> None:
        length = view.car.length
        places = np.arange(view.place.min() - 1.0, view.place.max() + AHEAD + 1.0, PLACE_STEP)
        front = shapely.line_interpolate_point(view.path.line, places)
        back = shapely.line_interpolate_point(view.path.line, places - length)
        fx, fy, bx, by = (shapely.get_x(front), shapely.get_y(front), shapely.get_x(back),
                          shapely.get_y(back))  # fmt: skip
        self.places = places
        self.x, self.y = (fx + bx) / 2.0, (fy + by) / 2.0
        self.heading = np.unwrap(np.arctan2(fx - bx, fy - by))  # radians, clockwise from north

    def at(self, places: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(x, y, heading) of the placed rectangle with its front at ``places``."""
        return (np.interp(places, self.places, self.x), np.interp(places, self.places, self.y),
                np.interp(places, self.places, self.heading))  # fmt: skip


def pedestrian_series(
    junction: Intersection, ego: Mover, person: PedestrianMover
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(times, TTC, DRAC) of ``ego`` against ``person`` at the ego's samples while both
    are both on the map (inf TTC and 0 DRAC where none applies): what the extremes are taken
    from."""
    view = CarView(junction, ego)
    times, mine, theirs = _shared(view, person)
    if not times.size:
        return times, np.zeros(0), np.zeros(0)
    return (times, *_ttc_drac(_PlacedPath(view), mine, theirs, ego, person))


def _shared(view: CarView, person: PedestrianMover) -> tuple[np.ndarray, Poses, Poses]:
    """The ego's sample times within the pedestrian's, and both poses at them."""
    if len(person.samples) < 2:
        none = np.zeros(0)
        return none, view.at(none), Poses(none, none, none, none, none)
    walker = _Walker(person)
    times = view.t[(view.t >= walker.t[0]) & (view.t <= walker.t[-1])]
    return times, view.at(times), walker.at(times)


def _ttc_drac(
    placed: _PlacedPath, mine: Poses, theirs: Poses, ego: Mover, person: PedestrianMover
) -> tuple[np.ndarray, np.ndarray]:
    ttc = _ttc(placed, mine, theirs, ego, person)
    with np.errstate(divide="ignore", invalid="ignore"):
        drac = np.where(np.isfinite(ttc) & (mine.speed > 0.0), mine.speed / (2.0 * ttc), 0.0)
    return ttc, drac


def _pair(
    junction: Intersection, view: CarView, placed: _PlacedPath, person: PedestrianMover
) -> PairCriticality:
    pets = tuple(filter(None, [_pet(junction, view.car, person)]))
    times, mine, theirs = _shared(view, person)
    if not times.size:
        return PairCriticality(person.id, None, pets, None, None)
    ttc, drac = _ttc_drac(placed, mine, theirs, view.car, person)
    return PairCriticality(
        person.id,
        extreme_at(times, ttc, np.isfinite(ttc), smallest=True),
        pets,
        extreme_at(times, drac, drac > 0.0, smallest=False),
        closest(times, mine, theirs, view.car, person),
    )


class _Walker:
    """A pedestrian's samples as arrays."""

    def __init__(self, person: PedestrianMover) -> None:
        self.t = np.array([s.t for s in person.samples])
        self.x = np.array([s.x for s in person.samples])
        self.y = np.array([s.y for s in person.samples])
        self.heading = np.unwrap(np.radians([s.heading for s in person.samples]))
        self.speed = np.array([s.speed for s in person.samples])

    def at(self, times: np.ndarray) -> Poses:
        """Pose and speed at ``times`` (within the samples), interpolated (no place)."""
        return Poses(
            np.interp(times, self.t, self.x),
            np.interp(times, self.t, self.y),
            np.interp(times, self.t, self.heading),
            np.interp(times, self.t, self.speed),
            np.zeros(times.shape),
        )


def _ttc(
    placed: _PlacedPath, mine: Poses, theirs: Poses, ego: Mover, person: PedestrianMover
) -> np.ndarray:
    """The TTC at each time (inf where none is predicted)."""
    ttc = np.full(mine.x.shape, math.inf)
    apart = np.hypot(mine.x - theirs.x, mine.y - theirs.y)
    moving = (mine.speed > 0.0) | (theirs.speed > 0.0)
    for k in np.flatnonzero((apart <= RANGE) & moving):
        ttc[k] = _first_contact(placed, mine, theirs, int(k), ego, person)
    return ttc


def _first_contact(
    placed: _PlacedPath, mine: Poses, theirs: Poses, k: int, ego: Mover, person: PedestrianMover
) -> float:
    """When the two rectangles, moved on from sample ``k`` at constant speeds, first
    overlap (inf: never, or they overlap already). The times tried are SEARCH_STEP metres
    of their closing apart, first every COARSE of them: the centres close in by at most
    that much in between, so only the fine times next to a coarse one where the centres
    were near enough are tried; then the first overlap is placed within its step."""
    speed, pace = float(mine.speed[k]), float(theirs.speed[k])
    step = SEARCH_STEP / (speed + pace)
    count = math.ceil(AHEAD / max(speed, pace) / step)
    x0, y0, h0 = placed.at(np.array([mine.place[k]]))
    shift = (mine.x[k] - x0[0], mine.y[k] - y0[0],
             (mine.heading[k] - h0[0] + math.pi) % (2 * math.pi) - math.pi)  # fmt: skip
    heading = float(theirs.heading[k])
    sin, cos = math.sin(heading), math.cos(heading)

    def gaps(at: np.ndarray) -> np.ndarray:
        x, y, _ = placed.at(mine.place[k] + speed * at)
        return np.hypot(x + shift[0] - theirs.x[k] - pace * at * sin,  # type: ignore[no-any-return]
                        y + shift[1] - theirs.y[k] - pace * at * cos)  # fmt: skip

    def touching(at: np.ndarray) -> np.ndarray:
        x, y, turn = placed.at(mine.place[k] + speed * at)
        return overlap(
            (x + shift[0], y + shift[1], turn + shift[2], ego.length, ego.width),
            (theirs.x[k] + pace * at * sin, theirs.y[k] + pace * at * cos, heading,
             person.length, person.width),
        )  # fmt: skip

    reach = (math.hypot(ego.length, ego.width) + math.hypot(person.length, person.width)) / 2.0
    coarse = np.arange(0, count + COARSE, COARSE)
    near = np.flatnonzero(gaps(coarse * step) <= reach + (COARSE + 1) * SEARCH_STEP)
    if not near.size:
        return math.inf
    around = np.arange(-COARSE, COARSE + 1)
    fine = np.unique(np.clip(coarse[near][:, None] + around[None, :], 0, count))
    fine = fine[gaps(fine * step) <= reach + SEARCH_STEP]
    hits = fine[touching(fine * step)]
    if not hits.size:
        return math.inf
    if hits[0] == 0:
        return math.inf  # already overlapping: a collision, no TTC
    low, high = float((hits[0] - 1) * step), float(hits[0] * step)
    for _ in range(ROUNDS):
        within = np.append(low + (high - low) * np.arange(1, REFINE) / REFINE, high)
        hit = int(np.flatnonzero(touching(within))[0])
        low, high = (float(within[hit - 1]) if hit else low), float(within[hit])
    return high


Box = tuple[np.ndarray | float, np.ndarray | float, np.ndarray | float, float, float]


def overlap(first: Box, second: Box) -> np.ndarray:
    """Whether the interiors of two rectangles (x, y of the centre, heading in radians
    clockwise from north, length along it, width; arrays element by element) overlap:
    the separating axis test on the four axes of the two rectangles (touching edges do
    not overlap, as ``events.overlapping``)."""
    (ax, ay, ah, al, aw), (bx, by, bh, bl, bw) = first, second
    dx, dy = np.subtract(bx, ax), np.subtract(by, ay)
    sides = [
        ((np.sin(ah), np.cos(ah)), al / 2.0), ((np.cos(ah), -np.sin(ah)), aw / 2.0),
        ((np.sin(bh), np.cos(bh)), bl / 2.0), ((np.cos(bh), -np.sin(bh)), bw / 2.0),
    ]  # fmt: skip
    inside = np.ones(np.broadcast(dx, dy).shape, dtype=bool)
    for (nx, ny), _ in sides:
        reach = sum(half * np.abs(ux * nx + uy * ny) for (ux, uy), half in sides)
        inside &= np.abs(dx * nx + dy * ny) < reach
    return inside


def _pet(junction: Intersection, ego: Mover, person: PedestrianMover) -> AreaPet | None:
    """The PET at the conflict area of the ego's route and the pedestrian's walk, when both
    went into it."""
    walk = junction.walk(person.walk)
    if ego.route.id not in walk.conflicts:
        return None
    crossing = junction.crossings[walk.crossing]
    lane = junction.connecting_lanes[ego.route.connecting_lane]
    area = lane.polygon.intersection(crossing.polygon)
    if area.is_empty or area.area <= 0.0:
        return None
    name = f"{ego.route.connecting_lane}|{crossing.lane}"
    passes = []
    for who in (ego, person):
        events = region_events(who.samples, who.length, who.width, area, name)
        entered = next((e.time for e in events if e.kind is EventKind.ENTERED_LANE), None)
        if entered is None:
            return None
        left = next((e.time for e in events
                     if e.kind is EventKind.LEFT_LANE and e.time >= entered), None)  # fmt: skip
        passes.append((entered, left, who.samples[-1].t, who.id))
    (_, first_left, first_end, _), (second_entered, _, _, _) = sorted(
        passes, key=lambda p: (p[0], p[3])
    )
    if first_left is None and second_entered > first_end:
        return None  # the first one's trajectory ended inside: no exit to measure from
    gap = 0.0 if first_left is None else max(0.0, second_entered - first_left)
    return AreaPet(name, round(gap, DIGITS), round(second_entered, DIGITS))
