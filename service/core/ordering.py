"""Step 2: choose the order of events with clingo (asp/extension.lp over the rule set).

Old non-egos keep their numeric times (their mutual order is given as facts); new non-egos
and the two certificate egos get time symbols, and clingo chooses the perceptible order of
every pair of their events that matters to a rule or to the no-collision requirement, and
whether each stops at a stop sign. Answer sets are drawn lazily, one at a time.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from enum import StrEnum

import clingo

from service.core.events import EventKind, LaneEvent
from service.core.network import Intersection
from service.core.rules import (
    REAL_LTE,
    REQUESTED_LANE,
    TIME,
    Fact,
    Predicate,
    TimedEvent,
    asp_dir,
    event_facts,
    geometry_facts,
    perceptible_order,
    rule_set_file,
    time_symbol,
)
from service.core.timing import DWELL, fastest

OLD = Predicate("old", 1)
NEW = Predicate("new", 1)
CERTIFICATE = Predicate("certificate", 1)
STOP_TIME = Predicate("stopTime", 2)
NOMINAL = Predicate("nominal", 2)
EARLIEST = Predicate("earliest", 2)
LATEST = Predicate("latest", 2)
GROUPS = ("complexity", "solvability", "noCollision")
GROUP_EXPLANATIONS = {
    "complexity": "no order of events lets an ego pass the old test-case and still violate "
    "a new car's right-of-way",
    "solvability": "no order of events leaves the new test-case solvable",
    "noCollision": "every order that works needs two cars in each other's lanes at once",
}


class CarKind(StrEnum):
    OLD = "old"
    NEW = "new"
    CERTIFICATE = "certificate"


@dataclass(frozen=True)
class OrderingCar:
    """A car in Step 2: its kind, route and events (numeric times matter for old cars only)."""

    car: str
    kind: CarKind
    fork: str
    lane: str  # the connecting lane of its route
    events: tuple[LaneEvent, ...]
    start_speed: float | None = None  # fixed for the certificates


@dataclass(frozen=True)
class Limits:
    """What bounds every symbolic car's timing (the test-case's parameters)."""

    duration: float
    a_min: float
    a_max: float
    v_max: float


def _time_bounds(
    car: OrderingCar, timed: Sequence[TimedEvent], stop_sign: bool, limits: Limits
) -> list[Fact]:
    """earliest/latest of each symbol: no faster than v_max and a_max allow from the start
    (a certificate must also stop at a sign: braking, standing, pulling away), never after
    the end of the duration."""
    facts = []
    entry = [t.event.distance for t in timed if t.event.kind is EventKind.ENTERED]
    stand = entry[0] - 0.5 if (entry and stop_sign and car.kind is CarKind.CERTIFICATE) else None
    start = car.start_speed if car.start_speed is not None else limits.v_max
    for t in timed:
        distance = t.event.distance
        if stand is not None and distance > stand:  # reach the stand, stand, pull away
            early = (
                fastest(stand, start, limits.a_max, limits.v_max)
                + DWELL
                + fastest(distance - stand, 0.0, limits.a_max, limits.v_max)
            )
        else:
            early = fastest(distance, start, limits.a_max, limits.v_max)
        facts.append(EARLIEST(t.symbol, math.floor(early * 1000)))
        facts.append(LATEST(t.symbol, math.ceil(limits.duration * 1000)))
    return facts


def stop_symbol(car: str) -> clingo.Symbol:
    return clingo.Function("s", [clingo.String(car)])


@dataclass(frozen=True)
class Ordering:
    """One answer set: the chosen relations between time symbols and the chosen stops."""

    index: int
    relations: tuple[tuple[str, clingo.Symbol, clingo.Symbol], ...]  # ("lessThan"|"equal", s, t)
    stops: frozenset[str]
    violated: tuple[tuple[str, str], ...] = field(default=())  # (new car, rule) by "illegal"

    def describe(self) -> list[str]:
        return [f"{kind}({a},{b})" for kind, a, b in self.relations]


def timed_events(car: OrderingCar) -> list[TimedEvent]:
    """The car's events with time symbols; a symbolic car's events at one distance share one."""
    timed: list[TimedEvent] = []
    index = -1
    previous: float | None = None
    for event in car.events:
        if event.kind is EventKind.EXITED:
            continue
        if car.kind is CarKind.OLD or previous is None or event.distance > previous + 1e-6:
            index += 1
        previous = event.distance
        timed.append(TimedEvent(car.car, time_symbol(car.car, index), event))
    return timed


STOP_DELAY = 4.0  # seconds a stop at a sign adds to a car's nominal schedule


def _nominal(car: OrderingCar, timed: Sequence[TimedEvent], stop_sign: bool) -> list[Fact]:
    """Plausible times of a symbolic car's events: Step 1's constant speed, delayed after
    the stop line by STOP_DELAY where the car has a stop sign."""
    entry = [t.event for t in timed if t.event.kind is EventKind.ENTERED]
    delay_from = entry[0].distance if (entry and stop_sign) else float("inf")
    facts = []
    for t in timed:
        delay = STOP_DELAY if t.event.distance >= delay_from - 1e-6 else 0.0
        facts.append(NOMINAL(t.symbol, round((t.event.time + delay) * 1000)))
    if entry:
        facts.append(NOMINAL(stop_symbol(car.car), round((entry[0].time + 1.0) * 1000)))
    return facts


def ordering_facts(
    intersection: Intersection, cars: Sequence[OrderingCar], m: float, limits: Limits
) -> tuple[list[clingo.Symbol], dict[clingo.Symbol, TimedEvent]]:
    """Facts of Step 2 and the events behind every time symbol."""
    facts = geometry_facts(intersection)
    symbols: dict[clingo.Symbol, TimedEvent] = {}
    old_timed: list[TimedEvent] = []
    requested = {car.lane for car in cars}
    for car in cars:
        kind_fact = {CarKind.OLD: OLD, CarKind.NEW: NEW, CarKind.CERTIFICATE: CERTIFICATE}
        facts += [kind_fact[car.kind](car.car), REQUESTED_LANE(car.car, car.lane)]
        timed = [
            t
            for t in timed_events(car)
            if t.event.kind not in (EventKind.ENTERED_LANE, EventKind.LEFT_LANE)
            or t.event.lane in requested
        ]
        for t in timed:
            symbols.setdefault(t.symbol, t)
        facts += event_facts(car.car, car.fork, timed)
        if car.kind is CarKind.OLD:
            old_timed += timed
            for t in timed:
                facts.append(EARLIEST(t.symbol, math.floor(t.event.time * 1000)))
                facts.append(LATEST(t.symbol, math.ceil(t.event.time * 1000)))
            continue
        facts += _time_bounds(car, timed, intersection.forks[car.fork].stop_sign, limits)
        facts.append(STOP_TIME(car.car, stop_symbol(car.car)))
        facts += _nominal(car, timed, intersection.forks[car.fork].stop_sign)
        distinct = list(dict.fromkeys(t.symbol for t in timed))
        facts += [TIME(s) for s in distinct]
        facts += [REAL_LTE(a, b) for a, b in itertools.pairwise(distinct)]
    facts += perceptible_order(old_timed, m)
    facts += [NOMINAL(t.symbol, round(t.event.time * 1000)) for t in old_timed]
    return facts, symbols


class OrderingSearch:
    """Answer sets of Step 2, drawn one at a time."""

    def __init__(
        self,
        intersection: Intersection,
        cars: Sequence[OrderingCar],
        m: float,
        seed: int,
        limits: Limits,
    ) -> None:
        self.cars = {car.car: car for car in cars}
        self.facts, self.symbols = ordering_facts(intersection, cars, m, limits)
        self.control = clingo.Control(
            [
                "--models=0",
                "--warn=none",
                "--heuristic=Domain",
                f"--seed={seed}",
                "--rand-freq=0.02",
                f"--const=m_ms={round(m * 1000)}",
            ]
        )
        for path in (
            rule_set_file(intersection.control),
            asp_dir() / "time_axioms.lp",
            asp_dir() / "extension.lp",
        ):
            self.control.load(str(path))
        with self.control.backend() as backend:
            for fact in self.facts:
                backend.add_rule([backend.add_atom(fact)])
        self.control.ground([("base", [])])
        for group in GROUPS:
            self._enforce(group, True)
        self.symbolic = {c for c, car in self.cars.items() if car.kind is not CarKind.OLD}
        self.drawn = 0
        self.learned = 0

    def _enforce(self, group: str, value: bool) -> None:
        self.control.assign_external(clingo.Function("enforce", [clingo.Function(group)]), value)

    def next_ordering(self) -> Ordering | None:
        """The next answer set, or None when there is none left. Each is drawn afresh and
        then blocked, so what Step 3 learns (``forbid``) prunes the search that follows."""
        with self.control.solve(yield_=True) as handle:
            model = next(iter(handle), None)
            if model is None:
                return None
            ordering = self._ordering(self.drawn, model.symbols(atoms=True))
        self.drawn += 1
        literals = [f"{kind}({a},{b})" for kind, a, b in ordering.relations]
        for car in sorted(self.symbolic):
            stop = f'stoppedAtForkAtTime("{car}",_,{stop_symbol(car)})'
            literals.append(stop if car in ordering.stops else f"not {stop}")
        self._add_constraint(literals)
        return ordering

    def forbid(self, relations: Sequence[tuple[str, clingo.Symbol, clingo.Symbol]]) -> None:
        """Rule out every answer set with all of these relations (they cannot hold together)."""
        self._add_constraint([f"{kind}({a},{b})" for kind, a, b in relations])

    def _add_constraint(self, literals: Sequence[str]) -> None:
        name = f"learned{self.learned}"
        self.learned += 1
        self.control.add(name, [], ":- " + ", ".join(literals) + ".")
        self.control.ground([(name, [])])

    def _ordering(self, index: int, atoms: Sequence[clingo.Symbol]) -> Ordering:
        relations = []
        stops = set()
        violated = []
        symbolic = self.symbolic
        for atom in atoms:
            if atom.match("lessThan", 2) or atom.match("equal", 2):
                a, b = atom.arguments
                if _car_of(a) in symbolic or _car_of(b) in symbolic:
                    if atom.name == "equal" and str(a) > str(b):
                        continue  # each simultaneity once
                    relations.append((atom.name, a, b))
            elif atom.match("stoppedAtForkAtTime", 3) and atom.arguments[0].string in symbolic:
                stops.add(atom.arguments[0].string)
            elif atom.match("violatesRightOfForRule", 3) and atom.arguments[0].string == "illegal":
                violated.append((atom.arguments[1].string, str(atom.arguments[2])))
        relations.sort(key=lambda r: (r[0], str(r[1]), str(r[2])))
        return Ordering(index, tuple(relations), frozenset(stops), tuple(sorted(violated)))

    def explain_unsatisfiable(self) -> str:
        """Which requirement could not be met: the first group whose release makes it SAT."""
        for group in GROUPS:
            self._enforce(group, False)
            satisfiable = self.control.solve().satisfiable
            self._enforce(group, True)
            if satisfiable:
                return GROUP_EXPLANATIONS[group]
        return "no order of events meets the requirements even one at a time"


def _car_of(symbol: clingo.Symbol) -> str:
    return str(symbol.arguments[0].string)
