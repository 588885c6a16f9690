"""Step 3's event windows: how far each planned event time may move with the order kept.

A plan (service.core.generator.timing) gives every knot of every symbolic car one time. The
curves (service.core.generator.timing_curves) need not pass an event exactly then: any
time keeps the order as long as every relation still holds. ``event_windows`` gives each
knot an interval around its planned time such that every choice of times within the
intervals keeps every relation (``lessThan``, ``equal``, the headways, the earliest and
latest times of queues and signal spans, the end of the duration, the running and crossing
limits within one car): the slack of a relation between two symbolic knots is shared
half and half, towards an old car's fixed time it is the symbolic knot's alone. A curve
then only has to reach the event's distance within its window (it is below the distance
at the window's start, at or beyond it at its end), which many more curves do than pass
it at one instant: the plan's times are a guide, not a demand.

Stand-stills (a stop at a sign and its end) keep their planned times: the order speaks of
when the stand begins, and a window there would let the car creep up to the line.
Windows narrower than ``NARROWEST`` are points.
"""

from __future__ import annotations

import math
from collections import defaultdict

from service.core.generator.timing import CarPlan, TimingProblem

NARROWEST = 0.02  # seconds: a window narrower than this is the planned time itself
Windows = dict[str, list[tuple[float, float]]]  # car -> (earliest, latest) of each knot


def event_windows(problem: TimingProblem, planned: dict[str, list[float]]) -> Windows:
    """Every knot's window (``planned``: each car's knot times, as a plan gives them)."""
    time_of = dict(problem.fixed)
    symbolic: set[str] = set()
    for car in problem.cars:
        for knot, t in zip(car.knots, planned[car.car], strict=True):
            if knot.symbol is not None:
                time_of[knot.symbol] = t
                symbolic.add(knot.symbol)
    later: dict[str, float] = defaultdict(lambda: math.inf)  # how far a symbol may move up
    earlier: dict[str, float] = defaultdict(lambda: math.inf)  # ... and down

    def before(a: str, b: str, gap: float) -> None:
        """Keep time(b) - time(a) >= gap."""
        if a not in time_of or b not in time_of:
            return
        slack = max(0.0, time_of[b] - time_of[a] - gap)
        share = slack / 2 if a in symbolic and b in symbolic else slack
        later[a] = min(later[a], share)
        earlier[b] = min(earlier[b], share)

    for kind, a, b in problem.relations:
        if kind == "lessThan":
            before(a, b, problem.m + problem.margin)
        else:  # equal: |time(b) - time(a)| <= m - margin
            before(a, b, -(problem.m - problem.margin))
            before(b, a, -(problem.m - problem.margin))
    for a, b, gap in problem.gaps:
        before(a, b, gap)
    for symbol, t in problem.earliest:
        if symbol in symbolic:
            earlier[symbol] = min(earlier[symbol], max(0.0, time_of[symbol] - t))
    for symbol, t in problem.latest:
        if symbol in symbolic:
            later[symbol] = min(later[symbol], max(0.0, t - time_of[symbol]))
    windows: Windows = {}
    for car in problem.cars:
        times = planned[car.car]
        found = []
        for j, (knot, t) in enumerate(zip(car.knots, times, strict=True)):
            if knot.symbol is None or knot.stop:
                found.append((t, t))
                continue
            low = t - earlier[knot.symbol]
            high = min(t + later[knot.symbol], problem.duration - problem.margin)
            # the car's own knots (and its start) stay apart: a window reaches at most a
            # third of the way to the next planned time
            low = max(low, t - (t - (times[j - 1] if j > 0 else 0.0)) / 3)
            if j + 1 < len(times):
                high = min(high, t + (times[j + 1] - t) / 3)
            found.append((min(low, t), max(high, t)))
        windows[car.car] = _within_car(problem, car, times, found)
    return windows


def _within_car(problem: TimingProblem, car: CarPlan, times: list[float],
                found: list[tuple[float, float]]) -> list[tuple[float, float]]:  # fmt: skip
    """The windows narrowed so that the car's own limits still hold for every choice: the
    span of running a sign and of crossing its lane no longer than the plan allowed."""
    spans = []
    if car.run is not None:
        first, last = car.run
        spans.append((first, last, (car.knots[last].distance - car.knots[first].distance)
                      / problem.v_run))  # fmt: skip
    least = car.crossing or problem.crossing
    if car.inside is not None and least:
        entry, leave = car.inside
        spans.append((entry, leave,
                      (car.knots[leave].distance - car.knots[entry].distance) / least))  # fmt: skip
    for first, last, longest in spans:
        slack = max(0.0, longest - (times[last] - times[first])) / 2
        low = found[first][0]
        high = found[last][1]
        found[first] = (max(low, times[first] - slack), found[first][1])
        found[last] = (found[last][0], min(high, times[last] + slack))
    return [(low, high) if high - low >= NARROWEST else (t, t)
            for (low, high), t in zip(found, times, strict=True)]  # fmt: skip
