"""Step 3's curves: each car's composite cubic Bezier d(t) through its knots at the times a
plan (service.core.generator.timing) gave them, by HiGHS's simplex.

One linear program per car, with the plan's knot times fixed: every piece's end distance
and speed, so that the controls are in order (the car never backs up and makes no new
event), the acceleration stays within the bounds at both ends of every piece (it is linear
in between), the speed within v_max, zero at a stand, at least v_run while running a sign,
the certificates' start speed; smoothest first (least peak acceleration, then least
acceleration and jerk). Between two knots the curve has free knots at most ``PIECE``
seconds apart. A follower keeps its gap behind the curves fitted before it and ahead of
the old cars behind it at every time step (service.core.generator.timing_gaps: rows added
as they bind).

``fit_curve`` fits one car, ``frontier`` the furthest a car can get behind the cars ahead,
and ``Fitter`` every car's curves at a plan's times (what timing_aims and timing_solve
call).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from service.core.generator.linear import (
    Linear,
    LinearProgram,
    combine,
    total,
    value_of,
)
from service.core.generator.timing import WORK, CarPlan, Curve, TimingProblem
from service.core.generator.timing_gaps import gap_rows, solve_with_gaps
from service.core.generator.timing_windows import Windows, event_windows
from service.core.motion.kinematics import SAME, Bounds

PIECE = 2.0  # seconds: the longest piece of a curve (free knots between events)
CLEARANCE = 0.01  # metres a free knot keeps from the knots around it (events stay sharp),
# and a car passes on either side of an event's point within the event's window
STOP_LEAD = 0.1  # seconds before a stand when a stopping car is still faster than v_stop
STOP_LEAD_BRAKING = 3.0  # ... or this many times v_stop over its strongest braking, when
# that is longer (a pedestrian's gentle braking: a stand within 0.1 s of v_stop is too abrupt)
CRUISE = 0.5  # share of v_max a car makes for after its last event (the curve's end)
TAIL_WEIGHT = 1.0  # cost per m/s and second the speed misses that after the last event


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


def _anchors(
    problem: TimingProblem, car: CarPlan, windows: Sequence[tuple[float, float]]
) -> list[tuple[_Boundary, bool]]:
    """The fixed points of a car's curve, with whether each is a stand: the start; each
    knot at its planned time (a point window), or the start and end of its window (up to
    CLEARANCE below the knot's distance at the start, as far beyond it at the end: the
    event happens within, and so does an event the checker or a replay in SUMO places a
    few millimetres off); the end of the duration (distance free up to ``reach``)."""
    distances = [0.0] + [k.distance for k in car.knots] + [car.reach]
    found = [(_Boundary(0.0, 0.0, 0.0, 0.0, car.start_speed), False)]
    for j, (knot, (low, high)) in enumerate(zip(car.knots, windows, strict=True), start=1):
        here = knot.distance
        if high - low <= SAME:
            found.append((_Boundary(low, here, here, here, 0.0 if knot.stop else None), knot.stop))
            continue
        before = min(CLEARANCE, (here - distances[j - 1]) / 4)
        after = min(CLEARANCE, (distances[j + 1] - here) / 4)
        found.append((_Boundary(low, None, distances[j - 1], here - before, None), False))
        found.append((_Boundary(high, None, here + after, distances[j + 1], None), False))
    return found


def _boundaries(
    problem: TimingProblem, car: CarPlan, windows: Sequence[tuple[float, float]]
) -> list[_Boundary]:
    """Piece ends: the anchors (``_anchors``), and free knots at most PIECE apart between
    them. Before a stand, the car keeps above v_stop from its previous anchor until a lead
    (``stop_lead``) before the stand, so that its stop begins when it is planned (the
    checker's stop is the first moment at v_stop or below), not while it creeps up to the
    line."""
    anchors = _anchors(problem, car, windows)
    found = [anchors[0][0]]
    before_stand = stop_lead(problem.v_stop, problem.bounds_of(car))
    for j in range(1, len(anchors) + 1):
        last = j == len(anchors)  # the end of the duration: the distance is free
        previous, previous_stands = anchors[j - 1]
        if last:
            point, stands = _Boundary(problem.duration, None, previous.low, car.reach, None), False
        else:
            point, stands = anchors[j]
        low, high = previous.low, point.high
        stand = not last and point.distance is not None and high - low <= SAME
        clearance = 0.0 if stand else min(CLEARANCE, (high - low) / 4)
        stops_here = stands and not previous_stands
        span_all = point.t - previous.t
        lead = before_stand if stops_here and span_all > before_stand else 0.0
        floor = problem.v_stop if lead else 0.0
        if floor and found[-1].speed is None:
            at = found[-1]
            found[-1] = _Boundary(at.t, at.distance, at.low, at.high, at.speed, floor)
        span = span_all - lead
        pieces = 1 if stand else max(1, math.ceil(span / PIECE - 1e-9))
        for k in range(1, pieces + (1 if lead else 0)):
            t = previous.t + span * k / pieces
            found.append(_Boundary(t, None, low + clearance, high - clearance, None, floor))
        if last:
            found.append(_Boundary(point.t, None, low + clearance, high, None))
        else:
            found.append(point)
    return found


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
    windows: Sequence[tuple[float, float]],
    fitted: dict[str, Curve] | None = None,
) -> Curve | None:
    """The smoothest curve of one car through its knots within their windows
    (service.core.generator.timing_windows; a point window: the planned time), behind the
    cars ahead of it (``fitted``: their curves) and ahead of the old cars behind it; None
    when the bounds allow none (or the work limit was reached)."""
    points = _boundaries(problem, car, windows)
    bounds = problem.bounds_of(car)
    program = LinearProgram(WORK)
    d, v = _unknowns(program, bounds.v_max, points)
    ends = [p.t for p in points]
    rows = gap_rows(problem, car.car, bounds.v_max, ends, [p.low for p in points],
                    [p.high for p in points], fitted or {})  # fmt: skip
    running = _running_span(car, windows)
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
    last_knot = windows[-1][1] if windows else 0.0
    for k in range(1, len(points)):
        if points[k].t > last_knot:
            miss = program.magnitude(v[k] - CRUISE * bounds.v_max)
            cost.append(miss * (TAIL_WEIGHT * (points[k].t - points[k - 1].t)))
    program.minimize(total(cost))
    solution = solve_with_gaps(program, rows, ends, d, v)
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
    ends = [p.t for p in points]
    rows = gap_rows(problem, car.car, bounds.v_max, ends, [p.low for p in points],
                    [p.high for p in points], fitted)  # fmt: skip
    solution = solve_with_gaps(program, rows, ends, d, v)
    return None if solution is None else _curve(points, d, v, solution)


FRONTIER_PIECE = 1.0  # seconds: the pieces of a frontier (a stand on it ends on a piece end)


def _evaluate(term: Linear, solution: dict[str, float]) -> float:
    return value_of(term, solution)


def _running_span(
    car: CarPlan, windows: Sequence[tuple[float, float]]
) -> tuple[float, float] | None:
    """From the earliest the car may reach the first knot of its run to the latest it may
    reach the last: it keeps v_run throughout."""
    if car.run is None:
        return None
    return windows[car.run[0]][0], windows[car.run[1]][1]


class Fitter:
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

    def _key(self, name: str, windows: Windows) -> tuple[Any, ...]:
        """A curve depends on its knots' windows and on those of the cars it follows."""
        ahead = tuple(self._key(leader, windows) for leader in self.leaders[name])
        return (name, tuple(windows[name]), ahead)

    def fit_all(self, planned: dict[str, list[float]] | None) -> dict[str, Curve]:
        """Every car's curve; empty unless all of them fit. A car that failed is tried
        first next time, unless it follows another symbolic car (leaders come first)."""
        if planned is None:
            return {}
        curves: dict[str, Curve] = {}
        windows = event_windows(self.problem, planned)
        for name in self.order:
            key = self._key(name, windows)
            if key not in self.fitted:
                self.fitted[key] = fit_curve(self.problem, self.cars[name], windows[name],
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
