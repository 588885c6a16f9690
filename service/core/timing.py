"""Step 3: event times and composite cubic Bezier time-to-distance curves, with z3.

Each symbolic car's distance travelled d(t) is a composite cubic Bezier curve whose time
control points sit at thirds of each segment, so d is a cubic in t on every segment. Knots:
t = 0 (d = 0), every event the order speaks of, a stand-still pair at a chosen stop, and
the duration (d free up to the end of the car's poses). Constraints (design section 4):
ordered intermediate control distances (the car never backs up, so it makes no new events),
acceleration within [a_min, a_max] at both ends of every segment (it is linear in t, so
that bounds it everywhere), slope continuity at every knot, speed at most v_max (through
the derivative's control values), at most v_stop at a stop, at least v_run from arriving to
entering when running a sign, the ego's start speed for the certificates, and every chosen
order relation with a safety margin.

Fast method first: a linear program for the knot times (z3 over linear real arithmetic)
with only necessary kinematic conditions (no segment faster than v_max on average, braking
to a stand and pulling away no quicker than the acceleration bounds allow), smoothest
schedule first. When the times are infeasible, the relations in z3's unsatisfiable core are
returned: no curve can realise them, so Step 2 may rule them out for good. Then the curves:
each knot's speed is chosen from a grid, which turns every bound of a segment into an exact
set of durations, so knot times and speeds are found together (linear arithmetic and
Booleans); failing that, control points by a linear program per car with the planned times
fixed. The complete nonlinear formulation (times and control points together, as in the
paper) is ``solve_complete``: a child process that is killed at its budget.
"""

from __future__ import annotations

import bisect
import math
import time
from dataclasses import dataclass
from fractions import Fraction

import z3

from service.core.budget import run_with_budget
from service.core.errors import BudgetExceeded

DWELL = 0.5  # seconds a stopping car stands still at least


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
    reach: float  # how far its poses go: the end distance must not pass it
    start_speed: float | None  # fixed for the certificates, free for new non-egos
    run: tuple[int, int] | None  # knot indices between which it runs a stop sign


@dataclass(frozen=True)
class TimingProblem:
    cars: tuple[CarPlan, ...]
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


@dataclass(frozen=True)
class Curve:
    """A composite cubic Bezier d(t): knot times and distances, two controls a segment."""

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
        return distance, max(speed, 0.0)


@dataclass(frozen=True)
class TimingSolution:
    curves: dict[str, Curve]
    method: str  # "linear" or "nonlinear"


@dataclass(frozen=True)
class TimingFailure:
    """Why no curves were found; ``core``: indices of relations that cannot hold together."""

    reason: str
    core: tuple[int, ...] = ()
    proved: bool = False  # shown impossible (the core may be empty), not merely not found


def _value(model: z3.ModelRef, term: z3.ArithRef) -> float:
    value = model.eval(term, model_completion=True)
    if z3.is_rational_value(value):
        return float(value.as_fraction())
    return float(value.approx(20).as_fraction())  # algebraic numbers from nlsat


def _real(x: float, ctx: z3.Context) -> z3.RatNumRef:
    return z3.RealVal(Fraction(x).limit_denominator(10**9), ctx)


class _Times:
    """z3 variables for knot times, and the relations between them."""

    def __init__(self, problem: TimingProblem, ctx: z3.Context) -> None:
        self.problem = problem
        self.ctx = ctx
        self.var: dict[str, z3.ArithRef] = {}
        self.knots: dict[str, list[z3.ArithRef]] = {}
        for car in problem.cars:
            self.knots[car.car] = [z3.Real(f"T_{car.car}_{k}", ctx) for k in range(len(car.knots))]
            for knot, term in zip(car.knots, self.knots[car.car], strict=True):
                if knot.symbol is not None:
                    self.var[knot.symbol] = term
        self.fixed = dict(problem.fixed)

    def term(self, symbol: str) -> z3.ArithRef:
        if symbol in self.var:
            return self.var[symbol]
        return _real(self.fixed[symbol], self.ctx)

    def order(self) -> list[z3.BoolRef]:
        return [constraint for constraint, _ in self.labelled_order()]

    def labelled_order(self) -> list[tuple[z3.BoolRef, str]]:
        """The order relations (labelled ``rel:I``, I their index) and headways."""
        p = self.problem
        found = []
        for index, (kind, a, b) in enumerate(p.relations):
            if a not in self.var and b not in self.var:
                continue
            label = f"rel:{index}"
            if kind == "lessThan":
                found.append((self.term(b) - self.term(a) >= p.m + p.margin, label))
            else:
                found.append((self.term(b) - self.term(a) <= p.m - p.margin, label))
                found.append((self.term(a) - self.term(b) <= p.m - p.margin, label))
        for a, b, gap in p.gaps:
            found.append((self.term(b) - self.term(a) >= gap, f"headway:{a}:{b}"))
        return found


COMFORT = 0.7  # share of the speed and acceleration bounds the first timing plan uses
EDGE = 0.9  # orders that need more than this share are left alone


def _speed_caps(car: CarPlan, problem: TimingProblem, share: float) -> list[float]:
    """The highest speed the car can have at the start and at each knot: v_max, what it can
    gain from its start speed or from a stand-still behind it, and what it can still brake
    away before a stand-still ahead of it."""
    top, speed_up, slow_down = share * problem.v_max, share * problem.a_max, -share * problem.a_min
    distances = [0.0] + [k.distance for k in car.knots]
    stands = [k.distance for k in car.knots if k.stop]
    caps = []
    for j, distance in enumerate(distances):
        cap = top
        if car.start_speed is not None:
            cap = min(cap, math.sqrt(car.start_speed**2 + 2 * speed_up * distance))
            if j == 0:
                cap = car.start_speed
        for stand in stands:
            gap = distance - stand
            cap = min(cap, math.sqrt(2 * (speed_up if gap >= 0 else slow_down) * abs(gap)))
        caps.append(cap)
    return caps


def _kinematics(
    problem: TimingProblem, times: _Times, share: float
) -> tuple[list[z3.BoolRef], list[z3.ArithRef]]:
    """Conditions on knot times with ``share`` of the speed and acceleration bounds, and the
    pace changes to keep small. With share 1.0 they are necessary conditions: between any
    two knots a car needs at least the time it takes to cover the distance from the highest
    speed it can have at the first (accelerating at most a_max), and to arrive no faster
    than it can have at the second (braking at most a_min), never above v_max."""
    found: list[z3.BoolRef] = []
    cost: list[z3.ArithRef] = []
    top, speed_up, slow_down = share * problem.v_max, share * problem.a_max, -share * problem.a_min
    for car in problem.cars:
        terms = [_real(0.0, times.ctx), *times.knots[car.car]]
        distances = [0.0] + [k.distance for k in car.knots]
        caps = _speed_caps(car, problem, share)
        found += [t <= problem.duration - problem.margin for t in terms[1:]]
        for i in range(len(terms)):
            for k in range(i + 1, len(terms)):
                gap = distances[k] - distances[i]
                if gap <= 1e-9:
                    if k == i + 1:
                        found.append(terms[k] - terms[i] >= DWELL)
                    continue
                least = max(
                    fastest(gap, caps[i], speed_up, top), fastest(gap, caps[k], slow_down, top)
                )
                found.append(terms[k] - terms[i] >= least)
        paces = [
            (terms[j] - terms[j - 1]) * (1.0 / (distances[j] - distances[j - 1]))
            for j in range(1, len(terms))
            if distances[j] - distances[j - 1] > 1e-9
        ]
        if car.start_speed is not None and car.start_speed > 0.5 and paces:
            deviation = z3.Real(f"start_{car.car}", times.ctx)
            found += [
                deviation >= paces[0] - 1.0 / car.start_speed,
                deviation >= 1.0 / car.start_speed - paces[0],
            ]
            cost.append(deviation * 4)
        for k in range(1, len(paces)):
            change = z3.Real(f"change_{car.car}_{k}", times.ctx)
            found += [change >= paces[k] - paces[k - 1], change >= paces[k - 1] - paces[k]]
            cost.append(change)
    return found, cost


def _plan_times(
    problem: TimingProblem, timeout_ms: int, ctx: z3.Context
) -> tuple[dict[str, list[float]] | None, list[int], bool]:
    """The linear timing step: knot times, smoothest first, within a share of the bounds
    (COMFORT, then EDGE). Else None, the indices of the relations in an unsatisfiable
    core, and whether that is a proof: the order is impossible with the full bounds (the
    conditions are necessary), or it is possible only at their very edge, where no curve
    with a margin exists in practice (a core of the EDGE conditions, not a proof)."""
    times = _Times(problem, ctx)
    for share in (COMFORT, EDGE):
        kinematics, cost = _kinematics(problem, times, share)
        optimizer = z3.Optimize(ctx=ctx)
        optimizer.set("timeout", max(timeout_ms, 1))
        optimizer.add(*times.order(), *kinematics)
        if cost:
            optimizer.minimize(z3.Sum(cost))
        if optimizer.check() == z3.sat:
            model = optimizer.model()
            planned = {c: [_value(model, t) for t in terms] for c, terms in times.knots.items()}
            return planned, [], False
    for share, proof in ((1.0, True), (EDGE, False)):
        core = _order_core(times, _kinematics(problem, times, share)[0], timeout_ms)
        if core is not None:
            return None, core, proof
    return None, [], False


def _order_core(times: _Times, kinematics: list[z3.BoolRef], timeout_ms: int) -> list[int] | None:
    """Indices of order relations that cannot hold together with ``kinematics``; None when
    they can (or z3 cannot tell)."""
    solver = z3.Solver(ctx=times.ctx)
    solver.set("timeout", max(timeout_ms, 1))
    solver.add(*kinematics)
    labels = {}
    for k, (constraint, label) in enumerate(times.labelled_order()):
        flag = z3.Bool(f"track_{k}", times.ctx)
        labels[str(flag)] = label
        solver.assert_and_track(constraint, flag)
    if solver.check() != z3.unsat:
        return None
    core = {labels[str(flag)] for flag in solver.unsat_core()}
    return sorted(int(label[4:]) for label in core if label.startswith("rel:"))


def fastest(distance: float, start_speed: float, accel: float, top: float) -> float:
    """Least time to cover ``distance`` from ``start_speed`` accelerating at most ``accel``
    up to ``top`` (braking to a stand is the same, backwards in time)."""
    if start_speed >= top:
        return distance / top
    ramp = (top * top - start_speed * start_speed) / (2 * accel)
    if distance <= ramp:
        return (-start_speed + math.sqrt(start_speed**2 + 2 * accel * distance)) / accel
    return (top - start_speed) / accel + (distance - ramp) / top


def _segment_constraints(
    problem: TimingProblem,
    car: CarPlan,
    times: list[z3.ArithRef | float],
    controls: list[tuple[z3.ArithRef, z3.ArithRef]],
    end: z3.ArithRef,
) -> list[z3.BoolRef]:
    """Constraints of design section 4 on one car's curve, multiplied out by the segment
    length h (and h squared): linear when the times are numbers, the paper's quadratic
    form when they are variables."""
    p = problem
    distances: list[z3.ArithRef | float] = [0.0] + [k.distance for k in car.knots] + [end]
    found: list[z3.BoolRef] = []
    for j, (c1, c2) in enumerate(controls):
        d0, d3 = distances[j], distances[j + 1]
        h = times[j + 1] - times[j]
        found += [d0 <= c1, c1 <= c2, c2 <= d3]
        start_acc = 6 * (d0 - 2 * c1 + c2)
        end_acc = 6 * (c1 - 2 * c2 + d3)
        hh = h * h
        found += [p.a_min * hh <= start_acc, start_acc <= p.a_max * hh]
        found += [p.a_min * hh <= end_acc, end_acc <= p.a_max * hh]
        for rise in (c1 - d0, c2 - c1, d3 - c2):
            found.append(3 * rise <= p.v_max * h)
        if car.run and car.run[0] < j <= car.run[1]:
            found += [
                3 * (c1 - d0) >= p.v_run * h,
                3 * (c2 - c1) >= p.v_run * h,
                3 * (d3 - c2) >= p.v_run * h,
            ]
        if j + 1 < len(controls):
            n1, _ = controls[j + 1]
            h_next = times[j + 2] - times[j + 1]
            found.append((d3 - c2) * h_next == (n1 - d3) * h)
        if j < len(car.knots) and car.knots[j].stop:
            found.append(3 * (d3 - c2) <= p.v_stop * h)
    if car.start_speed is not None:
        c1, _ = controls[0]
        found.append(3 * c1 == car.start_speed * (times[1] - times[0]))
    found += [end >= (car.knots[-1].distance if car.knots else 0.0), end <= car.reach]
    return found


def _fit_curve(
    problem: TimingProblem, car: CarPlan, knot_times: list[float], timeout_ms: int, ctx: z3.Context
) -> Curve | None:
    """The linear step for one car: control points with the knot times fixed."""
    times = [0.0, *knot_times, problem.duration]
    controls = [(z3.Real(f"c1_{j}", ctx), z3.Real(f"c2_{j}", ctx)) for j in range(len(times) - 1)]
    end = z3.Real("end", ctx)
    optimizer = z3.Optimize(ctx=ctx)
    optimizer.set("timeout", max(timeout_ms, 1))
    optimizer.add(*_segment_constraints(problem, car, times, controls, end))
    distances: list[z3.ArithRef | float] = [0.0] + [k.distance for k in car.knots] + [end]
    effort: list[z3.ArithRef] = []
    for j, (c1, c2) in enumerate(controls):
        h2 = (times[j + 1] - times[j]) ** 2
        for acc in (distances[j] - 2 * c1 + c2, c1 - 2 * c2 + distances[j + 1]):
            size = z3.Real(f"effort_{j}_{len(effort)}", ctx)
            optimizer.add(size >= acc * (1.0 / h2), size >= -acc * (1.0 / h2))
            effort.append(size)
    optimizer.minimize(z3.Sum(effort))
    if optimizer.check() != z3.sat:
        return None
    model = optimizer.model()
    return Curve(
        times=tuple(times),
        distances=tuple([0.0] + [k.distance for k in car.knots] + [_value(model, end)]),
        controls=tuple((_value(model, a), _value(model, b)) for a, b in controls),
    )


def _roots(a: float, b: float, c: float) -> tuple[float, float] | None:
    """Real roots of a h^2 + b h + c (a != 0), smaller first."""
    disc = b * b - 4 * a * c
    if disc < 0:
        return None
    low, high = (-b - math.sqrt(disc)) / (2 * a), (-b + math.sqrt(disc)) / (2 * a)
    return (low, high) if low <= high else (high, low)


SPEED_GRID = (0.0, 0.05, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.85, 1.0)  # shares of v_max


def _durations(
    gap: float, v0: float, v1: float, problem: TimingProblem, runs: bool
) -> list[tuple[float, float]]:
    """Every duration h (as closed intervals) for which the segment with end speeds v0, v1
    (controls at d0 + v0 h/3 and d1 - v1 h/3) keeps every bound of design section 4."""
    if gap <= 1e-9:
        return [(DWELL, math.inf)] if v0 == 0 and v1 == 0 else []
    low, high = 1e-3, math.inf
    if v0 + v1 > 0:
        high = 3 * gap / (v0 + v1)  # controls in order: the car never backs up
    low = max(low, 3 * gap / (problem.v_max + v0 + v1))  # middle speed at most v_max
    if runs:
        high = min(high, 3 * gap / (v0 + v1 + problem.v_run))
    brake, push = -problem.a_min, problem.a_max
    # start acceleration 6 gap / h^2 - 2 (2 v0 + v1) / h, end 2 (v0 + 2 v1) / h - 6 gap / h^2
    for size, b in ((push, 2 * (2 * v0 + v1)), (brake, 2 * (v0 + 2 * v1))):
        roots = _roots(size, b, -6 * gap)  # size h^2 + b h - 6 gap >= 0
        if roots is not None:
            low = max(low, roots[1])
    if low > high:
        return []
    intervals = [(low, high)]
    for size, b in ((brake, 2 * (2 * v0 + v1)), (push, 2 * (v0 + 2 * v1))):
        roots = _roots(size, -b, 6 * gap)  # size h^2 - b h + 6 gap >= 0: not between roots
        if roots is None or roots[0] >= roots[1]:
            continue
        kept = []
        for a, z in intervals:
            if a <= roots[0]:
                kept.append((a, min(z, roots[0])))
            if z >= roots[1]:
                kept.append((max(a, roots[1]), z))
        intervals = kept
    return intervals


def _speed_options(car: CarPlan, problem: TimingProblem) -> list[list[float]]:
    """The speeds each knot (the start first) may take: the grid under what it can reach,
    zero at a stand, the start speed where fixed, at least v_run while running a sign."""
    caps = _speed_caps(car, problem, 1.0)
    options = []
    for j, cap in enumerate(caps):
        if j == 0 and car.start_speed is not None:
            options.append([car.start_speed])
        elif j > 0 and car.knots[j - 1].stop:
            options.append([0.0])
        else:
            speeds = sorted({share * problem.v_max for share in SPEED_GRID} | {cap})
            least = problem.v_run if car.run and car.run[0] <= j - 1 <= car.run[1] else 0.0
            options.append([v for v in speeds if least <= v <= cap + 1e-9])
    return options


def _fit_on_speed_grid(
    problem: TimingProblem, timeout_ms: int, ctx: z3.Context
) -> dict[str, Curve] | None:
    """Curves whose knot speeds come from a grid: for each pair of end speeds, every bound
    is an exact set of segment durations, so one linear problem with a choice of speed per
    knot (z3, linear arithmetic and Booleans) finds knot times and speeds together."""
    times = _Times(problem, ctx)
    solver = z3.Solver(ctx=ctx)
    solver.set("timeout", max(timeout_ms, 1))
    solver.add(*times.order())
    chosen: dict[str, list[list[tuple[float, z3.BoolRef]]]] = {}
    for car in problem.cars:
        terms = [_real(0.0, ctx), *times.knots[car.car]]
        distances = [0.0] + [k.distance for k in car.knots]
        picks: list[list[tuple[float, z3.BoolRef]]] = []
        for j, speeds in enumerate(_speed_options(car, problem)):
            if not speeds:
                return None
            if len(speeds) == 1:
                picks.append([(speeds[0], z3.BoolVal(True, ctx))])
                continue
            flags = [z3.Bool(f"v_{car.car}_{j}_{i}", ctx) for i in range(len(speeds))]
            solver.add(z3.PbEq([(f, 1) for f in flags], 1))
            picks.append(list(zip(speeds, flags, strict=True)))
        for j in range(1, len(terms)):
            h = terms[j] - terms[j - 1]
            solver.add(terms[j] <= problem.duration - problem.margin)
            runs = bool(car.run and car.run[0] < j <= car.run[1])
            for v0, f0 in picks[j - 1]:
                for v1, f1 in picks[j]:
                    spans = _durations(distances[j] - distances[j - 1], v0, v1, problem, runs)
                    inside = [
                        z3.And(h >= lo, h <= hi) if hi < math.inf else h >= lo for lo, hi in spans
                    ]
                    solver.add(
                        z3.Implies(
                            z3.And(f0, f1), z3.Or(inside) if inside else z3.BoolVal(False, ctx)
                        )
                    )
        chosen[car.car] = picks
    if solver.check() != z3.sat:
        return None
    model = solver.model()
    curves = {}
    for car in problem.cars:
        knot_times = [_value(model, t) for t in times.knots[car.car]]
        speeds = [
            next(v for v, f in pick if z3.is_true(model.eval(f, model_completion=True)))
            for pick in chosen[car.car]
        ]
        curve = _close_curve(problem, car, knot_times, speeds, timeout_ms, ctx)
        if curve is None:
            return None
        curves[car.car] = curve
    return curves


def _close_curve(
    problem: TimingProblem,
    car: CarPlan,
    knot_times: list[float],
    speeds: list[float],
    timeout_ms: int,
    ctx: z3.Context,
) -> Curve | None:
    """The curve through the knots with the given speeds, and a last segment to the end of
    the duration (its end distance and second control found by a small linear program)."""
    distances = [0.0] + [k.distance for k in car.knots]
    moments = [0.0, *knot_times]
    controls = []
    for j in range(1, len(moments)):
        h = moments[j] - moments[j - 1]
        controls.append(
            (distances[j - 1] + speeds[j - 1] * h / 3, distances[j] - speeds[j] * h / 3)
        )
    h = problem.duration - moments[-1]
    last, v = distances[-1], speeds[-1]
    c1 = last + v * h / 3
    c2, end = z3.Real("c2", ctx), z3.Real("end", ctx)
    solver = z3.Optimize(ctx=ctx)
    solver.set("timeout", max(timeout_ms, 1))
    hh = h * h
    solver.add(c1 <= c2, c2 <= end, end <= car.reach, c1 <= car.reach)
    solver.add(
        problem.a_min * hh <= 6 * (last - 2 * c1 + c2),
        6 * (last - 2 * c1 + c2) <= problem.a_max * hh,
    )
    solver.add(
        problem.a_min * hh <= 6 * (c1 - 2 * c2 + end), 6 * (c1 - 2 * c2 + end) <= problem.a_max * hh
    )
    solver.add(3 * (c2 - c1) <= problem.v_max * h, 3 * (end - c2) <= problem.v_max * h)
    effort = z3.Real("effort", ctx)
    solver.add(effort >= 6 * (c1 - 2 * c2 + end) - 6 * (last - 2 * c1 + c2))
    solver.add(effort >= 6 * (last - 2 * c1 + c2) - 6 * (c1 - 2 * c2 + end))
    solver.minimize(effort)
    if solver.check() != z3.sat:
        return None
    model = solver.model()
    controls.append((c1, _value(model, c2)))
    return Curve(
        times=(*moments, problem.duration),
        distances=(*distances, _value(model, end)),
        controls=tuple(controls),
    )


def solve_nonlinear(problem: TimingProblem) -> dict[str, Curve] | tuple[int, ...] | None:
    """The complete formulation (times and controls together); run it under a budget.
    Curves; when it is infeasible, the indices of relations in an unsatisfiable core;
    None when z3 gives up."""
    ctx = z3.Context()
    times = _Times(problem, ctx)
    solver = z3.SolverFor("QF_NRA", ctx=ctx)
    labels = {}
    for k, (constraint, label) in enumerate(times.labelled_order()):
        flag = z3.Bool(f"track_{k}", ctx)
        labels[str(flag)] = label
        solver.assert_and_track(constraint, flag)
    parts: dict[
        str, tuple[list[z3.ArithRef | float], list[tuple[z3.ArithRef, z3.ArithRef]], z3.ArithRef]
    ] = {}
    for car in problem.cars:
        knot_times: list[z3.ArithRef | float] = [0.0, *times.knots[car.car], problem.duration]
        controls = [
            (z3.Real(f"c1_{car.car}_{j}", ctx), z3.Real(f"c2_{car.car}_{j}", ctx))
            for j in range(len(knot_times) - 1)
        ]
        end = z3.Real(f"end_{car.car}", ctx)
        for j in range(1, len(knot_times)):
            gap = knot_times[j] - knot_times[j - 1]
            solver.add(gap >= (DWELL if j < len(knot_times) - 1 and _dwell(car, j) else 0.01))
        for term in times.knots[car.car]:
            solver.add(term <= problem.duration - problem.margin)
        solver.add(*_segment_constraints(problem, car, knot_times, controls, end))
        parts[car.car] = (knot_times, controls, end)
    verdict = solver.check()
    if verdict == z3.unknown:
        return None
    if verdict == z3.unsat:
        core = {labels[str(flag)] for flag in solver.unsat_core()}
        return tuple(sorted(int(label[4:]) for label in core if label.startswith("rel:")))
    model = solver.model()
    curves = {}
    for car in problem.cars:
        knot_times, controls, end = parts[car.car]
        curves[car.car] = Curve(
            times=tuple(_value(model, t) if not isinstance(t, float) else t for t in knot_times),
            distances=tuple([0.0] + [k.distance for k in car.knots] + [_value(model, end)]),
            controls=tuple((_value(model, a), _value(model, b)) for a, b in controls),
        )
    return curves


def _dwell(car: CarPlan, j: int) -> bool:
    return j >= 2 and car.knots[j - 1].distance - car.knots[j - 2].distance <= 1e-9


def solve_timing(problem: TimingProblem, budget: float) -> TimingSolution | TimingFailure:
    """The linear steps: curves for every car, or what failed (with an unsatisfiable core
    when there is one). The nonlinear formulation is ``solve_complete``."""
    started = time.monotonic()
    ctx = z3.Context()  # a fresh context per problem: z3's answers do not depend on history
    planned, core, proof = _plan_times(problem, int(budget * 1000), ctx)
    if planned is None:
        if proof:
            return TimingFailure("no event times can realise this order", tuple(core), True)
        if core:
            return TimingFailure("this order needs the very edge of the bounds", tuple(core))
        return TimingFailure("the linear timing step gave up")
    direct = _fit_on_speed_grid(problem, int((budget - (time.monotonic() - started)) * 1000), ctx)
    if direct is not None:
        return TimingSolution(direct, "linear")
    curves = {}
    for car in problem.cars:
        left = budget - (time.monotonic() - started)
        curve = _fit_curve(problem, car, planned[car.car], int(left * 1000), ctx)
        if curve is None:
            break
        curves[car.car] = curve
    else:
        return TimingSolution(curves, "linear")
    return TimingFailure(f"the linear curve step failed for {car.car}")


def solve_complete(problem: TimingProblem, budget: float) -> TimingSolution | TimingFailure:
    """The nonlinear formulation in a child process that is killed at ``budget``."""
    if budget <= 0.05:
        return TimingFailure("no time left for the nonlinear step")
    try:
        solved = run_with_budget(solve_nonlinear, (problem,), budget, "the nonlinear timing step")
    except BudgetExceeded:
        return TimingFailure(f"the nonlinear step ran out of its {budget:.1f} s")
    if solved is None:
        return TimingFailure("the nonlinear step gave up")
    if isinstance(solved, tuple):
        return TimingFailure("the nonlinear step proved it infeasible", solved, True)
    return TimingSolution(solved, "nonlinear")
