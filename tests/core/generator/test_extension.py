"""The generator end to end: real SUMO, clingo and z3; every result checked independently."""

from __future__ import annotations

import itertools
import json
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

from service.core.checker.check import check_testcase
from service.core.errors import (
    InvalidInput,
    InvalidTestCase,
    NoMoreComplexTestCase,
    NoneFound,
    UnknownRoute,
)
from service.core.generator import search
from service.core.generator.extension import Extension, extend_testcase
from service.core.generator.ordering import (
    Ordering,
    OrderingSearch,
)
from service.core.generator.search import ExtensionSearch
from service.core.generator.timing import TimingFailure, TimingProblem
from service.core.generator.verification import verify_extension
from service.core.motion.invariants import motion_fault
from service.core.motion.poses import PoseSample
from service.core.testcase import (
    TestCase,
    dump_testcase,
    implausible_trajectories,
    load_testcase_intersection,
    new_testcase,
    parse_testcase,
)
from tests.conftest import TOWN07
from tests.helpers import off_road_samples, with_nonegos


def samples(rows: list) -> list[PoseSample]:  # type: ignore[type-arg]
    return [PoseSample(**row.model_dump()) for row in rows]


def assert_strictly_more_complex(old: TestCase, new: TestCase) -> None:
    """The certificates do what they claim, judged by the checker alone."""
    assert new.certificates is not None
    solvability = check_testcase(new, samples(new.certificates.solvability), "solvability")
    assert solvability.passed, solvability.reasons
    complexity = samples(new.certificates.complexity)
    on_old = check_testcase(old, complexity, "complexity")
    assert on_old.passed, on_old.reasons
    on_new = check_testcase(new, complexity, "complexity")
    assert not on_new.passed
    assert on_new.goal_reached and not on_new.collisions
    added = {n.id for n in new.road_users} - {n.id for n in old.road_users}
    assert on_new.violations and all(v.other in added for v in on_new.violations)
    # Old non-egos (cars and pedestrians) are kept exactly: the solutions are a subset.
    assert new.nonegos[: len(old.nonegos)] == old.nonegos
    assert new.pedestrians[: len(old.pedestrians)] == old.pedestrians
    assert implausible_trajectories(new) == []  # every car and certificate drivable
    assert off_road_samples(new) == []  # no car or certificate off the network


@pytest.fixture(scope="module")
def y_start() -> TestCase:
    return new_testcase("y-uncontrolled", "N2C_0:C2SE_0", duration=25.0, name="y")


@pytest.fixture(scope="module")
def y_extension(y_start: TestCase) -> Extension:
    return extend_testcase(y_start, ["SW2C_0:C2N_0", "SE2C_0:C2N_0"], seed=0, budget=120)


def test_y_junction_adds_a_conflicting_and_a_free_car(
    y_start: TestCase, y_extension: Extension
) -> None:
    new = y_extension.testcase
    assert [(n.id, n.route.id, n.added_in) for n in new.nonegos] == [
        ("car1", "SW2C_0:C2N_0", 1),
        ("car2", "SE2C_0:C2N_0", 1),
    ]
    assert_strictly_more_complex(y_start, new)
    provenance = new.provenance or {}
    assert provenance["new_nonegos"] == ["car1", "car2"]
    assert provenance["parent"] and provenance["seed"] == 0
    assert provenance["complexity_certificate_violates"]


def test_new_cars_keep_the_bounds(y_extension: Extension) -> None:
    params = y_extension.testcase.params
    for car in y_extension.testcase.nonegos:
        trajectory = car.trajectory
        assert len(trajectory) == round(y_extension.testcase.duration / 0.1) + 1
        for a, b in itertools.pairwise(trajectory):
            assert b.distance >= a.distance - 1e-6  # never backs up
            assert (b.speed - a.speed) / 0.1 <= params.a_max + 0.05
            assert (b.speed - a.speed) / 0.1 >= params.a_min - 0.05
        assert max(s.speed for s in trajectory) <= params.v_max + 1e-6


def test_same_seed_gives_the_same_bytes(y_start: TestCase, y_extension: Extension) -> None:
    again = extend_testcase(y_start, ["SW2C_0:C2N_0", "SE2C_0:C2N_0"], seed=0, budget=120)
    assert dump_testcase(again.testcase) == dump_testcase(y_extension.testcase)


def test_certificates_pass_scengen_check_as_a_separate_process(
    y_start: TestCase, y_extension: Extension, tmp_path: Path
) -> None:
    old_file, new_file = tmp_path / "old.json", tmp_path / "new.json"
    old_file.write_text(dump_testcase(y_start))
    new_file.write_text(dump_testcase(y_extension.testcase))
    certificates = y_extension.testcase.certificates
    assert certificates is not None
    for name, rows in (("solvability", certificates.solvability),
                       ("complexity", certificates.complexity)):  # fmt: skip
        (tmp_path / f"{name}.json").write_text(json.dumps([r.model_dump() for r in rows]))

    def check(testcase: Path, certificate: str) -> int:
        command = [sys.executable, "-m", "service", "check", str(testcase), "--ego",
                   str(tmp_path / f"{certificate}.json")]  # fmt: skip
        return subprocess.run(command, capture_output=True, check=False).returncode

    assert check(new_file, "solvability") == 0
    assert check(old_file, "complexity") == 0
    assert check(new_file, "complexity") == 1


def test_four_way_car_from_the_left(tmp_path: Path) -> None:
    start = new_testcase("4way-stop", "S2C_1:C2W_1", duration=25.0)
    new = extend_testcase(start, ["W2C_0:C2E_0"], seed=0, budget=120).testcase
    assert_strictly_more_complex(start, new)


UNSEEN = Path(__file__).parents[2] / "data" / "junctions"


@pytest.mark.parametrize(
    ("junction", "ego", "route"),
    [
        ("skewed-allway", "ENE2C_0:C2SSW_0", "WSW2C_0:C2ENE_0"),
        ("skewed-allway", "N2C_0:C2ENE_0", "SSW2C_0:C2N_0"),
        ("y-uneven", "ESE2C_0:C2SW_0", "N2C_0:C2ESE_0"),
        ("y-uneven", "N2C_0:C2ESE_0", "SW2C_0:C2N_0"),
    ],
)
def test_junctions_no_constant_was_tuned_on_get_verified_extensions(
    junction: str, ego: str, route: str
) -> None:
    start = new_testcase(UNSEEN / f"{junction}.net.xml", ego, junction="C", duration=30.0)
    extension = extend_testcase(start, [route], seed=0, budget=120)
    assert_strictly_more_complex(start, extension.testcase)
    assert_motion_invariants(extension.testcase)
    assert_new_cars_cross_without_stalling(extension.testcase)


def assert_new_cars_cross_without_stalling(testcase: TestCase) -> None:
    """A new car leaves its connecting lane at most (its length inside) / v_run after it
    entered the junction: it does not stall inside."""
    intersection = load_testcase_intersection(testcase)
    for car in testcase.nonegos:
        if car.added_in != max_level(testcase):
            continue
        lane = intersection.route(car.route.id).connecting_lane
        entered = next(e for e in car.events if e.kind == "entered")
        left = next(e for e in car.events if e.kind == "left_lane" and e.lane == lane)
        longest = (left.distance - entered.distance) / testcase.params.v_run
        assert left.t - entered.t <= longest + 2 * testcase.timestep, car.id


def assert_motion_invariants(testcase: TestCase) -> None:
    """Every generated trajectory keeps the invariants, judged on its samples alone."""
    assert testcase.certificates is not None
    generated = [n.trajectory for n in testcase.nonegos if n.added_in == max_level(testcase)]
    generated += [testcase.certificates.solvability, testcase.certificates.complexity]
    for index, rows in enumerate(generated):
        start = testcase.ego.start.speed if index >= len(generated) - 2 else None
        assert motion_fault(rows, testcase.params, testcase.timestep, start) is None


def max_level(testcase: TestCase) -> int:
    return max(n.added_in for n in testcase.nonegos)


def test_routes_that_never_meet_the_ego_have_no_extension() -> None:
    start = new_testcase("4way-stop", "S2C_1:C2W_1")
    with pytest.raises(NoMoreComplexTestCase, match="none of them crosses or merges"):
        extend_testcase(start, ["E2C_0:C2N_0"], budget=30)


@pytest.mark.parametrize(
    ("routes", "error", "message"),
    [
        (["S2C_1:C2E_1"], UnknownRoute, "no connection from fork 'S2C_1'"),
        ([], InvalidInput, "at least one new route"),
    ],
)
def test_bad_routes_are_refused(routes: list[str], error: type[Exception], message: str) -> None:
    start = new_testcase("4way-stop", "S2C_1:C2W_1")
    with pytest.raises(error, match=message):
        extend_testcase(start, routes, budget=30)


def test_old_testcase_that_fails_its_own_checks_is_refused(y_extension: Extension) -> None:
    document = json.loads(dump_testcase(y_extension.testcase))
    document["certificates"]["solvability"] = document["certificates"]["complexity"]
    broken = parse_testcase(document)
    with pytest.raises(InvalidTestCase, match="fails its own checks"):
        extend_testcase(broken, ["SE2C_0:C2SW_0"], budget=30)


def test_a_tiny_budget_is_honoured() -> None:
    start = new_testcase("4way-stop", "S2C_1:C2W_1", duration=25.0)
    started = time.monotonic()
    ran_out = r"budget exhausted: the budget of 0\.01 s ran out"
    with pytest.raises(NoneFound, match=ran_out) as error:
        extend_testcase(start, ["W2C_0:C2E_0", "N2C_0:C2S_0", "E2C_1:C2S_1"], budget=0.01)
    assert error.value.context["budget_exhausted"] is True
    # The budget is checked between the steps and between answer sets; Step 1 (a SUMO
    # process) takes about half a second alone, several on a loaded machine (CI ran over
    # 4 s with two test workers and two busy loops): a bound against a hang, not a timing.
    assert time.monotonic() - started < 0.01 + 20.0


def test_an_automatic_start_is_fitted_to_the_road_before_the_fork(cache_dir: Path) -> None:
    """Town07 725: the ego starts 30 m up 15_0; the new car's automatic start (where the ego
    starts) does not fit on the 17.91 m before fork -26#1_0, so it starts at the road's
    far end, and the provenance says so; a start the user gives is still refused."""
    old = new_testcase(TOWN07, "15_0:14_0", "725", "allway_stop", cache_dir=cache_dir)
    junction = load_testcase_intersection(old, cache_dir)
    said: list[str] = []
    new = extend_testcase(old, ["-26#1_0:14_0"], seed=0, budget=120, intersection=junction,
                          progress=said.append).testcase  # fmt: skip
    assert_strictly_more_complex(old, new)
    assert new.provenance is not None
    assert new.provenance["shortened_starts"] == [
        {"car": "car1", "route": "-26#1_0:14_0", "automatic": 30.0, "start": 17.91}
    ]
    assert said[0] == ("car1 (-26#1_0:14_0): the road before its fork is 17.91 m long, so its "
                       "automatic start is 17.91 m before the line, not 30 m")  # fmt: skip
    with pytest.raises(InvalidInput, match=r"start distance 30 m is longer than the road"):
        extend_testcase(old, ["-26#1_0:14_0"], start_distance=30.0, intersection=junction)


def test_each_order_of_both_search_rounds_is_timed_by_its_own_problem(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Issue 43's crash: the search runs a round at 70 % of the bounds, then one at all of
    them, and each round numbers its answer sets from 0. Step 3's problems were kept by that
    number, so the second round timed an order with another order's problem and indexed
    its core into the wrong relations (an IndexError on Town03, silently wrong cores
    elsewhere). Here the new car must come 50 m in a 14.4 s test-case, and the first
    round's orders are refused as Step 3 refuses one it cannot time (with a core), so the
    second round draws more. (Since Step 1's poses are 0.1 m apart, Step 3 times the first
    round's order here, and no case tried fails a first round by itself.) The order
    search, and Step 3 of the second round, run for real; the spies record what they were
    given."""
    drawn: list[tuple[int, Ordering]] = []
    first: list[Ordering] = []
    rounds: list[OrderingSearch] = []
    timing: list[tuple[Ordering, TimingProblem]] = []
    current: list[Ordering] = []
    next_ordering, attempt = OrderingSearch.next_ordering, ExtensionSearch.attempt
    solve = search.solve_timing

    def drawing(self: OrderingSearch) -> Ordering | None:
        if self not in rounds:
            rounds.append(self)
        found = next_ordering(self)
        if found is not None:
            drawn.append((rounds.index(self), found))
            if rounds.index(self) == 0:
                first.append(found)
        return found

    def attempting(self: ExtensionSearch, ordering: Ordering, *args: Any, **kwargs: Any) -> Any:
        current[:] = [ordering]
        return attempt(self, ordering, *args, **kwargs)

    def solving(problem: TimingProblem) -> Any:
        timing.append((current[0], problem))
        if current[0] in first:  # refused as Step 3 refuses an order it cannot time
            return TimingFailure("no speed profile within 85 % of the bounds", (0,))
        return solve(problem)

    monkeypatch.setattr(OrderingSearch, "next_ordering", drawing)
    monkeypatch.setattr(ExtensionSearch, "attempt", attempting)
    monkeypatch.setattr(search, "solve_timing", solving)
    old = new_testcase("4way-stop", "S2C_1:C2W_1", duration=14.4)
    new = extend_testcase(old, ["W2C_1:C2E_1"], start_distance=50.0).testcase
    assert {number for number, _ in drawn} == {0, 1}, "both rounds draw answer sets"
    second = [ordering for number, ordering in drawn if number == 1]
    assert any(ordering in second for ordering, _ in timing), "the second round is timed"
    for ordering, problem in timing:
        assert problem.relations == ordering.named
    assert_strictly_more_complex(old, new)


def test_a_certificate_that_collides_after_its_goal_is_not_verified(
    y_start: TestCase, y_extension: Extension
) -> None:
    """The pass-fail criteria end with the goal, but a certificate collides with nobody
    over its whole trajectory: a car standing on the ego's exit lane, where the
    solvability certificate gets 4 s after its goal, leaves the certificate passing and
    the candidate refused."""
    new = y_extension.testcase
    junction = load_testcase_intersection(new)
    ids = [n.id for n in new.nonegos]
    assert verify_extension(y_start, new, junction, ids) is None
    assert new.certificates is not None
    solvability = samples(new.certificates.solvability)
    goal = check_testcase(new, solvability, "solvability").goal_time
    assert goal is not None
    there = next(s for s in solvability if s.t >= goal + 4.0)
    standing = [PoseSample(round(k * new.timestep, 6), there.x, there.y, there.heading, 0.0, 0.0)
                for k in range(len(solvability))]  # fmt: skip
    blocked = with_nonegos(new, [("car9", "SW2C_0:C2SE_0", standing)])
    verdict = check_testcase(blocked, solvability, "solvability")
    assert verdict.passed and [c.other for c in verdict.after_goal_collisions] == ["car9"]
    late = verdict.after_goal_collisions[0]
    assert verify_extension(y_start, blocked, junction, [*ids, "car9"]) == (
        f"solvability certificate collides with car9 at {late.t:.2f} s, after its goal "
        "in the new test-case"
    )
