"""Step 3: event times and composite cubic Bezier time-to-distance curves (z3 and HiGHS).

Each symbolic car's distance travelled d(t) is a composite cubic Bezier curve whose time
control points sit at thirds of each piece, so d is a cubic in t on every piece. Knots:
t = 0 (d = 0), every event the order speaks of (and arriving, entering and leaving its own
lane), a stand-still pair where it stops at its sign, and the duration. Between two knots
the curve has free knots at most ``PIECE`` seconds apart, so one segment can brake, stand
and go again wherever the order needs it.

Two kinds of linear program (service.core.generator.linear: optima by HiGHS's simplex, Boolean
choices and unsatisfiable cores by z3 over the rationals):

1. the plan: the knot times of every car at once, keeping every order relation with its
   margin, the headways, and the necessary kinematic conditions of service.core.motion.kinematics
   with a share of the bounds in reserve (``SHARES``: the curves then have room), smoothest
   first (the pace changes least from knot to knot);
2. the curves, one car at a time with the plan's knot times fixed: every piece's end
   distance and speed, so that the controls are in order (the car never backs up and makes
   no new event), the acceleration stays within the bounds at both ends of every piece (it
   is linear in between), the speed within v_max, zero at a stand, at least v_run while
   running a sign, the certificates' start speed; smoothest first (least peak acceleration,
   then least acceleration and jerk).

When the plan is infeasible even with the full bounds, the relations of z3's unsatisfiable
core go back to Step 2: no speed profile can realise them together. Every solve is limited
by a count of work (z3's ``rlimit``, HiGHS's simplex iterations), never by a clock: the same
problem gives the same curves on an idle and on a saturated machine.
"""

from __future__ import annotations

import bisect
import dataclasses
import functools
import itertools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from service.core.generator.linear import (
    Linear,
    LinearProgram,
    combine,
    total,
    value_of,
    values,
)
from service.core.motion.kinematics import SAME, Bounds, duration_range, least_gaps, speed_caps

PIECE = 2.0  # seconds: the longest piece of a curve (free knots between events)
SHARES = (0.7, 0.85)  # shares of the bounds a plan may use (the curves keep the rest)
WORK = 4_000_000  # z3 rlimit of one program with choices or a core (a count, not seconds)
CLEARANCE = 0.01  # metres a free knot keeps from the knots around it (events stay sharp)
STOP_LEAD = 0.1  # seconds before a stand when a stopping car is still faster than v_stop
STOP_LEAD_BRAKING = 3.0  # ... or this many times v_stop over its strongest braking, when
# that is longer (a pedestrian's gentle braking: a stand within 0.1 s of v_stop is too abrupt)
INSIDE_WEIGHT = 0.1  # plan cost of a second inside the junction beyond three times
# the least time to cross it and two seconds (pace changes cost seconds per metre)
CRUISE = 0.5  # share of v_max a car makes for after its last event (the curve's end)
TAIL_WEIGHT = 1.0  # cost per m/s and second the speed misses that after the last event
TICK = 2e-4  # seconds at least between two knots (plans are rounded to 0.1 ms)
AIM_WEIGHT = 10.0  # plan cost per second an aimed event misses its aim (beats smoothness)


@dataclass(frozen=True)
class Knot:
    """A point of a car's curve: the event's time symbol (None: end of a stand-still)."""

    symbol: str | None
    distance: float
    stop: bool = False


@dataclass(frozen=True)
class CarPlan:
    """One symbolic car in Step 3."""

    car: str
    knots: tuple[Knot, ...]  # by distance; excludes the start (t = 0, d = 0)
    reach: float  # the end distance must not pass it (inf: the car drives on off the map)
    start_speed: float | None  # fixed for the certificates, free for new non-egos
    run: tuple[int, int] | None  # knot indices between which it runs a stop sign
    inside: tuple[int, int] | None = None  # knot indices of entering and leaving its lane
    bounds: Bounds | None = None  # its own speed and acceleration bounds (a pedestrian's
    # walking bounds); None: the problem's, a car's
    crossing: float | None = None  # its own least average speed inside (a pedestrian's on
    # its crosswalk); None: the problem's


@dataclass(frozen=True)
class Following:
    """``follower`` keeps behind ``leader`` on their fork (service.core.motion.queues) or on their
    exit lane (``joined``, service.core.generator.merging): while the leader's rear is before
    ``parting``, the follower's front stays ``gap + headway x its speed`` behind it. Places
    are distances minus each car's ``line``. A ``joined`` pair keeps the gap only once the
    leader's rear (or, behind a symbolic leader, the old follower's front) has reached
    place 0, the start of the shared lane. An old car of the pair (``fixed``: its samples
    as (t, distance, speed)) is given; a symbolic leader is fitted before its followers."""

    leader: str
    follower: str
    leader_line: float
    follower_line: float
    leader_length: float
    parting: float
    gap: float
    headway: float
    fixed: tuple[tuple[float, float, float], ...] = ()  # the old car's samples, if any
    joined: bool = False  # the cars come from two forks into one lane at place 0


@dataclass(frozen=True)
class TimingProblem:
    cars: tuple[CarPlan, ...]  # a leader before its followers
    fixed: tuple[tuple[str, float], ...]  # old cars' time symbols and their times
    relations: tuple[tuple[str, str, str], ...]  # ("lessThan"|"equal", s, t)
    gaps: tuple[tuple[str, str, float], ...]  # (s, t, g): t at least g after s (headways)
    duration: float
    m: float
    margin: float
    a_min: float
    a_max: float
    v_stop: float
    v_run: float
    v_max: float
    earliest: tuple[tuple[str, float], ...] = ()  # (s, t): s at least t (queues)
    latest: tuple[tuple[str, float], ...] = ()  # (s, t): s at most t (queues)
    follows: tuple[Following, ...] = ()
    timestep: float = 0.1  # the test-case's: where the following is kept
    crossing: float | None = None  # least average speed from entering to leaving its lane
    aims: tuple[tuple[str, float], ...] = ()  # (s, t): the plan keeps s close to t (variety)

    @property
    def bounds(self) -> Bounds:
        return Bounds(self.v_max, self.a_max, self.a_min)

    def bounds_of(self, car: CarPlan) -> Bounds:
        """The speed and acceleration bounds of ``car``: its own, or the problem's."""
        return car.bounds or self.bounds


@dataclass(frozen=True)
class Curve:
    """A composite cubic Bezier d(t): piece end times and distances, two controls a piece."""

    times: tuple[float, ...]
    distances: tuple[float, ...]
    controls: tuple[tuple[float, float], ...]

    def at(self, t: float) -> tuple[float, float]:
        """(distance, speed) at time t (clamped to the curve's span)."""
        t = min(max(t, self.times[0]), self.times[-1])
        j = min(bisect.bisect_right(self.times, t) - 1, len(self.controls) - 1)
        h = self.times[j + 1] - self.times[j]
        s = (t - self.times[j]) / h
        d0, d3 = self.distances[j], self.distances[j + 1]
        d1, d2 = self.controls[j]
        u = 1.0 - s
        distance = u**3 * d0 + 3 * u * u * s * d1 + 3 * u * s * s * d2 + s**3 * d3
        speed = 3.0 * (u * u * (d1 - d0) + 2 * u * s * (d2 - d1) + s * s * (d3 - d2)) / h
        return distance, speed


@dataclass(frozen=True)
class TimingSolution:
    curves: dict[str, Curve]
    method: str  # how the plan was made: "linear, 70 % of the bounds" and the like


@dataclass(frozen=True)
class TimingFailure:
    """Why no curves were found; ``core``: indices of relations that cannot hold together."""

    reason: str
    core: tuple[int, ...] = ()
    proved: bool = False  # shown impossible (the core may be empty), not merely not found


class _Plan:
    """The linear program of the plan: a time variable per knot, the relations between
    them (labelled ``rel:I``, I the relation's index), the necessary kinematic conditions
    with a share of the bounds, and the pace changes to keep small."""

    def __init__(self, problem: TimingProblem, share: float, queued: bool = True) -> None:
        self.problem = problem
        self.program = LinearProgram(WORK)
        self.var: dict[str, Linear] = {}
        self.knots: dict[str, list[str]] = {}
        for number, car in enumerate(problem.cars):
            names = [f"T{number}_{k}" for k in range(len(car.knots))]
            self.knots[car.car] = names
            for knot, name in zip(car.knots, names, strict=True):
                term = self.program.variable(name)
                if knot.symbol is not None:
                    self.var[knot.symbol] = term
        self.fixed = dict(problem.fixed)
        self._order()
        if queued:
            self._queues()
        self.cost = total([self._kinematics(number, car, share)
                           for number, car in enumerate(problem.cars)]
                          + [self.program.magnitude(self.var[symbol] - t) * AIM_WEIGHT
                             for symbol, t in problem.aims if symbol in self.var])  # fmt: skip

    def term(self, symbol: str) -> Linear:
        return self.var[symbol] if symbol in self.var else Linear.of(self.fixed[symbol])

    def _order(self) -> None:
        p, program = self.problem, self.program
        for index, (kind, a, b) in enumerate(p.relations):
            if a not in self.var and b not in self.var:
                continue
            label = f"rel{index}"
            if kind == "lessThan":
                program.at_least(self.term(b) - self.term(a), p.m + p.margin, label)
            else:
                program.at_most(self.term(b) - self.term(a), p.m - p.margin, label)
                program.at_most(self.term(a) - self.term(b), p.m - p.margin, label)
        for a, b, gap in p.gaps:
            program.at_least(self.term(b) - self.term(a), gap)
        for symbol, t in p.earliest:
            if symbol in self.var:
                program.at_least(self.var[symbol], t)
        for symbol, t in p.latest:
            if symbol in self.var:
                program.at_most(self.var[symbol], t)

    def _queues(self) -> None:
        """A follower reaches each of its knots only ``headway`` after its leader has
        reached the first of its own knots at or beyond where the leader must then be
        (queues.needed place: the gap and the leader's length ahead, up to the parting).
        Sufficient at the knots, not necessary (the leader may pass that place before its
        knot), so kept out of Step 2 and of proofs: the curves then have room to follow."""
        p = self.problem
        cars = {car.car: car for car in p.cars}
        for follow in p.follows:
            follower = cars.get(follow.follower)
            if follower is None:
                self._ahead_of(follow, cars[follow.leader])
                continue
            names = self.knots[follower.car]
            leader = cars.get(follow.leader)
            for knot, name in zip(follower.knots, names, strict=True):
                place = knot.distance - follow.follower_line
                if follow.joined and place < 0:
                    continue  # not yet in the shared lane
                target = min(follow.parting, place + follow.gap) + follow.leader_length
                term = Linear({name: 1.0})
                if leader is None:  # an old leader: its samples give the time
                    reached = _first_time(follow.fixed, target + follow.leader_line)
                    if reached is not None:
                        self.program.at_least(term, reached + follow.headway)
                    continue
                at = next((j for j, k in enumerate(leader.knots)
                           if k.distance - follow.leader_line >= target - SAME), None)  # fmt: skip
                if at is not None:
                    ahead = Linear({self.knots[leader.car][at]: 1.0})
                    self.program.at_least(term - ahead, follow.headway)

    def _ahead_of(self, follow: Following, leader: CarPlan) -> None:
        """A symbolic car ahead of an old one reaches each of its knots ``headway`` before
        the old car's front gets to where it would then be too close (the gap and the
        leader's length behind the knot), while the knot is before the parting."""
        for knot, name in zip(leader.knots, self.knots[leader.car], strict=True):
            place = knot.distance - follow.leader_line
            if place - follow.leader_length >= follow.parting:
                continue
            if follow.joined and place < follow.leader_length:
                continue  # its rear is not yet in the shared lane
            behind = place - follow.leader_length - follow.gap + follow.follower_line
            reached = _first_time(follow.fixed, behind)
            if reached is not None:
                self.program.at_most(Linear({name: 1.0}), reached - follow.headway)

    def _kinematics(self, number: int, car: CarPlan, share: float) -> Linear:
        p, program = self.problem, self.program
        terms = [Linear(), *(Linear({name: 1.0}) for name in self.knots[car.car])]
        distances = [0.0] + [k.distance for k in car.knots]
        bounds = p.bounds_of(car).scaled(share)
        for j, gap in enumerate(least_gaps(distances, car.start_speed, bounds)):
            program.at_least(terms[j + 1] - terms[j], max(gap, TICK))
        for term in terms[1:]:
            program.at_most(term, p.duration - p.margin)
        if car.run is not None:
            first, last = car.run
            run = car.knots[last].distance - car.knots[first].distance
            program.at_most(terms[last + 1] - terms[first + 1], run / p.v_run)
        least = car.crossing or p.crossing
        if car.inside is not None and least:
            entry, leave = car.inside
            inside = car.knots[leave].distance - car.knots[entry].distance
            program.at_most(terms[leave + 1] - terms[entry + 1], inside / least)
        paces = [
            (terms[j] - terms[j - 1]) * (1.0 / (distances[j] - distances[j - 1]))
            for j in range(1, len(terms))
            if distances[j] - distances[j - 1] > SAME
        ]
        cost = []
        if car.inside is not None:  # cross briskly: wait before the line, not inside
            entry, leave = car.inside
            gaps = least_gaps(distances, car.start_speed, bounds)
            comfortable = 3 * sum(gaps[entry + 1 : leave + 1]) + 2.0
            lingering = program.variable(f"linger{number}", 0)
            program.at_least(lingering - (terms[leave + 1] - terms[entry + 1]), -comfortable)
            cost.append(lingering * INSIDE_WEIGHT)
        if car.start_speed is not None and car.start_speed > 0.5 and paces:
            cost.append(program.magnitude(paces[0] - 1.0 / car.start_speed) * 4)
        cost += [program.magnitude(b - a) for a, b in itertools.pairwise(paces)]
        return total(cost)

    def continuity(self, previous: dict[str, list[float]], share: float) -> None:
        """Average speeds of neighbouring segments may differ by no more than the bounds
        can change the speed between their middles (a stand counts as speed 0, the start
        as the start speed). The average speed D / h is linearised around ``previous``, a
        plan of the same knots, so that the program stays linear."""
        for car in self.problem.cars:
            own = self.problem.bounds_of(car)
            up, down = share * own.a_max, -share * own.a_min
            names, before = self.knots[car.car], [0.0, *previous[car.car]]
            terms = [Linear(), *(Linear({name: 1.0}) for name in names)]
            distances = [0.0] + [k.distance for k in car.knots]
            start = Linear.of(car.start_speed) if car.start_speed is not None else None
            speeds: list[tuple[Linear, Linear, Linear]] = []  # (speed, half before, after)
            if start is not None:
                speeds.append((start, Linear(), Linear()))
            for j in range(1, len(terms)):
                gap, span = distances[j] - distances[j - 1], terms[j] - terms[j - 1]
                if gap <= SAME:
                    speeds.append((Linear(), Linear(), Linear()))
                    continue
                guess = max(before[j] - before[j - 1], TICK)
                average = span * (-gap / guess**2) + 2 * gap / guess
                speeds.append((average, span * 0.5, span * 0.5))
            for (first, _, after), (second, ahead, _) in itertools.pairwise(speeds):
                reach = after + ahead
                self.program.at_most(second - first - reach * up, 0)
                self.program.at_most(first - second - reach * down, 0)


def plan_times(
    problem: TimingProblem, share: float, previous: dict[str, list[float]] | None = None
) -> dict[str, list[float]] | None:
    """The knot times of every car with ``share`` of the bounds, smoothest first; with
    ``previous`` (a plan of the same problem), speeds kept continuous around it. None when
    there are none (or the work limit was reached). Rounded to 0.1 ms: the curves' pieces
    then have short rational lengths."""
    plan = _Plan(problem, share)
    if previous is not None:
        plan.continuity(previous, share)
    plan.program.minimize(plan.cost)
    solution = plan.program.solve()
    if solution is None:
        return None
    return {
        car: [round(t, 4) for t in values(solution, names)] for car, names in plan.knots.items()
    }


SPEED_GRID = (0.0, 0.1, 0.2, 0.3, 0.45, 0.6, 0.75, 0.9, 1.0)  # shares of the plan's v_max


def _speed_options(car: CarPlan, problem: TimingProblem, bounds: Bounds) -> list[list[float]]:
    """The speeds each point (the start, then every knot) may take in a grid plan: the grid
    up to the highest speed the car can have there, zero at a stand, the start speed where
    it is fixed, at least v_run where it runs a sign."""
    distances = [0.0] + [k.distance for k in car.knots]
    caps = speed_caps(distances, car.start_speed, bounds)
    options = []
    for j, cap in enumerate(caps):
        if j == 0 and car.start_speed is not None:
            options.append([car.start_speed])
        elif j > 0 and car.knots[j - 1].stop:
            options.append([0.0])
        else:
            floor = problem.v_run if car.run and car.run[0] <= j - 1 <= car.run[1] else 0.0
            grid = sorted({share * bounds.v_max for share in SPEED_GRID} | {cap})
            options.append([v for v in grid if floor <= v <= cap + 1e-9])
    return options


def plan_on_speed_grid(
    problem: TimingProblem, share: float
) -> tuple[dict[str, list[float]] | None, list[int] | None]:
    """Knot times chosen together with knot speeds from a grid. For two end speeds, the
    durations one segment can take form an interval (kinematics.duration_range), so with a
    speed chosen at every knot each segment can be driven by construction: a mixed-integer
    program over the plan's relations (any solution; the curves are smoothed afterwards).
    (plan, None) when there is one; else (None, the indices of relations that no grid plan
    can keep together), or (None, None) when z3 cannot tell."""
    plan = _Plan(problem, share)
    program = plan.program
    for number, car in enumerate(problem.cars):
        bounds = problem.bounds_of(car).scaled(share)
        options = _speed_options(car, problem, bounds)
        if not all(options):
            return None, []
        chosen = [program.choice(f"s{number}_{j}", len(o)) if len(o) > 1 else [""]
                  for j, o in enumerate(options)]  # fmt: skip
        terms = [Linear(), *(Linear({name: 1.0}) for name in plan.knots[car.car])]
        distances = [0.0] + [k.distance for k in car.knots]
        for j in range(1, len(terms)):
            floor = problem.v_run if car.run and car.run[0] + 1 < j <= car.run[1] + 1 else 0.0
            span = terms[j] - terms[j - 1]
            for (a, v0), (b, v1) in itertools.product(
                zip(chosen[j - 1], options[j - 1], strict=True),
                zip(chosen[j], options[j], strict=True),
            ):
                window = duration_range(distances[j] - distances[j - 1], v0, v1, bounds, floor)
                condition = [name for name in (a, b) if name]
                if window is None:
                    if not condition:
                        return None, []
                    program.when(condition, None, span, None)
                elif condition:
                    longest = window[1] if window[1] < math.inf else None
                    program.when(condition, window[0], span, longest)
                else:
                    program.at_least(span, window[0])
                    if window[1] < math.inf:
                        program.at_most(span, window[1])
    solution, labels = program.solve_or_conflict()
    if solution is None:
        return None, None if labels is None else sorted({int(label[3:]) for label in labels})
    times = {car: [round(t, 4) for t in values(solution, names)]
             for car, names in plan.knots.items()}  # fmt: skip
    return times, None


def entry_window(problem: TimingProblem, symbol: str) -> tuple[float, float] | None:
    """The earliest and the latest time of ``symbol`` in any plan with the comfortable
    share of the bounds (Step 3 aims within it for a variety of timings); None when there
    is no plan or the symbol is not planned."""
    ends = []
    for sign in (1.0, -1.0):
        plan = _Plan(problem, SHARES[0])
        if symbol not in plan.var:
            return None
        plan.program.minimize(plan.var[symbol] * sign)
        solution = plan.program.solve()
        if solution is None:
            return None
        ends.append(round(value_of(plan.var[symbol], solution), 4))
    return ends[0], ends[1]


def order_core(problem: TimingProblem) -> list[int] | None:
    """Indices of order relations that cannot hold together under the full bounds (a
    proof: the conditions are necessary); None when they can, or z3 cannot tell."""
    core = _Plan(problem, 1.0, queued=False).program.conflict()
    return None if core is None else sorted({int(label[3:]) for label in core})


@dataclass(frozen=True)
class _Boundary:
    """A piece end of a curve: its time, and its distance when it is a knot (else free
    within ``low``..``high``), its speed when fixed."""

    t: float
    distance: float | None
    low: float
    high: float
    speed: float | None
    least_speed: float = 0.0


def stop_lead(v_stop: float, bounds: Bounds) -> float:
    """Seconds before a stand when a stopping car is still faster than ``v_stop``:
    STOP_LEAD, or longer where its braking is gentle (STOP_LEAD_BRAKING)."""
    return max(STOP_LEAD, STOP_LEAD_BRAKING * v_stop / -bounds.a_min)


def _boundaries(problem: TimingProblem, car: CarPlan, knot_times: list[float]) -> list[_Boundary]:
    """Piece ends: the start, the knots, and free knots at most PIECE apart between them.
    Before a stand, the car keeps above v_stop from its previous knot until a lead
    (``stop_lead``) before the stand, so that its stop begins when it is planned (the
    checker's stop is the first moment at v_stop or below), not while it creeps up to the
    line."""
    times = [0.0, *knot_times, problem.duration]
    distances = [0.0] + [k.distance for k in car.knots]
    stopped = [False] + [k.stop for k in car.knots]
    found = [_Boundary(times[0], 0.0, 0.0, 0.0, car.start_speed)]
    before_stand = stop_lead(problem.v_stop, problem.bounds_of(car))
    for j in range(1, len(times)):
        last = j == len(times) - 1  # the end of the duration: the distance is free
        low = distances[j - 1]
        high = car.reach if last else distances[j]
        stand = not last and high - low <= SAME
        clearance = 0.0 if stand else min(CLEARANCE, (high - low) / 4)
        stops_here = not last and stopped[j] and not stopped[j - 1]
        lead = before_stand if stops_here and times[j] - times[j - 1] > before_stand else 0.0
        floor = problem.v_stop if lead else 0.0
        if floor and found[-1].speed is None:
            previous = found[-1]
            found[-1] = _Boundary(previous.t, previous.distance, previous.low, previous.high,
                                  previous.speed, floor)  # fmt: skip
        span = times[j] - lead - times[j - 1]
        pieces = 1 if stand else max(1, math.ceil(span / PIECE - 1e-9))
        for k in range(1, pieces + (1 if lead else 0)):
            t = times[j - 1] + span * k / pieces
            found.append(_Boundary(t, None, low + clearance, high - clearance, None, floor))
        if last:
            found.append(_Boundary(times[j], None, low + clearance, high, None))
        else:
            found.append(_Boundary(times[j], high, high, high, 0.0 if stopped[j] else None))
    return found


def _on_piece(
    points: Sequence[_Boundary], d: Sequence[Linear], v: Sequence[Linear], t: float
) -> tuple[int, Linear, Linear]:
    """(piece, distance, speed) of the curve at time t, linear in the piece's unknowns:
    with controls d0 + v0 h/3 and d1 - v1 h/3, d(t) = d0 (u^3 + 3u^2 s) + v0 u^2 s h
    + d1 (3 u s^2 + s^3) - v1 u s^2 h and v(t) = u^2 v0 + s^2 v1 + 6us (d1 - d0)/h
    - 2us (v0 + v1), for s the share of the piece and u = 1 - s."""
    times = [p.t for p in points]
    k = min(max(bisect.bisect_right(times, t) - 1, 0), len(points) - 2)
    h = times[k + 1] - times[k]
    s = (t - times[k]) / h
    u = 1 - s
    distance = combine((u**3 + 3 * u * u * s, d[k]), (u * u * s * h, v[k]),
                       (3 * u * s * s + s**3, d[k + 1]), (-u * s * s * h, v[k + 1]))  # fmt: skip
    speed = combine((u * u - 2 * u * s, v[k]), (s * s - 2 * u * s, v[k + 1]),
                    (6 * u * s / h, d[k + 1]), (-6 * u * s / h, d[k]))  # fmt: skip
    return k, distance, speed


def _first_time(rows: Sequence[tuple[float, float, float]], distance: float) -> float | None:
    """The first sample time at which an old car's distance reaches ``distance``."""
    return next((t for t, d, _ in rows if d >= distance - SAME), None)


FOLLOW_SLACK = 0.05  # metres a planned follower keeps beyond the gap (samples are rounded)


def _places(
    follow: Following, name: str, fitted: dict[str, Curve], times: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(places, speeds) at ``times`` of the other car of ``follow`` (fitted or old)."""
    line = follow.leader_line if name == follow.leader else follow.follower_line
    if follow.fixed:
        rows = np.array(follow.fixed)
        return np.interp(times, rows[:, 0], rows[:, 1]) - line, np.interp(
            times, rows[:, 0], rows[:, 2]
        )
    at = np.array([fitted[name].at(float(t)) for t in times])
    return at[:, 0] - line, at[:, 1]


@dataclass(frozen=True)
class _GapRow:
    """One time step's gap condition on a curve: ``term <= bound`` (behind a leader) or
    ``term >= bound`` (ahead of an old follower)."""

    term: Linear
    bound: float
    behind: bool

    def add_to(self, program: LinearProgram) -> None:
        if self.behind:
            program.at_most(self.term, self.bound)
        else:
            program.at_least(self.term, self.bound)

    def holds(self, solution: dict[str, float]) -> bool:
        """Whether the solution keeps the row, within the LP solver's tolerance."""
        value = value_of(self.term, solution)
        bound = self.bound
        return value <= bound + ROW_TOLERANCE if self.behind else value >= bound - ROW_TOLERANCE


def _following(
    problem: TimingProblem,
    car: CarPlan,
    points: Sequence[_Boundary],
    d: Sequence[Linear],
    v: Sequence[Linear],
    fitted: dict[str, Curve],
) -> list[_GapRow]:
    """The car keeps behind the cars ahead of it and ahead of the old cars behind it, at
    every time step (the checker's samples), with FOLLOW_SLACK and the plan's headway:
    one row per step at which the condition can bind."""
    steps = round(problem.duration / problem.timestep)
    step_times = np.round(np.arange(1, steps + 1) * problem.timestep, 9)
    highs = [p.high for p in points]
    lows = [p.low for p in points]
    times = [p.t for p in points]
    rows: list[_GapRow] = []
    for follow in problem.follows:
        if car.car not in (follow.leader, follow.follower):
            continue
        behind = car.car == follow.follower
        if not behind and not follow.fixed:
            continue  # a symbolic follower keeps behind this car when it is fitted
        places, speeds = _places(
            follow, follow.leader if behind else follow.follower, fitted, step_times
        )
        gap = follow.gap + FOLLOW_SLACK
        for t, place, speed in zip(step_times.tolist(), places.tolist(), speeds.tolist(),
                                   strict=True):  # fmt: skip
            k = min(max(bisect.bisect_right(times, t) - 1, 0), len(points) - 2)
            if behind:
                rear = place - follow.leader_length
                if rear >= follow.parting or (follow.joined and rear < 0):
                    continue
                bound = rear - gap + follow.follower_line
                if bound >= highs[k + 1] + follow.headway * problem.bounds_of(car).v_max:
                    continue  # the car cannot be that far yet
                _, distance, pace = _on_piece(points, d, v, t)
                rows.append(_GapRow(distance + pace * follow.headway, bound, True))
            else:
                if follow.joined and place < 0:
                    continue  # the old follower has not reached the shared lane
                needed = min(follow.parting, place + gap + follow.headway * max(speed, 0.0))
                least = needed + follow.leader_length + follow.leader_line
                if least <= lows[k]:
                    continue
                _, distance, _ = _on_piece(points, d, v, t)
                rows.append(_GapRow(distance, least, False))
    return rows


ROW_TOLERANCE = 1e-6  # metres a solution may miss a gap row by (the LP solver's tolerance)
GAP_ROUNDS = 12  # rounds of adding the violated gap rows before adding all of them


def _solve_with_gaps(program: LinearProgram, rows: Sequence[_GapRow]) -> dict[str, float] | None:
    """The optimum of ``program`` that keeps every gap row. Rows are added where the
    optimum without them breaks them, round by round (most never bind, and each one makes
    the optimisation slower); after GAP_ROUNDS rounds, all of them. A relaxation without
    a solution has none with every row either."""
    chosen: set[int] = set()
    for _ in range(GAP_ROUNDS):
        attempt = program.copy()
        for index in sorted(chosen):
            rows[index].add_to(attempt)
        solution = attempt.solve()
        if solution is None:
            return None
        broken = {index for index, row in enumerate(rows) if not row.holds(solution)}
        if not broken:
            return solution
        chosen |= broken
    for row in rows:
        row.add_to(program)
    return program.solve()


def _pieces(
    program: LinearProgram,
    bounds: Bounds,
    points: Sequence[_Boundary],
    d: Sequence[Linear],
    v: Sequence[Linear],
) -> list[tuple[Linear, Linear, Linear]]:
    """The rows every curve keeps on each piece: controls in order (it never backs up),
    the speed in the middle within v_max, the acceleration at both ends within the bounds.
    Per piece: (middle speed, acceleration at the start, at the end)."""
    found = []
    one = 1.0
    for k in range(len(points) - 1):
        h = points[k + 1].t - points[k].t
        d0, d1, v0, v1 = d[k], d[k + 1], v[k], v[k + 1]
        # Controls c1 = d0 + v0 h / 3 and c2 = d1 - v1 h / 3, multiplied out.
        program.at_least(combine((one, d1), (-one, d0), (-h / 3, v0), (-h / 3, v1)), 0)
        middle = combine((3 / h, d1), (-3 / h, d0), (-one, v0), (-one, v1))
        program.at_most(middle, bounds.v_max)
        start = combine((6 / h**2, d1), (-6 / h**2, d0), (-4 / h, v0), (-2 / h, v1))
        end = combine((-6 / h**2, d1), (6 / h**2, d0), (2 / h, v0), (4 / h, v1))
        for acceleration in (start, end):
            program.at_least(acceleration, bounds.a_min)
            program.at_most(acceleration, bounds.a_max)
        found.append((middle, start, end))
    return found


def _unknowns(
    program: LinearProgram, v_max: float, points: Sequence[_Boundary]
) -> tuple[list[Linear], list[Linear]]:
    """Every piece end's distance and speed: fixed where the point says, else variables."""
    d: list[Linear] = []
    v: list[Linear] = []
    for k, point in enumerate(points):
        if point.distance is not None:
            d.append(Linear.of(point.distance))
        else:
            d.append(program.variable(f"d{k}", point.low, point.high))
        if point.speed is not None:
            v.append(Linear.of(point.speed))
        else:
            v.append(program.variable(f"v{k}", point.least_speed, v_max))
    return d, v


def _curve(points: Sequence[_Boundary], d: Sequence[Linear], v: Sequence[Linear],
           solution: dict[str, float]) -> Curve:  # fmt: skip
    distances = [_evaluate(term, solution) for term in d]
    speeds = [_evaluate(term, solution) for term in v]
    times = [float(p.t) for p in points]
    controls = []
    for k in range(len(points) - 1):
        third = (times[k + 1] - times[k]) / 3
        controls.append(
            (distances[k] + speeds[k] * third, distances[k + 1] - speeds[k + 1] * third)
        )
    return Curve(tuple(times), tuple(distances), tuple(controls))


def fit_curve(
    problem: TimingProblem,
    car: CarPlan,
    knot_times: list[float],
    fitted: dict[str, Curve] | None = None,
) -> Curve | None:
    """The smoothest curve of one car through its knots at the planned times, behind the
    cars ahead of it (``fitted``: their curves) and ahead of the old cars behind it; None
    when the bounds allow none (or the work limit was reached)."""
    points = _boundaries(problem, car, knot_times)
    bounds = problem.bounds_of(car)
    program = LinearProgram(WORK)
    d, v = _unknowns(program, bounds.v_max, points)
    rows = _following(problem, car, points, d, v, fitted or {})
    running = _running_span(car, knot_times)
    peak = program.variable("peak")
    cost: list[Linear] = [peak * 10]
    for k, (middle, start, end) in enumerate(_pieces(program, bounds, points, d, v)):
        h = points[k + 1].t - points[k].t
        for acceleration in (start, end):
            program.at_most(acceleration - peak, 0)
            program.at_least(acceleration + peak, 0)
            cost.append(program.magnitude(acceleration) * (h / 2))
        if running is not None and running[0] <= points[k].t and points[k + 1].t <= running[1]:
            for speed in (v[k], v[k + 1], middle):
                program.at_least(speed, problem.v_run)
        if points[k].least_speed and points[k + 1].least_speed:
            program.at_least(middle, min(points[k].least_speed, points[k + 1].least_speed))
    # After its last event the car gathers speed towards CRUISE of v_max, rather than keep
    # whatever speed it left the junction with (a crawl out of the junction blocks the exit
    # lane for every later car that leaves into it): the time its speed misses it costs.
    last_knot = knot_times[-1] if knot_times else 0.0
    for k in range(1, len(points)):
        if points[k].t > last_knot:
            miss = program.magnitude(v[k] - CRUISE * bounds.v_max)
            cost.append(miss * (TAIL_WEIGHT * (points[k].t - points[k - 1].t)))
    program.minimize(total(cost))
    solution = _solve_with_gaps(program, rows)
    return None if solution is None else _curve(points, d, v, solution)


def frontier(
    problem: TimingProblem, car: CarPlan, fitted: dict[str, Curve], cap: float = math.inf
) -> Curve | None:
    """The car's furthest progress behind the cars it follows (``fitted``: the symbolic
    ones' curves) from its start, whatever its knots, never beyond ``cap``: a curve without
    knots, pieces FRONTIER_PIECE long, that keeps every gap and bound and maximises the
    distances of its piece ends. None when there is none."""
    steps = max(1, math.ceil(problem.duration / FRONTIER_PIECE))
    high = min(car.reach, cap)
    points = [_Boundary(0.0, 0.0, 0.0, 0.0, car.start_speed)]
    points += [_Boundary(problem.duration * k / steps, None, 0.0, high, None)
               for k in range(1, steps + 1)]  # fmt: skip
    program = LinearProgram(WORK)
    bounds = problem.bounds_of(car)
    d, v = _unknowns(program, bounds.v_max, points)
    _pieces(program, bounds, points, d, v)
    program.minimize(total(d[1:]) * -1.0)
    solution = _solve_with_gaps(program, _following(problem, car, points, d, v, fitted))
    return None if solution is None else _curve(points, d, v, solution)


FRONTIER_PIECE = 1.0  # seconds: the pieces of a frontier (a stand on it ends on a piece end)


def _earliest_knots(
    problem: TimingProblem, car: CarPlan, fitted: dict[str, Curve]
) -> list[tuple[str, float]] | None:
    """When the car's frontier first passes each of its knots; for a knot where it stands,
    when a frontier that may not pass it first stands there (it must brake on the way)."""
    free = frontier(problem, car, fitted)
    if free is None:
        return None
    found = []
    for knot in car.knots:
        if knot.symbol is None:
            continue
        reach = free
        if knot.stop:
            capped = frontier(problem, car, fitted, cap=knot.distance)
            reach = capped if capped is not None else free
        found.append((knot.symbol, _passes(reach, knot.distance - CLEARANCE, problem.timestep)))
    return found


def _evaluate(term: Linear, solution: dict[str, float]) -> float:
    return value_of(term, solution)


def _running_span(car: CarPlan, knot_times: list[float]) -> tuple[float, float] | None:
    if car.run is None:
        return None
    return knot_times[car.run[0]], knot_times[car.run[1]]


class _Fitter:
    """Every car's curve at planned times, remembered within one problem: a car whose knot
    times did not change is not fitted again, and the car that failed last is tried first
    (plans that differ mostly keep the same car's trouble)."""

    def __init__(self, problem: TimingProblem) -> None:
        self.problem = problem
        self.order = [car.car for car in problem.cars]
        self.cars = {car.car: car for car in problem.cars}
        self.fitted: dict[tuple[Any, ...], Curve | None] = {}
        self.failed: str | None = None  # the car whose curve did not fit last time
        self.ahead: dict[str, Curve] = {}  # the curves fitted before it
        self.leaders = {
            car.car: sorted(
                {f.leader for f in problem.follows if f.follower == car.car and not f.fixed}
            )
            for car in problem.cars
        }

    def _key(self, name: str, planned: dict[str, list[float]]) -> tuple[Any, ...]:
        """A curve depends on its knot times and on those of the cars it follows."""
        ahead = tuple(self._key(leader, planned) for leader in self.leaders[name])
        return (name, tuple(planned[name]), ahead)

    def fit_all(self, planned: dict[str, list[float]] | None) -> dict[str, Curve]:
        """Every car's curve; empty unless all of them fit. A car that failed is tried
        first next time, unless it follows another symbolic car (leaders come first)."""
        if planned is None:
            return {}
        curves: dict[str, Curve] = {}
        for name in self.order:
            key = self._key(name, planned)
            if key not in self.fitted:
                self.fitted[key] = fit_curve(self.problem, self.cars[name], planned[name],
                                             curves)  # fmt: skip
            curve = self.fitted[key]
            if curve is None:
                self.failed, self.ahead = name, dict(curves)
                if not self.leaders[name]:
                    self.order.remove(name)
                    self.order.insert(0, name)
                return {}
            curves[name] = curve
        return {car.car: curves[car.car] for car in self.problem.cars}


FRONTIER_ROUNDS = 3  # followers whose knots are planned again behind their frontier
BEHIND = "a follower planned behind the cars ahead"  # said of curves from such a plan

Planner = Callable[[TimingProblem], "dict[str, list[float]] | None"]


def _fit_behind(problem: TimingProblem, fitter: _Fitter, planner: Planner) -> dict[str, Curve]:
    """After ``fitter`` failed on a follower's curve: every curve of plans by ``planner``
    that see the cars ahead of the follower better.

    A plan sees a leader only at the follower's knots: a follower stuck behind a leader that
    stands cannot then reach its next knot in time. Its knots are planned again no earlier
    than its frontier (the furthest it can get behind the cars ahead) passes them, and every
    curve is fitted again; at most FRONTIER_ROUNDS followers. A heuristic for the plans
    only: the frontier is one curve's, not a bound on every motion, so it stays out of
    Step 2 and of the proofs."""
    informed, done = problem, set()
    for _ in range(FRONTIER_ROUNDS):
        name = fitter.failed
        if name is None or name in done or not any(f.follower == name for f in problem.follows):
            break
        done.add(name)
        earliest = _earliest_knots(problem, fitter.cars[name], fitter.ahead)
        if earliest is None:
            break
        informed = dataclasses.replace(
            informed, earliest=informed.earliest + tuple((s, t) for s, t in earliest if t > 0)
        )
        curves = fitter.fit_all(planner(informed))
        if curves:
            return curves
    return {}


def _grid_plan(
    problem: TimingProblem, share: float, smoothed: bool
) -> dict[str, list[float]] | None:
    """A speed-grid plan, smoothed with continuous speeds around it or as it is."""
    grid = plan_on_speed_grid(problem, share)[0]
    return plan_times(problem, share, grid) if grid and smoothed else grid


AIM_REACH = 0.25  # seconds a grid plan may miss an aim by (a speed grid has no objective)


def _solve_aimed(problem: TimingProblem) -> TimingSolution | None:
    """Curves that keep the problem's aims, or None: the smooth plan with the aims in its
    cost, then speed-grid plans that hold every aimed event within AIM_REACH of its aim (a
    grid plan is any solution, so it keeps an aim only as a condition), smoothed and as
    they are, the comfortable share first. No proofs and no cores here: an aim is no part
    of the order (the caller times the order without aims for those)."""
    fitter = _Fitter(problem)
    share = SHARES[0]
    curves = fitter.fit_all(plan_times(problem, share))
    if curves:
        return TimingSolution(curves, f"linear, {round(share * 100)} % of the bounds")
    held = _within_aims(problem)
    for share in SHARES:
        grid = plan_on_speed_grid(held, share)[0]
        if grid is None:
            continue
        for planned in (plan_times(problem, share, grid), grid):
            curves = fitter.fit_all(planned)
            if curves:
                method = f"speed grid, {round(share * 100)} % of the bounds"
                return TimingSolution(curves, method)
    return None


def _within_aims(problem: TimingProblem) -> TimingProblem:
    """The problem with every aimed event held within AIM_REACH of its aim."""
    return dataclasses.replace(
        problem,
        earliest=problem.earliest + tuple((s, t - AIM_REACH) for s, t in problem.aims),
        latest=problem.latest + tuple((s, t + AIM_REACH) for s, t in problem.aims),
    )


def _passes(curve: Curve, distance: float, timestep: float) -> float:
    """The first time step at which ``curve`` has covered ``distance`` (its end if never)."""
    steps = round(curve.times[-1] / timestep)
    return next(
        (k * timestep for k in range(steps + 1) if curve.at(k * timestep)[0] >= distance - SAME),
        curve.times[-1],
    )


def solve_timing(problem: TimingProblem) -> TimingSolution | TimingFailure:
    """Curves for every car, or what failed. First the smooth plan with the comfortable
    share of the bounds; when its curves do not fit and a speed-grid plan exists within the
    largest share (checked first: most orders that fail, fail here), the smooth plan with
    its followers planned behind the cars ahead, the smooth plan again with continuous
    speeds around the grid plan, then speed-grid plans (smoothed and as they are), the
    comfortable share first. With aims, only plans that keep them (``_solve_aimed``; a
    failure then has no core: the aims are no part of the order). When no grid plan
    exists: the relations that cannot hold together, a proof when even the necessary
    conditions rule them out, else those that no grid plan within the largest share keeps
    (orders at the very edge of the bounds are left alone: no curve with room to spare
    realises them)."""
    if problem.aims:
        return _solve_aimed(problem) or TimingFailure("no curves keep the aims")
    comfortable, largest = SHARES[0], SHARES[-1]
    fitter = _Fitter(problem)
    smooth = plan_times(problem, comfortable)
    curves = fitter.fit_all(smooth)
    if curves:
        return TimingSolution(curves, f"linear, {round(comfortable * 100)} % of the bounds")
    edge, unreachable = plan_on_speed_grid(problem, largest)
    if edge is None:  # no grid plan: an order at the very edge of the bounds, or beyond
        core = order_core(problem) if smooth is None else None
        if core is not None:
            return TimingFailure("no event times can realise this order", tuple(core), True)
        reason = f"no speed profile within {round(largest * 100)} % of the bounds"
        return TimingFailure(reason, tuple(unreachable or ()))
    curves = _fit_behind(problem, fitter, functools.partial(plan_times, share=comfortable))
    if curves:
        return TimingSolution(
            curves, f"linear, {round(comfortable * 100)} % of the bounds, {BEHIND}"
        )
    curves = fitter.fit_all(smooth and plan_times(problem, comfortable, smooth))
    if curves:
        return TimingSolution(curves, f"linear, {round(comfortable * 100)} % of the bounds")
    for share in SHARES:
        grid = edge if share == largest else plan_on_speed_grid(problem, share)[0]
        for smoothed in (True, False):
            planned = plan_times(problem, share, grid) if grid and smoothed else grid
            method = f"speed grid, {round(share * 100)} % of the bounds"
            curves = fitter.fit_all(planned)
            if curves:
                return TimingSolution(curves, method)
            planner = functools.partial(_grid_plan, share=share, smoothed=smoothed)
            curves = _fit_behind(problem, fitter, planner)
            if curves:
                return TimingSolution(curves, f"{method}, {BEHIND}")
    return TimingFailure("no curves within the bounds for the planned event times")
