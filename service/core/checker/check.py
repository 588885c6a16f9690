"""The pass-fail checker: judge an ego trajectory against a test-case.

The ego passes when it reaches its exit lane, fully out of the junction, within the
duration; collides with no non-ego, car or pedestrian; and violates no traffic rule and no
non-ego's right-of-way (a car's, or a pedestrian's: ``other`` is the pedestrian) under the
rule set of the junction's control type. The judgement ends with the goal: at the moment
the ego is on its exit lane and its rectangle has left the junction for good (its rear is
out: every event of the ego at the junction comes before), or at the duration when it
never gets there. A collision that starts later, and a
violation whose ego events all come later, are kept in the verdict as information (its
``after_goal_*``); they do not fail the ego. The criticality measures end there too.
Events of every road user are computed from its trajectory (service.core.motion.events:
a car's at the crosswalks too, a pedestrian's on its walk), their
perceptible order from the numbers with one m (service.core.checker.rules), and the
rules decide. The rules a pedestrian breaks (21950 (b), 21456) are not the ego's: the
verdict keeps them as information (``pedestrians_broke``). With all orders given, the rule
program is stratified, so the check is bounded: it runs in the caller's process.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from shapely.geometry import Point

from service.core.checker.pedestrians import Walker, walker
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
from service.core.checker.verdict import (
    CROSSING,
    PEDESTRIAN,
    REAR_END,
    CollisionRecord,
    EventRef,
    RoadUserViolation,
    Verdict,
    Violation,
)
from service.core.errors import InvalidTrajectory
from service.core.motion.collisions import Motion, first_collision
from service.core.motion.criticality import Mover, measure_criticality
from service.core.motion.criticality_records import Criticality
from service.core.motion.events import EventKind, LaneEvent, compute_events
from service.core.motion.pedestrian_criticality import PedestrianMover, measure_pedestrians
from service.core.motion.poses import (
    PoseSample,
    centre_to_front,
    interpolate_heading,
    start_front,
)
from service.core.motion.queues import QueueCar, follows, line_distance
from service.core.network import Intersection
from service.core.testcase import (
    NonEgo,
    Pedestrian,
    TestCase,
    load_testcase_intersection,
    readable_name,
)

EGO = "ego"
START_TOLERANCE = 2.0  # metres between the trajectory's first front bumper and the start


@dataclass(frozen=True)
class Car:
    """A car as the checker sees it: id, route, size, samples and events."""

    id: str
    fork: str
    lane: str  # the connecting lane of its route
    length: float
    width: float
    samples: Sequence[PoseSample]
    events: tuple[LaneEvent, ...]
    line: float  # distance travelled at which its front reaches the junction (queues)

    @property
    def in_queue(self) -> QueueCar:
        first = self.samples[0].distance if self.samples else 0.0
        return QueueCar(self.id, self.fork, self.lane, self.length, self.width, self.line, first)


def testcase_label(testcase: TestCase) -> str:
    """What a verdict calls a test-case: its name, or for a document without one the
    readable default (network, junction, ego route and level)."""
    return testcase.name or readable_name(testcase)


def check_testcase(
    testcase: TestCase,
    ego: Sequence[PoseSample],
    controller: str = "ego",
    intersection: Intersection | None = None,
    criticality: bool = True,
) -> Verdict:
    """The verdict on ``ego`` (samples of the ego's rectangle centre) in ``testcase``, with
    the criticality measures unless told not to (service.core.motion.criticality)."""
    return Judge(testcase, intersection).verdict(ego, controller, criticality)


class Judge:
    """The checker for one test-case: the non-egos' events (cars' and pedestrians') are
    computed once, then any number of ego trajectories are judged against them."""

    def __init__(
        self,
        testcase: TestCase,
        intersection: Intersection | None = None,
        known: Judge | None = None,
    ) -> None:
        """``known``: the judge of a test-case whose non-egos this one keeps (an extension
        keeps its parent's): their events are taken from it, where the cars are equal."""
        self.testcase = testcase
        self.junction = intersection or load_testcase_intersection(testcase)
        reuse = {car.id: car for car in known.nonegos} if known is not None else {}
        kept = {n.id: n for n in known.testcase.nonegos} if known is not None else {}
        self.nonegos: list[Car] = [
            reuse[n.id] if kept.get(n.id) == n else _nonego_car(testcase, self.junction, n)
            for n in testcase.nonegos
        ]
        self.queued: dict[tuple[str, float], Car] = {}
        self.nonegos = self._in_queues(self.nonegos)
        walking = {w.id: w for w in known.pedestrians} if known is not None else {}
        kept_walking = {p.id: p for p in known.testcase.pedestrians} if known is not None else {}
        self.pedestrians: list[Walker] = [
            walking[p.id] if kept_walking.get(p.id) == p else _walker(testcase, self.junction, p)
            for p in testcase.pedestrians
        ]

    def _in_queues(self, cars: Sequence[Car]) -> list[Car]:
        """The cars with the arrivals of those in a queue: a car behind another on its fork
        arrives no earlier than the last car ahead of it entered (service.core.motion.queues)."""
        entries = {
            car.id: next((e.time for e in car.events if e.kind is EventKind.ENTERED), math.inf)
            for car in cars
        }
        after: dict[str, float] = {}
        for follow in follows([car.in_queue for car in cars], self.junction):
            after[follow.follower] = max(after.get(follow.follower, -math.inf),
                                         entries[follow.leader])  # fmt: skip
        found = []
        for car in cars:
            if car.id not in after:
                found.append(car)
                continue
            key = (car.id, after[car.id])
            queued = self.queued.get(key) if car.id != EGO else None  # the ego varies
            if queued is None:
                queued = _car(car.id, car.fork, car.lane, car.length, car.width, car.samples,
                              self.testcase, self.junction, after[car.id])  # fmt: skip
                if car.id != EGO:
                    self.queued[key] = queued
            found.append(queued)
        return found

    def ego_car(self, ego: Sequence[PoseSample]) -> Car:
        """The ego as the checker sees it (its events), after checking where it starts."""
        _check_start(self.testcase, self.junction, ego)
        return _ego_car(self.testcase, self.junction, ego)

    def verdict(
        self, ego: Sequence[PoseSample] | Car, controller: str = "ego", criticality: bool = False
    ) -> Verdict:
        """The verdict on an ego trajectory (or an ego car made by ``ego_car``); with the
        criticality measures when asked (users see them; the generator's checks skip them)."""
        car = ego if isinstance(ego, Car) else self.ego_car(ego)
        cars = self._in_queues([car, *self.nonegos])
        car = cars[0]
        goal_time = _goal_time(self.testcase, self.junction, car)
        end = goal_time if goal_time is not None else self.testcase.duration
        collisions = _collisions(cars, self.pedestrians)
        broken = _violations(self.junction, cars, self.pedestrians, self.testcase.params.m,
                             self.testcase.duration)  # fmt: skip
        violations = broken.get(EGO, [])
        measures = self.criticality(cars, end) if criticality else None
        return Verdict(
            testcase=testcase_label(self.testcase),
            controller=controller,
            goal_reached=goal_time is not None,
            goal_time=goal_time,
            collisions=tuple(c for c in collisions if c.t <= end),
            violations=tuple(v for v in violations if _ego_time(v) <= end),
            ego_events=tuple(_refs(car)),
            duration=self.testcase.duration,
            criticality=measures,
            after_goal_collisions=tuple(c for c in collisions if c.t > end),
            after_goal_violations=tuple(v for v in violations if _ego_time(v) > end),
            pedestrians_broke=tuple(
                RoadUserViolation(p.id, v) for p in self.pedestrians for v in broken.get(p.id, [])
            ),
        )

    def criticality(self, cars: Sequence[Car], end: float = math.inf) -> Criticality:
        """The criticality of the ego (``cars[0]``) against each other car, then each
        pedestrian, the ego's drive measured until ``end`` (the judgement's end: its goal)."""
        routes = {EGO: self.testcase.ego.route.id}
        routes.update((n.id, n.route.id) for n in self.testcase.nonegos)
        movers = [
            Mover(car.id, self.junction.route(routes[car.id]), car.length, car.width,
                  judged_samples(car.samples, end) if car.id == EGO else car.samples)
            for car in cars
        ]  # fmt: skip
        against_cars = measure_criticality(self.junction, movers[0], movers[1:])
        people = [PedestrianMover(p.id, p.walk, p.length, p.width, p.samples)
                  for p in self.pedestrians]  # fmt: skip
        against_people = measure_pedestrians(self.junction, movers[0], people)
        return Criticality((*against_cars.others, *against_people))

    def rules_broken_by(self, car_id: str) -> list[Violation]:
        """The traffic rules (not right-of-way) that non-ego ``car_id`` breaks, among the
        non-egos: at a signalized junction a generated car obeys its signal. A pedestrian's
        id gives the rules of the pedestrian it breaks (21950 (b) against the cars, 21456)."""
        found = _violations(self.junction, self.nonegos, self.pedestrians, self.testcase.params.m,
                            self.testcase.duration).get(car_id, [])  # fmt: skip
        return [v for v in found if v.other is None]


def _car(
    car_id: str, fork: str, lane: str, length: float, width: float,
    samples: Sequence[PoseSample], testcase: TestCase, junction: Intersection,
    not_before: float = -math.inf,
) -> Car:  # fmt: skip
    events = compute_events(
        samples, length, width, junction, fork,
        testcase.params.arrival_distance, testcase.params.v_stop, not_before,
    )  # fmt: skip
    line = line_distance(samples, length, junction.fork(fork), events) if samples else 0.0
    return Car(car_id, fork, lane, length, width, samples, tuple(events), line)


def _ego_car(testcase: TestCase, junction: Intersection, samples: Sequence[PoseSample]) -> Car:
    route = junction.route(testcase.ego.route.id)
    ego = testcase.ego
    return _car(EGO, route.fork, route.connecting_lane, ego.length, ego.width, samples,
                testcase, junction)  # fmt: skip


def _nonego_car(testcase: TestCase, junction: Intersection, nonego: NonEgo) -> Car:
    route = junction.route(nonego.route.id)
    samples = [PoseSample(**s.model_dump()) for s in nonego.trajectory]
    return _car(nonego.id, route.fork, route.connecting_lane, nonego.length, nonego.width,
                samples, testcase, junction)  # fmt: skip


def _walker(testcase: TestCase, junction: Intersection, person: Pedestrian) -> Walker:
    samples = [PoseSample(**s.model_dump()) for s in person.trajectory]
    walking = testcase.params.walk
    return walker(junction, person.id, person.walk, person.length, person.width, samples,
                  walking.arrival_distance, testcase.params.v_stop)  # fmt: skip


def _check_start(testcase: TestCase, junction: Intersection, ego: Sequence[PoseSample]) -> None:
    if len(ego) < 2:
        raise InvalidTrajectory("the ego trajectory needs at least 2 samples")
    route = junction.route(testcase.ego.route.id)
    expected = start_front(junction, route, testcase.ego.start.distance)
    first = ego[0]
    actual = centre_to_front(first.x, first.y, first.heading, testcase.ego.length)
    miss = math.dist(expected, actual)
    if miss > START_TOLERANCE:
        raise InvalidTrajectory(
            f"the ego trajectory starts with its front at ({actual[0]:.1f}, {actual[1]:.1f}), "
            f"{miss:.1f} m from the test-case's start ({expected[0]:.1f}, {expected[1]:.1f}), "
            f"{testcase.ego.start.distance:g} m before the stop line of {route.fork!r}"
        )


LANE_KINDS = (EventKind.ENTERED_LANE, EventKind.LEFT_LANE)


def _timed(cars: Sequence[Car], people: Sequence[Walker] = ()) -> list[TimedEvent]:
    """Events the rules can use, each with a time symbol: a car's on the requested lanes
    (its own, the other cars', the pedestrians' crossings), without ``exited``; a
    pedestrian's on the cars' lanes, with ``exited`` (when it leaves its crossing)."""
    car_lanes = {car.lane for car in cars}
    relevant = car_lanes | {person.lane for person in people}
    timed = []
    for car in cars:
        chosen = [
            e
            for e in car.events
            if e.kind is not EventKind.EXITED and (e.kind not in LANE_KINDS or e.lane in relevant)
        ]
        timed += [TimedEvent(car.id, time_symbol(car.id, k), e) for k, e in enumerate(chosen)]
    for person in people:
        chosen = [e for e in person.events if e.kind not in LANE_KINDS or e.lane in car_lanes]
        timed += [TimedEvent(person.id, time_symbol(person.id, k), e) for k, e in enumerate(chosen)]
    return timed


VERDICT_ATOMS = (("law", 2), ("violatesRightOfForRuleAt", 4), ("violatesRuleAt", 3))


def _violations(
    junction: Intersection,
    cars: Sequence[Car],
    people: Sequence[Walker],
    m: float,
    duration: float,
) -> dict[str, list[Violation]]:
    """The rules each road user breaks among ``cars`` and ``people``, by its id (one
    violation of a rule against one other, the earliest; ordered by time)."""
    timed = _timed(cars, people)
    facts = geometry_facts(junction) + perceptible_order(timed, m)
    facts += signal_facts(junction, duration) + phase_facts(junction, timed, duration)
    for car in cars:
        facts.append(REQUESTED_LANE(car.id, car.lane))
        facts += event_facts(car.id, car.fork, [t for t in timed if t.car == car.id])
    for person in people:
        facts += pedestrian_facts(person.id, person.lane, [t for t in timed if t.car == person.id])
    atoms = solve_rules(junction.control, facts, VERDICT_ATOMS)
    by_symbol = {t.symbol: t for t in timed}
    laws = {str(a.arguments[0]): a.arguments[1].string for a in atoms if a.name == "law"}
    found: dict[tuple[str, str, str | None], Violation] = {}
    for atom in atoms:
        name, arguments = atom.name, atom.arguments
        if name == "violatesRightOfForRuleAt":
            other: str | None = arguments[1].string
            rule, times = arguments[2], arguments[3]
        elif name == "violatesRuleAt":
            other, rule, times = None, arguments[1], arguments[2]
        else:
            continue
        by = arguments[0].string
        events = tuple(_ref(by_symbol[s]) for s in times.arguments)
        candidate = Violation(str(rule), laws[str(rule)], other, events)
        key = (by, candidate.rule, other)
        if key not in found or _earlier(candidate, found[key]):
            found[key] = candidate
    broken: dict[str, list[Violation]] = {}
    for (by, _, _), violation in found.items():
        broken.setdefault(by, []).append(violation)
    return {
        by: sorted(found, key=lambda v: (v.events[0].t, v.rule, v.other or ""))
        for by, found in broken.items()
    }


def _ego_time(violation: Violation) -> float:
    """When the ego did what ``violation`` judges: its first event in it (the first event of
    any car if none is the ego's)."""
    times = [e.t for e in violation.events if e.car == EGO] or [e.t for e in violation.events]
    return min(times, default=-math.inf)


def judged_samples(samples: Sequence[PoseSample], end: float) -> list[PoseSample]:
    """The samples until ``end``, the last one at ``end`` itself (interpolated between the
    samples around it) when no sample falls on it."""
    kept = [s for s in samples if s.t <= end]
    if len(kept) == len(samples) or not kept or kept[-1].t >= end:
        return kept
    a, b = kept[-1], samples[len(kept)]
    share = (end - a.t) / (b.t - a.t)
    kept.append(
        PoseSample(
            end, a.x + share * (b.x - a.x), a.y + share * (b.y - a.y),
            interpolate_heading(a.heading, b.heading, share),
            a.speed + share * (b.speed - a.speed), a.distance + share * (b.distance - a.distance),
        )
    )  # fmt: skip
    return kept


def _earlier(first: Violation, second: Violation) -> bool:
    return [e.t for e in first.events] < [e.t for e in second.events]


def _ref(timed: TimedEvent) -> EventRef:
    event = timed.event
    return EventRef(timed.car, event.kind.value, event.lane, round(event.time, 6))


def _refs(car: Car) -> list[EventRef]:
    return [EventRef(car.id, e.kind.value, e.lane, round(e.time, 6)) for e in car.events]


def _collisions(cars: Sequence[Car], people: Sequence[Walker] = ()) -> list[CollisionRecord]:
    """The ego's first collision with each car and each pedestrian; between two cars of one
    fork it is a rear-end collision (one drove into the other on their common lane)."""
    ego, others = cars[0], cars[1:]
    ego_motion = Motion(ego.samples, ego.length, ego.width)
    found = []
    road_users: list[Car | Walker] = [*others, *people]
    for other in road_users:
        hit = first_collision(ego_motion, Motion(other.samples, other.length, other.width))
        if hit is not None:
            if isinstance(other, Walker):
                kind = PEDESTRIAN
            else:
                kind = REAR_END if other.fork == ego.fork else CROSSING
            found.append(CollisionRecord(other.id, round(hit.time, 6), hit.x, hit.y, kind))
    return found


def until_goal(
    testcase: TestCase, samples: Sequence[PoseSample], intersection: Intersection
) -> list[PoseSample]:
    """An ego's samples until its goal, where its test ends: up to the first sample at or
    after it (all of them when it never gets there). Pictures draw a certificate so: it
    leaves at its goal, as the replay's ego does."""
    ego = _ego_car(testcase, intersection, samples)
    goal = _goal_time(testcase, intersection, ego)
    if goal is None:
        return list(samples)
    last = next((k for k, s in enumerate(samples) if s.t >= goal - 1e-9), len(samples) - 1)
    return list(samples[: last + 1])


def _goal_time(testcase: TestCase, junction: Intersection, ego: Car) -> float | None:
    """When the ego is on its exit lane and fully out of the junction, if within the duration."""
    exited = [e for e in ego.events if e.kind is EventKind.EXITED]
    if not exited or exited[-1].time > testcase.duration + 1e-9:
        return None
    exit_lane = junction.exits[testcase.ego.route.exit]
    lane_area = exit_lane.departure.buffer(exit_lane.width / 2.0, cap_style="flat")
    motion = Motion(ego.samples, ego.length, ego.width)
    x, y, _ = motion.poses(_array(exited[-1].time))
    if not lane_area.contains(Point(float(x[0]), float(y[0]))):
        return None
    return round(exited[-1].time, 6)


def _array(value: float) -> np.ndarray:
    return np.array([value])
