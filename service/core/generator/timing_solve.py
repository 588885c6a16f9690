"""Step 3's solve: curves for every car that realise an order, or what failed.

``solve_timing`` tries plans (service.core.generator.timing) in turn and fits every car's
curve to each plan, every event within its window around the planned time
(service.core.generator.timing_windows, service.core.generator.timing_curves): the smooth
plan first;
then, when a speed-grid plan exists, plans again with a follower's knots behind its
frontier (the furthest it can get behind the cars ahead), the smooth plan with continuous
speeds, and speed-grid plans; with aims, only plans that keep them
(service.core.generator.timing_aims). When no plan exists, the relations that cannot hold
together go back to Step 2. Answers are remembered by problem (``REMEMBERED``).
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable

from service.core.generator.timing import (
    SHARES,
    CarPlan,
    Curve,
    TimingFailure,
    TimingProblem,
    TimingSolution,
    order_core,
    plan_on_speed_grid,
    plan_times,
)
from service.core.generator.timing_aims import solve_aimed
from service.core.generator.timing_curves import CLEARANCE, Fitter, frontier
from service.core.motion.kinematics import SAME

FRONTIER_ROUNDS = 3  # followers whose knots are planned again behind their frontier
BEHIND = "a follower planned behind the cars ahead"  # said of curves from such a plan

Planner = Callable[[TimingProblem], "dict[str, list[float]] | None"]
GridPlan = tuple["dict[str, list[float]] | None", "list[int] | None"]


class _Made:
    """The speed-grid plans and frontiers of one problem, each made once: the fall-backs
    ask for the same ones again (a problem informed of a follower's frontier differs from
    the one given only in its ``earliest`` times)."""

    def __init__(self) -> None:
        self.grids: dict[tuple[object, float], GridPlan] = {}
        self.knots: dict[tuple[object, ...], list[tuple[str, float]] | None] = {}

    def grid(self, problem: TimingProblem, share: float) -> GridPlan:
        key = (problem.earliest, share)
        if key not in self.grids:
            self.grids[key] = plan_on_speed_grid(problem, share)
        return self.grids[key]

    def earliest_knots(
        self, problem: TimingProblem, car: CarPlan, fitted: dict[str, Curve]
    ) -> list[tuple[str, float]] | None:
        key = (car.car, *sorted(fitted.items(), key=lambda item: item[0]))
        if key not in self.knots:
            self.knots[key] = _earliest_knots(problem, car, fitted)
        return self.knots[key]


def _fit_behind(
    problem: TimingProblem, fitter: Fitter, planner: Planner, made: _Made
) -> dict[str, Curve]:
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
        earliest = made.earliest_knots(problem, fitter.cars[name], fitter.ahead)
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
    problem: TimingProblem, share: float, smoothed: bool, made: _Made
) -> dict[str, list[float]] | None:
    """A speed-grid plan, smoothed with continuous speeds around it or as it is."""
    grid = made.grid(problem, share)[0]
    return plan_times(problem, share, grid) if grid and smoothed else grid


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


def _passes(curve: Curve, distance: float, timestep: float) -> float:
    """The first time step at which ``curve`` has covered ``distance`` (its end if never)."""
    steps = round(curve.times[-1] / timestep)
    return next(
        (k * timestep for k in range(steps + 1) if curve.at(k * timestep)[0] >= distance - SAME),
        curve.times[-1],
    )


REMEMBERED = 128  # Step 3 answers kept per process (a chain's second round asks again
# for up to ROUTE_ORDERS per route it retries)


@functools.lru_cache(maxsize=REMEMBERED)
def solve_timing(problem: TimingProblem) -> TimingSolution | TimingFailure:
    """Curves for every car, or what failed; remembered by problem (the answer depends on
    the problem alone: a chain's route that gets more answer sets in a second round draws
    its first ones again, and their Step 3 is not done twice). Callers do not change the
    answer. First the smooth plan with the comfortable
    share of the bounds; when its curves do not fit and a speed-grid plan exists within the
    largest share (checked first: most orders that fail, fail here), the smooth plan with
    its followers planned behind the cars ahead, the smooth plan again with continuous
    speeds around the grid plan, then speed-grid plans (smoothed and as they are), the
    comfortable share first. With aims, only plans that keep them (``solve_aimed``; a
    failure then has no core: the aims are no part of the order). When no grid plan
    exists: the relations that cannot hold together, a proof when even the necessary
    conditions rule them out, else those that no grid plan within the largest share keeps
    (orders at the very edge of the bounds are left alone: no curve with room to spare
    realises them)."""
    if problem.aims:
        return solve_aimed(problem) or TimingFailure("no curves keep the aims")
    comfortable, largest = SHARES[0], SHARES[-1]
    fitter, made = Fitter(problem), _Made()
    smooth = plan_times(problem, comfortable)
    curves = fitter.fit_all(smooth)
    if curves:
        return TimingSolution(curves, f"linear, {round(comfortable * 100)} % of the bounds")
    edge, unreachable = made.grid(problem, largest)
    if edge is None:  # no grid plan: an order at the very edge of the bounds, or beyond
        core = order_core(problem) if smooth is None else None
        if core is not None:
            return TimingFailure("no event times can realise this order", tuple(core), True)
        reason = f"no speed profile within {round(largest * 100)} % of the bounds"
        return TimingFailure(reason, tuple(unreachable or ()))
    planner = functools.partial(plan_times, share=comfortable)
    curves = _fit_behind(problem, fitter, planner, made)
    if curves:
        return TimingSolution(
            curves, f"linear, {round(comfortable * 100)} % of the bounds, {BEHIND}"
        )
    curves = fitter.fit_all(smooth and plan_times(problem, comfortable, smooth))
    if curves:
        return TimingSolution(curves, f"linear, {round(comfortable * 100)} % of the bounds")
    for share in SHARES:
        grid = made.grid(problem, share)[0]
        for smoothed in (True, False):
            planned = plan_times(problem, share, grid) if grid and smoothed else grid
            method = f"speed grid, {round(share * 100)} % of the bounds"
            curves = fitter.fit_all(planned)
            if curves:
                return TimingSolution(curves, method)
            planner = functools.partial(_grid_plan, share=share, smoothed=smoothed, made=made)
            curves = _fit_behind(problem, fitter, planner, made)
            if curves:
                return TimingSolution(curves, f"{method}, {BEHIND}")
    return TimingFailure("no curves within the bounds for the planned event times")
