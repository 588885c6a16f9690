"""The paper's Step 3, for comparison: one nonlinear z3 problem over knot times and controls.

Karimi and Duggirala solve the speed profiles of all symbolic cars at once: the knot times
are variables, so the Bezier constraints (multiplied out by the segment length h and h^2)
are polynomial. This module states that formulation on our TimingProblem (one cubic per
segment between knots, as the paper has it) so that `make bench` can time it against the
generator's linear method on the same problems. z3 runs under a work limit (rlimit) in a
child process that is killed at its budget.
"""

from __future__ import annotations

import math
from fractions import Fraction

import z3

from service.core.budget import run_with_budget
from service.core.errors import BudgetExceeded
from service.core.generator.timing import CarPlan, Curve, TimingProblem
from service.core.motion.kinematics import DWELL, SAME

WORK = 50_000_000  # z3 rlimit of the whole problem


def _real(x: float, ctx: z3.Context) -> z3.RatNumRef:
    return z3.RealVal(Fraction(round(x * 10**6), 10**6), ctx)


def _segments(
    problem: TimingProblem,
    car: CarPlan,
    times: list[z3.ArithRef],
    controls: list[tuple[z3.ArithRef, z3.ArithRef]],
    end: z3.ArithRef,
    ctx: z3.Context,
) -> list[z3.BoolRef]:
    """Design section 4's constraints on one car's curve, multiplied out by h and h^2."""
    p = problem
    distances = [_real(0.0, ctx)] + [_real(k.distance, ctx) for k in car.knots] + [end]
    a_min, a_max, v_max = _real(p.a_min, ctx), _real(p.a_max, ctx), _real(p.v_max, ctx)
    found: list[z3.BoolRef] = []
    for j, (c1, c2) in enumerate(controls):
        d0, d3 = distances[j], distances[j + 1]
        h = times[j + 1] - times[j]
        found += [d0 <= c1, c1 <= c2, c2 <= d3]
        start, finish, hh = 6 * (d0 - 2 * c1 + c2), 6 * (c1 - 2 * c2 + d3), h * h
        found += [a_min * hh <= start, start <= a_max * hh, a_min * hh <= finish]
        found += [finish <= a_max * hh]
        found += [3 * rise <= v_max * h for rise in (c1 - d0, c2 - c1, d3 - c2)]
        if car.run and car.run[0] < j <= car.run[1]:
            v_run = _real(p.v_run, ctx)
            found += [3 * rise >= v_run * h for rise in (c1 - d0, c2 - c1, d3 - c2)]
        if j + 1 < len(controls):
            following, _ = controls[j + 1]
            found.append((d3 - c2) * (times[j + 2] - times[j + 1]) == (following - d3) * h)
        if j < len(car.knots) and car.knots[j].stop:
            found.append(3 * (d3 - c2) <= _real(p.v_stop, ctx) * h)
    if car.start_speed is not None:
        found.append(3 * controls[0][0] == _real(car.start_speed, ctx) * (times[1] - times[0]))
    last = car.knots[-1].distance if car.knots else 0.0
    found.append(end >= _real(last, ctx))
    if math.isfinite(car.reach):  # the generator's cars drive on past the end of the road
        found.append(end <= _real(car.reach, ctx))
    return found


def solve_nonlinear(problem: TimingProblem) -> dict[str, Curve] | str:
    """Curves for every car from the one nonlinear problem, or why there are none."""
    ctx = z3.Context()
    solver = z3.SolverFor("QF_NRA", ctx=ctx)
    solver.set("rlimit", WORK)
    symbols: dict[str, z3.ArithRef] = {}
    parts = {}
    for car in problem.cars:
        knots = [z3.Real(f"T_{car.car}_{k}", ctx) for k in range(len(car.knots))]
        symbols.update({k.symbol: t for k, t in zip(car.knots, knots, strict=True) if k.symbol})
        times = [_real(0.0, ctx), *knots, _real(problem.duration, ctx)]
        controls = [(z3.Real(f"a_{car.car}_{j}", ctx), z3.Real(f"b_{car.car}_{j}", ctx))
                    for j in range(len(times) - 1)]  # fmt: skip
        end = z3.Real(f"end_{car.car}", ctx)
        for j in range(1, len(times)):
            stand = (
                j < len(times) - 1
                and j >= 2
                and (car.knots[j - 1].distance - car.knots[j - 2].distance <= SAME)
            )
            solver.add(times[j] - times[j - 1] >= _real(DWELL if stand else 0.01, ctx))
        solver.add(*[t <= _real(problem.duration - problem.margin, ctx) for t in knots])
        solver.add(*_segments(problem, car, times, controls, end, ctx))
        parts[car.car] = (times, controls, end)

    def term(symbol: str) -> z3.ArithRef:
        return symbols[symbol] if symbol in symbols else _real(dict(problem.fixed)[symbol], ctx)

    for kind, a, b in problem.relations:
        if a in symbols or b in symbols:
            if kind == "lessThan":
                solver.add(term(b) - term(a) >= _real(problem.m + problem.margin, ctx))
            else:
                within = _real(problem.m - problem.margin, ctx)
                solver.add(term(b) - term(a) <= within, term(a) - term(b) <= within)
    for a, b, gap in problem.gaps:
        solver.add(term(b) - term(a) >= _real(gap, ctx))
    verdict = solver.check()
    if verdict != z3.sat:
        return "infeasible" if verdict == z3.unsat else "z3 gave up"
    model = solver.model()

    def value(x: z3.ArithRef) -> float:
        found = model.eval(x, model_completion=True)
        return float(found.as_fraction() if z3.is_rational_value(found) else
                     found.approx(20).as_fraction())  # fmt: skip

    curves = {}
    for car in problem.cars:
        times, controls, end = parts[car.car]
        curves[car.car] = Curve(
            times=tuple(value(t) for t in times),
            distances=(0.0, *(k.distance for k in car.knots), value(end)),
            controls=tuple((value(a), value(b)) for a, b in controls),
        )
    return curves


def solve_paper(problem: TimingProblem, budget: float) -> dict[str, Curve] | str:
    """``solve_nonlinear`` in a child process that is killed after ``budget`` seconds."""
    try:
        return run_with_budget(solve_nonlinear, (problem,), budget, "the nonlinear Step 3")
    except BudgetExceeded:
        return f"ran out of its {budget:g} s"
