"""The judgement ends with the goal: what happens after it is information, not failure.

Real SUMO drives (Step 1 poses) on the bundled four-way stop, retimed by hand, judged by the
real checker. The ego goes straight on (S2C_0:C2N_0), stops at the line, and then stands on
its exit lane; car1 follows it on its fork and runs into it there, or into it before its
goal. The timings were chosen with the events printed; each comment says what happens.
"""

from __future__ import annotations

import json
from xml.etree import ElementTree as ET

import numpy as np
import pytest

from service.cli.output import print_verdict
from service.core.checker.check import check_testcase, judged_samples
from service.core.checker.verdict import REAR_END, Verdict, junit_report
from service.core.motion.poses import PoseSample, PoseTrack, generate_poses
from service.core.network import Intersection, load_intersection
from service.core.testcase import TestCase, new_testcase
from tests.helpers import drive_with_stops, retime, with_nonegos

START = 40.0  # the ego's front 40 m before its stop line
LINE = START - 0.5
DURATION = 25.0
EGO_ROUTE = "S2C_0:C2N_0"  # straight on; its connecting lane is 20.8 m long
BEHIND = 100.0  # car1 starts 100 m before the same stop line
# the ego stops at the line, drives through and stands with its front 35 m past the line
# (its rear 9.2 m past where it left the junction, from about 14 s to the end)
STANDS = [(LINE, 0.5), (START + 35.0, 100.0)]


@pytest.fixture(scope="module")
def four_way() -> Intersection:
    return load_intersection("4way-stop")


@pytest.fixture(scope="module")
def tracks(four_way: Intersection) -> dict[tuple[str, float], PoseTrack]:
    requests = [(four_way.route(EGO_ROUTE), START), (four_way.route(EGO_ROUTE), BEHIND),
                (four_way.route("E2C_0:C2W_0"), START)]  # fmt: skip
    drives = generate_poses(four_way, requests, 8.0, DURATION, 0.1)
    return {(track.route, track.start_distance): track for track in drives}


def _samples(
    track: PoseTrack, stops: list[tuple[float, float]], cruise: float = 8.0
) -> list[PoseSample]:
    return retime(track, drive_with_stops(stops, cruise, start_speed=cruise), DURATION, 0.1)


def _testcase(car: str, samples: list[PoseSample]) -> TestCase:
    base = new_testcase("4way-stop", EGO_ROUTE, start_distance=START, duration=DURATION)
    return with_nonegos(base, [("car1", car, samples)])


def _ego(tracks: dict[tuple[str, float], PoseTrack]) -> list[PoseSample]:
    return _samples(tracks[(EGO_ROUTE, START)], STANDS)


def test_a_collision_after_the_goal_is_information_not_failure(
    tracks: dict[tuple[str, float], PoseTrack], four_way: Intersection
) -> None:
    # car1 cruises at 8 m/s through the junction behind the ego and runs into it where it
    # stands on its exit lane, about 4 s after its goal: the ego could not avoid it
    car1 = _samples(tracks[(EGO_ROUTE, BEHIND)], [])
    verdict = check_testcase(_testcase(EGO_ROUTE, car1), _ego(tracks), "x", four_way)
    assert verdict.goal_time is not None and 11.0 < verdict.goal_time < 13.0
    assert verdict.passed, verdict.reasons
    assert verdict.collisions == () and verdict.reasons == []
    [late] = verdict.after_goal_collisions
    assert late.other == "car1" and late.kind == REAR_END
    assert late.t > verdict.goal_time + 3.0
    assert verdict.judged_until == verdict.goal_time
    assert verdict.information == [f"after its goal (not judged): {late.describe()}"]
    # nothing after the goal counts in how close it came either: car1 touched it later
    assert verdict.criticality is not None and verdict.criticality.distance is not None
    assert verdict.criticality.distance.value > 0.0
    assert verdict.criticality.distance.t <= verdict.goal_time


def test_a_collision_before_the_goal_still_fails(
    tracks: dict[tuple[str, float], PoseTrack], four_way: Intersection
) -> None:
    # car1 at 12 m/s reaches the ego while it pulls away from the stop line (about 8 s)
    car1 = _samples(tracks[(EGO_ROUTE, BEHIND)], [], cruise=12.0)
    verdict = check_testcase(_testcase(EGO_ROUTE, car1), _ego(tracks), "x", four_way)
    assert verdict.goal_reached and not verdict.passed
    [hit] = verdict.collisions
    assert hit.other == "car1" and hit.kind == REAR_END and hit.t < 9.0
    assert verdict.after_goal_collisions == ()
    assert verdict.reasons == [hit.describe()] and verdict.information == []


def test_a_crossing_car_hitting_the_ego_as_it_leaves_the_junction_fails_it(
    tracks: dict[tuple[str, float], PoseTrack], four_way: Intersection
) -> None:
    # car1 crosses from the east after waiting 2.9 s at its line and clips the ego's rear
    # when the ego's front is already half a metre past the exit line: its rear is still in
    # the junction, so this is before its goal, and judged
    car1 = _samples(tracks[("E2C_0:C2W_0", START)], [(LINE, 2.9)])
    ego = _ego(tracks)
    verdict = check_testcase(_testcase("E2C_0:C2W_0", car1), ego, "x", four_way)
    [hit] = verdict.collisions
    connecting = four_way.route(EGO_ROUTE).connecting_lane
    exit_line = START + four_way.connecting_lanes[connecting].centreline.length
    front = np.interp(hit.t, [s.t for s in ego], [s.distance for s in ego])
    assert front > exit_line  # past the exit line with its front, not yet out
    assert verdict.goal_time is not None and hit.t < verdict.goal_time
    assert not verdict.passed and verdict.after_goal_collisions == ()


def test_the_goal_is_where_the_rear_has_left_the_junction(
    tracks: dict[tuple[str, float], PoseTrack], four_way: Intersection
) -> None:
    """The goal (the judgement's end) is the ego's last event at the junction: its exit,
    its whole rectangle out; its front is then a car's length past the exit line."""
    ego = _ego(tracks)
    verdict = check_testcase(_testcase(EGO_ROUTE, _samples(tracks[(EGO_ROUTE, BEHIND)], [])),
                             ego, "x", four_way)  # fmt: skip
    assert verdict.goal_time is not None
    assert max(e.t for e in verdict.ego_events) == verdict.goal_time
    assert verdict.ego_events[-1].kind == "exited"
    connecting = four_way.route(EGO_ROUTE).connecting_lane
    exit_line = START + four_way.connecting_lanes[connecting].centreline.length
    front = np.interp(verdict.goal_time, [s.t for s in ego], [s.distance for s in ego])
    assert front == pytest.approx(exit_line + 5.0, abs=0.05)


def test_judged_samples_end_at_the_judgements_end() -> None:
    samples = [PoseSample(0.1 * k, 0.0, 2.0 * k, 0.0, 20.0, 2.0 * k) for k in range(6)]
    kept = judged_samples(samples, 0.25)
    assert [s.t for s in kept] == pytest.approx([0.0, 0.1, 0.2, 0.25])
    assert kept[-1].y == pytest.approx(5.0) and kept[-1].distance == pytest.approx(5.0)
    assert judged_samples(samples, 0.2) == samples[:3]
    assert judged_samples(samples, 9.0) == samples


def test_after_goal_records_in_json_junit_and_text(
    tracks: dict[tuple[str, float], PoseTrack],
    four_way: Intersection,
    capsys: pytest.CaptureFixture[str],
) -> None:
    car1 = _samples(tracks[(EGO_ROUTE, BEHIND)], [])
    verdict = check_testcase(_testcase(EGO_ROUTE, car1), _ego(tracks), "sumo", four_way)
    document = json.loads(verdict.to_json())
    assert document["passed"] is True and document["collisions"] == []
    assert document["judged_until"] == document["goal"]["time"] == verdict.goal_time
    assert [c["other"] for c in document["after_goal"]["collisions"]] == ["car1"]
    assert document["after_goal"]["violations"] == []
    assert document["reasons"] == [] and len(document["information"]) == 1
    assert Verdict.from_dict(document) == verdict
    # a JUnit case that passed: no failure, whatever happened after the goal
    case = ET.fromstring(junit_report([verdict])).find("testsuite/testcase")
    assert case is not None and case.find("failure") is None
    print_verdict(verdict)
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("PASS")
    late = verdict.after_goal_collisions[0]
    assert lines[2] == f"  after its goal (not judged): {late.describe()}"


def test_a_verdict_stored_before_the_judgement_end_reads_back() -> None:
    """Verdicts stored before ``after_goal`` was kept read back with none."""
    document = Verdict("t", "sumo", True, 8.0, duration=20.0).to_dict()
    del document["after_goal"], document["judged_until"], document["information"]
    read = Verdict.from_dict(document)
    assert read.after_goal_collisions == () and read.after_goal_violations == ()
    assert read.passed
