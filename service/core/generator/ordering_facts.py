"""Step 2's facts: the road users as Step 2 sees them (``OrderingCar``, ``CarKind``,
``Limits``, ``QueueBounds``), their timed events, and the facts clingo is given
(``ordering_facts``): the geometry, the old cars' times and order, each symbolic car's
least travel times between its events (service.core.motion.kinematics), its lingering
bounds, its nominal schedule, the duration. service.core.generator.ordering searches over
them."""

from __future__ import annotations

import itertools
import math
import random
from collections.abc import Sequence
from dataclasses import dataclass
from enum import StrEnum

import clingo
import clingo.ast

from service.core.checker.rules import (
    REAL_LTE,
    REQUESTED_LANE,
    TIME,
    Fact,
    Predicate,
    TimedEvent,
    event_facts,
    geometry_facts,
    pedestrian_facts,
    perceptible_order,
    phase_facts,
    signal_facts,
    time_symbol,
)
from service.core.motion.events import EventKind, LaneEvent
from service.core.motion.kinematics import Bounds, least_gaps, lingering, stand_before
from service.core.network import Intersection

OLD = Predicate("old", 1)
NEW = Predicate("new", 1)
CERTIFICATE = Predicate("certificate", 1)
STOP_TIME = Predicate("stopTime", 2)
NOMINAL = Predicate("nominal", 2)
OLD_TIME = Predicate("oldTime", 3)
SYMBOLIC_TIME = Predicate("symbolicTime", 1)
MIN_GAP = Predicate("minGap", 3)
MIN_GAP_STOPPED = Predicate("minGapStopped", 4)
MAX_GAP_RUNNING = Predicate("maxGapRunning", 4)
MAX_GAP_INSIDE = Predicate("maxGapInside", 3)
LINGER_LEVEL = Predicate("lingerLevel", 3)
LINGER_AFTER = Predicate("lingerAfter", 5)
LINGER_BEFORE = Predicate("lingerBefore", 5)
HEADWAY = Predicate("headway", 3)
EARLIEST = Predicate("earliest", 2)
LATEST = Predicate("latest", 2)
AHEAD_OF = Predicate("aheadOf", 2)
HORIZON = Predicate("horizon", 1)
START = clingo.Number(0)  # the zero of clingo-dl's time line: t = 0
STOP_DELAY = 4.0  # seconds a stop at a sign adds to a car's nominal schedule
NOMINAL_SPREAD = 6.0  # seconds a new car's nominal schedule is late by at most (seeded)


CROSSING_PACE = 0.9  # m/s: a generated pedestrian's least average speed over its crosswalk
# (3 ft/s, the slowest walking speed crossings are timed for: no one lingers on one)


class CarKind(StrEnum):
    OLD = "old"
    NEW = "new"
    CERTIFICATE = "certificate"


@dataclass(frozen=True)
class OrderingCar:
    """A road user in Step 2: its kind, route and events (numeric times matter for old
    ones only). A pedestrian (``walker``) has its walk's crossing for a fork and the
    crossing's lane for a connecting lane (docs/pedestrians.md)."""

    car: str
    kind: CarKind
    fork: str
    lane: str  # the connecting lane of its route
    events: tuple[LaneEvent, ...]
    start_speed: float | None = None  # fixed for the certificates
    walker: bool = False  # a person on foot: its crossing's events, the walking bounds


@dataclass(frozen=True)
class Limits:
    """What bounds every symbolic car's timing: the test-case's parameters and the margin."""

    duration: float
    bounds: Bounds
    v_run: float
    margin: float  # seconds every relation with a symbolic time keeps beyond m
    crossing: float | None = None  # least average speed from entering to leaving its lane
    walking: Bounds | None = None  # the pedestrians' bounds (None: the cars')

    def of(self, car: OrderingCar) -> Limits:
        """The limits of ``car``: a pedestrian walks within the walking bounds, and crosses
        at CROSSING_PACE on average at least (no one lingers on a crosswalk)."""
        if not car.walker or self.walking is None:
            return self
        crossing = CROSSING_PACE if self.crossing else None
        return Limits(self.duration, self.walking, self.v_run, self.margin, crossing,
                      self.walking)  # fmt: skip


def stop_symbol(car: str) -> clingo.Symbol:
    return clingo.Function("s", [clingo.String(car)])


@dataclass(frozen=True)
class QueueBounds:
    """Conditions on time symbols (seconds) that the queues ask of the symbolic cars
    (service.core.generator.following works them out)."""

    headways: tuple[tuple[clingo.Symbol, clingo.Symbol, float], ...] = ()  # t >= s + g
    earliest: tuple[tuple[clingo.Symbol, float], ...] = ()  # t >= the number
    latest: tuple[tuple[clingo.Symbol, float], ...] = ()  # t <= the number
    ahead: tuple[tuple[str, str], ...] = ()  # (new car, "illegal"): it may drive into it


ONE_PLACE = 0.01  # metres: a symbolic car's events this close share one time symbol


def timed_events(car: OrderingCar) -> list[TimedEvent]:
    """The car's events with time symbols; a symbolic car's events within ONE_PLACE of the
    first of them share one (a car passes a centimetre in a blink; Step 3 plans it as one
    point, at the first event's distance)."""
    timed: list[TimedEvent] = []
    index = -1
    first: float | None = None
    for event in car.events:
        if event.kind is EventKind.EXITED:
            continue
        if car.kind is CarKind.OLD or first is None or event.distance > first + ONE_PLACE:
            index += 1
            first = event.distance
        timed.append(TimedEvent(car.car, time_symbol(car.car, index), event))
    return timed


def _points(timed: Sequence[TimedEvent]) -> list[tuple[clingo.Symbol, float]]:
    """A symbolic car's distinct time symbols with their (first event's) distances."""
    found: dict[clingo.Symbol, float] = {}
    for t in timed:
        found.setdefault(t.symbol, t.event.distance)
    return list(found.items())


def _first(timed: Sequence[TimedEvent], kind: EventKind) -> TimedEvent | None:
    return next((t for t in timed if t.event.kind is kind), None)


def _gap_facts(
    points: Sequence[tuple[clingo.Symbol | None, float]],
    start_speed: float | None,
    bounds: Bounds,
) -> list[tuple[clingo.Symbol, clingo.Symbol, int]]:
    """(S, T, ms) for consecutive named points (the start is START): T at least ms after S.
    Unnamed points (the end of a stand) add their gaps to the next named one."""
    distances = [0.0] + [d for _, d in points]
    gaps = least_gaps(distances, start_speed, bounds)
    found = []
    behind, carried = START, 0.0
    for (symbol, _), gap in zip(points, gaps, strict=True):
        carried += gap
        if symbol is None:
            continue
        found.append((behind, symbol, math.floor(carried * 1000)))
        behind, carried = symbol, 0.0
    return found


def event_groups(car: OrderingCar) -> list[list[TimedEvent]]:
    """The car's timed events by time symbol, in order (one group per point of its drive)."""
    groups: dict[clingo.Symbol, list[TimedEvent]] = {}
    for timed in timed_events(car):
        groups.setdefault(timed.symbol, []).append(timed)
    return list(groups.values())


def stand_distance(car: OrderingCar) -> float | None:
    """Where the car stands when it stops at its sign: just before the point where it enters
    the junction, after every point before that; None when it cannot stop there (it has
    not arrived at an earlier point)."""
    groups = event_groups(car)
    entry = next(
        (k for k, g in enumerate(groups) if any(t.event.kind is EventKind.ENTERED for t in g)),
        None,
    )
    if entry is None:
        return None
    earlier = [t.event for group in groups[:entry] for t in group]
    if not any(e.kind is EventKind.ARRIVED for e in earlier):
        return None
    return stand_before(groups[entry][0].event.distance, max(e.distance for e in earlier))


def _time_facts(
    car: OrderingCar,
    timed: Sequence[TimedEvent],
    stop_sign: bool,
    limits: Limits,
    may_stop: bool = False,
) -> list[Fact]:
    """Difference-constraint facts of a symbolic car: least gaps between its consecutive
    symbols however it drives, the stronger ones when it stops at its sign (braking to the
    stand, standing, pulling away), and the longest gap from arriving to entering when it
    runs the sign (at least v_run all the way). ``may_stop``: the car may stop at its line
    without a sign (a signal): its stop is a choice, with no longest gap when it does not."""
    points: list[tuple[clingo.Symbol | None, float]] = list(_points(timed))
    facts = [MIN_GAP(a, b, g) for a, b, g in _gap_facts(points, car.start_speed, limits.bounds)]
    facts += [SYMBOLIC_TIME(s) for s, _ in points if s is not None]
    facts += _linger_facts([(START, 0.0), *points], limits.bounds)
    arrived, entered = _first(timed, EventKind.ARRIVED), _first(timed, EventKind.ENTERED)
    leaves = next((t for t in timed if t.event.kind is EventKind.LEFT_LANE
                   and t.event.lane == car.lane), None)  # fmt: skip
    if limits.crossing and entered is not None and leaves is not None:
        inside = leaves.event.distance - entered.event.distance
        longest = math.ceil(inside / limits.crossing * 1000)
        facts.append(MAX_GAP_INSIDE(entered.symbol, leaves.symbol, longest))
    stand = stand_distance(car)
    if not (stop_sign or may_stop) or arrived is None or entered is None or stand is None:
        return facts
    stop = stop_symbol(car.car)
    facts += [SYMBOLIC_TIME(stop), STOP_TIME(car.car, stop)]
    behind = [p for p in points if p[1] < stand]
    stopping = [*behind, (stop, stand), (None, stand), *points[len(behind) :]]
    stopped_gaps = _gap_facts(stopping, car.start_speed, limits.bounds)
    facts += [MIN_GAP_STOPPED(car.car, a, b, g) for a, b, g in stopped_gaps]
    if not stop_sign:
        return facts
    run = entered.event.distance - arrived.event.distance
    longest = math.ceil(run / limits.v_run * 1000)
    facts.append(MAX_GAP_RUNNING(car.car, arrived.symbol, entered.symbol, longest))
    return facts


def _linger_facts(
    points: Sequence[tuple[clingo.Symbol | None, float]], bounds: Bounds
) -> list[Fact]:
    """A car that takes long over one segment cannot be fast at its ends (kinematics.
    lingering): lingerLevel(P, Q, L) for segment P..Q and a duration of L ms; with it,
    lingerAfter(P, Q, L, R, G) (R at least G ms after Q) and lingerBefore(P, Q, L, O, G)
    (P at least G ms after O). Durations are rounded up and gaps down: necessary still."""
    symbols = [symbol for symbol, _ in points]
    facts: list[Fact] = []
    levels = set()
    for linger in lingering([distance for _, distance in points], bounds):
        first, last = symbols[linger.segment - 1], symbols[linger.segment]
        other = symbols[linger.other]
        level = math.ceil(linger.seconds * 1000)
        least = math.floor(linger.least * 1000)
        if first is None or last is None or other is None:
            continue
        levels.add((first, last, level))
        if linger.other > linger.segment:
            facts.append(LINGER_AFTER(first, last, level, other, least))
        else:
            facts.append(LINGER_BEFORE(first, last, level, other, least))
    return facts + [LINGER_LEVEL(*key) for key in sorted(levels)]


def _nominal(
    car: OrderingCar, timed: Sequence[TimedEvent], stop_sign: bool, seed: int
) -> list[Fact]:
    """Plausible times of a symbolic car's events: Step 1's constant speed, delayed after
    the stop line by STOP_DELAY where the car has a stop sign; a new car's schedule is
    also late by up to NOMINAL_SPREAD seconds, drawn from the seed (so that other seeds
    try other orders first)."""
    entry = [t.event for t in timed if t.event.kind is EventKind.ENTERED]
    delay_from = entry[0].distance if (entry and stop_sign) else float("inf")
    late = 0.0
    if car.kind is CarKind.NEW:  # a string seed is hashed with SHA-512: the same everywhere
        late = random.Random(f"{seed}:{car.car}").uniform(0.0, NOMINAL_SPREAD)
    facts = []
    for t in timed:
        delay = late + (STOP_DELAY if t.event.distance >= delay_from - 1e-6 else 0.0)
        facts.append(NOMINAL(t.symbol, round((t.event.time + delay) * 1000)))
    if entry:
        stop = entry[0].time + late + 1.0
        facts.append(NOMINAL(stop_symbol(car.car), round(stop * 1000)))
    return facts


def ordering_facts(
    intersection: Intersection,
    cars: Sequence[OrderingCar],
    m: float,
    limits: Limits,
    seed: int = 0,
    queue: QueueBounds | None = None,
) -> tuple[list[clingo.Symbol], dict[clingo.Symbol, TimedEvent]]:
    """Facts of Step 2 and the events behind every time symbol; ``queue``: what the
    queues ask of the symbolic cars (service.core.generator.following)."""
    facts = geometry_facts(intersection) + signal_facts(intersection, limits.duration)
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
        if car.walker:  # its crossing's lane names its crossing
            facts += pedestrian_facts(car.car, car.lane, timed)
        else:
            facts += event_facts(car.car, car.fork, timed)
        if car.kind is CarKind.OLD:
            old_timed += timed
            for t in timed:
                ms = t.event.time * 1000
                facts.append(OLD_TIME(t.symbol, math.floor(ms), math.ceil(ms)))
            continue
        stop_sign = not car.walker and intersection.forks[car.fork].stop_sign
        may_stop = car.fork in intersection.signal_forks
        facts += _time_facts(car, timed, stop_sign, limits.of(car), may_stop)
        facts += _nominal(car, timed, stop_sign, seed)
        distinct = list(dict.fromkeys(t.symbol for t in timed))
        facts += [TIME(s) for s in distinct]
        facts += [REAL_LTE(a, b) for a, b in itertools.pairwise(distinct)]
    facts += perceptible_order(old_timed, m)
    facts += phase_facts(intersection, old_timed, limits.duration)
    facts += [NOMINAL(t.symbol, round(t.event.time * 1000)) for t in old_timed]
    horizon = math.floor((limits.duration - limits.margin) * 1000)
    facts.append(HORIZON(horizon))
    if queue is not None:
        facts += [HEADWAY(a, b, math.floor(gap * 1000)) for a, b, gap in queue.headways]
        facts += [EARLIEST(s, min(math.ceil(t * 1000 - 1e-6), horizon + 1))
                  for s, t in queue.earliest]  # fmt: skip
        facts += [LATEST(s, math.floor(t * 1000 + 1e-6)) for s, t in queue.latest]
        facts += [AHEAD_OF(clingo.String(a), clingo.String(b)) for a, b in queue.ahead]
    return facts, symbols
