"""Cars from different forks that leave into one exit lane: who is ahead there.

Two such cars share the end of their connecting lanes, so Step 2 orders them like any two
conflicting cars: one is out of the other's lane perceptibly before the other enters it.
That one is ahead on the exit lane, and the other follows it there. Step 3 keeps the gap
(``params.gap + params.headway x speed``, the headway with the safety margin, as in a
queue) from the moment the leader's rear has passed the start of the exit lane, or, behind
a symbolic leader, from the moment an old follower's front reaches it: before that, the
order in the junction keeps them apart. Without this, nothing in Steps 2 and 3 stopped a
car from catching up with a slower one behind the junction, and the verification rejected
such candidates (a collision on the exit lane) only after they were timed.

Places on the exit lane are distances travelled minus each car's ``exit_line``: the
distance at which its front reaches the exit lane (where it reaches the junction plus the
length of its connecting lane).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

from service.core.generator.ordering import Ordering
from service.core.generator.ordering_facts import (
    CarKind,
    OrderingCar,
    timed_events,
)
from service.core.generator.timing import Following
from service.core.motion.events import EventKind
from service.core.network import Intersection

Rows = tuple[tuple[float, float, float], ...]  # an old car's samples: (t, distance, speed)


def exit_line(junction: Intersection, car: OrderingCar, entry_line: float) -> float:
    """The distance travelled at which the car's front reaches its exit lane."""
    return entry_line + junction.connecting_lanes[car.lane].length


def _entered(car: OrderingCar, lane: str, times: Mapping[str, float]) -> float | None:
    """When the car enters ``lane`` (an old car's number, a symbolic car's Step 2 time)."""
    for timed in timed_events(car):
        if timed.event.kind is EventKind.ENTERED_LANE and timed.event.lane == lane:
            if car.kind is CarKind.OLD:
                return timed.event.time
            return times.get(str(timed.symbol))
    return None


def exit_followings(
    junction: Intersection,
    cars: Sequence[OrderingCar],
    ordering: Ordering,
    lines: Mapping[str, tuple[float, float]],
    rows: Mapping[str, Rows],
    gap: float,
    headway: float,
) -> tuple[Following, ...]:
    """Step 3's pairs on exit lanes: for two cars from different forks with one exit lane,
    at least one of them symbolic and not both certificates, the one that enters the
    other's connecting lane first (in ``ordering``) leads. ``lines``: each car's entry
    line and length; ``rows``: the old cars' samples."""
    exit_of = {route.connecting_lane: route.exit for route in junction.routes.values()}
    cars = [car for car in cars if not car.walker]  # people on foot share no exit lane
    exits = {car.car: exit_of[car.lane] for car in cars}
    times = dict(ordering.times)
    found = []
    for k, a in enumerate(cars):
        for b in cars[k + 1 :]:
            if a.fork == b.fork or exits[a.car] != exits[b.car]:
                continue
            if CarKind.OLD in (a.kind, b.kind) and a.kind == b.kind:
                continue  # two old cars: their numbers are given
            if a.kind is CarKind.CERTIFICATE and b.kind is CarKind.CERTIFICATE:
                continue  # alternative egos never meet
            first, second = _entered(a, b.lane, times), _entered(b, a.lane, times)
            if first is None or second is None or math.isclose(first, second):
                continue
            leader, follower = (a, b) if first < second else (b, a)
            fixed = rows.get(leader.car) or rows.get(follower.car) or ()
            found.append(
                Following(
                    leader.car,
                    follower.car,
                    exit_line(junction, leader, lines[leader.car][0]),
                    exit_line(junction, follower, lines[follower.car][0]),
                    lines[leader.car][1],
                    math.inf,
                    gap,
                    headway,
                    fixed,
                    joined=True,
                )
            )
    return tuple(found)
