"""Step 3 on random timing problems that are solvable by construction (hypothesis).

Each problem comes from real motions: every car drives a random profile of constant
accelerations within the bounds (some stop and stand on the way); its knots are points of
that drive, and the order relations are read off the drive's own times with room to spare.
So a speed profile exists for every problem, and the checks are:

- whatever curves Step 3 returns keep every invariant (a car with its own bounds, a
  pedestrian's, keeps those): distance never decreases, speed in
  [0, v_max], acceleration in [a_min, a_max] (finely differenced), the start speed, standing
  where a knot says, at least v_run where the car runs a sign, and every order relation
  holds between the times the curves pass their knots, with the margin;
- Step 3 never claims a proof that such a problem is impossible.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from dataclasses import dataclass
from fractions import Fraction

import pytest
import z3
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from service.core.generator.linear import Linear, LinearProgram, total, value_of
from service.core.generator.timing import (
    SHARES,
    CarPlan,
    Curve,
    Knot,
    TimingFailure,
    TimingProblem,
    TimingSolution,
    order_core,
    plan_on_speed_grid,
    plan_times,
)
from service.core.generator.timing_curves import stop_lead
from service.core.generator.timing_solve import solve_timing
from service.core.generator.timing_windows import event_windows
from service.core.motion.invariants import motion_fault
from service.core.motion.kinematics import DWELL, Bounds
from service.core.testcase import Params

PARAMS = Params()
PARAMS_BOUNDS = Bounds(PARAMS.v_max, PARAMS.a_max, PARAMS.a_min)
# motion_fault's view of a pedestrian: the walking bounds in a car's parameters
WALKING_PARAMS = Params(
    v_max=PARAMS.walk.v_max, a_max=PARAMS.walk.a_max, a_min=PARAMS.walk.a_min, v_run=1.0
)
DURATION = 20.0
MARGIN = 0.2
STEP = 0.05  # seconds: the drives are integrated this finely


@dataclass(frozen=True)
class Drive:
    """A car's real motion, sampled every STEP: times, distances and speeds."""

    times: list[float]
    distances: list[float]
    speeds: list[float]

    def time_at(self, distance: float) -> float:
        """When the drive first reaches ``distance`` (linear between samples)."""
        for k in range(1, len(self.distances)):
            if self.distances[k] >= distance:
                d0, d1 = self.distances[k - 1], self.distances[k]
                share = 0.0 if d1 == d0 else (distance - d0) / (d1 - d0)
                return self.times[k - 1] + share * STEP
        return math.inf


WALKING = Bounds(PARAMS.walk.v_max, PARAMS.walk.a_max, PARAMS.walk.a_min)


@st.composite
def drives(
    draw: st.DrawFn, start_speed: float | None, stop: bool, bounds: Bounds = PARAMS_BOUNDS
) -> tuple[Drive, float | None]:
    """A motion within ``bounds`` and the distance where it stands (when it stops)."""
    v = start_speed if start_speed is not None else draw(st.floats(0.0, bounds.v_max))
    t, d = 0.0, 0.0
    times, distances, speeds = [0.0], [0.0], [v]
    stand_at = draw(st.floats(4.0, 12.0)) if stop else math.inf
    stood: float | None = None
    while t < DURATION + 1.0:
        accel = draw(st.floats(bounds.a_min * 0.9, bounds.a_max * 0.9))
        for _ in range(draw(st.integers(10, 60))):
            if stood is None and t >= stand_at:
                brake = -bounds.a_min * 0.8
                while v > 0:  # brake to a stand, then stand
                    v = max(0.0, v - brake * STEP)
                    t, d = t + STEP, d + v * STEP
                    times.append(t), distances.append(d), speeds.append(v)
                stood = round(d, 6)  # knots sit on Step 3's micrometre grid
                for _ in range(round(draw(st.floats(DWELL + 0.5, 3.0)) / STEP)):
                    t += STEP
                    times.append(t), distances.append(d), speeds.append(0.0)
                accel = bounds.a_max * 0.8
            v = min(max(v + accel * STEP, 0.0), bounds.v_max)
            t, d = t + STEP, d + v * STEP
            times.append(t), distances.append(d), speeds.append(v)
    return Drive(times, distances, speeds), stood


@st.composite
def problems(draw: st.DrawFn) -> tuple[TimingProblem, dict[str, Drive]]:
    """A timing problem that the drives it was read from solve."""
    cars, drives_of, symbols = [], {}, {}
    for number in range(draw(st.integers(1, 3))):
        name = f"car{number}"
        walking = draw(st.booleans())  # a pedestrian: its own, gentler bounds
        certificate = not walking and draw(st.booleans())
        start = 8.0 if certificate else None
        bounds = WALKING if walking else PARAMS_BOUNDS
        drive, stood = draw(drives(start, stop=draw(st.booleans()), bounds=bounds))
        moments = sorted(draw(st.lists(st.floats(0.5, DURATION - MARGIN - 0.5), min_size=2,
                                       max_size=5, unique=True)))  # fmt: skip
        points: list[float] = []
        for moment in moments:  # points the drive passes in time, a centimetre apart at least
            point = math.floor(drive.distances[round(moment / STEP)] * 1000) / 1000
            late = drive.time_at(point) > DURATION - MARGIN - 0.05
            if point > 0.5 and not late and all(abs(point - p) >= 0.01 for p in points):
                points.append(point)
        points = sorted(p for p in points if stood is None or abs(p - stood) > 0.5)
        knots = [Knot(f"{name}:{k}", p) for k, p in enumerate(points)]
        if stood is not None and drive.time_at(stood) < DURATION - MARGIN - DWELL:
            place = sum(1 for k in knots if k.distance < stood)
            stand = [Knot(f"{name}:stop", stood, stop=True), Knot(None, stood, stop=True)]
            knots[place:place] = stand
        if not knots:
            continue
        for knot in knots:
            if knot.symbol is not None:
                symbols[knot.symbol] = drive.time_at(knot.distance)
        reach = drive.distances[-1]
        cars.append(CarPlan(name, tuple(knots), reach, start, None,
                            bounds=WALKING if walking else None))  # fmt: skip
        drives_of[name] = drive
    fixed = tuple((f"old:{k}", draw(st.floats(1.0, DURATION - 1.0))) for k in range(2))
    known = {**symbols, **dict(fixed)}
    relations = []
    names = sorted(known)
    for a in names:
        for b in names:
            if a >= b or a.split(":")[0] == b.split(":")[0] or not draw(st.booleans()):
                continue
            gap = known[b] - known[a]
            room = PARAMS.m + MARGIN + 0.1
            if gap >= room:
                relations.append(("lessThan", a, b))
            elif -gap >= room:
                relations.append(("lessThan", b, a))
            elif abs(gap) <= PARAMS.m - MARGIN - 0.1:
                relations.append(("equal", a, b))
    problem = TimingProblem(
        cars=tuple(cars), fixed=fixed, relations=tuple(relations), gaps=(),
        duration=DURATION, m=PARAMS.m, margin=MARGIN, a_min=PARAMS.a_min,
        a_max=PARAMS.a_max, v_stop=PARAMS.v_stop, v_run=PARAMS.v_run, v_max=PARAMS.v_max,
    )  # fmt: skip
    return problem, drives_of


def crossing(curve: Curve, distance: float) -> float:
    """When the curve first reaches ``distance`` (bisection; it never backs up)."""
    low, high = 0.0, curve.times[-1]
    if curve.at(high)[0] < distance - 1e-9:
        return math.inf
    for _ in range(60):
        middle = (low + high) / 2
        if curve.at(middle)[0] >= distance - 1e-9:
            high = middle
        else:
            low = middle
    return high


def assert_invariants(problem: TimingProblem, car: CarPlan, curve: Curve) -> None:
    """The curve keeps the car's own bounds (a pedestrian's where it has them)."""
    fine = 0.01
    own = problem.bounds_of(car)
    samples = [curve.at(k * fine) for k in range(round(DURATION / fine) + 1)]
    for (d0, v0), (d1, v1) in itertools.pairwise(samples):
        assert d1 >= d0 - 1e-9, "backs up"
        assert -1e-6 <= v1 <= own.v_max + 1e-6, "speed outside [0, v_max]"
        assert own.a_min - 0.05 <= (v1 - v0) / fine <= own.a_max + 0.05, "acceleration"
    if car.start_speed is not None:
        assert abs(samples[0][1] - car.start_speed) < 1e-6
    assert samples[-1][0] <= car.reach + 1e-6

    @dataclass(frozen=True)
    class Row:
        t: float
        speed: float
        distance: float

    rows: list[Row] = []
    for k in range(round(DURATION / 0.1) + 1):  # as the generator samples and stores it
        distance, speed = curve.at(k * 0.1)
        if rows and rows[-1].distance - 1e-6 < distance < rows[-1].distance:
            distance = rows[-1].distance
        rows.append(Row(round(k * 0.1, 9), round(max(speed, 0.0), 6), round(distance, 6)))
    checked = PARAMS if car.bounds is None else WALKING_PARAMS
    assert motion_fault(rows, checked, 0.1, car.start_speed) is None
    for first, second in zip(car.knots, car.knots[1:], strict=False):
        if first.stop and second.stop:  # a stand: faster than v_stop until just before it
            begin = crossing(curve, first.distance)
            lead = stop_lead(problem.v_stop, own)
            if begin > lead:  # a car that stands (almost) where it starts has no approach
                assert curve.at(begin - lead - 1e-3)[1] > problem.v_stop - 1e-6
            assert abs(curve.at(begin + DWELL / 2)[1]) < 1e-6


def assert_relations_hold(problem: TimingProblem, times: dict[str, float]) -> None:
    """Every order relation holds between ``times`` with its margin (within the plan's
    rounding to 0.1 ms)."""
    for kind, a, b in problem.relations:
        gap = times[b] - times[a]
        if kind == "lessThan":
            assert gap >= problem.m + problem.margin - 1e-3, (kind, a, b, gap)
        else:
            assert abs(gap) <= problem.m - problem.margin + 1e-3, (kind, a, b, gap)


@settings(
    max_examples=30,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
@given(problems())
def test_step3_keeps_every_invariant_on_solvable_problems(
    case: tuple[TimingProblem, dict[str, Drive]],
) -> None:
    problem, _ = case
    result = solve_timing(problem)
    if isinstance(result, TimingFailure):
        assert not result.proved, f"claimed impossible, yet the drives solve it: {result.reason}"
        return
    assert isinstance(result, TimingSolution)
    times: dict[str, float] = dict(problem.fixed)
    for car in problem.cars:
        curve = result.curves[car.car]
        assert_invariants(problem, car, curve)
        for knot in car.knots:
            if knot.symbol is not None:
                times[knot.symbol] = crossing(curve, knot.distance)
    assert_relations_hold(problem, times)


def _transport_like() -> tuple[LinearProgram, Linear, list[Linear]]:
    """A small program with magnitudes in its objective, like Step 3's."""
    program = LinearProgram(4_000_000)
    xs = [program.variable(f"x{k}", 0, 10) for k in range(6)]
    program.at_least(total(xs), 17)
    for a, b in itertools.pairwise(xs):
        program.at_most(a - b, 2)
    cost = total([program.magnitude(x - k / 3) for k, x in enumerate(xs)])
    program.minimize(cost)
    return program, cost, xs


def test_solve_finds_z3s_exact_optimum() -> None:
    """HiGHS's optimum of a linear program is z3's exact optimum (over the rationals) to
    within HiGHS's tolerance, and keeps every constraint."""
    program, cost, xs = _transport_like()
    found = program.solve()
    assert found is not None
    assert program.objective is not None
    exact = z3.Optimize(ctx=z3.Context())
    exact.from_string(program._text(named=False) + f"\n(minimize {program.objective.smt()})")
    assert exact.check() == z3.sat
    model = exact.model()
    best = sum(
        (model[d].as_fraction() for d in model.decls() if d.name().startswith("abs")),
        Fraction(0),
    )
    assert value_of(cost, found) == pytest.approx(float(best), abs=1e-7)
    assert value_of(total(xs), found) >= 17 - 1e-9
    assert all(-1e-9 <= found[f"x{k}"] <= 10 + 1e-9 for k in range(6))


def test_solve_reports_no_solution_and_takes_booleans_to_z3() -> None:
    program, _, xs = _transport_like()
    program.at_most(total(xs), 16)  # against at least 17
    assert program.solve() is None
    assert program.conflict() == []  # no labelled row: the unlabelled ones clash alone
    choosing = LinearProgram(4_000_000)
    x = choosing.variable("x", 0, 10)
    small, large = choosing.choice("size", 2)
    choosing.when([small], None, x, 1)
    choosing.when([large], 9, x, None)
    choosing.when([small], None, Linear(), None)  # small is ruled out
    found = choosing.solve()
    assert found is not None
    assert found["size_1"] == 1.0 and found["x"] >= 9
    choosing.minimize(x)
    with pytest.raises(ValueError, match="Boolean"):
        choosing.solve()


@st.composite
def conflicting_problems(draw: st.DrawFn) -> TimingProblem:
    """A solvable problem with some of its relations turned around or tightened: often
    no speed profile can keep them all, and then Step 3 names the ones that clash."""
    problem, _ = draw(problems())
    relations = list(problem.relations)
    for index in draw(st.lists(st.integers(0, max(len(relations) - 1, 0)), max_size=3)):
        if index < len(relations):
            kind, a, b = relations[index]
            relations[index] = ("lessThan", b, a) if kind == "lessThan" else ("lessThan", a, b)
    return dataclasses.replace(problem, relations=tuple(relations))


@settings(
    max_examples=25,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
@given(conflicting_problems())
def test_step3_cores_name_only_the_problems_own_relations_and_clash_alone(
    problem: TimingProblem,
) -> None:
    """A core is a set of indices into the problem's own relations (Step 2 forbids exactly
    those: issue 43's crash indexed a core into another order's relations), and those
    relations clash by themselves: the problem with only them has no plan either (a
    proved core: not even the necessary conditions; else no speed-grid plan)."""
    result = solve_timing(problem)
    if not isinstance(result, TimingFailure) or not result.core:
        return
    assert all(0 <= i < len(problem.relations) for i in result.core), result.core
    assert len(set(result.core)) == len(result.core)
    alone = dataclasses.replace(problem, relations=tuple(problem.relations[i] for i in result.core))
    if result.proved:
        assert order_core(alone) is not None
    else:
        assert plan_on_speed_grid(alone, SHARES[-1])[0] is None


@settings(
    max_examples=40,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
@given(problems(), st.data())
def test_every_choice_of_times_within_the_windows_keeps_the_order(
    case: tuple[TimingProblem, dict[str, Drive]], data: st.DataObject
) -> None:
    """The curves may pass an event anywhere within its window: any such times (the
    windows' ends drawn at random) keep every relation with its margin (within the plan's
    rounding to 0.1 ms), every car's knots stay in order, a stand keeps its planned time,
    and each window holds the plan's time."""
    problem, _ = case
    planned = plan_times(problem, SHARES[0])
    if planned is None:
        return
    windows = event_windows(problem, planned)
    times: dict[str, float] = dict(problem.fixed)
    for car in problem.cars:
        chosen = []
        for knot, t, (low, high) in zip(car.knots, planned[car.car], windows[car.car],
                                         strict=True):  # fmt: skip
            assert low <= t <= high
            if knot.stop or knot.symbol is None:
                assert low == high == t
            chosen.append(data.draw(st.sampled_from([low, high, (low + high) / 2])))
            if knot.symbol is not None:
                times[knot.symbol] = chosen[-1]
        assert all(a < b for a, b in itertools.pairwise(chosen)), "knots out of order"
        assert all(high <= problem.duration - problem.margin + 1e-9
                   for _, high in windows[car.car])  # fmt: skip
    assert_relations_hold(problem, times)


@settings(max_examples=3, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])  # fmt: skip
@given(problems())
def test_step3_is_remembered_by_problem_and_gives_the_same_answer(
    case: tuple[TimingProblem, dict[str, Drive]],
) -> None:
    """A problem equal to one solved before (a chain's second round draws its first
    answer sets again) gets the remembered answer, and that is the answer solving it
    afresh gives."""
    problem, _ = case
    first = solve_timing(problem)
    hits = solve_timing.cache_info().hits
    again = solve_timing(dataclasses.replace(problem))  # equal, not the same object
    assert again is first
    assert solve_timing.cache_info().hits == hits + 1
    assert solve_timing.__wrapped__(problem) == first
