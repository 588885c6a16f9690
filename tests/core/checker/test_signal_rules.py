"""Signal rules (CVC 21451-21453) at the ASP level: hand-written events with numeric times
on the bundled and test signalized junctions, real clingo, the phases from the programs.

m = 1 s. tests/data/junctions/skewed-signal.tll.xml, y-signal.tll.xml and
sumo_nets/*-signal.tll.xml have the programs; the times below are chosen from them.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from service.core.checker.rules import (
    REQUESTED_LANE,
    TimedEvent,
    event_facts,
    geometry_facts,
    perceptible_order,
    phase_facts,
    signal_facts,
    solve_rules,
    time_symbol,
)
from service.core.motion.events import EventKind, LaneEvent
from service.core.network import Intersection, load_intersection

ARRIVED, STOPPED, ENTERED = EventKind.ARRIVED, EventKind.STOPPED, EventKind.ENTERED
IN, OUT = EventKind.ENTERED_LANE, EventKind.LEFT_LANE
JUNCTIONS = Path(__file__).parents[2] / "data" / "junctions"
Event = tuple[str, EventKind, str | None, float]


@pytest.fixture(scope="module")
def four_way() -> Intersection:
    return load_intersection("4way-signal")  # N-S green 0-20, yellow 20-23; E-W green 25-45


@pytest.fixture(scope="module")
def t_signal() -> Intersection:
    return load_intersection("t-signal")  # stem right turn on red (s) 0-22, green 22-34


@pytest.fixture(scope="module")
def skewed() -> Intersection:
    # offset 10: E-W green until 6, yellow 6-9, all red 9-10, leading lefts 10-16
    return load_intersection(JUNCTIONS / "skewed-signal.net.xml")


def judge(
    intersection: Intersection, routes: dict[str, str], events: list[Event]
) -> set[tuple[str, ...]]:
    """Violations as (violator, other, rule) and (violator, rule); a lane given as a route
    id is that route's connecting lane, None the car's fork."""
    timed = []
    for k, (car, kind, where, time) in enumerate(events):
        route = intersection.route(routes[car])
        lane = route.fork if where is None else intersection.routes[where].connecting_lane
        timed.append(TimedEvent(car, time_symbol(car, k), LaneEvent(kind, lane, time, 0.0)))
    facts = geometry_facts(intersection) + perceptible_order(timed, 1.0)
    facts += signal_facts(intersection, 60.0) + phase_facts(intersection, timed, 60.0)
    for car, route_id in routes.items():
        route = intersection.route(route_id)
        facts.append(REQUESTED_LANE(car, route.connecting_lane))
        facts += event_facts(car, route.fork, [t for t in timed if t.car == car])
    found: set[tuple[str, ...]] = set()
    for atom in solve_rules(intersection.control, facts):
        if atom.match("violatesRightOfForRule", 3):
            v1, v2, rule = atom.arguments
            found.add((v1.string, v2.string, str(rule)))
        elif atom.match("violatesRule", 2):
            found.add((atom.arguments[0].string, str(atom.arguments[1])))
    return found


def test_the_rule_set_names_each_signal_section(four_way: Intersection) -> None:
    laws = {
        str(a.arguments[0]): a.arguments[1].string
        for a in solve_rules(four_way.control, [], [("law", 2)])
    }
    assert laws == {
        "yieldToInsideOnGreen": "21451(a)",
        "yieldToInsideOnArrow": "21451(b)",
        "turnOnGreenYieldsToOncoming": "21801(a)",
        "stopAtRed": "21453(a)",
        "stopBeforeRightOnRed": "21453(b)",
        "yieldOnRightOnRed": "21453(b)",
        "stopAtRedArrow": "21453(c)",
        # people on foot (tests/core/checker/test_pedestrian_rules.py)
        "yieldToPedestrianOnGreen": "21451(a)",
        "yieldToPedestrianOnArrow": "21451(b)",
        "yieldToPedestrianOnRightOnRed": "21453(b)",
        "yieldToPedestrian": "21950(a)",
        "leavesCurbIntoHazard": "21950(b)",
        "passesCarStoppedForPedestrian": "21951",
        "walkAgainstSignal": "21456(a)(3)",
    }


# --- 21453 (a) and 21452: red and yellow ---------------------------------------------------

EAST = {"ego": "W2C_0:C2E_0"}


def test_entering_on_a_circular_red_violates_21453a(four_way: Intersection) -> None:
    events: list[Event] = [("ego", ARRIVED, None, 8.0), ("ego", ENTERED, None, 10.0)]
    assert judge(four_way, EAST, events) == {("ego", "stopAtRed")}


def test_waiting_for_green_keeps_21453a(four_way: Intersection) -> None:
    events: list[Event] = [("ego", ARRIVED, None, 8.0), ("ego", ENTERED, None, 25.5)]
    assert judge(four_way, EAST, events) == set()


def test_entering_on_yellow_is_lawful_under_21452(four_way: Intersection) -> None:
    events: list[Event] = [("ego", ARRIVED, None, 19.0), ("ego", ENTERED, None, 22.0)]
    assert judge(four_way, {"ego": "S2C_0:C2N_0"}, events) == set()


def test_entering_the_moment_red_begins_is_red(four_way: Intersection) -> None:
    events: list[Event] = [("ego", ARRIVED, None, 20.0), ("ego", ENTERED, None, 23.0)]
    assert judge(four_way, {"ego": "S2C_0:C2N_0"}, events) == {("ego", "stopAtRed")}


# --- 21451 (a): yield to traffic lawfully inside ---------------------------------------------

CLEARING = {"ego": "W2C_0:C2E_0", "car1": "S2C_0:C2N_0"}


def _clearing(ego_into_car_lane: float, car_entered: float = 22.0) -> list[Event]:
    return [
        ("car1", ARRIVED, None, car_entered - 1.0),
        ("car1", ENTERED, None, car_entered),  # on yellow: lawful
        ("ego", ARRIVED, None, 20.0),
        ("ego", ENTERED, None, 25.5),  # its fresh green
        ("ego", IN, "S2C_0:C2N_0", ego_into_car_lane),
        ("car1", OUT, "W2C_0:C2E_0", 27.0),
    ]


def test_entering_on_fresh_green_into_a_car_still_clearing_violates_21451a(
    four_way: Intersection,
) -> None:
    assert judge(four_way, CLEARING, _clearing(26.0)) == {("ego", "car1", "yieldToInsideOnGreen")}


def test_waiting_for_the_clearing_car_keeps_21451a(four_way: Intersection) -> None:
    assert judge(four_way, CLEARING, _clearing(28.0)) == set()


def test_a_car_that_ran_the_red_is_not_lawfully_inside(four_way: Intersection) -> None:
    # car1 entered at 24.0, on red: the ego owes it nothing under 21451
    found = judge(four_way, CLEARING, _clearing(26.0, car_entered=24.0))
    assert found == {("car1", "stopAtRed")}


# --- 21451 (a) with 21801 (a): a left turn on a circular green -------------------------------

LEFT = {"ego": "S2C_1:C2W_1", "car1": "N2C_0:C2S_0"}


def _left(car_arrived: float, ego_into_car_lane: float) -> list[Event]:
    return [
        ("car1", ARRIVED, None, car_arrived),
        ("ego", ARRIVED, None, 4.0),
        ("ego", ENTERED, None, 6.0),  # permissive g
        ("ego", IN, "N2C_0:C2S_0", ego_into_car_lane),
        ("car1", ENTERED, None, car_arrived + 2.0),
        ("car1", OUT, "S2C_1:C2W_1", car_arrived + 4.0),
    ]


def test_a_permissive_left_before_close_oncoming_traffic_violates_21801a(
    four_way: Intersection,
) -> None:
    found = judge(four_way, LEFT, _left(5.0, 7.0))
    assert found == {("ego", "car1", "turnOnGreenYieldsToOncoming")}


def test_a_permissive_left_that_waits_for_oncoming_traffic_keeps_21801a(
    four_way: Intersection,
) -> None:
    assert judge(four_way, LEFT, _left(5.0, 9.5)) == set()


def test_oncoming_traffic_that_arrives_later_is_no_hazard(four_way: Intersection) -> None:
    assert judge(four_way, LEFT, _left(8.0, 7.0)) == set()


# --- 21451 (b) and 21453 (c): arrows --------------------------------------------------------

ARROW = {"ego": "N2C_0:C2ENE_0", "car1": "WSW2C_0:C2ENE_0"}


def _arrow(ego_into_car_lane: float) -> list[Event]:
    return [
        ("car1", ARRIVED, None, 6.0),
        ("car1", ENTERED, None, 8.0),  # on yellow
        ("ego", ARRIVED, None, 9.0),
        ("ego", ENTERED, None, 10.5),  # the leading protected left
        ("ego", IN, "WSW2C_0:C2ENE_0", ego_into_car_lane),
        ("car1", OUT, "N2C_0:C2ENE_0", 12.0),
    ]


def test_a_green_arrow_into_a_car_inside_violates_21451b(skewed: Intersection) -> None:
    assert judge(skewed, ARROW, _arrow(11.0)) == {("ego", "car1", "yieldToInsideOnArrow")}


def test_a_green_arrow_that_waits_keeps_21451b(skewed: Intersection) -> None:
    assert judge(skewed, ARROW, _arrow(13.0)) == set()


def test_going_straight_while_only_the_left_arrow_is_green_violates_21453c(
    skewed: Intersection,
) -> None:
    events: list[Event] = [("ego", ARRIVED, None, 10.0), ("ego", ENTERED, None, 12.0)]
    found = judge(skewed, {"ego": "N2C_0:C2SSW_0"}, events)
    assert found == {("ego", "stopAtRedArrow")}


def test_going_straight_on_the_through_green_keeps_21453c(skewed: Intersection) -> None:
    events: list[Event] = [("ego", ARRIVED, None, 16.0), ("ego", ENTERED, None, 19.0)]
    assert judge(skewed, {"ego": "N2C_0:C2SSW_0"}, events) == set()


# --- 21453 (b): right turn on red ------------------------------------------------------------

RIGHT = {"ego": "S2C_0:C2E_0"}


def test_a_right_on_red_without_a_full_stop_violates_21453b(t_signal: Intersection) -> None:
    events: list[Event] = [("ego", ARRIVED, None, 3.0), ("ego", ENTERED, None, 5.0)]
    assert judge(t_signal, RIGHT, events) == {("ego", "stopBeforeRightOnRed")}


def test_a_right_on_red_after_a_full_stop_keeps_21453b(t_signal: Intersection) -> None:
    events: list[Event] = [
        ("ego", ARRIVED, None, 3.0),
        ("ego", STOPPED, None, 4.0),
        ("ego", ENTERED, None, 6.0),
    ]
    assert judge(t_signal, RIGHT, events) == set()


def _right_on_red(ego_into_car_lane: float) -> list[Event]:
    return [
        ("car1", ARRIVED, None, 5.0),  # straight on its green
        ("ego", ARRIVED, None, 3.0),
        ("ego", STOPPED, None, 4.0),
        ("ego", ENTERED, None, 6.0),
        ("ego", IN, "W2C_0:C2E_0", ego_into_car_lane),
        ("car1", ENTERED, None, 7.0),
        ("car1", OUT, "S2C_0:C2E_0", 8.0),
    ]


def test_a_right_on_red_in_front_of_traffic_on_green_violates_21453b(
    t_signal: Intersection,
) -> None:
    found = judge(t_signal, {**RIGHT, "car1": "W2C_0:C2E_0"}, _right_on_red(7.0))
    assert found == {("ego", "car1", "yieldOnRightOnRed")}


def test_a_right_on_red_that_yields_keeps_21453b(t_signal: Intersection) -> None:
    assert judge(t_signal, {**RIGHT, "car1": "W2C_0:C2E_0"}, _right_on_red(9.5)) == set()


def test_a_left_on_the_stems_red_is_a_red_light_violation(t_signal: Intersection) -> None:
    # the stem's right may go on red (s), its left may not: a red arrow beside an s
    events: list[Event] = [("ego", ARRIVED, None, 3.0), ("ego", ENTERED, None, 5.0)]
    assert judge(t_signal, {"ego": "S2C_0:C2W_0"}, events) == {("ego", "stopAtRed")}
