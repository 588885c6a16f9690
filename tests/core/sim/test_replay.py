"""Replay in libsumo with ego controllers, judged by the checker (real SUMO, no mocks)."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path
from typing import Any

import pytest

from service.core.budget import run_with_budget
from service.core.checker.check import Judge
from service.core.errors import BudgetExceeded, InvalidInput, InvalidTestCase
from service.core.export.bundle import export_bundle
from service.core.generator.additions import candidate_routes
from service.core.generator.extension import extend_testcase
from service.core.motion.poses import centre_to_front, generate_poses, plan_drive, start_front
from service.core.network import parsed_network
from service.core.sim.replay import departures, evaluate
from service.core.testcase import (
    TestCase,
    dump_testcase,
    load_testcase_intersection,
    new_testcase,
    parse_testcase,
)
from tests.conftest import TOWN05, TOWN07
from tests.helpers import car_ahead_of_ego, retime, with_nonegos

pytestmark = pytest.mark.slow  # 14 s of work or more: `make test-fast` leaves it out

DOCS = Path(__file__).resolve().parents[3] / "docs" / "controllers.md"


@pytest.fixture(scope="module")
def y_start() -> TestCase:
    return new_testcase("y-uncontrolled", "N2C_0:C2SE_0", duration=25.0, name="y")


@pytest.fixture(scope="module")
def y_new(y_start: TestCase) -> TestCase:
    return extend_testcase(y_start, ["SW2C_0:C2N_0"], seed=0, budget=120).testcase


@pytest.fixture(scope="module")
def four_way_start() -> TestCase:
    return new_testcase("4way-stop", "E2C_1:C2S_1", duration=25.0, name="left")


def test_a_replayed_certificate_follows_it_exactly(y_new: TestCase) -> None:
    assert y_new.certificates is not None
    for kind in ("solvability", "complexity"):
        evaluation = evaluate(y_new, f"certificate:{kind}")
        recorded = getattr(y_new.certificates, kind)
        # until its goal: there its test is over, and it leaves the simulation at the first
        # step past it (its rear a metre out of the junction)
        passed = departures(y_new, load_testcase_intersection(y_new))[0].goal
        assert passed is not None
        assert evaluation.trajectory[-2].distance < passed <= evaluation.trajectory[-1].distance
        goal = evaluation.verdict.goal_time
        assert goal is not None and goal <= evaluation.trajectory[-1].t < recorded[-1].t
        shown = recorded[: len(evaluation.trajectory)]
        for replayed, original in zip(evaluation.trajectory, shown, strict=True):
            assert replayed.distance == pytest.approx(original.distance, abs=1e-6)
            # the centre comes from SUMO's front bumper and heading; in curves SUMO's heading
            # differs from the interpolated one by tenths of a degree: a few centimetres
            assert math.dist((replayed.x, replayed.y), (original.x, original.y)) < 0.05


def test_a_warm_child_replays_as_a_fresh_one(y_new: TestCase) -> None:
    """Built-in drivers replay in warm children (service.core.sim.replay.REPLAYS), one
    after another in the same process: each replay is the one a fresh child gives."""
    from service.core.sim import replay

    intersection = load_testcase_intersection(y_new)
    controllers = ["sumo", "sumo-rolling-stop", "sumo+rss", "certificate:complexity"]
    warm = [evaluate(y_new, name, intersection) for name in controllers * 2]
    original = replay.REPLAYS.call
    try:
        replay.REPLAYS.call = run_with_budget  # type: ignore[method-assign]
        fresh = [evaluate(y_new, name, intersection) for name in controllers]
    finally:
        replay.REPLAYS.call = original  # type: ignore[method-assign]
    for k, evaluation in enumerate(warm):
        assert evaluation == fresh[k % len(controllers)], controllers[k % len(controllers)]


def test_certificates_pass_and_fail_as_defined(y_start: TestCase, y_new: TestCase) -> None:
    assert evaluate(y_new, "certificate:solvability").verdict.passed
    complexity = evaluate(y_new, "certificate:complexity").verdict
    assert not complexity.passed
    assert complexity.goal_reached and not complexity.collisions
    assert {v.other for v in complexity.violations} == {"car1"}


def test_sumo_stops_at_the_sign_and_passes(four_way_start: TestCase) -> None:
    evaluation = evaluate(four_way_start, "sumo")
    assert evaluation.verdict.passed, evaluation.verdict.reasons
    assert min(s.speed for s in evaluation.trajectory) <= 0.1


@pytest.mark.parametrize("controller", ["sumo-rolling-stop", "sumo-aggressive"])
def test_drivers_that_do_not_stop_fail_the_stop_sign(
    four_way_start: TestCase, controller: str
) -> None:
    verdict = evaluate(four_way_start, controller).verdict
    assert verdict.goal_reached
    assert [v.rule for v in verdict.violations] == ["stopAtSign"]


def test_the_rolling_stop_keeps_rolling(four_way_start: TestCase) -> None:
    trajectory = evaluate(four_way_start, "sumo-rolling-stop").trajectory
    start = four_way_start.ego.start.distance
    approach = [s.speed for s in trajectory if 0 < start - s.distance <= 10.0]
    assert approach and min(approach) >= 2.9


def _write(folder: Path, name: str, code: str) -> None:
    (folder / f"{name}.py").write_text(code)


def test_the_user_controller_from_the_docs_works(
    y_new: TestCase, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    blocks = re.findall(r"```python\n(.*?)```", DOCS.read_text(), re.DOTALL)
    blocks = [block for block in blocks if "class Careful" in block]  # the gym's uses it
    assert len(blocks) == 1
    _write(tmp_path, "careful", blocks[0])
    monkeypatch.chdir(tmp_path)
    evaluation = evaluate(y_new, "careful:Careful")
    assert evaluation.error is None
    assert evaluation.verdict.passed, evaluation.verdict.reasons


def test_a_controller_that_raises_fails_with_the_error(
    y_new: TestCase, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    _write(tmp_path, "broken", "class Broken:\n    def step(self, obs):\n        return 1 / 0\n")
    monkeypatch.chdir(tmp_path)
    verdict = evaluate(y_new, "broken:Broken").verdict
    assert not verdict.passed
    assert "ZeroDivisionError" in verdict.reasons[0]


def test_a_controller_that_hangs_is_stopped_at_the_budget_without_a_verdict(
    y_new: TestCase, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The budget is the caller's limit: running out of it is an error, not a FAIL."""
    _write(
        tmp_path,
        "stuck",
        "class Stuck:\n    def step(self, obs):\n        while True:\n            pass\n",
    )
    monkeypatch.chdir(tmp_path)
    with pytest.raises(BudgetExceeded, match=r"budget of 3 s .*no verdict on stuck:Stuck"):
        evaluate(y_new, "stuck:Stuck", budget=3.0)


def test_a_budget_too_small_for_sumo_is_an_error_not_a_fail(four_way_start: TestCase) -> None:
    # a warm child replays this 25 s test-case in under 10 ms: only a microsecond is
    # surely too small (the answer cannot even be read back in it)
    with pytest.raises(BudgetExceeded, match=r"budget of 1e-06 s .*no verdict on sumo"):
        evaluate(four_way_start, "sumo", budget=1e-6)


def test_a_missing_user_module_fails_with_its_name(y_new: TestCase) -> None:
    verdict = evaluate(y_new, "no_such_module:Controller").verdict
    assert not verdict.passed and "no_such_module" in verdict.reasons[0]


def test_unknown_controller_names_the_choices(y_new: TestCase) -> None:
    with pytest.raises(InvalidInput, match="sumo-cautious"):
        evaluate(y_new, "autopilot")


def test_certificates_need_a_generated_testcase(y_start: TestCase) -> None:
    with pytest.raises(InvalidInput, match="has none"):
        evaluate(y_start, "certificate:solvability")


def test_a_controller_registered_by_entry_point_is_found_by_name(
    y_new: TestCase, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Registration through package metadata (faked here: installing a package is out of a
    test's reach); the replay itself is real."""
    from importlib.metadata import EntryPoint

    import service.core.sim.controllers as controllers

    registered = [EntryPoint("steady", "steady:Steady", controllers.ENTRY_POINT_GROUP)]
    monkeypatch.setattr(controllers, "entry_points", lambda group: registered)
    _write(tmp_path, "steady", "class Steady:\n    def step(self, obs):\n        return 0.0\n")
    monkeypatch.chdir(tmp_path)
    assert "steady" in controllers.controller_names()
    evaluation = evaluate(y_new, "steady")
    assert evaluation.error is None
    assert evaluation.verdict.controller == "steady"
    # constant speed through the junction: it reaches its exit without stopping anywhere
    assert evaluation.verdict.goal_reached
    assert min(s.speed for s in evaluation.trajectory) > 7.9


@pytest.mark.parametrize(
    ("network", "junction", "control", "ego"),
    [
        (TOWN07, "358", "right_before_left", "-40_0:35_0"),  # fork lane 26.85 m
        (TOWN05, "2062", "allway_stop", "-27_0:-28_0"),  # the start 7.5 m into a junction
    ],
)
def test_a_start_inside_an_upstream_junction_is_replayed_and_exported(
    network: Path, junction: str, control: str, ego: str, tmp_path: Path
) -> None:
    """With the default start (30 m) the ego, and the new car, start on internal lanes of
    the junction before: SUMO inserts them before it and moves them onto their start."""
    start = new_testcase(network, ego, junction=junction, control=control, duration=25.0)
    intersection = load_testcase_intersection(start)
    route = intersection.route(ego)
    assert plan_drive(intersection, route, 30.0, 8.0, 25.0, 0.1).start_on is not None
    new = candidate_routes(start, intersection)[0]
    extended = extend_testcase(start, [new], seed=0, budget=120).testcase
    evaluation = evaluate(extended, "sumo", intersection)
    assert evaluation.error is None and not evaluation.verdict.errors
    first = evaluation.trajectory[0]
    front = centre_to_front(first.x, first.y, first.heading, extended.ego.length)
    expected = start_front(intersection, route, 30.0)
    assert math.dist(front, expected) < 0.05
    assert first.distance == 0.0
    assert evaluate(extended, "certificate:solvability", intersection).verdict.passed
    harder = evaluate(extended, "certificate:complexity", intersection).verdict
    assert harder.goal_reached and not harder.collisions
    assert {v.other for v in harder.violations} == {"car1"}
    export_bundle(extended, tmp_path, intersection)
    assert "moveTo('ego'" in (tmp_path / "README.md").read_text()


def test_a_car_starting_fast_after_an_upstream_junction_is_inserted_at_once() -> None:
    """Town07 358 with the ego 60 m out: the new car starts on lane 43_0 at about 6 m/s just
    after a junction where it must yield. SUMO's insertion checks would hold it back
    ("unpriorised junction too close") and the replay would lose it; the test-case fixes
    every start, so the checks are off and every car is on the map from the first step
    (the runner fails the replay when one is not)."""
    start = new_testcase(TOWN07, "-40_0:35_0", junction="358", control="right_before_left",
                         start_distance=60.0, duration=25.0)  # fmt: skip
    extended = extend_testcase(start, ["41_0:35_0"], seed=0, budget=120).testcase
    intersection = load_testcase_intersection(extended)
    for controller in ("sumo", "certificate:solvability"):
        evaluation = evaluate(extended, controller, intersection)
        assert evaluation.error is None and not evaluation.verdict.errors
        assert evaluation.verdict.passed, evaluation.verdict.reasons


RECORDER = """
import json

import libsumo


class Recorder:
    \"\"\"Brakes to a stand, waits there until GO s, then drives on at 4 m/s; writes down
    what it is told, what SUMO's getLeader says and every non-ego's lane at each step.\"\"\"

    def step(self, obs):
        leader = obs.leader
        record = {
            "t": obs.t,
            "distance": obs.distance,
            "leader": None if leader is None else [leader.id, leader.gap, leader.speed],
            "sumo": libsumo.vehicle.getLeader("ego", 100.0),
            "min_gap": libsumo.vehicle.getMinGap("ego"),
            "lanes": {o.id: libsumo.vehicle.getLaneID(o.id) for o in obs.others},
        }
        with open(OUT, "a") as out:
            out.write(json.dumps(record) + "\\n")
        if obs.t < GO:
            return obs.a_min
        return 1.5 if obs.ego.speed < 4.0 else 0.0
"""


def _record_observations(testcase: TestCase, go: float, folder: Path) -> list[dict[str, Any]]:
    """Replay ``testcase`` with the recorder driving the ego; what it wrote, step by step."""
    out = folder / "observations.jsonl"
    _write(folder, "recorder", f"GO = {go!r}\nOUT = {str(out)!r}\n" + RECORDER)
    evaluation = evaluate(testcase, "recorder:Recorder")
    assert evaluation.error is None
    return [json.loads(line) for line in out.read_text().splitlines()]


def _check_sumo_gap(record: dict[str, Any]) -> None:
    """Where SUMO's getLeader names the same car, the gap is its distance plus the ego's
    minGap (SUMO measures from the ego's front plus its minGap)."""
    assert record["min_gap"] > 0
    sumo = record["sumo"]
    if sumo is not None and sumo[0] == record["leader"][0]:
        assert record["leader"][1] == pytest.approx(sumo[1] + record["min_gap"], abs=1e-6)


def test_the_leader_is_the_car_ahead_on_the_fork(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The queue of docs/rules.md: car1 starts ahead of the ego and goes straight on where the ego
    turns right. Its gap (rear bumper to the ego's front) agrees with the test-case's
    trajectory while its rear is on the fork; once its rear is on its own connecting lane,
    nobody is ahead of the ego."""
    case = car_ahead_of_ego()
    monkeypatch.chdir(tmp_path)
    records = _record_observations(case, 9.0, tmp_path)
    car = case.nonegos[0]
    ahead = Judge(case).nonegos[0].in_queue  # places on the fork: distance - line
    gaps, left = [], 0
    for record in records:
        step = round(record["t"] / case.timestep)
        if step >= len(car.trajectory):  # car1 has left the map: nobody is ahead
            assert record["leader"] is None, record
            continue
        sample = car.trajectory[step]
        rear = sample.distance - ahead.line - ahead.length  # metres past the stop line
        if rear > 0.5:
            assert record["leader"] is None, record
            left += 1
        elif rear < -0.5:
            expected = rear - (record["distance"] - case.ego.start.distance)
            leader, gap, speed = record["leader"]
            assert leader == car.id
            assert gap == pytest.approx(expected, abs=0.5)
            assert speed == pytest.approx(sample.speed, abs=0.5)
            _check_sumo_gap(record)
            gaps.append(gap)
    assert left and gaps
    closest = min(range(len(gaps)), key=gaps.__getitem__)
    assert gaps[closest] < gaps[0] - 1.0 < gaps[-1] - 2.0  # the ego closes in, then car1 pulls away


def _merging_case() -> TestCase:
    """The ego (E2C_0:C2N_0, 30 m out) and "merge" from the south (S2C_0:C2N_0, 10 m out,
    5 m/s throughout), which crosses into the ego's exit lane while the ego waits."""
    base = new_testcase("4way-stop", "E2C_0:C2N_0", duration=20.0)
    junction = load_testcase_intersection(base)
    (track,) = generate_poses(junction, [(junction.route("S2C_0:C2N_0"), 10.0)], 5.0, 20.0, 0.1)
    samples = retime(track, lambda t: (5.0 * t, 5.0), 20.0, 0.1)
    return with_nonegos(base, [("merge", "S2C_0:C2N_0", samples)])


def test_a_merging_car_is_the_leader_once_on_the_ego_lane(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """No leader while the car is on its own fork and connecting lane (SUMO's getLeader can
    name it there, as a car to yield to); once it is on the ego's exit lane, it is."""
    case = _merging_case()
    junction = load_testcase_intersection(case)

    def on_exit(route: str, start: float, distance: float) -> float:
        """Metres of a front from the start of the exit lane (negative: before it)."""
        lane = junction.connecting_lanes[junction.route(route).connecting_lane]
        return distance - start - lane.centreline.length

    monkeypatch.chdir(tmp_path)
    records = _record_observations(case, 8.0, tmp_path)
    before = after = 0
    for record in records:
        lane = record["lanes"]["merge"]
        if lane in ("S2C_0", ":C_9_0"):
            assert record["leader"] is None, record
            before += 1
        elif lane == "C2N_0":
            sample = case.nonegos[0].trajectory[round(record["t"] / case.timestep)]
            rear = on_exit("S2C_0:C2N_0", 10.0, sample.distance) - 5.0
            expected = rear - on_exit(case.ego.route.id, 30.0, record["distance"])
            assert record["leader"] is not None and record["leader"][0] == "merge", record
            assert record["leader"][1] == pytest.approx(expected, abs=0.5)
            _check_sumo_gap(record)
            after += 1
    assert before and after


STAND = """
import json


class Stand:
    \"\"\"Brakes and stands; writes down which other cars it is shown at each step.\"\"\"

    def step(self, obs):
        with open(OUT, "a") as out:
            out.write(json.dumps({"t": obs.t, "others": [o.id for o in obs.others]}) + "\\n")
        return obs.a_min
"""


def test_a_user_controller_is_no_longer_shown_a_car_that_left(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A car whose trajectory ends before the test-case does has left the map there: the
    replay removes it from SUMO and from what the controller observes at that very step
    (it was still shown, and SUMO refused the replay: Vehicle 'gone' is not known)."""
    base = new_testcase("4way-stop", "E2C_0:C2N_0", duration=8.0)
    junction = load_testcase_intersection(base)
    (track,) = generate_poses(junction, [(junction.route("S2C_0:C2N_0"), 10.0)], 5.0, 8.0, 0.1)
    samples = retime(track, lambda t: (5.0 * t, 5.0), 4.0, 0.1)  # its last sample at 4 s
    case = with_nonegos(base, [("gone", "S2C_0:C2N_0", samples)])
    out = tmp_path / "seen.jsonl"
    _write(tmp_path, "stand", f"OUT = {str(out)!r}\n" + STAND)
    monkeypatch.chdir(tmp_path)
    evaluation = evaluate(case, "stand:Stand")
    assert evaluation.error is None
    assert not evaluation.verdict.goal_reached  # it stood, and was judged for it
    seen = [json.loads(line) for line in out.read_text().splitlines()]
    assert seen[-1]["t"] == pytest.approx(7.9)  # every step was observed, to the end
    assert {tuple(r["others"]) for r in seen if r["t"] < 3.95} == {("gone",)}
    assert {tuple(r["others"]) for r in seen if r["t"] > 3.95} == {()}


def test_a_car_that_starts_faster_than_its_lane_allows_replays() -> None:
    """The outside test's case: a non-ego starts at 14.09 m/s on N2C (limit 13.89 m/s; a
    generated car may, up to v_max). The non-egos follow their trajectories, not the lanes'
    limits, and SUMO accepts them."""
    base = new_testcase("4way-stop", "S2C_0:C2N_0", duration=30.0)
    junction = load_testcase_intersection(base)
    (track,) = generate_poses(junction, [(junction.route("N2C_0:C2S_0"), 60.0)], 8.0, 30.0, 0.1)

    def braking(t: float) -> tuple[float, float]:  # 14.09 m/s, braking at 2 m/s² to 5 m/s
        slow = min(t, (14.09 - 5.0) / 2.0)
        return 14.09 * slow - slow * slow + 5.0 * (t - slow), 14.09 - 2.0 * slow

    case = with_nonegos(base, [("fast", "N2C_0:C2S_0", retime(track, braking, 12.0, 0.1))])
    net = parsed_network(junction.network_file)
    assert case.nonegos[0].trajectory[0].speed > net.getLane("N2C_0").getSpeed()
    evaluation = evaluate(case, "sumo", junction)
    assert evaluation.error is None and not evaluation.verdict.errors


def test_an_ego_faster_than_its_lane_allows_is_the_users_error() -> None:
    """SUMO would refuse to insert the ego: the replay and the generator say so, naming the
    lane and its limit, instead of crashing."""
    document = json.loads(dump_testcase(new_testcase("4way-stop", "S2C_0:C2N_0")))
    document["ego"]["start"]["speed"] = 14.5  # within v_max (15), above the lane's 13.89
    fast = parse_testcase(document)
    with pytest.raises(InvalidTestCase, match=r"speed limit of lane '[^']+' .*13\.89 m/s"):
        evaluate(fast, "sumo")
    with pytest.raises(InvalidTestCase, match=r"speed limit of lane"):
        extend_testcase(fast, ["W2C_0:C2E_0"], seed=0, budget=60)
