"""The checker with people on foot, on trajectories: Step 1 poses of real SUMO drives
retimed by hand, pedestrians walking straight across a crossing at 1.3 m/s, the real
checker (events, facts, clingo, collisions).

The networks are the bundled four-ways with crossings (tests/data/junctions/*-crossings,
crossings and walks as the network loader reads them). At the all-way stop the
ego goes straight north from lane 1 (S2C_1:C2N_1), its front 40 m before the line: its near
crosswalk :C_c2 begins at the line, its far one :C_c0 lies at its exit. A pedestrian waits
at the curb, its centre 1 m before the crossing, then walks: C_c2+ (from the south-west
corner) meets the ego's lane last, C_c2- (from the south-east corner) first. The timings
were chosen with the events printed; each comment says what happens.
"""

from __future__ import annotations

import dataclasses
import json

import pytest

from service.core.checker.check import Judge, check_testcase
from service.core.checker.verdict import PEDESTRIAN, Verdict
from service.core.motion.events import EventKind
from service.core.motion.poses import PoseSample, PoseTrack, generate_poses
from service.core.network import Intersection, Walk
from service.core.network.signals import SignalPhase, SignalProgram
from service.core.testcase import (
    TestCase,
    dump_testcase,
    new_testcase,
    parse_testcase,
    under_testcase_signals,
)
from tests.core.checker.crossing_model import JUNCTIONS, signal_crossings, stop_crossings
from tests.helpers import drive_with_stops, retime, with_nonegos

START = 40.0
LINE = START - 0.5  # the ego stands half a metre before its stop line
DURATION = 30.0
PACE = 1.3  # m/s
CURB = 1.0  # m: a waiting pedestrian's centre before the crossing
EGO = "S2C_1:C2N_1"
BESIDE = "S2C_2:C2N_2"  # lane 2, beside the ego
TURN = "N2C_1:C2W_1"  # at the signal: the north's right turn, g 0-20 s, crossing :C_c3


@pytest.fixture(scope="module")
def stop() -> Intersection:
    return stop_crossings()


@pytest.fixture(scope="module")
def signal() -> Intersection:
    return signal_crossings()


@pytest.fixture(scope="module")
def tracks(stop: Intersection, signal: Intersection) -> dict[str, PoseTrack]:
    """Step 1 poses: the ego's route and the one beside it (car1 starts 15 m out) at the
    stop, the right turn at the signal."""
    found = {}
    requests = [(stop.route(EGO), START), (stop.route(BESIDE), 15.0)]
    for track in generate_poses(stop, requests, 8.0, DURATION, 0.1):
        found[track.route] = track
    (track,) = generate_poses(signal, [(signal.route(TURN), START)], 8.0, DURATION, 0.1)
    found[track.route] = track
    return found


def driving(track: PoseTrack, stops: list[tuple[float, float]]) -> list[PoseSample]:
    """A car at 8 m/s that stands at each (distance, wait) of ``stops``."""
    return retime(track, drive_with_stops(stops, 8.0, start_speed=8.0), DURATION, 0.1)


def walking(walk: Walk, stops: list[tuple[float, float]]) -> list[PoseSample]:
    """A pedestrian on a straight line along ``walk``'s path (beyond its ends too), from
    standing with its centre CURB metres before the crossing; ``stops``: (distance, wait),
    the first (0, wait) its wait at the curb; it walks at PACE, speeding up at 1 m/s^2."""
    profile = drive_with_stops(stops, PACE, accelerate=1.0, brake=1.5, start_speed=0.0)
    (x0, y0), (x1, y1) = walk.path.coords[0], walk.path.coords[-1]
    ux, uy = (x1 - x0) / walk.length, (y1 - y0) / walk.length
    samples = []
    for k in range(round(DURATION / 0.1) + 1):
        t = round(k * 0.1, 6)
        distance, speed = profile(t)
        along = distance - CURB
        samples.append(PoseSample(t, x0 + ux * along, y0 + uy * along, walk.heading, speed,
                                  distance))  # fmt: skip
    return samples


def with_people(
    base: TestCase,
    cars: list[tuple[str, str, list[PoseSample]]],
    people: list[tuple[str, str, list[PoseSample]]],
) -> TestCase:
    """``base`` with cars (id, route, samples) and pedestrians (id, walk, samples)."""
    document = json.loads(dump_testcase(with_nonegos(base, cars)))
    document["schema"] = "scengen/testcase/2"
    document["pedestrians"] = [
        {"id": person, "walk": walk, "added_in": 1,
         "trajectory": [dataclasses.asdict(s) for s in samples]}
        for person, walk, samples in people
    ]  # fmt: skip
    return parse_testcase(document)


def stop_case(
    people: list[tuple[str, str, list[PoseSample]]],
    cars: list[tuple[str, str, list[PoseSample]]] = (),  # type: ignore[assignment]
) -> TestCase:
    base = new_testcase(JUNCTIONS / "stop-crossings.net.xml", EGO, start_distance=START,
                        duration=DURATION)  # fmt: skip
    return with_people(base, list(cars), people)


def judged(
    testcase: TestCase, ego: list[PoseSample], intersection: Intersection
) -> tuple[Verdict, list[tuple[str, str]]]:
    """The verdict, and its violations as (law, other)."""
    verdict = check_testcase(testcase, ego, "hand-built", intersection)
    return verdict, [(v.law, v.other or "") for v in verdict.violations]


# --- 21950 (a) ------------------------------------------------------------------------------


def test_cutting_in_front_of_a_pedestrian_fails_21950a(
    stop: Intersection, tracks: dict[str, PoseTrack]
) -> None:
    # ped1 (C_c2+) steps on at 4.3 s and reaches the ego's lane at 11.7 s; the ego stops
    # for the sign at 6 s and reaches the crosswalk at 7.5 s, ped1 on it in its path
    person = walking(stop.walk("C_c2+"), [(0.0, 3.0)])
    testcase = stop_case([("ped1", "C_c2+", person)])
    verdict, found = judged(testcase, driving(tracks[EGO], [(LINE, 0.5)]), stop)
    assert found == [("21950(a)", "ped1")]
    assert verdict.collisions == () and verdict.goal_reached and not verdict.passed
    reason = verdict.reasons[0]
    assert reason.startswith("violated CVC 21950(a) (yieldToPedestrian) of pedestrian ped1: ")
    violation = verdict.violations[0]
    kinds = [(e.car, e.kind, e.lane) for e in violation.events]
    assert kinds == [("ped1", "entered", ":C_c2"), ("ego", "entered_lane", ":C_c2_0"),
                     ("ped1", "left_lane", ":C_9_0")]  # fmt: skip
    stepped, reached, cleared = (e.t for e in violation.events)
    assert reached - stepped >= 1.0 and cleared - reached >= 1.0


def test_waiting_for_the_pedestrian_passes(
    stop: Intersection, tracks: dict[str, PoseTrack]
) -> None:
    # the ego stands at its line until 14.3 s: ped1 leaves its lane at 14.35 s, the ego
    # reaches the crosswalk at 14.98 s (perceptibly simultaneous, as for cars)
    person = walking(stop.walk("C_c2+"), [(0.0, 3.0)])
    testcase = stop_case([("ped1", "C_c2+", person)])
    verdict, _ = judged(testcase, driving(tracks[EGO], [(LINE, 8.0)]), stop)
    assert verdict.passed, verdict.reasons
    assert verdict.pedestrians_broke == ()


def test_a_pedestrian_still_crossing_at_the_end_keeps_the_right_of_way(
    stop: Intersection, tracks: dict[str, PoseTrack]
) -> None:
    # ped1 steps on at 4.3 s and stops in the middle of the crossing (the test ends there):
    # an ego that goes has entered the crosswalk with ped1 before its lane
    walk = stop.walk("C_c2+")
    person = walking(walk, [(0.0, 3.0), (CURB + walk.length / 2, 100.0)])
    testcase = stop_case([("ped1", "C_c2+", person)])
    verdict, found = judged(testcase, driving(tracks[EGO], [(LINE, 4.0)]), stop)
    assert found == [("21950(a)", "ped1")]
    assert [e.kind for e in verdict.violations[0].events] == ["entered", "entered_lane"]


def test_hitting_a_pedestrian_is_a_collision_with_a_pedestrian(
    stop: Intersection, tracks: dict[str, PoseTrack]
) -> None:
    # ped1 (C_c2-) is in the ego's lane from 3.7 s to 6.4 s; the ego runs its sign and
    # reaches the crosswalk at 5 s
    person = walking(stop.walk("C_c2-"), [(0.0, 2.4)])
    testcase = stop_case([("ped1", "C_c2-", person)])
    verdict, found = judged(testcase, driving(tracks[EGO], []), stop)
    assert [(c.other, c.kind) for c in verdict.collisions] == [("ped1", PEDESTRIAN)]
    assert "collided with pedestrian ped1 at" in " ".join(verdict.reasons)
    assert ("21950(a)", "ped1") in found and ("22450(a)", "") in found


# --- 21950 (b) -------------------------------------------------------------------------------


def test_stepping_out_in_front_of_a_close_car_breaks_21950b_not_the_car(
    stop: Intersection, tracks: dict[str, PoseTrack]
) -> None:
    # the ego reaches its far crosswalk :C_c0 at 10.9 s and leaves it at 12.1 s; ped1
    # (C_c0+, from the north-east corner) steps 0.3 m into it, into the ego's lane, at
    # 10.6 s, stops there (0.4 m from the ego's side) until it has passed, and walks on
    walk = stop.walk("C_c0+")
    person = walking(walk, [(0.0, 9.3), (CURB + 0.3 - 0.1075, 2.5)])
    testcase = stop_case([("ped1", "C_c0+", person)])
    verdict, _ = judged(testcase, driving(tracks[EGO], [(LINE, 0.5)]), stop)
    assert verdict.passed, verdict.reasons
    ((by, broken),) = [(b.by, b.violation) for b in verdict.pedestrians_broke]
    assert (by, broken.rule, broken.law, broken.other) == (
        "ped1", "leavesCurbIntoHazard", "21950(b)", None,
    )  # fmt: skip
    assert verdict.information == [f"pedestrian ped1 (not the ego's failure) {broken.describe()}"]
    round_trip = Verdict.from_dict(json.loads(verdict.to_json()))
    assert round_trip.pedestrians_broke == verdict.pedestrians_broke


def test_a_verdict_without_pedestrians_writes_no_pedestrian_key(
    stop: Intersection, tracks: dict[str, PoseTrack]
) -> None:
    base = new_testcase(JUNCTIONS / "stop-crossings.net.xml", EGO, start_distance=START,
                        duration=DURATION)  # fmt: skip
    verdict = check_testcase(base, driving(tracks[EGO], [(LINE, 0.5)]), "x", stop)
    assert verdict.passed and "pedestrians_broke" not in verdict.to_dict()


# --- 21951 -----------------------------------------------------------------------------------


def _passing(
    stop: Intersection, tracks: dict[str, PoseTrack], ego_waits: float
) -> tuple[Verdict, list[tuple[str, str]]]:
    """car1 (lane 2, 15 m out) stands at its line from 3.1 s until 10.5 s for ped1
    (C_c2-), who steps on at 4.3 s, is past the ego's lane at 7 s and past car1's at
    9.4 s; the ego (lane 1, 40 m out) comes up behind it (arrives at 3.75 s, not
    perceptibly before car1 stood) and stops at its sign."""
    person = walking(stop.walk("C_c2-"), [(0.0, 3.0)])
    car = driving(tracks[BESIDE], [(14.5, 7.3)])
    testcase = stop_case([("ped1", "C_c2-", person)], [("car1", BESIDE, car)])
    return judged(testcase, driving(tracks[EGO], [(LINE, ego_waits)]), stop)


def test_passing_a_car_stopped_for_a_pedestrian_fails_21951(
    stop: Intersection, tracks: dict[str, PoseTrack]
) -> None:
    # the ego reaches the crosswalk at 7.5 s: ped1 has left its lane, not car1's
    verdict, found = _passing(stop, tracks, 0.5)
    assert found == [("21951", "ped1")]
    assert verdict.collisions == () and verdict.goal_reached
    assert verdict.violations[0].rule == "passesCarStoppedForPedestrian"
    assert [(e.car, e.kind) for e in verdict.violations[0].events] == [
        ("car1", "stopped"), ("ped1", "entered"), ("ego", "entered_lane"),
    ]  # fmt: skip


def test_waiting_beside_the_stopped_car_passes_21951(
    stop: Intersection, tracks: dict[str, PoseTrack]
) -> None:
    # the ego reaches the crosswalk at 9.7 s, ped1 past car1's lane at 9.4 s
    verdict, _ = _passing(stop, tracks, 3.0)
    assert verdict.passed, verdict.reasons


# --- At the signal: 21451 (a) and 21456 ----------------------------------------------------


def signal_case(
    people: list[tuple[str, str, list[PoseSample]]], signals: SignalProgram | None = None
) -> TestCase:
    base = new_testcase(JUNCTIONS / "signal-crossings.net.xml", TURN, start_distance=START,
                        duration=DURATION, signals=signals)  # fmt: skip
    return with_people(base, [], people)


def turn_only(colour: str) -> SignalProgram:
    """One phase: the north's right turn (link 0) shows ``colour``, :C_c3 (link 19) walks,
    every other link is red."""
    state = ["r"] * 20
    state[0], state[19] = colour, "G"
    return SignalProgram("C", "turn", 0.0, (SignalPhase(DURATION, "".join(state)),))


def test_turning_on_green_into_a_pedestrian_on_walk_fails_21451a(
    signal: Intersection, tracks: dict[str, PoseTrack]
) -> None:
    # ped1 (C_c3-, from the south-west corner) steps on at 2.3 s on WALK and meets the
    # ego's exit lane last; the ego turns right on its g at 5 s and reaches the crosswalk
    # at 5.6 s, ped1 in the middle of it
    person = walking(signal.walk("C_c3-"), [(0.0, 1.0)])
    testcase = signal_case([("ped1", "C_c3-", person)])
    verdict, found = judged(testcase, driving(tracks[TURN], []), signal)
    assert found == [("21451(a)", "ped1")]
    assert verdict.violations[0].rule == "yieldToPedestrianOnGreen"
    assert verdict.collisions == () and verdict.goal_reached


def test_turning_on_green_after_the_pedestrian_passes(
    signal: Intersection, tracks: dict[str, PoseTrack]
) -> None:
    # the ego stands inside the junction, 1 m before the crosswalk, until ped1 is past
    entered = next(
        e.distance
        for e in Judge(signal_case([]), signal).ego_car(driving(tracks[TURN], [])).events
        if e.kind is EventKind.ENTERED_LANE and e.lane == ":C_c3_0"
    )
    person = walking(signal.walk("C_c3-"), [(0.0, 1.0)])
    testcase = signal_case([("ped1", "C_c3-", person)])
    verdict, _ = judged(testcase, driving(tracks[TURN], [(entered - 1.0, 6.5)]), signal)
    assert verdict.passed, verdict.reasons


def test_stepping_onto_the_crossing_on_dont_walk_breaks_21456(
    signal: Intersection, tracks: dict[str, PoseTrack]
) -> None:
    # ped1 steps on at 15.3 s, on the flashing don't walk (14-20 s); the ego is long gone
    person = walking(signal.walk("C_c3-"), [(0.0, 14.0)])
    testcase = signal_case([("ped1", "C_c3-", person)])
    verdict, _ = judged(testcase, driving(tracks[TURN], []), signal)
    assert verdict.passed, verdict.reasons
    broken = [(b.by, b.violation.rule, b.violation.law) for b in verdict.pedestrians_broke]
    assert broken == [("ped1", "walkAgainstSignal", "21456(a)(3)")]
    # what the generator asks of a new pedestrian, among the non-egos
    assert [v.rule for v in Judge(testcase, signal).rules_broken_by("ped1")] == [
        "walkAgainstSignal"
    ]


def test_a_pedestrian_who_starts_on_walk_breaks_no_rule(
    signal: Intersection, tracks: dict[str, PoseTrack]
) -> None:
    # ped1 steps on at 12.3 s on WALK and is still crossing on the flashing don't walk
    person = walking(signal.walk("C_c3-"), [(0.0, 11.0)])
    testcase = signal_case([("ped1", "C_c3-", person)])
    assert Judge(testcase, signal).rules_broken_by("ped1") == []


@pytest.mark.parametrize(
    ("colour", "stops", "law", "rule"),
    [
        # a protected right turn: the ego turns on its arrow at 5 s, at the crosswalk at 5.6 s
        ("G", [], "21451(b)", "yieldToPedestrianOnArrow"),
        # a right on red: the ego stops at its line at 6.3 s, turns at 7.5 s, at the
        # crosswalk at 9 s
        ("s", [(LINE, 0.5)], "21453(b)", "yieldToPedestrianOnRightOnRed"),
    ],
)
def test_turning_on_an_arrow_or_on_red_into_a_pedestrian_fails_its_signal_law(
    signal: Intersection,
    tracks: dict[str, PoseTrack],
    colour: str,
    stops: list[tuple[float, float]],
    law: str,
    rule: str,
) -> None:
    # ped1 (C_c3-) is on the crossing from 2.3 s, in the ego's exit lane from 9.9 s to 12.7 s
    person = walking(signal.walk("C_c3-"), [(0.0, 1.0)])
    testcase = signal_case([("ped1", "C_c3-", person)], turn_only(colour))
    junction = under_testcase_signals(signal, testcase)
    verdict, found = judged(testcase, driving(tracks[TURN], stops), junction)
    assert found == [(law, "ped1")] and verdict.violations[0].rule == rule
    assert verdict.collisions == () and verdict.goal_reached
    # waiting at the line until 12.3 s, the ego reaches the crosswalk at 14.5 s, ped1 past
    # its lane at 12.7 s
    verdict, _ = judged(testcase, driving(tracks[TURN], [(LINE, 6.0)]), junction)
    assert verdict.passed, verdict.reasons
