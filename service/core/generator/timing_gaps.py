"""Step 3's gap rows: a car's curve keeps behind the cars ahead of it and ahead of the old
cars behind it, at every time step (the checker's samples).

A curve (service.core.generator.timing_curves) is a composite cubic Bezier whose piece
ends have unknown distances ``d`` and speeds ``v``; at a time t inside a piece, its
distance and speed are linear in the piece's four unknowns (``on_piece``). A gap condition
at one step is one such linear row. There is a row for every step at which the condition
can bind (hundreds a curve), most never bind, and each one makes the optimisation slower:
``GapRows`` keeps them as arrays, tells which ones a solution breaks with numpy, and builds
the linear row of a step only when it is added to the program (``solve_with_gaps``).
"""

from __future__ import annotations

import bisect
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from service.core.generator.linear import Linear, LinearProgram, combine, value_of
from service.core.generator.timing import Curve, Following, TimingProblem

FOLLOW_SLACK = 0.05  # metres a planned follower keeps beyond the gap (samples are rounded)
ROW_TOLERANCE = 1e-6  # metres a solution may miss a gap row by (the LP solver's tolerance)
GAP_ROUNDS = 12  # rounds of adding the violated gap rows before adding all of them


def on_piece(
    times: Sequence[float], d: Sequence[Linear], v: Sequence[Linear], t: float
) -> tuple[Linear, Linear]:
    """(distance, speed) of the curve at time t, linear in its piece's unknowns: with
    controls d0 + v0 h/3 and d1 - v1 h/3, d(t) = d0 (u^3 + 3u^2 s) + v0 u^2 s h
    + d1 (3 u s^2 + s^3) - v1 u s^2 h and v(t) = u^2 v0 + s^2 v1 + 6us (d1 - d0)/h
    - 2us (v0 + v1), for s the share of the piece and u = 1 - s (``times``: the piece
    ends)."""
    k = min(max(bisect.bisect_right(times, t) - 1, 0), len(times) - 2)
    h = times[k + 1] - times[k]
    s = (t - times[k]) / h
    u = 1 - s
    distance = combine((u**3 + 3 * u * u * s, d[k]), (u * u * s * h, v[k]),
                       (3 * u * s * s + s**3, d[k + 1]), (-u * s * s * h, v[k + 1]))  # fmt: skip
    speed = combine((u * u - 2 * u * s, v[k]), (s * s - 2 * u * s, v[k + 1]),
                    (6 * u * s / h, d[k + 1]), (-6 * u * s / h, d[k]))  # fmt: skip
    return distance, speed


def _at(times: np.ndarray, d: np.ndarray, v: np.ndarray, t: np.ndarray) -> np.ndarray:
    """(distances, speeds) at the times ``t`` of the curve whose piece ends have times
    ``times``, distances ``d`` and speeds ``v`` (numbers: a solution's)."""
    k = np.clip(np.searchsorted(times, t, side="right") - 1, 0, len(times) - 2)
    h = times[k + 1] - times[k]
    s = (t - times[k]) / h
    u = 1 - s
    distance = (d[k] * (u**3 + 3 * u * u * s) + v[k] * u * u * s * h
                + d[k + 1] * (3 * u * s * s + s**3) - v[k + 1] * u * s * s * h)  # fmt: skip
    speed = ((u * u - 2 * u * s) * v[k] + (s * s - 2 * u * s) * v[k + 1]
             + 6 * u * s / h * (d[k + 1] - d[k]))  # fmt: skip
    return np.stack([distance, speed])


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
class GapRows:
    """The gap rows of one curve: at ``times[i]``, distance + ``headway[i]`` x speed at
    most ``bound[i]`` (``behind[i]``: behind a leader, ``headway`` its own) or distance at
    least ``bound[i]`` (ahead of an old follower, ``headway`` 0)."""

    times: np.ndarray
    bound: np.ndarray
    behind: np.ndarray
    headway: np.ndarray

    def term(self, index: int, ends: Sequence[float], d: Sequence[Linear],
             v: Sequence[Linear]) -> Linear:  # fmt: skip
        distance, speed = on_piece(ends, d, v, float(self.times[index]))
        return distance + speed * float(self.headway[index]) if self.behind[index] else distance

    def add(self, index: int, program: LinearProgram, ends: Sequence[float],
            d: Sequence[Linear], v: Sequence[Linear]) -> None:  # fmt: skip
        term = self.term(index, ends, d, v)
        if self.behind[index]:
            program.at_most(term, float(self.bound[index]))
        else:
            program.at_least(term, float(self.bound[index]))

    def broken(self, ends: Sequence[float], d: Sequence[Linear], v: Sequence[Linear],
               solution: dict[str, float]) -> set[int]:  # fmt: skip
        """The rows the solution breaks, beyond the LP solver's tolerance."""
        if not len(self.times):
            return set()
        distances = np.array([value_of(term, solution) for term in d])
        speeds = np.array([value_of(term, solution) for term in v])
        distance, speed = _at(np.array(ends), distances, speeds, self.times)
        value = distance + speed * self.headway
        over = np.where(self.behind, value - self.bound, self.bound - value)
        return set(np.flatnonzero(over > ROW_TOLERANCE).tolist())


def gap_rows(
    problem: TimingProblem,
    car: str,
    bounds_v_max: float,
    ends: Sequence[float],
    lows: Sequence[float],
    highs: Sequence[float],
    fitted: dict[str, Curve],
) -> GapRows:
    """The car keeps behind the cars ahead of it and ahead of the old cars behind it, at
    every time step, with FOLLOW_SLACK and the plan's headway: a row per step at which the
    condition can bind (``ends``, ``lows``, ``highs``: the curve's piece ends and the range
    of each one's distance)."""
    steps = round(problem.duration / problem.timestep)
    step_times = np.round(np.arange(1, steps + 1) * problem.timestep, 9)
    ends_array = np.array(ends)
    k = np.clip(np.searchsorted(ends_array, step_times, side="right") - 1, 0, len(ends) - 2)
    high_after, low_at = np.array(highs)[k + 1], np.array(lows)[k]
    found: list[tuple[np.ndarray, np.ndarray, bool, float]] = []
    for follow in problem.follows:
        if car not in (follow.leader, follow.follower):
            continue
        behind = car == follow.follower
        if not behind and not follow.fixed:
            continue  # a symbolic follower keeps behind this car when it is fitted
        other = follow.leader if behind else follow.follower
        places, speeds = _places(follow, other, fitted, step_times)
        gap = follow.gap + FOLLOW_SLACK
        if behind:
            rear = places - follow.leader_length
            bound = rear - gap + follow.follower_line
            keep = rear < follow.parting
            if follow.joined:
                keep &= rear >= 0
            keep &= bound < high_after + follow.headway * bounds_v_max  # else it cannot be there
            found.append((step_times[keep], bound[keep], True, follow.headway))
        else:
            keep = np.ones(len(step_times), dtype=bool)
            if follow.joined:
                keep &= places >= 0  # the old follower has not reached the shared lane
            room = gap + follow.headway * np.maximum(speeds, 0.0)
            needed = np.minimum(follow.parting, places + room)
            least = needed + follow.leader_length + follow.leader_line
            keep &= least > low_at
            found.append((step_times[keep], least[keep], False, 0.0))
    if not found:
        empty = np.zeros(0)
        return GapRows(empty, empty, np.zeros(0, dtype=bool), empty)
    return GapRows(
        np.concatenate([times for times, _, _, _ in found]),
        np.concatenate([bound for _, bound, _, _ in found]),
        np.concatenate([np.full(len(times), behind) for times, _, behind, _ in found]),
        np.concatenate([np.full(len(times), headway) for times, _, _, headway in found]),
    )


def solve_with_gaps(
    program: LinearProgram,
    rows: GapRows,
    ends: Sequence[float],
    d: Sequence[Linear],
    v: Sequence[Linear],
) -> dict[str, float] | None:
    """The optimum of ``program`` that keeps every gap row. Rows are added where the
    optimum without them breaks them, round by round; after GAP_ROUNDS rounds, all of
    them. A relaxation without a solution has none with every row either."""
    chosen: set[int] = set()
    for _ in range(GAP_ROUNDS):
        attempt = program.copy()
        for index in sorted(chosen):
            rows.add(index, attempt, ends, d, v)
        solution = attempt.solve()
        if solution is None:
            return None
        broken = rows.broken(ends, d, v, solution)
        if not broken:
            return solution
        chosen |= broken
    for index in range(len(rows.times)):
        rows.add(index, program, ends, d, v)
    return program.solve()
