"""Hand-written event traces with pedestrians as the rule files' facts (the pedestrian
laws' tests at the ASP level): real builders (service.core.checker.rules), real clingo."""

from __future__ import annotations

import clingo

from service.core.checker.rules import (
    REQUESTED_LANE,
    TimedEvent,
    event_facts,
    geometry_facts,
    pedestrian_facts,
    perceptible_order,
    phase_facts,
    signal_facts,
    solve_rules,
    time_symbol,
)
from service.core.checker.verdict import RIGHTS_OF_PEDESTRIANS
from service.core.motion.events import EventKind, LaneEvent
from service.core.network import Intersection

ARRIVED, STOPPED, ENTERED, EXITED = (
    EventKind.ARRIVED, EventKind.STOPPED, EventKind.ENTERED, EventKind.EXITED,
)  # fmt: skip
IN, OUT = EventKind.ENTERED_LANE, EventKind.LEFT_LANE
Event = tuple[str, EventKind, str | None, float]


def facts_of(
    intersection: Intersection,
    cars: dict[str, str],
    people: dict[str, str],
    events: list[Event],
    horizon: float = 60.0,
) -> list[clingo.Symbol]:
    """The facts of hand-written events, the k-th event's time symbol t(who, k). ``cars``:
    id -> route, ``people``: id -> walk. Where an event happens: None is a car's fork or a
    pedestrian's crossing, a route id that route's connecting lane, a crossing id that
    crossing's lane."""
    timed = []
    for k, (who, kind, where, time) in enumerate(events):
        if where is None and who in cars:
            lane = intersection.route(cars[who]).fork
        elif where is None:
            lane = intersection.walk(people[who]).crossing
        elif where in intersection.routes:
            lane = intersection.routes[where].connecting_lane
        else:
            lane = intersection.crossings[where].lane
        timed.append(TimedEvent(who, time_symbol(who, k), LaneEvent(kind, lane, time, 0.0)))
    facts = geometry_facts(intersection) + perceptible_order(timed, 1.0)
    facts += signal_facts(intersection, horizon) + phase_facts(intersection, timed, horizon)
    for car, route_id in cars.items():
        route = intersection.route(route_id)
        facts.append(REQUESTED_LANE(car, route.connecting_lane))
        facts += event_facts(car, route.fork, [t for t in timed if t.car == car])
    for person, walk_id in people.items():
        crossing = intersection.crossings[intersection.walk(walk_id).crossing]
        facts += pedestrian_facts(person, crossing.lane, [t for t in timed if t.car == person])
    return facts


def judge(
    intersection: Intersection, cars: dict[str, str], people: dict[str, str], events: list[Event]
) -> set[tuple[str, ...]]:
    """Violations as (violator, other, rule) and (violator, rule)."""
    found: set[tuple[str, ...]] = set()
    for atom in solve_rules(intersection.control, facts_of(intersection, cars, people, events)):
        if atom.match("violatesRightOfForRule", 3):
            v1, v2, rule = atom.arguments
            found.add((v1.string, v2.string, str(rule)))
            # a right-of-way owed to a pedestrian is one the verdict words so, and only
            # cars owe one
            assert (v2.string in people) == (str(rule) in RIGHTS_OF_PEDESTRIANS), atom
            assert v1.string in cars, atom
        elif atom.match("violatesRule", 2):
            found.add((atom.arguments[0].string, str(atom.arguments[1])))
    return found
