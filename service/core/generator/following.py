"""What following in a queue asks of the symbolic cars' event times (Steps 2 and 3).

For every pair of cars on one fork (service.core.motion.queues) in which at least one car is
symbolic (a new car or a certificate ego), two kinds of condition, both necessary for any
curves that keep the gap:

- the gap: when the follower's front is at place x, the leader's front is at least at
  min(parting, x + gap) + the leader's length. A symbolic follower's event at x therefore
  comes no earlier than the leader's last point before that place plus the least time to
  drive the rest (at v_max); an old leader's numbers give the time directly; an old
  follower bounds the symbolic leader's points from above;
- the queue: a car the generator plans arrives (comes within the arrival distance) only
  after every car ahead of it has entered the junction, so that its arrival is its own and
  the cars behind it keep theirs (a car still behind another has not arrived). A new car
  ahead of an old one therefore enters before the old one arrives.

The exception is the complexity certificate behind a new car: it may drive into it (a
rear-end collision is how it fails the new test-case), so it is only told who is ahead.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import clingo

from service.core.generator.ordering_facts import (
    START,
    CarKind,
    OrderingCar,
    QueueBounds,
    stand_distance,
    stop_symbol,
    timed_events,
)
from service.core.motion.events import EventKind
from service.core.motion.kinematics import DWELL, Bounds, fastest
from service.core.motion.queues import Follow, Places

CERTIFICATES = ("ego", "illegal")


@dataclass(frozen=True)
class QueueMember:
    """A car of a queue: its kind, length, line (distance at the junction) and, for an old
    car, its places over time."""

    car: OrderingCar
    length: float
    line: float
    places: Places | None = None  # old cars only


def _points(member: QueueMember) -> list[tuple[clingo.Symbol, float]]:
    """A symbolic car's start and time symbols with their places, and its stop symbol
    where it would stand (a symbol that stays free when the car does not stop)."""
    found: dict[clingo.Symbol, float] = {START: -member.line}
    for timed in timed_events(member.car):
        found.setdefault(timed.symbol, timed.event.distance - member.line)
    stand = stand_distance(member.car)
    if stand is not None:
        found[stop_symbol(member.car.car)] = stand - member.line
    return sorted(found.items(), key=lambda item: item[1])


def _symbol(member: QueueMember, kind: EventKind) -> clingo.Symbol | None:
    return next((t.symbol for t in timed_events(member.car) if t.event.kind is kind), None)


def _time(member: QueueMember, kind: EventKind) -> float | None:
    return next((e.time for e in member.car.events if e.kind is kind), None)


def queue_bounds(
    follows: Sequence[Follow],
    members: dict[str, QueueMember],
    gap: float,
    bounds: Bounds,
    horizon: float,
) -> QueueBounds:
    """The conditions of every pair with a symbolic car. ``members`` names the ego's queue
    entry "ego"; it stands for both certificates."""
    headways: list[tuple[clingo.Symbol, clingo.Symbol, float]] = []
    earliest: list[tuple[clingo.Symbol, float]] = []
    latest: list[tuple[clingo.Symbol, float]] = []
    ahead: list[tuple[str, str]] = []
    for follow in follows:
        for leader_id in _cars(follow.leader):
            for follower_id in _cars(follow.follower):
                leader, follower = members[leader_id], members[follower_id]
                kinds = (leader.car.kind, follower.car.kind)
                if CarKind.OLD in kinds and kinds[0] == kinds[1]:
                    continue  # two old cars: their numbers are given
                if follower_id == "illegal" and leader.car.kind is CarKind.NEW:
                    ahead.append((leader_id, follower_id))
                    continue
                _gap(follow, leader, follower, gap, bounds, horizon, headways, earliest, latest)
                _queue(leader, follower, headways, earliest, latest)
    return QueueBounds(tuple(headways), tuple(earliest), tuple(latest), tuple(ahead))


def _cars(queue_id: str) -> tuple[str, ...]:
    return CERTIFICATES if queue_id == "ego" else (queue_id,)


def _target(follow: Follow, place: float, gap: float, length: float) -> float:
    """Where the leader's front is at least when the follower's front is at ``place``."""
    return min(follow.parting, place + gap) + length


def _gap(
    follow: Follow,
    leader: QueueMember,
    follower: QueueMember,
    gap: float,
    bounds: Bounds,
    horizon: float,
    headways: list[tuple[clingo.Symbol, clingo.Symbol, float]],
    earliest: list[tuple[clingo.Symbol, float]],
    latest: list[tuple[clingo.Symbol, float]],
) -> None:
    v_max, a_max = bounds.v_max, bounds.a_max
    if follower.places is None:  # a symbolic follower
        lead_points = None if leader.places is not None else _points(leader)
        for symbol, place in _points(follower)[1:]:
            target = _target(follow, place, gap, leader.length)
            if leader.places is not None:
                reached = leader.places.first_time_at(target)
                earliest.append((symbol, horizon + 1.0 if reached is None else reached))
                continue
            assert lead_points is not None
            stop = stop_symbol(leader.car.car)
            for anchor, at in [(s, x) for s, x in lead_points if x <= target] or lead_points[:1]:
                if anchor == stop:  # it stands there, then pulls away
                    seconds = DWELL + fastest(target - at, 0.0, a_max, v_max)
                else:
                    seconds = max(target - at, 0.0) / v_max
                if anchor == START:
                    earliest.append((symbol, seconds))
                else:
                    headways.append((anchor, symbol, seconds))
        return
    for symbol, place in _points(leader)[1:]:  # an old follower, a symbolic leader
        if symbol == stop_symbol(leader.car.car):
            continue
        if place - leader.length >= follow.parting:
            continue
        reached = follower.places.first_time_at(place - leader.length - gap)
        if reached is not None:
            latest.append((symbol, reached))


def _queue(
    leader: QueueMember,
    follower: QueueMember,
    headways: list[tuple[clingo.Symbol, clingo.Symbol, float]],
    earliest: list[tuple[clingo.Symbol, float]],
    latest: list[tuple[clingo.Symbol, float]],
) -> None:
    """The follower arrives no earlier than the leader entered."""
    arrived = _symbol(follower, EventKind.ARRIVED)
    entered = _symbol(leader, EventKind.ENTERED)
    if follower.places is not None:
        arrival = _time(follower, EventKind.ARRIVED)
        if entered is not None and arrival is not None:
            latest.append((entered, arrival))
        return
    if arrived is None:
        return
    if leader.places is not None:
        entry = _time(leader, EventKind.ENTERED)
        earliest.append((arrived, math.inf if entry is None else entry))
    elif entered is not None:
        headways.append((entered, arrived, 0.0))
