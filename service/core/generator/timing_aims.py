"""Step 3 aimed: curves whose events keep close to given times (``TimingProblem.aims``).

A variety of timings of one order (service.core.generator.variety: a seed aims at a point
of each new car's ``timing.entry_window``) asks Step 3 for curves near those times: the
smooth plan with the aims in its cost (``timing.AIM_WEIGHT``), else speed-grid plans that
hold each aimed event within ``AIM_REACH`` of its aim, and every car's curve at the plan's
times (service.core.generator.timing_curves). ``timing_solve.solve_timing`` turns here when
a problem has aims.
"""

from __future__ import annotations

import dataclasses

from service.core.generator.timing import (
    SHARES,
    TimingProblem,
    TimingSolution,
    plan_on_speed_grid,
    plan_times,
)
from service.core.generator.timing_curves import Fitter

AIM_REACH = 0.25  # seconds a grid plan may miss an aim by (a speed grid has no objective)


def solve_aimed(problem: TimingProblem) -> TimingSolution | None:
    """Curves that keep the problem's aims, or None: the smooth plan with the aims in its
    cost, then speed-grid plans that hold every aimed event within AIM_REACH of its aim (a
    grid plan is any solution, so it keeps an aim only as a condition), smoothed and as
    they are, the comfortable share first. No proofs and no cores here: an aim is no part
    of the order (the caller times the order without aims for those)."""
    fitter = Fitter(problem)
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
