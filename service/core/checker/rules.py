"""Traffic rules: the clingo rule set of a control type and typed builders of its facts.

Facts are built through the helpers below, never as free text, so a renamed predicate
breaks a test (tests/core/checker/test_rules.py checks every input predicate against the
files).
Every identifier from a network or a test-case (car ids, lane ids) is an ASP string, so ids
such as ``-35_0`` or ``:C_11_0`` need no escaping. Time symbols are ``t(Car, K)``, a
pedestrian's too. A crossing is named by its lane (``:C_c0_0``) in every fact, as a car's
route by its connecting lane (docs/pedestrians.md, "The rules on an event trace").
"""

from __future__ import annotations

import functools
import itertools
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import clingo

from service.core.errors import ScengenError
from service.core.motion.events import EventKind, LaneEvent
from service.core.network import ControlType, Intersection
from service.core.network.signals import RULE_COLOURS

Fact = clingo.Symbol
EPSILON = 1e-9  # seconds: float noise below this never flips a perceptible order


def asp_dir() -> Path:
    """``asp/``: inside the installed package, or beside it in a source checkout."""
    package = Path(__file__).resolve().parents[2]
    for candidate in (package / "asp", package.parent / "asp"):
        if (candidate / "rules").is_dir():
            return candidate
    raise ScengenError("the rule files (asp/) are missing from this installation")


def rule_set_file(control: ControlType) -> Path:
    """The rule set of a control type: chosen by the junction, never by hand."""
    return asp_dir() / "rules" / f"{control.rule_set}.lp"


@dataclass(frozen=True)
class Predicate:
    """An input predicate of the rule files: name and arity."""

    name: str
    arity: int

    def __call__(self, *args: str | int | clingo.Symbol) -> Fact:
        if len(args) != self.arity:
            raise TypeError(f"{self.name}/{self.arity} takes {self.arity} arguments")
        return clingo.Function(self.name, [_term(a) for a in args])


def _term(value: str | int | clingo.Symbol) -> clingo.Symbol:
    if isinstance(value, clingo.Symbol):
        return value
    if isinstance(value, int):
        return clingo.Number(value)
    return clingo.String(value)


def constant(name: str) -> clingo.Symbol:
    """A plain ASP constant such as ``left``."""
    return clingo.Function(name, [])


# Geometry (geometry.lp)
IS_FORK = Predicate("isFork", 1)
LANE_FROM_FORK = Predicate("laneFromFork", 2)
LANE_TURN = Predicate("laneTurn", 2)
OVERLAPS = Predicate("overlaps", 2)
IS_TO_THE_RIGHT_OF = Predicate("isToTheRightOf", 2)
IS_OPPOSITE_OF = Predicate("isOppositeOf", 2)
SAME_DIRECTION = Predicate("sameDirection", 2)
HAS_STOP_SIGN = Predicate("hasStopSign", 1)
HAS_YIELD_SIGN = Predicate("hasYieldSign", 1)
REQUESTED_LANE = Predicate("requestedLane", 2)
# People on foot (pedestrians.lp)
PEDESTRIAN = Predicate("pedestrian", 1)
CROSSING_LANE = Predicate("crossingLane", 1)
CROSSING_AT_FORK = Predicate("crossingAtFork", 2)
ARRIVED_AT_CURB = Predicate("arrivedAtCurbAtTime", 3)
STOPPED_AT_CURB = Predicate("stoppedAtCurbAtTime", 3)
ENTERED_CROSSING = Predicate("enteredCrossingAtTime", 3)
LEFT_CROSSING = Predicate("leftCrossingAtTime", 3)
# Signals (signals.lp)
SIGNAL_LANE = Predicate("signalLane", 1)
LANE_COLOUR = Predicate("laneColour", 3)
PHASE_SPAN = Predicate("phaseSpan", 3)
PHASE_AT = Predicate("phaseAt", 2)
# Events (events.lp)
ARRIVED_AT_FORK = Predicate("arrivedAtForkAtTime", 3)
STOPPED_AT_FORK = Predicate("stoppedAtForkAtTime", 3)
ENTERED_FORK = Predicate("enteredForkAtTime", 3)
ENTERED_LANE = Predicate("enteredLaneAtTime", 3)
LEFT_LANE = Predicate("leftLaneAtTime", 3)
# Time (time.lp)
TIME = Predicate("time", 1)
EQUAL = Predicate("equal", 2)
LESS_THAN = Predicate("lessThan", 2)
REAL_LTE = Predicate("realLTE", 2)

INPUT_PREDICATES = (
    IS_FORK, LANE_FROM_FORK, LANE_TURN, OVERLAPS, IS_TO_THE_RIGHT_OF, IS_OPPOSITE_OF,
    SAME_DIRECTION, HAS_STOP_SIGN, HAS_YIELD_SIGN, REQUESTED_LANE, ARRIVED_AT_FORK, STOPPED_AT_FORK,
    ENTERED_FORK, ENTERED_LANE, LEFT_LANE, TIME, EQUAL, LESS_THAN, REAL_LTE, SIGNAL_LANE,
    LANE_COLOUR, PHASE_SPAN, PHASE_AT, PEDESTRIAN, CROSSING_LANE, CROSSING_AT_FORK,
    ARRIVED_AT_CURB, STOPPED_AT_CURB, ENTERED_CROSSING, LEFT_CROSSING,
)  # fmt: skip


def time_symbol(car: str, index: int) -> clingo.Symbol:
    return clingo.Function("t", [clingo.String(car), clingo.Number(index)])


def geometry_facts(intersection: Intersection) -> list[Fact]:
    """The intersection model as facts (geometry.lp), with its crossings (crossing_facts)."""
    facts = [IS_FORK(f) for f in intersection.forks]
    facts += [HAS_STOP_SIGN(f.lane) for f in intersection.forks.values() if f.stop_sign]
    facts += [HAS_YIELD_SIGN(f.lane) for f in intersection.forks.values() if f.yield_sign]
    for fork, others in intersection.to_its_right.items():
        facts += [IS_TO_THE_RIGHT_OF(other, fork) for other in sorted(others)]
    for fork, others in intersection.opposite.items():
        facts += [IS_OPPOSITE_OF(fork, other) for other in sorted(others)]
    for fork, others in intersection.same_direction.items():
        facts += [SAME_DIRECTION(fork, other) for other in sorted(others)]
    for route in intersection.routes.values():
        lane = route.connecting_lane
        facts += [LANE_FROM_FORK(lane, route.fork), LANE_TURN(lane, constant(route.turn.value))]
        for other in sorted(intersection.conflicts[route.id]):
            facts.append(OVERLAPS(lane, intersection.routes[other].connecting_lane))
    return facts + crossing_facts(intersection)


def crossing_facts(intersection: Intersection) -> list[Fact]:
    """The crossings of the junction as facts (pedestrians.lp): each crossing's lane, the
    car connecting lanes that cross it (its walks' conflicts: route ids) and the forks whose
    road it crosses (just past their limit line); none without crossings."""
    facts = []
    for crossing in intersection.crossings.values():
        facts.append(CROSSING_LANE(crossing.lane))
        conflicts = {
            intersection.routes[route].connecting_lane
            for walk in intersection.walks.values()
            if walk.crossing == crossing.id
            for route in walk.conflicts
        }
        facts += [OVERLAPS(crossing.lane, lane) for lane in sorted(conflicts)]
        facts += [
            CROSSING_AT_FORK(crossing.lane, fork.lane)
            for fork in intersection.forks.values()
            if fork.edge in crossing.edges
        ]
    return facts


def signal_facts(intersection: Intersection, horizon: float) -> list[Fact]:
    """The signal program over [0, horizon] s as facts (signals.lp): the phase instances
    and every signalled lane's colour in each, a crossing's lane showing its pedestrian
    signal (its link); none for a junction without signals."""
    program = intersection.signals
    if program is None:
        return []
    signalled = [
        (r.connecting_lane, r.link_index) for r in intersection.routes.values() if r.link_index >= 0
    ]
    signalled += [
        (c.lane, c.link_index) for c in intersection.crossings.values() if c.link_index >= 0
    ]
    facts = [SIGNAL_LANE(lane) for lane, _ in signalled]
    for instance in program.instances(horizon):
        low, high = math.floor(instance.start * 1000), math.floor(instance.end * 1000)
        facts.append(PHASE_SPAN(instance.index, low, high))
        for lane, link in signalled:
            colour = constant(RULE_COLOURS[instance.state[link]])
            facts.append(LANE_COLOUR(lane, instance.index, colour))
    return facts


def phase_facts(
    intersection: Intersection, timed: Iterable[TimedEvent], horizon: float
) -> list[Fact]:
    """phaseAt for every entry into the junction, and every pedestrian's step onto its
    crossing (an ``entered`` event too), from its number (signals.lp)."""
    program = intersection.signals
    if program is None:
        return []
    instances = program.instances(horizon)
    return [
        PHASE_AT(t.symbol, program.instance_at(t.event.time, instances).index)
        for t in timed
        if t.event.kind is EventKind.ENTERED
    ]


@dataclass(frozen=True)
class TimedEvent:
    """A car's event with its time symbol, as the rules see it."""

    car: str
    symbol: clingo.Symbol
    event: LaneEvent


def event_facts(car: str, fork: str, events: Iterable[TimedEvent]) -> list[Fact]:
    """The events of one car as facts (events.lp); ``exited`` plays no part in the rules."""
    facts = []
    for timed in events:
        event, symbol = timed.event, timed.symbol
        if event.kind is EventKind.ARRIVED:
            facts.append(ARRIVED_AT_FORK(car, fork, symbol))
        elif event.kind is EventKind.STOPPED:
            facts.append(STOPPED_AT_FORK(car, fork, symbol))
        elif event.kind is EventKind.ENTERED:
            facts.append(ENTERED_FORK(car, fork, symbol))
        elif event.kind is EventKind.ENTERED_LANE:
            facts.append(ENTERED_LANE(car, event.lane, symbol))
        elif event.kind is EventKind.LEFT_LANE:
            facts.append(LEFT_LANE(car, event.lane, symbol))
    return facts


def pedestrian_facts(person: str, crossing_lane: str, events: Iterable[TimedEvent]) -> list[Fact]:
    """A pedestrian as facts (pedestrians.lp): who it is, the crossing it walks (by its
    lane) and its events. ``arrived``, ``stopped``, ``entered`` and ``exited`` name the
    crossing whatever their ``lane`` says (the crossing's id); ``entered_lane`` and
    ``left_lane`` the lane they name (a car's connecting lane, or the crossing's lane)."""
    facts = [PEDESTRIAN(person), REQUESTED_LANE(person, crossing_lane)]
    for timed in events:
        event, symbol = timed.event, timed.symbol
        if event.kind is EventKind.ARRIVED:
            facts.append(ARRIVED_AT_CURB(person, crossing_lane, symbol))
        elif event.kind is EventKind.STOPPED:
            facts.append(STOPPED_AT_CURB(person, crossing_lane, symbol))
        elif event.kind is EventKind.ENTERED:
            facts.append(ENTERED_CROSSING(person, crossing_lane, symbol))
        elif event.kind is EventKind.EXITED:
            facts.append(LEFT_CROSSING(person, crossing_lane, symbol))
        elif event.kind is EventKind.ENTERED_LANE:
            facts.append(ENTERED_LANE(person, event.lane, symbol))
        elif event.kind is EventKind.LEFT_LANE:
            facts.append(LEFT_LANE(person, event.lane, symbol))
    return facts


def perceptible_order(timed: Sequence[TimedEvent], m: float) -> list[Fact]:
    """equal/lessThan for every pair of time symbols, from the numbers.

    |s - t| < m is perceptibly simultaneous; t - s >= m is s before t. A gap of exactly m
    counts as ordered (the paper's m <= t - s), with EPSILON absorbing float noise.
    """
    facts = [TIME(e.symbol) for e in timed]
    for first, second in itertools.combinations(timed, 2):
        gap = second.event.time - first.event.time
        if gap >= m - EPSILON:
            facts.append(LESS_THAN(first.symbol, second.symbol))
        elif -gap >= m - EPSILON:
            facts.append(LESS_THAN(second.symbol, first.symbol))
        else:
            facts.append(EQUAL(first.symbol, second.symbol))
    return facts


def solve_rules(
    control: ControlType, facts: Iterable[Fact], shown: Sequence[tuple[str, int]] = ()
) -> list[clingo.Symbol]:
    """The single answer set of the rule set of ``control`` over ``facts``: every atom, or
    only those of the ``shown`` predicates (name, arity; reading every atom of a large
    answer set into Python costs more than solving it).

    With every order given as facts, the program is stratified: grounding decides it and no
    search runs, so this cannot hang. Raises if the facts contradict the order axioms.
    """
    control_object = clingo.Control(["--models=1", "--warn=none"])
    control_object.load(str(rule_set_file(control)))
    if shown:
        control_object.add("base", [], " ".join(f"#show {n}/{a}." for n, a in shown))
    with control_object.backend() as backend:
        for fact in facts:
            atom = backend.add_atom(fact)
            backend.add_rule([atom])
    control_object.ground([("base", [])])
    found: list[clingo.Symbol] = []

    def keep(model: clingo.Model) -> None:
        found.extend(model.symbols(shown=True))

    result = control_object.solve(on_model=keep)
    if not result.satisfiable:
        raise ScengenError("the event order contradicts the order axioms (time.lp)")
    return found


@functools.cache
def people_laws(control: ControlType) -> frozenset[str]:
    """The rules of ``control``'s rule set that only a junction with crosswalks can test
    (its ``peopleLaw`` facts): those that protect people on foot, and theirs."""
    atoms = solve_rules(control, [], shown=[("peopleLaw", 1)])
    return frozenset(str(a.arguments[0]) for a in atoms)
