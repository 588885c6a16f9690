"""The pedestrian laws at a signal (CVC 21451 (a), (b) and 21453 (b) for people on foot,
21950 (a) for a car that ran its red, 21456) at the ASP level: hand-written events with
numeric times, real clingo, on the signalized four-way with crossings
(tests/data/junctions/signal-crossings: north-south green 0-20 s, walk on :C_c1 and :C_c3
0-14 s, flashing 14-20 s; east-west green 25-45 s, walk on :C_c0 and :C_c2 25-39 s).

m = 1 s. The ego turns right from the north (link 0, g 0-20 s) and leaves across :C_c3,
the west road's crossing; walking C_c3+ (southwards, from the north-west corner) a
pedestrian meets the ego's exit lane first.
"""

from __future__ import annotations

import dataclasses

import pytest

from service.core.checker.rules import solve_rules
from service.core.checker.verdict import RIGHTS_OF_PEDESTRIANS
from service.core.network import ControlType, Intersection
from service.core.network.signals import SignalPhase, SignalProgram
from tests.core.checker.crossing_model import signal_crossings, stop_crossings
from tests.core.checker.pedestrian_traces import (
    ARRIVED,
    ENTERED,
    EXITED,
    IN,
    OUT,
    STOPPED,
    Event,
    judge,
)


@pytest.fixture(scope="module")
def signal() -> Intersection:
    return signal_crossings()


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


def test_the_rule_sets_cite_each_pedestrian_section(signal: Intersection) -> None:
    def laws(intersection: Intersection) -> dict[str, str]:
        atoms = solve_rules(intersection.control, [], [("law", 2)])
        return {str(a.arguments[0]): a.arguments[1].string for a in atoms}

    common = {
        "yieldToPedestrian": "21950(a)",
        "leavesCurbIntoHazard": "21950(b)",
        "passesCarStoppedForPedestrian": "21951",
    }
    assert common.items() <= laws(stop_crossings()).items()
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
