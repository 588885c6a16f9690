"""What an extension adds, and what Steps 2 and 3 know of it before the search.

Before the search (service.core.generator.search): the new routes and walks checked, the
new cars' ids and where they start (given, or automatic: behind the cars already on their
fork or ahead of the ego), then, from Step 1's poses, every car's events as Step 2 orders
them and the queues the cars form (who follows whom, and what that asks of the times).
Its place in the method: service.core.generator.extension.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass

from service.core.checker.check import Judge
from service.core.errors import InvalidInput, NoMoreComplexTestCase
from service.core.generator.following import QueueMember, queue_bounds
from service.core.generator.ordering_facts import (
    CarKind,
    OrderingCar,
    QueueBounds,
    timed_events,
)
from service.core.generator.timing import TICK
from service.core.generator.walkers import NewPedestrians
from service.core.motion.events import LaneEvent, compute_events
from service.core.motion.invariants import ROUNDING
from service.core.motion.kinematics import Bounds
from service.core.motion.poses import PoseSample, PoseTrack, longest_start
from service.core.motion.queues import Follow, Places, QueueCar, follows, line_distance, needed_gap
from service.core.network import Intersection, Route, Walk
from service.core.testcase import TestCase

QUEUE_SPACING = 5.0  # metres a new car starts behind the room it needs on a fork in use
StartDistances = float | Sequence[float | None] | None


@dataclass(frozen=True)
class Added:
    """What an extension adds: cars on routes, and pedestrians on walks."""

    routes: tuple[Route, ...]
    ids: tuple[str, ...]  # the new cars'
    people: NewPedestrians

    @property
    def everyone(self) -> tuple[str, ...]:
        """The ids of every new road user: the cars, then the pedestrians."""
        return (*self.ids, *self.people.ids)


def validate_routes(
    old: TestCase, junction: Intersection, routes: Sequence[str], walks: Sequence[Walk] = ()
) -> list[Route]:
    if not routes and not walks:
        raise InvalidInput(
            "name at least one new route (FORK_LANE:EXIT_LANE) or walk (a crossing and its "
            "direction, as scengen intersection lists them) to add"
        )
    chosen = [junction.route(r) for r in routes]
    ego = junction.route(old.ego.route.id)
    for route in chosen:
        if not junction.conflicts[route.id]:
            raise InvalidInput(
                f"route {route.id} conflicts with no route at junction {junction.junction}: "
                "a car on it can never matter to anyone"
            )
    if not any(ego.id in junction.conflicts[route.id] or route.fork == ego.fork
               for route in chosen) and not any(ego.id in w.conflicts for w in walks):  # fmt: skip
        raise NoMoreComplexTestCase(
            "no more complex test-case exists for these routes: none of them crosses or "
            f"merges with the ego's route {ego.id} or starts ahead of the ego on its fork, "
            "and no walk crosses it, so no ego behaviour can violate a new road user's "
            "right-of-way or drive into it",
            routes=[*routes, *(w.id for w in walks)],
        )
    return chosen


def candidate_routes(old: TestCase, intersection: Intersection) -> list[str]:
    """Routes a new car may take: routes the junction offers (no parking lane or bay,
    service.core.network.lanes.side_lane_reason) that conflict with the ego's or start on
    its fork (a car ahead of the ego), sorted by id; a car on a fork in use joins the
    queue there. Then the walks a new pedestrian may take: those that cross the ego's
    route (docs/pedestrians.md), sorted by id."""
    ego = old.ego.route
    routes = sorted(
        route
        for route in intersection.offered_routes
        if route in intersection.conflicts[ego.id] or intersection.routes[route].fork == ego.fork
    )
    return routes + sorted(w.id for w in intersection.walks.values() if ego.id in w.conflicts)


def new_car_ids(old: TestCase, count: int) -> list[str]:
    taken = {n.id for n in old.road_users}
    ids: list[str] = []
    k = 1
    while len(ids) < count:
        if f"car{k}" not in taken:
            ids.append(f"car{k}")
        k += 1
    return ids


@dataclass(frozen=True)
class ShortenedStart:
    """An automatic start that did not fit on the road before its fork: the new car (by
    its place among the new routes) starts at the road's far end instead."""

    index: int
    route: str
    automatic: float  # where the car would have started on a longer road
    start: float  # where it starts: the whole road before its fork


def automatic_starts(
    old: TestCase,
    judge: Judge,
    routes: Sequence[Route],
    start: StartDistances,
    junction: Intersection,
) -> tuple[list[float], list[ShortenedStart]]:
    """Each new car's start distance: the one given, else automatic, and the automatic
    starts that were shortened. Automatically, a car on a fork no one uses starts where the
    ego does; on the ego's fork, ahead of the first car there; on a fork with other cars,
    behind the last one; with room for the gap and the headway at the start speed, and
    QUEUE_SPACING more; and never further back than the road before its fork goes (the
    longest start up to that which fits). InvalidInput when a car would start behind the
    ego or too close to a car already on its fork (for an automatic start: when the road
    has no room for it)."""
    given = _given_starts(routes, start)
    ego, params = old.ego, old.params
    ego_fork = ego.route.fork
    on_fork: dict[str, list[_Placed]] = {
        ego_fork: [_Placed(ego.start.distance, ego.length, "the ego", ego.start.speed)]
    }
    for car in judge.nonegos:
        speed = car.samples[0].speed if car.samples else 0.0
        on_fork.setdefault(car.fork, []).append(
            _Placed(car.in_queue.start, car.length, car.id, speed)
        )
    starts: list[float] = []
    shortened: list[ShortenedStart] = []
    for k, (route, wanted) in enumerate(zip(routes, given, strict=True)):
        there = on_fork.setdefault(route.fork, [])
        name = f"new car {k + 1} ({route.id})"
        cut = False
        if wanted is None:
            wanted = _automatic(old, there, route.fork == ego_fork)
            if wanted is None:
                first = min(p.start for p in there)
                raise InvalidInput(
                    f"{name}: no room ahead of the cars on the ego's fork {route.fork} (the "
                    f"first starts {first:g} m before the line); give its start distance"
                )
            wanted = round(wanted, 6)
            fitted = longest_start(junction, route, wanted)
            if fitted < wanted:
                shortened.append(ShortenedStart(k, route.id, wanted, fitted))
                wanted, cut = fitted, True
        wanted = round(wanted, 6)
        if route.fork == ego_fork and wanted > ego.start.distance:
            raise InvalidInput(
                f"{name} would start {wanted:g} m before the line, behind the ego "
                f"({ego.start.distance:g} m): a non-ego behind the ego would drive into any "
                "ego that waits longer than it does, so new cars on the ego's fork start "
                "ahead of it (a smaller start distance)"
            )
        placed = _Placed(wanted, ego.length, name, 0.0)
        for other in there:
            ahead, behind = (other, placed) if other.start < wanted else (placed, other)
            room = ahead.length + needed_gap(params.gap, params.headway, behind.speed)
            if behind.start - ahead.start >= room:
                continue
            if cut:
                raise InvalidInput(
                    f"{name}: no room on the road before fork {route.fork} ({wanted:g} m "
                    f"long) behind {other.name} ({other.start:g} m before the line): the car "
                    f"behind needs a car length plus its gap ({room:g} m) to the one ahead"
                )
            raise InvalidInput(
                f"{name} would start {wanted:g} m before the line, "
                f"{abs(wanted - other.start):g} m from {other.name} ({other.start:g} m) "
                f"on fork {route.fork}: the car behind needs a car length plus its gap "
                f"({room:g} m) to the one ahead"
            )
        there.append(placed)
        starts.append(wanted)
    return starts, shortened


@dataclass(frozen=True)
class _Placed:
    """A car on a fork at the start: metres before the line, length, name, speed."""

    start: float
    length: float
    name: str
    speed: float


def _automatic(old: TestCase, there: Sequence[_Placed], ego_fork: bool) -> float | None:
    """The automatic start of a new car on a fork with ``there`` on it."""
    params, length = old.params, old.ego.length
    if not there:
        return old.ego.start.distance
    if ego_fork:
        first = min(there, key=lambda p: p.start)
        room = length + needed_gap(params.gap, params.headway, first.speed)
        ahead = first.start - room - QUEUE_SPACING
        return ahead if ahead >= 0 else None
    last = max(there, key=lambda p: p.start)
    return last.start + last.length + params.gap + QUEUE_SPACING


def _given_starts(routes: Sequence[Route], start: StartDistances) -> list[float | None]:
    if start is None or isinstance(start, int | float):
        return [None if start is None else float(start)] * len(routes)
    given = list(start)
    if len(given) != len(routes):
        raise InvalidInput(
            f"give one start distance per new route: {len(routes)} routes, "
            f"{len(given)} start distances"
        )
    for value in given:
        if value is not None and (not math.isfinite(value) or value < 0):
            raise InvalidInput(f"start distances must be >= 0 m, got {value:g}")
    return given


def car_events(
    samples: Sequence[PoseSample],
    length: float,
    width: float,
    junction: Intersection,
    fork: str,
    old: TestCase,
) -> list[LaneEvent]:
    """A drive's events; remembered for the same samples (Step 1 keeps a drive, so the
    ego's drive of a chain's every level and every attempt is the same object) on the same
    junction."""
    key = (id(samples), length, width, id(junction), fork, old.params.arrival_distance,
           old.params.v_stop)  # fmt: skip
    kept = _EVENTS.get(key)
    if kept is not None and kept[0] is samples and kept[1] is junction:
        return list(kept[2])
    events = compute_events(
        samples, length, width, junction, fork, old.params.arrival_distance, old.params.v_stop
    )
    if len(_EVENTS) >= EVENTS_KEPT:
        _EVENTS.pop(next(iter(_EVENTS)))
    _EVENTS[key] = (samples, junction, tuple(events))
    return events


EVENTS_KEPT = 64  # drives whose events are remembered (the objects keep their ids alive)
_EVENTS: dict[
    tuple[object, ...], tuple[Sequence[PoseSample], Intersection, tuple[LaneEvent, ...]]
] = {}


def ordering_cars(
    old: TestCase,
    judge: Judge,
    junction: Intersection,
    ego_track: PoseTrack,
    new_tracks: dict[str, PoseTrack],
    new_routes: Sequence[Route],
    ids: Sequence[str],
) -> list[OrderingCar]:
    """The cars of Step 2; old cars with their events as the checker sees them (arrivals
    in a queue included)."""
    cars = [
        OrderingCar(car.id, CarKind.OLD, car.fork, car.lane, car.events) for car in judge.nonegos
    ]
    ego_route = junction.route(old.ego.route.id)
    ego_events = tuple(
        car_events(ego_track.samples, old.ego.length, old.ego.width, junction, ego_route.fork, old)
    )
    for name in ("ego", "illegal"):
        cars.append(
            OrderingCar(
                name,
                CarKind.CERTIFICATE,
                ego_route.fork,
                ego_route.connecting_lane,
                ego_events,
                old.ego.start.speed,
            )
        )
    for car_id, route in zip(ids, new_routes, strict=True):
        track = new_tracks[car_id]
        events = car_events(track.samples, track.length, track.width, junction, route.fork, old)
        cars.append(
            OrderingCar(car_id, CarKind.NEW, route.fork, route.connecting_lane, tuple(events))
        )
    return cars


@dataclass(frozen=True)
class Queue:
    """The queues of an extension: who follows whom, and what that asks of the times."""

    follows: tuple[Follow, ...]
    members: dict[str, QueueMember]
    bounds: QueueBounds


def queue_of(
    old: TestCase,
    judge: Judge,
    junction: Intersection,
    cars: Sequence[OrderingCar],
    tracks: dict[str, PoseTrack],
    ids: Sequence[str],
) -> Queue:
    cars = [car for car in cars if not car.walker]  # people on foot keep no queue
    by_name = {car.car: car for car in cars}
    members: dict[str, QueueMember] = {}
    queue_cars: list[QueueCar] = []
    for old_car in judge.nonegos:
        members[old_car.id] = QueueMember(
            by_name[old_car.id],
            old_car.length,
            old_car.line,
            Places.of(old_car.samples, old_car.in_queue),
        )
        queue_cars.append(old_car.in_queue)
    for name in ("ego", *ids):
        car, track = by_name[name], tracks[name]
        line = line_distance(track.samples, track.length, junction.fork(car.fork), car.events)
        queue_cars.append(QueueCar(name, car.fork, car.lane, track.length, track.width, line,
                                   track.samples[0].distance))  # fmt: skip
        members[name] = QueueMember(car, track.length, line)
    members["illegal"] = QueueMember(by_name["illegal"], members["ego"].length,
                                     members["ego"].line)  # fmt: skip
    found = tuple(follows(queue_cars, junction))
    limits = Bounds(old.params.v_max, old.params.a_max, old.params.a_min)
    bounds = queue_bounds(found, members, old.params.gap, limits, old.duration)
    at_start = tuple(  # events where a car starts (a queue's first car may have arrived)
        (t.symbol, TICK)
        for car in cars
        if car.kind is not CarKind.OLD
        for t in timed_events(car)
        if t.event.distance <= ROUNDING
    )
    bounds = dataclasses.replace(bounds, latest=bounds.latest + at_start)
    return Queue(found, members, bounds)
