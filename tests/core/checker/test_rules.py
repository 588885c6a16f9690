"""Traffic rules at the ASP level: hand-written events with numeric times, real clingo.

Times are in seconds with m = 1 s, so a gap of exactly 1.0 is perceptible and 0.99 is not.
"""

from __future__ import annotations

import re
from pathlib import Path

import clingo
import pytest

from service.core.checker.rules import (
    INPUT_PREDICATES,
    REQUESTED_LANE,
    TimedEvent,
    asp_dir,
    event_facts,
    geometry_facts,
    perceptible_order,
    rule_set_file,
    solve_rules,
    time_symbol,
)
from service.core.motion.events import EventKind, LaneEvent
from service.core.network import ControlType, Intersection

ARRIVED, STOPPED, ENTERED = EventKind.ARRIVED, EventKind.STOPPED, EventKind.ENTERED
IN, OUT = EventKind.ENTERED_LANE, EventKind.LEFT_LANE


def judge(
    intersection: Intersection,
    routes: dict[str, str],
    events: list[tuple[str, EventKind, str | None, float]],
    m: float = 1.0,
) -> set[tuple[str, ...]]:
    """Violations as (violator, other, rule) and (violator, rule) for hand-written events.

    A lane given as a route id means that route's connecting lane; None means the fork.
    """
    timed = []
    for k, (car, kind, where, time) in enumerate(events):
        route = intersection.route(routes[car])
        if where is None:
            lane = route.fork
        elif where in intersection.routes:
            lane = intersection.routes[where].connecting_lane
        else:
            lane = where
        timed.append(TimedEvent(car, time_symbol(car, k), LaneEvent(kind, lane, time, 0.0)))
    facts = geometry_facts(intersection) + perceptible_order(timed, m)
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


# --- 22450 (a): stop at the sign -------------------------------------------------------

ALONE = {"ego": "S2C_1:C2W_1"}


def test_running_a_stop_sign_violates_22450a(four_way: Intersection) -> None:
    found = judge(four_way, ALONE, [("ego", ARRIVED, None, 0.0), ("ego", ENTERED, None, 2.0)])
    assert found == {("ego", "stopAtSign")}


def test_stopping_at_the_sign_keeps_22450a(four_way: Intersection) -> None:
    events = [
        ("ego", ARRIVED, None, 0.0),
        ("ego", STOPPED, None, 1.5),
        ("ego", ENTERED, None, 2.0),
    ]
    assert judge(four_way, ALONE, events) == set()


def test_a_car_that_never_enters_has_not_run_the_sign(four_way: Intersection) -> None:
    assert judge(four_way, ALONE, [("ego", ARRIVED, None, 0.0)]) == set()


def test_uncontrolled_junction_has_no_stop_rule(y_junction: Intersection) -> None:
    routes = {"ego": "N2C_0:C2SE_0"}
    found = judge(y_junction, routes, [("ego", ARRIVED, None, 0.0), ("ego", ENTERED, None, 1.0)])
    assert found == set()


# --- 21800 (a): yield to a car already inside from another highway -----------------------

CROSSING = {"ego": "S2C_1:C2W_1", "car1": "W2C_0:C2E_0"}  # car1 comes from ego's left


def _inside(
    car_entered: float, ego_entered: float, ego_into_car_lane: float, car_out_of_ego_lane: float
) -> list[tuple[str, EventKind, str | None, float]]:
    return [
        ("car1", STOPPED, None, car_entered - 2.0),
        ("car1", ENTERED, None, car_entered),
        ("ego", STOPPED, None, ego_entered - 2.0),
        ("ego", ENTERED, None, ego_entered),
        ("ego", IN, "W2C_0:C2E_0", ego_into_car_lane),
        ("car1", OUT, "S2C_1:C2W_1", car_out_of_ego_lane),
    ]


def test_entering_a_lane_before_the_inside_car_left_violates_21800a(
    four_way: Intersection,
) -> None:
    # Entries exactly m apart count as ordered; so do lane events exactly m apart.
    found = judge(four_way, CROSSING, _inside(10.0, 11.0, 12.0, 13.0))
    assert found == {("ego", "car1", "yieldToInside")}


def test_waiting_for_the_inside_car_keeps_21800a(four_way: Intersection) -> None:
    assert judge(four_way, CROSSING, _inside(10.0, 11.0, 13.5, 13.0)) == set()


def test_lane_events_less_than_m_apart_are_not_a_21800a_violation(
    four_way: Intersection,
) -> None:
    assert judge(four_way, CROSSING, _inside(10.0, 11.0, 12.01, 13.0)) == set()


def test_entries_less_than_m_apart_are_simultaneous_not_21800a(four_way: Intersection) -> None:
    # Simultaneous entry with car1 on the ego's left: 21800 (c) asks car1 to yield, not ego.
    found = judge(four_way, CROSSING, _inside(10.0, 10.99, 12.0, 13.0))
    assert ("ego", "car1", "yieldToInside") not in found
    assert found == set()


def test_the_inside_car_owes_nothing_to_the_later_one(four_way: Intersection) -> None:
    events = [
        *_inside(10.0, 11.0, 13.5, 13.0),
        ("car1", IN, "S2C_1:C2W_1", 10.5),
        ("ego", OUT, "W2C_0:C2E_0", 16.0),
    ]
    assert judge(four_way, CROSSING, events) == set()


# --- 21800 (c): simultaneous entry at an all-way stop, yield to the right ----------------

FROM_RIGHT = {"ego": "S2C_1:C2W_1", "car1": "E2C_1:C2S_1"}  # car1 comes from ego's right


def _simultaneous(ego_entered: float, into: float, out: float) -> list[tuple]:  # type: ignore[type-arg]
    return [
        ("car1", STOPPED, None, 8.0),
        ("car1", ENTERED, None, 10.0),
        ("ego", STOPPED, None, 8.0),
        ("ego", ENTERED, None, ego_entered),
        ("ego", IN, "E2C_1:C2S_1", into),
        ("car1", OUT, "S2C_1:C2W_1", out),
    ]


def test_simultaneous_entry_not_yielding_to_the_right_violates_21800c(
    four_way: Intersection,
) -> None:
    found = judge(four_way, FROM_RIGHT, _simultaneous(10.5, 11.0, 13.0))
    assert found == {("ego", "car1", "yieldToRightAtAllWayStop")}


def test_simultaneous_entry_yielding_to_the_right_keeps_21800c(four_way: Intersection) -> None:
    assert judge(four_way, FROM_RIGHT, _simultaneous(10.5, 13.5, 13.0)) == set()


def test_entry_a_full_m_earlier_is_not_simultaneous(four_way: Intersection) -> None:
    # The ego entered first (exactly m before): car1 must yield to it under 21800 (a).
    events = _simultaneous(9.0, 11.0, 13.0)
    events[2] = ("ego", STOPPED, None, 7.0)
    assert ("ego", "car1", "yieldToRightAtAllWayStop") not in judge(four_way, FROM_RIGHT, events)


def test_simultaneous_entry_the_car_on_the_left_yields(four_way: Intersection) -> None:
    events = [
        ("car1", STOPPED, None, 8.0),
        ("car1", ENTERED, None, 10.0),
        ("ego", STOPPED, None, 8.0),
        ("ego", ENTERED, None, 10.2),
        ("car1", IN, "S2C_1:C2W_1", 11.0),
        ("ego", OUT, "E2C_1:C2S_1", 13.0),
    ]
    # Here car1 (on ego's right) went first; the ego on the left owes, car1 does not.
    assert judge(four_way, FROM_RIGHT, events) == set()


# --- 21800 (e): opposite directions with a left turn are left to 21801 --------------------


def test_21800e_excludes_oncoming_left_turns(four_way: Intersection) -> None:
    control = clingo.Control(["--warn=none"])
    control.load(str(rule_set_file(ControlType.ALLWAY_STOP)))
    facts = [
        *geometry_facts(four_way),
        REQUESTED_LANE("ego", four_way.route("S2C_1:C2W_1").connecting_lane),
        REQUESTED_LANE("car1", four_way.route("N2C_0:C2S_0").connecting_lane),
        REQUESTED_LANE("car2", four_way.route("W2C_0:C2E_0").connecting_lane),
    ]
    control.add("base", [], "".join(f"{fact}." for fact in facts))
    control.ground([("base", [])])
    excluded = set()
    with control.solve(yield_=True) as handle:
        for model in handle:
            for atom in model.symbols(atoms=True):
                if atom.match("excluded21800", 2):
                    excluded.add(tuple(a.string for a in atom.arguments))
    assert excluded == {("ego", "car1"), ("car1", "ego")}


# --- 21800 (b): simultaneous entry at an uncontrolled junction ----------------------------

Y_FROM_RIGHT = {"ego": "N2C_0:C2SE_0", "car1": "SW2C_0:C2N_0"}


def _y_events(ego_entered: float, into: float) -> list[tuple]:  # type: ignore[type-arg]
    return [
        ("car1", ENTERED, None, 10.0),
        ("ego", ENTERED, None, ego_entered),
        ("ego", IN, "SW2C_0:C2N_0", into),
        ("car1", OUT, "N2C_0:C2SE_0", 12.0),
    ]


def test_simultaneous_entry_not_yielding_to_the_right_violates_21800b(
    y_junction: Intersection,
) -> None:
    found = judge(y_junction, Y_FROM_RIGHT, _y_events(10.99, 11.0))
    assert found == {("ego", "car1", "yieldOnSimultaneousEntry")}


def test_simultaneous_entry_yielding_keeps_21800b(y_junction: Intersection) -> None:
    assert judge(y_junction, Y_FROM_RIGHT, _y_events(10.5, 12.5)) == set()


def test_uncontrolled_entry_after_the_other_is_21800a(y_junction: Intersection) -> None:
    found = judge(y_junction, Y_FROM_RIGHT, _y_events(11.0, 11.0))
    assert found == {("ego", "car1", "yieldToInside")}


def test_terminating_highway_yields_to_the_continuing_one(town07_y: Intersection) -> None:
    # -35_0 (continuing) has -40_0 (terminating) on its right. Normally the car on the left
    # yields; 21800 (b) makes the terminating highway yield instead.
    routes = {"ego": "-35_0:-41_0", "car1": "-40_0:35_0"}
    ego_goes = [
        ("ego", ENTERED, None, 10.0),
        ("car1", ENTERED, None, 10.2),
        ("ego", IN, "-40_0:35_0", 11.0),
        ("car1", OUT, "-35_0:-41_0", 13.0),
    ]
    assert judge(town07_y, routes, ego_goes) == set()
    car_goes = [
        ("ego", ENTERED, None, 10.0),
        ("car1", ENTERED, None, 10.2),
        ("car1", IN, "-35_0:-41_0", 11.0),
        ("ego", OUT, "-40_0:35_0", 13.0),
    ]
    assert judge(town07_y, routes, car_goes) == {("car1", "ego", "yieldOnSimultaneousEntry")}


# --- 21801: left turn and oncoming traffic -----------------------------------------------

LEFT_VS_ONCOMING = {"ego": "E2C_0:C2S_0", "car1": "W2C_0:C2E_0"}  # T junction, through road


def _left_turn(oncoming_arrived: float, into: float, out: float) -> list[tuple]:  # type: ignore[type-arg]
    return [
        ("car1", ARRIVED, None, oncoming_arrived),
        ("ego", ENTERED, None, 10.0),
        ("ego", IN, "W2C_0:C2E_0", into),
        ("car1", OUT, "E2C_0:C2S_0", out),
    ]


def test_turning_left_in_front_of_close_oncoming_traffic_violates_21801a(
    t_stop: Intersection,
) -> None:
    # car1 arrived less than m after the ego entered: close enough to be a hazard.
    found = judge(t_stop, LEFT_VS_ONCOMING, _left_turn(10.99, 11.0, 13.0))
    assert found == {("ego", "car1", "leftTurnYieldsToOncoming")}


def test_waiting_for_oncoming_traffic_keeps_21801a(t_stop: Intersection) -> None:
    assert judge(t_stop, LEFT_VS_ONCOMING, _left_turn(9.0, 13.5, 13.0)) == set()


def test_oncoming_traffic_arriving_a_full_m_later_is_no_hazard(t_stop: Intersection) -> None:
    assert judge(t_stop, LEFT_VS_ONCOMING, _left_turn(11.0, 11.5, 13.0)) == set()


ONCOMING_VS_LEFT = {"ego": "W2C_0:C2E_0", "car1": "E2C_0:C2S_0"}


def _oncoming(arrived: float, into: float, out: float) -> list[tuple]:  # type: ignore[type-arg]
    return [
        ("car1", ENTERED, None, 10.0),
        ("ego", ARRIVED, None, arrived),
        ("ego", IN, "E2C_0:C2S_0", into),
        ("car1", OUT, "W2C_0:C2E_0", out),
    ]


def test_oncoming_car_cutting_off_a_turning_car_violates_21801b(t_stop: Intersection) -> None:
    found = judge(t_stop, ONCOMING_VS_LEFT, _oncoming(11.0, 12.0, 13.0))
    assert found == {("ego", "car1", "oncomingYieldsToLeftTurn")}


def test_oncoming_car_letting_the_turn_finish_keeps_21801b(t_stop: Intersection) -> None:
    assert judge(t_stop, ONCOMING_VS_LEFT, _oncoming(11.0, 12.5, 13.0)) == set()


def test_21801b_protects_only_a_turn_begun_before_the_oncoming_car_came_close(
    t_stop: Intersection,
) -> None:
    found = judge(t_stop, ONCOMING_VS_LEFT, _oncoming(10.5, 12.0, 13.0))
    assert ("ego", "car1", "oncomingYieldsToLeftTurn") not in found
    assert ("car1", "ego", "leftTurnYieldsToOncoming") not in found  # car1 has no lane event


# --- 21802: stop sign on the minor road of a T ---------------------------------------------

FROM_STOP = {"ego": "S2C_0:C2W_0", "car1": "W2C_0:C2E_0"}


def _after_stop(through_arrived: float, into: float, out: float) -> list[tuple]:  # type: ignore[type-arg]
    return [
        ("ego", ARRIVED, None, 5.0),
        ("ego", STOPPED, None, 8.0),
        ("ego", ENTERED, None, 10.0),
        ("car1", ARRIVED, None, through_arrived),
        ("ego", IN, "W2C_0:C2E_0", into),
        ("car1", OUT, "S2C_0:C2W_0", out),
    ]


def test_pulling_out_in_front_of_an_approaching_car_violates_21802a(
    t_stop: Intersection,
) -> None:
    found = judge(t_stop, FROM_STOP, _after_stop(10.99, 11.0, 13.0))
    assert found == {("ego", "car1", "yieldAfterStop")}


def test_waiting_after_the_stop_keeps_21802a(t_stop: Intersection) -> None:
    assert judge(t_stop, FROM_STOP, _after_stop(9.0, 13.5, 13.0)) == set()


def test_a_car_arriving_a_full_m_after_the_entry_is_not_owed_21802a(t_stop: Intersection) -> None:
    assert judge(t_stop, FROM_STOP, _after_stop(11.0, 11.5, 13.0)) == set()


THROUGH_VS_STOP = {"ego": "W2C_0:C2E_0", "car1": "S2C_0:C2W_0"}


def _through(arrived: float, into: float, stopped: bool = True) -> list[tuple]:  # type: ignore[type-arg]
    events = [
        ("car1", ARRIVED, None, 5.0),
        ("car1", ENTERED, None, 10.0),
        ("ego", ARRIVED, None, arrived),
        ("ego", IN, "S2C_0:C2W_0", into),
        ("car1", OUT, "W2C_0:C2E_0", 13.0),
    ]
    if stopped:
        events.insert(1, ("car1", STOPPED, None, 8.0))
    return events


def test_not_yielding_to_a_car_that_stopped_and_entered_violates_21802b(
    t_stop: Intersection,
) -> None:
    found = judge(t_stop, THROUGH_VS_STOP, _through(11.0, 12.0))
    assert found == {("ego", "car1", "yieldToCarFromStop")}


def test_yielding_to_a_car_that_stopped_and_entered_keeps_21802b(t_stop: Intersection) -> None:
    assert judge(t_stop, THROUGH_VS_STOP, _through(11.0, 12.5)) == set()


def test_21802b_does_not_protect_a_car_that_ran_its_stop_sign(t_stop: Intersection) -> None:
    found = judge(t_stop, THROUGH_VS_STOP, _through(11.0, 12.0, stopped=False))
    assert found == {("car1", "stopAtSign")}


def test_all_way_stop_has_no_21802(four_way: Intersection) -> None:
    routes = {"ego": "W2C_0:C2E_0", "car1": "S2C_0:C2N_0"}
    events = [
        ("ego", STOPPED, None, 1.0),
        ("ego", ENTERED, None, 2.0),
        ("car1", STOPPED, None, 5.0),
        ("car1", ENTERED, None, 10.0),
        ("ego", ARRIVED, None, 0.0),
        ("car1", ARRIVED, None, 0.0),
    ]
    assert judge(four_way, routes, events) == set()


# --- 21803: yield sign on the minor road of a priority junction -----------------------------

FROM_YIELD = {"ego": "S2C_0:C2N_0", "car1": "W2C_0:C2E_0"}


def _at_yield(through_arrived: float, into: float, out: float) -> list[tuple]:  # type: ignore[type-arg]
    return [
        ("ego", ARRIVED, None, 8.0),
        ("ego", ENTERED, None, 10.0),
        ("car1", ARRIVED, None, through_arrived),
        ("ego", IN, "W2C_0:C2E_0", into),
        ("car1", OUT, "S2C_0:C2N_0", out),
    ]


def test_the_minor_road_has_yield_signs_and_no_stop_signs(skewed_yield: Intersection) -> None:
    assert skewed_yield.control is ControlType.PRIORITY
    signs = {f.lane: (f.stop_sign, f.yield_sign) for f in skewed_yield.forks.values()}
    assert signs == {"W2C_0": (False, False), "E2C_0": (False, False),
                     "S2C_0": (False, True), "N2C_0": (False, True)}  # fmt: skip


def test_pulling_out_in_front_of_an_approaching_car_violates_21803a(
    skewed_yield: Intersection,
) -> None:
    found = judge(skewed_yield, FROM_YIELD, _at_yield(10.99, 11.0, 13.0))
    assert found == {("ego", "car1", "yieldAtYieldSign")}


def test_pulling_out_in_front_of_a_car_inside_violates_21803a(skewed_yield: Intersection) -> None:
    found = judge(skewed_yield, FROM_YIELD, _at_yield(3.0, 11.0, 13.0))
    assert found == {("ego", "car1", "yieldAtYieldSign")}


def test_waiting_at_the_yield_sign_keeps_21803a(skewed_yield: Intersection) -> None:
    assert judge(skewed_yield, FROM_YIELD, _at_yield(9.0, 13.5, 13.0)) == set()


def test_a_yield_sign_asks_no_stop(skewed_yield: Intersection) -> None:
    # the ego never stops: at a stop sign that alone would break 22450 (a)
    assert judge(skewed_yield, FROM_YIELD, _at_yield(11.0, 11.5, 13.0)) == set()
    alone = [("ego", ARRIVED, None, 1.0), ("ego", ENTERED, None, 2.0)]
    assert judge(skewed_yield, {"ego": "S2C_0:C2N_0"}, alone) == set()


THROUGH_VS_YIELD = {"ego": "W2C_0:C2E_0", "car1": "S2C_0:C2N_0"}


def _through_yield(arrived: float, into: float) -> list[tuple]:  # type: ignore[type-arg]
    return [
        ("car1", ARRIVED, None, 5.0),
        ("car1", ENTERED, None, 10.0),
        ("ego", ARRIVED, None, arrived),
        ("ego", IN, "S2C_0:C2N_0", into),
        ("car1", OUT, "W2C_0:C2E_0", 13.0),
    ]


def test_not_yielding_to_a_car_that_entered_from_the_yield_sign_violates_21803b(
    skewed_yield: Intersection,
) -> None:
    found = judge(skewed_yield, THROUGH_VS_YIELD, _through_yield(11.0, 12.0))
    assert found == {("ego", "car1", "yieldToCarFromYieldSign")}


def test_yielding_to_a_car_that_entered_from_the_yield_sign_keeps_21803b(
    skewed_yield: Intersection,
) -> None:
    assert judge(skewed_yield, THROUGH_VS_YIELD, _through_yield(11.0, 12.5)) == set()


def test_the_major_road_owes_a_later_minor_car_nothing(skewed_yield: Intersection) -> None:
    # the ego on the major road entered first; the minor car arrives later and waits
    events = [
        ("ego", ARRIVED, None, 5.0),
        ("ego", ENTERED, None, 6.0),
        ("car1", ARRIVED, None, 7.0),
        ("car1", ENTERED, None, 9.0),
        ("car1", IN, "W2C_0:C2E_0", 10.0),
        ("ego", OUT, "S2C_0:C2N_0", 8.0),
    ]
    assert judge(skewed_yield, THROUGH_VS_YIELD, events) == set()


def test_a_yield_junction_keeps_21801_on_the_major_road(skewed_yield: Intersection) -> None:
    routes = {"ego": "W2C_0:C2N_0", "car1": "E2C_0:C2W_0"}
    events = [
        ("ego", ENTERED, None, 10.0),
        ("car1", ARRIVED, None, 10.5),
        ("ego", IN, "E2C_0:C2W_0", 11.0),
        ("car1", OUT, "W2C_0:C2N_0", 13.0),
    ]
    assert judge(skewed_yield, routes, events) == {("ego", "car1", "leftTurnYieldsToOncoming")}


def test_priority_stop_and_priority_differ_only_in_the_stop(
    t_stop: Intersection, cache_dir: Path
) -> None:
    from service.core.network import load_intersection

    t_yield = load_intersection("t-stop", control="priority", cache_dir=cache_dir)
    assert {f.lane for f in t_yield.forks.values() if f.yield_sign} == {"S2C_0"}
    events = [("ego", ARRIVED, None, 1.0), ("ego", ENTERED, None, 2.0)]
    assert judge(t_stop, {"ego": "S2C_0:C2W_0"}, events) == {("ego", "stopAtSign")}
    assert judge(t_yield, {"ego": "S2C_0:C2W_0"}, events) == set()


# --- The files themselves -------------------------------------------------------------------


def _lp_files() -> list[Path]:
    return sorted(asp_dir().rglob("*.lp"))


def test_every_rule_file_opens_with_its_contract() -> None:
    for path in _lp_files():
        head = path.read_text().split("\n\n")[0] + path.read_text()[:4000]
        for heading in ("Input predicates", "Output predicates", "Constants"):
            assert heading in head, f"{path.name} lacks '{heading}' in its opening comment"


def test_every_fact_builder_names_a_predicate_of_the_rules() -> None:
    text = "\n".join(
        "\n".join(line for line in p.read_text().splitlines() if not line.startswith("%"))
        for p in _lp_files()
    )
    for predicate in INPUT_PREDICATES:
        calls = re.findall(rf"\b{predicate.name}\(([^()]*(?:\([^()]*\))?[^()]*)\)", text)
        arities = {len(re.split(r",(?![^(]*\))", call)) for call in calls}
        assert predicate.arity in arities, f"{predicate.name}/{predicate.arity} is unused"


@pytest.mark.parametrize("control", list(ControlType))
def test_each_control_type_has_its_rule_set(control: ControlType) -> None:
    assert rule_set_file(control).is_file()


@pytest.mark.parametrize(
    ("facts", "why"),
    [
        ("time(a). time(b). lessThan(a,b). equal(a,b).", "ordered and simultaneous"),
        ("time(a). time(b). lessThan(a,b). lessThan(b,a).", "ordered both ways"),
        ("time(a). time(b). lessThan(a,b). realLTE(b,a).", "against the real order"),
    ],
)
def test_time_constraints_reject_contradictions(facts: str, why: str) -> None:
    control = clingo.Control(["--warn=none"])
    control.load(str(asp_dir() / "time.lp"))
    control.add("base", [], facts)
    control.ground([("base", [])])
    assert control.solve().unsatisfiable, why


def test_perceptible_order_ties_at_exactly_m_are_ordered() -> None:
    events = [
        TimedEvent("a", time_symbol("a", 0), LaneEvent(EventKind.ENTERED, "f", 1.0, 0.0)),
        TimedEvent("b", time_symbol("b", 0), LaneEvent(EventKind.ENTERED, "g", 2.0, 0.0)),
        TimedEvent("c", time_symbol("c", 0), LaneEvent(EventKind.ENTERED, "h", 2.9999, 0.0)),
    ]
    facts = {str(f) for f in perceptible_order(events, 1.0)}
    assert 'lessThan(t("a",0),t("b",0))' in facts
    assert 'equal(t("b",0),t("c",0))' in facts
    assert 'lessThan(t("a",0),t("c",0))' in facts
