"""The pedestrian laws (CVC 21950 (a), (b), 21951) at the ASP level: hand-written events with
numeric times, real clingo, on the bundled all-way stop with sidewalks and crossings guessed
(tests/data/junctions/stop-crossings; its crossings and walks as the network loader reads
them); and no car law treats a pedestrian as a car, under
every rule set. The signal laws for people on foot: test_pedestrian_signal_rules.py.

m = 1 s. The ego comes from the south on lane 1 (``S2C_1``) and its near crosswalk is :C_c2,
across the south road; walking C_c2+ (eastwards, from the south-west corner) a pedestrian
crosses the two southbound exit lanes first, then S2C_2's and last S2C_1's path; walking
C_c2- it meets S2C_1's path first. Times were chosen by hand: each comment says what
happens.
"""

from __future__ import annotations

import pytest

from service.core.checker.rules import solve_rules
from service.core.network import Intersection, load_intersection
from tests.core.checker.crossing_model import signal_crossings, stop_crossings
from tests.core.checker.pedestrian_traces import (
    ARRIVED,
    ENTERED,
    EXITED,
    IN,
    OUT,
    STOPPED,
    Event,
    facts_of,
    judge,
)

EGO = "S2C_1:C2N_1"  # straight on from the south, lane 1
BESIDE = "S2C_2:C2N_2"  # straight on from the south, lane 2, beside the ego
SOUTH = ":C_c2"


@pytest.fixture(scope="module")
def stop() -> Intersection:
    return stop_crossings()


@pytest.fixture(scope="module")
def signal() -> Intersection:
    return signal_crossings()


def _ego_stops(entered_crosswalk: float) -> list[Event]:
    """The ego stops at its sign and reaches the crosswalk as it enters the junction."""
    return [
        ("ego", ARRIVED, None, 5.0),
        ("ego", STOPPED, None, 6.0),
        ("ego", ENTERED, None, entered_crosswalk),
        ("ego", IN, SOUTH, entered_crosswalk),
        ("ego", OUT, SOUTH, entered_crosswalk + 1.5),
    ]


def _walks_east(
    stepped: float = 10.0, into: float | None = 17.0, out: float | None = 19.5
) -> list[Event]:
    """ped1 on C_c2+: on the crossing from ``stepped``, in the ego's lane from ``into`` to
    ``out`` (None: not within the trace), off the crossing 0.5 s after it."""
    events: list[Event] = [("ped1", ARRIVED, None, stepped - 1.0), ("ped1", ENTERED, None, stepped)]
    if into is not None:
        events.append(("ped1", IN, EGO, into))
    if out is not None:
        events += [("ped1", OUT, EGO, out), ("ped1", EXITED, None, out + 0.5)]
    return events


EAST = {"ped1": "C_c2+"}
ALONE = {"ego": EGO}


# --- 21950 (a): yield to a pedestrian on the crosswalk in the car's path ----------------


def test_entering_the_crosswalk_before_the_pedestrian_reaches_the_lane_violates_21950a(
    stop: Intersection,
) -> None:
    # ped1 stepped on at 10 and is still before the ego's lane (reaches it at 17)
    found = judge(stop, ALONE, EAST, _walks_east() + _ego_stops(12.0))
    assert found == {("ego", "ped1", "yieldToPedestrian")}


def test_entering_while_the_pedestrian_is_in_the_lane_violates_21950a(
    stop: Intersection,
) -> None:
    found = judge(stop, ALONE, EAST, _walks_east() + _ego_stops(18.0))
    assert found == {("ego", "ped1", "yieldToPedestrian")}


def test_waiting_until_the_pedestrian_has_left_the_lane_keeps_21950a(stop: Intersection) -> None:
    assert judge(stop, ALONE, EAST, _walks_east() + _ego_stops(20.5)) == set()


def test_entering_as_the_pedestrian_leaves_the_lane_is_not_a_21950a_violation(
    stop: Intersection,
) -> None:
    # 0.5 s after ped1 left the ego's lane: perceptibly simultaneous, as for cars
    assert judge(stop, ALONE, EAST, _walks_east() + _ego_stops(20.0)) == set()


def test_a_pedestrian_who_has_walked_past_the_lane_is_not_in_the_path(stop: Intersection) -> None:
    # C_c2-: ped1 meets the ego's lane first and is past it at 12.5, still on the crossing
    events: list[Event] = [
        ("ped1", ENTERED, None, 10.0),
        ("ped1", IN, EGO, 10.1),
        ("ped1", OUT, EGO, 12.5),
        ("ped1", EXITED, None, 20.0),
        *_ego_stops(14.0),
    ]
    assert judge(stop, ALONE, {"ped1": "C_c2-"}, events) == set()


def test_a_pedestrian_still_in_the_lane_when_the_trace_ends_is_in_the_path(
    stop: Intersection,
) -> None:
    # no event of ped1 leaving the ego's lane: it is in it until the end of the trace
    found = judge(stop, ALONE, EAST, _walks_east(out=None) + _ego_stops(18.0))
    assert found == {("ego", "ped1", "yieldToPedestrian")}


def test_a_pedestrian_still_before_the_lane_when_the_trace_ends_is_in_the_path(
    stop: Intersection,
) -> None:
    found = judge(stop, ALONE, EAST, _walks_east(into=None, out=None) + _ego_stops(12.0))
    assert found == {("ego", "ped1", "yieldToPedestrian")}


def test_a_pedestrian_off_the_crossing_without_touching_the_lane_is_not_in_the_path(
    stop: Intersection,
) -> None:
    events: list[Event] = [
        ("ped1", ENTERED, None, 10.0),
        ("ped1", EXITED, None, 11.0),  # back to the curb it came from
        *_ego_stops(12.0),
    ]
    assert judge(stop, ALONE, EAST, events) == set()


def test_the_violation_names_the_events(stop: Intersection) -> None:
    events = _walks_east() + _ego_stops(12.0)
    shown = [("violatesRightOfForRuleAt", 4)]
    (atom,) = solve_rules(stop.control, facts_of(stop, ALONE, EAST, events), shown)
    named = [events[s.arguments[1].number] for s in atom.arguments[3].arguments]
    assert named == [("ped1", ENTERED, None, 10.0), ("ego", IN, SOUTH, 12.0),
                     ("ped1", OUT, EGO, 19.5)]  # fmt: skip


def test_a_pedestrian_still_in_the_lane_at_the_end_is_named_without_a_clearing(
    stop: Intersection,
) -> None:
    events = _walks_east(out=None) + _ego_stops(18.0)
    shown = [("violatesRightOfForRuleAt", 4)]
    (atom,) = solve_rules(stop.control, facts_of(stop, ALONE, EAST, events), shown)
    named = [events[s.arguments[1].number] for s in atom.arguments[3].arguments]
    assert named == [("ped1", ENTERED, None, 10.0), ("ego", IN, SOUTH, 18.0)]


# --- 21950 (b): a pedestrian does not step in front of a car so close as to be a hazard --

WEST = {"ped1": "C_c2-"}  # from the south-east corner: the ego's lane first


def _ego_through(left_crosswalk: float | None = 12.0) -> list[Event]:
    events = [
        ("ego", ARRIVED, None, 5.0),
        ("ego", STOPPED, None, 6.0),
        ("ego", ENTERED, None, 10.0),
        ("ego", IN, SOUTH, 10.0),
    ]
    if left_crosswalk is not None:
        events.append(("ego", OUT, SOUTH, left_crosswalk))
    return events


def _steps_out(stepped: float, into_lane: float) -> list[Event]:
    return [
        ("ped1", ENTERED, None, stepped),
        ("ped1", IN, EGO, into_lane),
        ("ped1", OUT, EGO, into_lane + 3.0),
        ("ped1", EXITED, None, into_lane + 9.0),
    ]


def test_stepping_in_front_of_a_car_reaching_the_crosswalk_violates_21950b(
    stop: Intersection,
) -> None:
    # the ego reached the crosswalk at 10, ped1 stepped on at 10.5 (simultaneous) and was in
    # the ego's lane at 10.6, 1.4 s before the ego left the crosswalk: the ego owes nothing
    found = judge(stop, ALONE, WEST, _ego_through() + _steps_out(10.5, 10.6))
    assert found == {("ped1", "leavesCurbIntoHazard")}


def test_stepping_in_front_of_a_car_already_on_the_crosswalk_violates_21950b(
    stop: Intersection,
) -> None:
    found = judge(stop, ALONE, WEST, _ego_through(13.0) + _steps_out(11.5, 11.6))
    assert found == {("ped1", "leavesCurbIntoHazard")}


def test_reaching_the_lane_as_the_car_leaves_the_crosswalk_keeps_21950b(
    stop: Intersection,
) -> None:
    assert judge(stop, ALONE, WEST, _ego_through() + _steps_out(10.5, 11.2)) == set()


def test_stepping_out_perceptibly_before_the_car_comes_keeps_21950b(stop: Intersection) -> None:
    # ped1 stepped on a full m before the ego reached the crosswalk: 21950 (a) is the ego's
    found = judge(stop, ALONE, WEST, _ego_through() + _steps_out(9.0, 9.1))
    assert found == {("ego", "ped1", "yieldToPedestrian")}


def test_a_car_still_on_the_crosswalk_when_the_trace_ends_is_a_hazard(stop: Intersection) -> None:
    found = judge(stop, ALONE, WEST, _ego_through(None) + _steps_out(10.5, 11.2))
    assert found == {("ped1", "leavesCurbIntoHazard")}


def test_a_pedestrian_who_stepped_in_front_of_one_car_keeps_the_right_of_way_of_21950a(
    stop: Intersection,
) -> None:
    # car1, beside the ego, comes to the crosswalk 3 s after ped1 stepped in front of the ego
    # and while ped1 is still before its lane (C_c2-: the ego's lane, then car1's)
    events = [
        *_ego_through(),
        *_steps_out(10.5, 10.6),
        ("car1", ARRIVED, None, 9.0),
        ("car1", STOPPED, None, 11.0),
        ("car1", ENTERED, None, 13.5),
        ("car1", IN, SOUTH, 13.5),
        ("ped1", IN, BESIDE, 14.0),
        ("ped1", OUT, BESIDE, 16.0),
    ]
    found = judge(stop, {**ALONE, "car1": BESIDE}, WEST, events)
    assert found == {("ped1", "leavesCurbIntoHazard"), ("car1", "ped1", "yieldToPedestrian")}


# --- 21951: do not pass a car stopped at the crosswalk for a pedestrian --------------------


def _passing(
    ego_arrived: float = 7.0, ego_entered: float = 12.0, car_stops: bool = True
) -> list[Event]:
    """car1 (lane 2) stands at the crosswalk from 6 s; ped1 (C_c2-) has crossed the ego's
    lane by 10.5 s and is in car1's until 13 s; the ego (lane 1) comes up from behind,
    stops at its sign and enters."""
    events: list[Event] = [
        ("car1", ARRIVED, None, 4.0),
        ("ped1", ENTERED, None, 8.0),
        ("ped1", IN, EGO, 8.1),
        ("ped1", OUT, EGO, 10.5),
        ("ped1", IN, BESIDE, 10.6),
        ("ped1", OUT, BESIDE, 13.0),
        ("ped1", EXITED, None, 15.0),
        ("ego", ARRIVED, None, ego_arrived),
        ("ego", STOPPED, None, ego_arrived + 0.5),
        ("ego", ENTERED, None, ego_entered),
        ("ego", IN, SOUTH, ego_entered),
        ("ego", OUT, SOUTH, ego_entered + 1.5),
    ]
    if car_stops:
        events.insert(1, ("car1", STOPPED, None, 6.0))
    return events


PASSING = {"ego": EGO, "car1": BESIDE}


def test_passing_a_car_that_stands_for_a_pedestrian_violates_21951(stop: Intersection) -> None:
    # ped1 is past the ego's lane (no 21950 (a)) but still in car1's path
    found = judge(stop, PASSING, WEST, _passing())
    assert found == {("ego", "ped1", "passesCarStoppedForPedestrian")}


def test_waiting_until_the_pedestrian_is_past_the_stopped_car_keeps_21951(
    stop: Intersection,
) -> None:
    assert judge(stop, PASSING, WEST, _passing(ego_entered=14.0)) == set()


def test_a_car_that_stood_beside_before_the_other_stopped_does_not_approach_from_the_rear(
    stop: Intersection,
) -> None:
    assert judge(stop, PASSING, WEST, _passing(ego_arrived=5.0)) == set()


def test_a_car_that_did_not_stop_is_not_passed_under_21951(stop: Intersection) -> None:
    assert judge(stop, PASSING, WEST, _passing(car_stops=False)) == set()


def test_passing_into_the_pedestrian_breaks_21951_and_21950a(stop: Intersection) -> None:
    found = judge(stop, PASSING, WEST, _passing(ego_entered=9.5))
    assert found == {
        ("ego", "ped1", "passesCarStoppedForPedestrian"),
        ("ego", "ped1", "yieldToPedestrian"),
    }


# --- The car laws never see a pedestrian ----------------------------------------------------


@pytest.fixture(scope="module")
def every_rule_set(
    stop: Intersection, signal: Intersection, tmp_path_factory: pytest.TempPathFactory
) -> dict[str, Intersection]:
    """The four-ways with crossings under every rule set (the stop one rebuilt with
    netconvert as a priority stop and as uncontrolled: the crossings stay)."""
    cache = tmp_path_factory.mktemp("crossings")
    rebuilt = {
        control: load_intersection(stop.source_file, "C", control, cache)
        for control in ("priority_stop", "right_before_left")
    }
    return {"allway_stop": stop, "traffic_light": signal, **rebuilt}


@pytest.mark.parametrize(
    "rule_set", ["allway_stop", "priority_stop", "right_before_left", "traffic_light"]
)
def test_no_car_law_treats_a_pedestrian_as_a_car(
    every_rule_set: dict[str, Intersection], rule_set: str
) -> None:
    """ped1 and the ego fail to yield to each other in the car laws' own pattern (each is in
    the other's lane, perceptibly before the other left it), and ped1 arrives, stops and
    steps on where a car would: only a pedestrian law may judge them."""
    intersection = every_rule_set[rule_set]
    events: list[Event] = [
        ("ped1", ARRIVED, None, 25.0),
        ("ped1", STOPPED, None, 25.5),
        ("ped1", ENTERED, None, 26.0),
        ("ped1", IN, EGO, 27.0),
        ("ped1", OUT, EGO, 30.0),
        ("ped1", EXITED, None, 33.0),
        ("ego", ARRIVED, None, 25.0),
        ("ego", STOPPED, None, 25.5),
        ("ego", ENTERED, None, 28.0),
        ("ego", IN, SOUTH, 28.0),
        ("ego", OUT, SOUTH, 29.0),
    ]
    facts = facts_of(intersection, ALONE, EAST, events)
    atoms = solve_rules(intersection.control, facts)
    yielding = {
        (a.arguments[0].string, a.arguments[1].string) for a in atoms if a.match("failsToYield", 4)
    }
    assert yielding == {("ego", "ped1"), ("ped1", "ego")}
    found = judge(intersection, ALONE, EAST, events)
    # at the signal ped1 walks on its WALK (25-39 s) while the ego's light is red
    red = {("ego", "stopAtRed")} if rule_set == "traffic_light" else set()
    assert found == {("ego", "ped1", "yieldToPedestrian"), *red}
