"""Step 2's event times (asp/time_dl.lp with clingo-dl) and the answer sets it draws."""

from __future__ import annotations

import clingo
import clingo.ast
import pytest
from clingodl import ClingoDLTheory

from service.core.checker.check import Judge
from service.core.checker.rules import asp_dir
from service.core.generator.additions import ordering_cars, validate_routes
from service.core.generator.ordering import OrderingSearch
from service.core.generator.ordering_facts import (
    CarKind,
    OrderingCar,
    event_groups,
    stand_distance,
)
from service.core.generator.search import order_limits
from service.core.motion.events import EventKind, LaneEvent
from service.core.motion.poses import generate_poses
from service.core.network import Intersection
from service.core.testcase import new_testcase


def satisfiable(facts: str, m_ms: int = 1000, margin_ms: int = 200) -> bool:
    """Whether time_dl.lp with these facts has a model (times in ms)."""
    theory = ClingoDLTheory()  # type: ignore[no-untyped-call]
    control = clingo.Control(
        ["--warn=none", f"--const=m_ms={m_ms}", f"--const=margin_ms={margin_ms}"]
    )
    theory.register(control)
    with clingo.ast.ProgramBuilder(control) as builder:
        add = lambda ast: theory.rewrite_ast(ast, builder.add)  # noqa: E731
        clingo.ast.parse_files([str(asp_dir() / "time_dl.lp")], add)
        clingo.ast.parse_string(facts, add)
    control.ground([("base", [])])
    theory.prepare(control)
    return bool(control.solve(on_model=theory.on_model).satisfiable)


@pytest.mark.parametrize(
    ("facts", "expected", "why"),
    [
        ("symbolicTime(a;b;c). lessThan(a,b). lessThan(b,c). lessThan(c,a). horizon(9000).",
         False, "a cycle of perceptible orders has no times"),
        ("symbolicTime(a;b;c). lessThan(a,b). lessThan(b,c). horizon(9000).",
         True, "a chain of orders has times"),
        ("symbolicTime(a). minGap(0,a,3000). horizon(2000).",
         False, "a car cannot reach its event before its least travel time"),
        ("symbolicTime(a). minGap(0,a,3000). horizon(4000).", True, "within the duration"),
        ("oldTime(o,1000,1000). symbolicTime(s). lessThan(o,s). horizon(2100).",
         False, "after an old car's event by m plus the margin (1.2 s) is past the horizon"),
        ("oldTime(o,1000,1000). symbolicTime(s). lessThan(o,s). horizon(2300).",
         True, "m plus the margin fits"),
        ("oldTime(o,5000,5000). symbolicTime(s). equal(s,o). minGap(0,s,5900). horizon(9000).",
         False, "simultaneous means within m minus the margin (0.8 s)"),
        ("oldTime(o,5000,5000). symbolicTime(s). equal(s,o). minGap(0,s,5700). horizon(9000).",
         True, "0.7 s after is simultaneous"),
        ("oldTime(o,0,0). oldTime(p,500,500). lessThan(o,p). horizon(9000).",
         True, "old cars' facts are numbers, judged without the margin"),
        ("symbolicTime(a). earliest(a,6000). latest(a,5000). horizon(9000).",
         False, "queue: a follower that must arrive after the leader entered (6 s) cannot "
                "also arrive before the old car behind it (5 s)"),
        ("symbolicTime(a). earliest(a,5000). latest(a,6000). horizon(9000).",
         True, "queue: between the leader's entry and the arrival of the car behind"),
        ("symbolicTime(a). earliest(a,9500). horizon(9000).",
         False, "queue: a car whose leader enters after the duration never arrives in it"),
        ("symbolicTime(a;b). headway(b,a,1000). lessThan(a,b). horizon(9000).",
         False, "queue headway: a follower's event 1 s after its leader's cannot come first"),
        ("symbolicTime(a;b). headway(b,a,1000). lessThan(b,a). horizon(9000).",
         True, "queue headway: the follower after its leader"),
        ("symbolicTime(e;l). maxGapInside(e,l,3000). horizon(9000). &diff{ e - 0 } <= 1000. "
         "&diff{ 0 - l } <= -5000.",
         False, "a car that entered by 1 s leaves its lane within 3 s: not at 5 s"),
        ("symbolicTime(e;l). maxGapInside(e,l,3000). horizon(9000). &diff{ e - 0 } <= 1000. "
         "&diff{ 0 - l } <= -3500.",
         True, "it may leave at 3.5 s"),
        ("symbolicTime(p;q;r). lingerLevel(p,q,2000). lingerAfter(p,q,2000,r,3000). "
         "horizon(20000). &diff{ p - 0 } <= 1000. &diff{ 0 - q } <= -4000. "
         "&diff{ r - q } <= 2000.",
         False, "a segment that took 3 s (2 s or more) puts r at least 3 s after q"),
        ("symbolicTime(p;q;r). lingerLevel(p,q,2000). lingerAfter(p,q,2000,r,3000). "
         "horizon(20000). &diff{ p - 0 } <= 1000. &diff{ r - q } <= 2000.",
         True, "a segment under 2 s does not linger: r may follow q sooner"),
        ("symbolicTime(o;p;q). lingerLevel(p,q,2000). lingerBefore(p,q,2000,o,3000). "
         "horizon(20000). &diff{ 0 - q } <= -9000. &diff{ p - q } <= -2000. "
         "&diff{ p - o } <= 2000.",
         False, "nor can it have come to p at full speed: p at least 3 s after o"),
        ("symbolicTime(e). phaseAt(e,1). phaseSpan(1,20000,23000). minGap(0,e,22900). "
         "horizon(45000).",
         False, "an entry in the phase from 20 to 23 s keeps the margin (0.2 s) from its end"),
        ("symbolicTime(e). phaseAt(e,1). phaseSpan(1,20000,23000). minGap(0,e,22700). "
         "horizon(45000).",
         True, "22.7 s is inside, with the margin"),
        ("symbolicTime(e). phaseAt(e,1). phaseSpan(1,20000,23000). horizon(45000). "
         "&diff{ e - 0 } <= 20100.",
         False, "nor may it be within the margin after the switch (20.1 s)"),
    ],
)  # fmt: skip
def test_difference_constraints_decide_the_times(facts: str, expected: bool, why: str) -> None:
    assert satisfiable(facts) is expected, why


def test_a_stop_adds_its_gaps_and_running_a_sign_bounds_the_approach() -> None:
    base = "symbolicTime(a;e). minGap(0,a,1000). minGap(a,e,1000). horizon(9000). "
    stopped = base + 'stoppedAtForkAtTime("v",f,s). minGapStopped("v",a,e,4000). '
    assert satisfiable(stopped + "&diff{ e - 0 } <= 4500.") is False
    assert satisfiable(base + 'minGapStopped("v",a,e,4000). &diff{ e - 0 } <= 4500.') is True
    running = base + 'maxGapRunning("v",a,e,1500). &diff{ a - 0 } <= 1000. '
    assert satisfiable(running + "&diff{ 0 - e } <= -3000.") is False
    assert satisfiable(running + 'stoppedAtForkAtTime("v",f,s). &diff{ 0 - e } <= -3000.')


@pytest.mark.parametrize("seed", [0, 1])
def test_every_answer_set_comes_with_times_that_keep_its_relations(
    four_way: Intersection, seed: int
) -> None:
    old = new_testcase("4way-stop", "S2C_1:C2W_1", duration=25.0)
    routes = validate_routes(old, four_way, ["W2C_0:C2E_0", "N2C_0:C2S_0"])
    ego_route = four_way.route(old.ego.route.id)
    tracks = generate_poses(
        four_way, [(ego_route, 30.0), *((r, 30.0) for r in routes)], 8.0, 25.0, 0.1
    )
    ids = ["car1", "car2"]
    cars = ordering_cars(
        old,
        Judge(old, four_way),
        four_way,
        tracks[0],
        dict(zip(ids, tracks[1:], strict=True)),
        routes,
        ids,
    )
    limits = order_limits(old)
    search = OrderingSearch(four_way, cars, old.params.m, seed, limits)
    drawn = [search.next_ordering() for _ in range(5)]
    assert all(ordering is not None for ordering in drawn)
    for ordering in drawn:
        assert ordering is not None
        times = dict(ordering.times)
        for kind, a, b in ordering.relations:
            gap = times[str(b)] - times[str(a)]
            if kind == "lessThan":
                assert gap >= old.params.m + limits.margin - 1e-9
            else:
                assert abs(gap) < old.params.m - limits.margin
        assert all(0 <= t <= old.duration - limits.margin for t in times.values())
    assert len({o.relations for o in drawn if o is not None}) == 5  # each is new


def test_a_stopping_car_stands_before_every_event_of_the_point_where_it_enters() -> None:
    # On a skewed junction the rectangle touches connecting lanes a hair before the junction
    # polygon: one point of the drive, and the stand must come before all of it.
    events = (
        LaneEvent(EventKind.ARRIVED, "f", 2.5, 20.0),
        LaneEvent(EventKind.ENTERED_LANE, ":C_3_0", 3.75, 29.99698),
        LaneEvent(EventKind.ENTERED, "f", 3.75, 29.99699),
        LaneEvent(EventKind.ENTERED_LANE, ":C_2_0", 4.0, 32.17),
    )
    car = OrderingCar("ego", CarKind.CERTIFICATE, "f", ":C_3_0", events, 8.0)
    stand = stand_distance(car)
    assert stand is not None and 20.0 < stand < 29.99698
    assert [len(group) for group in event_groups(car)] == [1, 2, 1]


def test_a_car_that_enters_where_it_arrives_cannot_stop_before_the_line() -> None:
    events = (
        LaneEvent(EventKind.ARRIVED, "f", 0.0, 0.0),
        LaneEvent(EventKind.ENTERED, "f", 0.0, 0.001),
    )
    car = OrderingCar("car1", CarKind.NEW, "f", ":C_0_0", events)
    assert stand_distance(car) is None


def test_what_step3_rules_out_stays_out_of_every_later_answer_set(four_way: Intersection) -> None:
    """Refusals teach Step 2: once relations are forbidden (an untimeable order's core) no
    later answer set has all of them; once an order is blocked as alike (its relations
    among the test-case's cars and its new cars' stops), no later one repeats them."""
    old = new_testcase("4way-stop", "S2C_1:C2W_1", duration=25.0)
    routes = validate_routes(old, four_way, ["W2C_0:C2E_0", "N2C_0:C2S_0"])
    tracks = generate_poses(
        four_way,
        [(four_way.route(old.ego.route.id), 30.0), *((r, 30.0) for r in routes)],
        8.0,
        25.0,
        0.1,
    )
    ids = ["car1", "car2"]
    cars = ordering_cars(old, Judge(old, four_way), four_way, tracks[0],
                         dict(zip(ids, tracks[1:], strict=True)), routes, ids)  # fmt: skip
    search = OrderingSearch(four_way, cars, old.params.m, 0, order_limits(old))
    first = search.next_ordering()
    assert first is not None
    core = list(first.relations[:2])
    search.forbid(core)
    second = search.next_ordering()
    assert second is not None
    among_new = [
        relation
        for relation, named in zip(second.relations, second.named, strict=True)
        if '"ego"' not in " ".join(named) and '"illegal"' not in " ".join(named)
    ]
    assert among_new  # the two new cars meet: their order is part of the test-case
    search.block_alike(among_new, second.stops & set(ids), ids)
    later = [search.next_ordering() for _ in range(8)]
    assert all(ordering is not None for ordering in later)
    for ordering in later:
        assert ordering is not None
        assert not set(core) <= set(ordering.relations)
        alike = set(among_new) <= set(ordering.relations)
        assert not (alike and ordering.stops & set(ids) == second.stops & set(ids))
