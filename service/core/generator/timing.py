"""Step 3: the timing problem, its answer, and the program of the plan (z3 and HiGHS).

Each symbolic car's distance travelled d(t) is a composite cubic Bezier curve whose time
control points sit at thirds of each piece, so d is a cubic in t on every piece. Knots:
t = 0 (d = 0), every event the order speaks of (and arriving, entering and leaving its own
lane), a stand-still pair where it stops at its sign, and the duration. Between two knots
the curve has free knots (service.core.generator.timing_curves), so one segment can brake,
stand and go again wherever the order needs it.

Two kinds of linear program (service.core.generator.linear: optima by HiGHS's simplex, Boolean
choices and unsatisfiable cores by z3 over the rationals):

1. the plan (this module): the knot times of every car at once, keeping every order
   relation with its margin, the headways, and the necessary kinematic conditions of
   service.core.motion.kinematics with a share of the bounds in reserve (``SHARES``: the
   curves then have room), smoothest first (the pace changes least from knot to knot); or
   knot times chosen with knot speeds from a grid (``plan_on_speed_grid``);
2. the curves (service.core.generator.timing_curves), one car at a time, each event
   within a window around the plan's time in which every relation still holds
   (service.core.generator.timing_windows): the plan guides the curves, it does not pin
   them.

When the plan is infeasible even with the full bounds, the relations of z3's unsatisfiable
core go back to Step 2 (``order_core``): no speed profile can realise them together. Every
solve is limited by a count of work (z3's ``rlimit``, HiGHS's simplex iterations), never by
a clock: the same problem gives the same curves on an idle and on a saturated machine.

Step 3's modules, each importing only those before it: this one (the problem and its
answer, the plans, the window of an event's times that variety aims within);
``timing_windows`` (how far each planned time may move with the order kept);
``timing_gaps`` (the rows that keep a curve behind the cars ahead, as arrays);
``timing_curves`` (a car's curve through its planned knots, every car's curves at a plan's
times); ``timing_aims`` (curves that keep aimed event times); ``timing_solve``
(``solve_timing``: plans, then curves, and what is tried when they do not fit).
"""

from __future__ import annotations

import bisect
import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

from service.core.generator.linear import (
    Linear,
    LinearProgram,
    total,
    value_of,
    values,
)
from service.core.motion.kinematics import SAME, Bounds, duration_range, least_gaps, speed_caps

SHARES = (0.7, 0.85)  # shares of the bounds a plan may use (the curves keep the rest)
WORK = 4_000_000  # z3 rlimit of one program with choices or a core (a count, not seconds)
INSIDE_WEIGHT = 0.1  # plan cost of a second inside the junction beyond three times
# the least time to cross it and two seconds (pace changes cost seconds per metre)
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
    arrival: int | None = None  # knot index of arriving at its line (None: at its start)


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


def _first_time(rows: Sequence[tuple[float, float, float]], distance: float) -> float | None:
    """The first sample time at which an old car's distance reaches ``distance``."""
    return next((t for t, d, _ in rows if d >= distance - SAME), None)
