"""The pedestrian laws (CVC 21950, 21951, 21451 and 21453 (b) for people on foot, 21456) at
the ASP level: hand-written events with numeric times, real clingo, on the bundled four-ways
with sidewalks and crossings guessed (tests/data/junctions/*-crossings; crossings and walks
built by tests/core/checker/crossing_model.py).

m = 1 s. At the all-way stop the ego comes from the south on lane 1 (``S2C_1``) and its near
crosswalk is :C_c2, across the south road; walking C_c2+ (eastwards, from the south-west
corner) a pedestrian crosses the two southbound exit lanes first, then S2C_2's and last
S2C_1's path; walking C_c2- it meets S2C_1's path first. Times were chosen by hand: each
comment says what happens.
"""

from __future__ import annotations

import dataclasses

import clingo
import pytest

from service.core.checker.rules import (
    REQUESTED_LANE,
    TimedEvent,
    event_facts,
    geometry_facts,
    pedestrian_facts,
    perceptible_order,
    phase_facts,
    signal_facts,
    solve_rules,
    time_symbol,
)
from service.core.checker.verdict import RIGHTS_OF_PEDESTRIANS
from service.core.motion.events import EventKind, LaneEvent
from service.core.network import ControlType, Intersection, load_intersection
from service.core.network.signals import SignalPhase, SignalProgram
from tests.core.checker.crossing_model import signal_crossings, stop_crossings, with_crossings

ARRIVED, STOPPED, ENTERED, EXITED = (
    EventKind.ARRIVED, EventKind.STOPPED, EventKind.ENTERED, EventKind.EXITED,
)  # fmt: skip
IN, OUT = EventKind.ENTERED_LANE, EventKind.LEFT_LANE
Event = tuple[str, EventKind, str | None, float]

EGO = "S2C_1:C2N_1"  # straight on from the south, lane 1
BESIDE = "S2C_2:C2N_2"  # straight on from the south, lane 2, beside the ego
SOUTH = ":C_c2"


@pytest.fixture(scope="module")
def stop() -> Intersection:
    return stop_crossings()


@pytest.fixture(scope="module")
def signal() -> Intersection:
    return signal_crossings()


def facts_of(
    intersection: Intersection,
    cars: dict[str, str],
    people: dict[str, str],
    events: list[Event],
    horizon: float = 60.0,
) -> list[clingo.Symbol]:
    """The facts of hand-written events, the k-th event's time symbol t(who, k). ``cars``:
    id -> route, ``people``: id -> walk. Where an event happens: None is a car's fork or a
    pedestrian's crossing, a route id that route's connecting lane, a crossing id that
    crossing's lane."""
    timed = []
    for k, (who, kind, where, time) in enumerate(events):
        if where is None and who in cars:
            lane = intersection.route(cars[who]).fork
        elif where is None:
            lane = intersection.walk(people[who]).crossing
        elif where in intersection.routes:
            lane = intersection.routes[where].connecting_lane
        else:
            lane = intersection.crossings[where].lane
        timed.append(TimedEvent(who, time_symbol(who, k), LaneEvent(kind, lane, time, 0.0)))
    facts = geometry_facts(intersection) + perceptible_order(timed, 1.0)
    facts += signal_facts(intersection, horizon) + phase_facts(intersection, timed, horizon)
    for car, route_id in cars.items():
        route = intersection.route(route_id)
        facts.append(REQUESTED_LANE(car, route.connecting_lane))
        facts += event_facts(car, route.fork, [t for t in timed if t.car == car])
    for person, walk_id in people.items():
        crossing = intersection.crossings[intersection.walk(walk_id).crossing]
        facts += pedestrian_facts(person, crossing.lane, [t for t in timed if t.car == person])
    return facts


def judge(
    intersection: Intersection, cars: dict[str, str], people: dict[str, str], events: list[Event]
) -> set[tuple[str, ...]]:
    """Violations as (violator, other, rule) and (violator, rule)."""
    found: set[tuple[str, ...]] = set()
    for atom in solve_rules(intersection.control, facts_of(intersection, cars, people, events)):
        if atom.match("violatesRightOfForRule", 3):
            v1, v2, rule = atom.arguments
            found.add((v1.string, v2.string, str(rule)))
            # a right-of-way owed to a pedestrian is one the verdict words so, and only
            # cars owe one
            assert (v2.string in people) == (str(rule) in RIGHTS_OF_PEDESTRIANS), atom
            assert v1.string in cars, atom
        elif atom.match("violatesRule", 2):
            found.add((atom.arguments[0].string, str(atom.arguments[1])))
    return found


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


# --- At a signal: 21451 (a), (b), 21453 (b) for people on foot, and 21456 -------------------

RIGHT_TURN = {"ego": "N2C_1:C2W_1"}  # link 0, g 0-20 s; crosses :C_c3 (west road) leaving
SOUTHWARDS = {"ped1": "C_c3+"}  # from the north-west corner, the ego's exit lane first
WEST_ROAD = ":C_c3"


def _turning(ego_reaches_crosswalk: float, stepped: float = 2.0) -> list[Event]:
    return [
        ("ped1", ENTERED, None, stepped),
        ("ped1", IN, "N2C_1:C2W_1", stepped + 0.1),
        ("ped1", OUT, "N2C_1:C2W_1", stepped + 3.0),
        ("ped1", EXITED, None, stepped + 9.0),
        ("ego", ARRIVED, None, 1.0),
        ("ego", ENTERED, None, 3.0),
        ("ego", IN, WEST_ROAD, ego_reaches_crosswalk),
        ("ego", OUT, WEST_ROAD, ego_reaches_crosswalk + 1.5),
    ]


def _program(intersection: Intersection, right_turn: str) -> Intersection:
    """One phase: the north's right turn shows ``right_turn``, :C_c3 walks, the rest red."""
    state = ["r"] * 20
    state[0], state[19] = right_turn, "G"
    assert intersection.signals is not None
    program = SignalProgram("C", "test", 0.0, (SignalPhase(60.0, "".join(state)),))
    return dataclasses.replace(intersection, signals=program)


def test_turning_on_green_into_a_pedestrian_on_walk_violates_21451a(signal: Intersection) -> None:
    found = judge(signal, RIGHT_TURN, SOUTHWARDS, _turning(4.0))
    assert found == {("ego", "ped1", "yieldToPedestrianOnGreen")}


def test_turning_on_green_after_the_pedestrian_keeps_21451a(signal: Intersection) -> None:
    assert judge(signal, RIGHT_TURN, SOUTHWARDS, _turning(6.0)) == set()


def test_turning_on_a_green_arrow_into_a_pedestrian_violates_21451b(signal: Intersection) -> None:
    found = judge(_program(signal, "G"), RIGHT_TURN, SOUTHWARDS, _turning(4.0))
    assert found == {("ego", "ped1", "yieldToPedestrianOnArrow")}


def test_turning_on_a_green_arrow_after_the_pedestrian_keeps_21451b(signal: Intersection) -> None:
    assert judge(_program(signal, "G"), RIGHT_TURN, SOUTHWARDS, _turning(6.0)) == set()


def test_turning_right_on_red_into_a_pedestrian_violates_21453b(signal: Intersection) -> None:
    events = [*_turning(4.0), ("ego", STOPPED, None, 2.0)]
    found = judge(_program(signal, "s"), RIGHT_TURN, SOUTHWARDS, events)
    assert found == {("ego", "ped1", "yieldToPedestrianOnRightOnRed")}


def test_turning_right_on_red_after_the_pedestrian_keeps_21453b(signal: Intersection) -> None:
    events = [*_turning(6.0), ("ego", STOPPED, None, 2.0)]
    assert judge(_program(signal, "s"), RIGHT_TURN, SOUTHWARDS, events) == set()


def test_a_car_running_its_red_into_a_pedestrian_violates_21950a(signal: Intersection) -> None:
    # ped1 stepped on at 13 s on walk and crawls; the ego enters on red at 24 s
    events: list[Event] = [
        ("ped1", ENTERED, None, 13.0),
        ("ped1", IN, "N2C_1:C2W_1", 13.1),
        ("ped1", OUT, "N2C_1:C2W_1", 30.0),
        ("ego", ARRIVED, None, 22.0),
        ("ego", ENTERED, None, 24.0),
        ("ego", IN, WEST_ROAD, 25.0),
    ]
    found = judge(signal, RIGHT_TURN, SOUTHWARDS, events)
    assert found == {("ego", "stopAtRed"), ("ego", "ped1", "yieldToPedestrian")}


@pytest.mark.parametrize(("stepped", "colour"), [(16.0, "y"), (24.0, "r")])
def test_stepping_onto_the_crossing_on_dont_walk_violates_21456(
    signal: Intersection, stepped: float, colour: str
) -> None:
    assert signal.signal_colour_of_crossing(signal.crossings[WEST_ROAD], stepped) == colour
    events: list[Event] = [("ped1", ARRIVED, None, 1.0), ("ped1", ENTERED, None, stepped)]
    assert judge(signal, {}, SOUTHWARDS, events) == {("ped1", "walkAgainstSignal")}


def test_a_pedestrian_who_started_on_walk_may_finish_under_21456(signal: Intersection) -> None:
    events: list[Event] = [
        ("ped1", ENTERED, None, 13.0),  # walk; flashing from 14, don't walk from 20
        ("ped1", IN, "N2C_1:C2W_1", 13.1),
        ("ped1", OUT, "N2C_1:C2W_1", 18.0),
        ("ped1", EXITED, None, 22.0),
    ]
    assert judge(signal, {}, SOUTHWARDS, events) == set()


def test_a_pedestrian_who_walked_against_the_signal_is_not_lawfully_within(
    signal: Intersection,
) -> None:
    events = _turning(17.5, stepped=16.0)  # ped1 steps on at the flashing don't walk
    events[5] = ("ego", ENTERED, None, 17.0)
    found = judge(signal, RIGHT_TURN, SOUTHWARDS, events)
    assert found == {("ped1", "walkAgainstSignal")}


def test_the_rule_sets_cite_each_pedestrian_section(
    stop: Intersection, signal: Intersection
) -> None:
    def laws(intersection: Intersection) -> dict[str, str]:
        atoms = solve_rules(intersection.control, [], [("law", 2)])
        return {str(a.arguments[0]): a.arguments[1].string for a in atoms}

    common = {
        "yieldToPedestrian": "21950(a)",
        "leavesCurbIntoHazard": "21950(b)",
        "passesCarStoppedForPedestrian": "21951",
    }
    assert common.items() <= laws(stop).items()
    assert {
        **common,
        "yieldToPedestrianOnGreen": "21451(a)",
        "yieldToPedestrianOnArrow": "21451(b)",
        "yieldToPedestrianOnRightOnRed": "21453(b)",
        "walkAgainstSignal": "21456(a)(3)",
    }.items() <= laws(signal).items()
    assert laws(signal).keys() >= RIGHTS_OF_PEDESTRIANS
    for control in ControlType:
        assert common.keys() <= {
            str(a.arguments[0]) for a in solve_rules(control, [], [("law", 2)])
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
        control: with_crossings(load_intersection(stop.source_file, "C", control, cache))
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
