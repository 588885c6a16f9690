"""Distinct extensions: --count, seeds that matter, and avoiding test-cases already taken.
Real SUMO, clingo and z3; every test-case returned is checked by the checker on its own."""

from __future__ import annotations

import itertools

import pytest

from service.core.errors import InvalidInput, NoneFound
from service.core.generator.extension import Extensions, extend_testcase, extend_testcases
from service.core.generator.variety import (
    DISTINCT_GAP,
    describe_variants,
    distinct_count,
    is_new,
    seed_aim,
    signature,
    variant_name,
)
from service.core.sim.replay import evaluate
from service.core.testcase import (
    MAX_NAME_LENGTH,
    TestCase,
    dump_testcase,
    load_testcase_intersection,
    name_stem,
    new_testcase,
)
from tests.conftest import DATA
from tests.core.generator.test_extension import assert_strictly_more_complex

pytestmark = pytest.mark.slow  # 14 s of work or more: `make test-fast` leaves it out

ROUTE = ["W2C_0:C2E_0"]  # crosses the ego's route at the four-way stop
JUNCTIONS = DATA / "junctions"


@pytest.fixture(scope="module")
def start() -> TestCase:
    return new_testcase("4way-stop", "S2C_1:C2N_1", duration=30.0, name="variety")


@pytest.fixture(scope="module")
def five(start: TestCase) -> Extensions:
    return extend_testcases(start, ROUTE, count=5, seed=0, budget=240)


def test_count_returns_distinct_verified_extensions(start: TestCase, five: Extensions) -> None:
    testcases = [e.testcase for e in five.found]
    assert len(testcases) == 5, five.shortfall(5)
    assert distinct_count(testcases) == 5
    for a, b in itertools.combinations(testcases, 2):
        assert dump_testcase(a) != dump_testcase(b)
        assert not signature(a).same_as(signature(b))
    for testcase in testcases:
        assert_strictly_more_complex(start, testcase)


def test_the_first_of_count_is_the_single_extension(start: TestCase, five: Extensions) -> None:
    single = extend_testcase(start, ROUTE, seed=0, budget=240)
    assert dump_testcase(single.testcase) == dump_testcase(five.found[0].testcase)


def test_distinct_means_another_order_or_entries_a_gap_apart(five: Extensions) -> None:
    marks = [signature(e.testcase) for e in five.found]
    for a, b in itertools.combinations(marks, 2):
        pairs = list(zip(a.cars, b.cars, strict=True))
        assert (
            a.order != b.order
            or any(x.stops != y.stops for x, y in pairs)
            or any(abs(x.entry - y.entry) >= DISTINCT_GAP for x, y in pairs)
            or any(abs(x.arrival - y.arrival) >= DISTINCT_GAP for x, y in pairs)
        )


def test_seeds_give_distinct_test_cases(start: TestCase) -> None:
    testcases = [extend_testcase(start, ROUTE, seed=s, budget=240).testcase for s in range(4)]
    assert distinct_count(testcases) == 4
    again = extend_testcase(start, ROUTE, seed=3, budget=240).testcase
    assert dump_testcase(again) == dump_testcase(testcases[3])  # the same seed, the same bytes
    for testcase in testcases:
        assert_strictly_more_complex(start, testcase)


def test_avoid_gives_the_next_distinct_one(start: TestCase, five: Extensions) -> None:
    first = five.found[0].testcase
    other = extend_testcase(start, ROUTE, seed=0, budget=240, avoid=[first]).testcase
    assert is_new(signature(other), [signature(first)])
    assert_strictly_more_complex(start, other)


def test_fewer_than_asked_says_why(start: TestCase) -> None:
    many = extend_testcases(start, ROUTE, count=200, seed=0, budget=600, max_orders=3)
    assert len(many.found) < 200
    reason = many.shortfall(200)
    assert reason is not None and f"{len(many.found)} distinct extensions" in reason
    # which of the search's counts ran out: Step 2's answer sets, then the timings'
    assert "answer sets" in reason and ("ran out" in reason or "looked at" in reason), reason
    assert distinct_count([e.testcase for e in many.found]) == len(many.found)


def test_avoiding_everything_found_is_none_found(start: TestCase) -> None:
    few = extend_testcases(start, ROUTE, count=200, seed=0, budget=600, max_orders=1)
    with pytest.raises(NoneFound, match="the same test-case as one already taken"):
        extend_testcase(start, ROUTE, seed=0, budget=600, max_orders=1,
                        avoid=[e.testcase for e in few.found])  # fmt: skip


def test_count_below_one_is_bad_input(start: TestCase) -> None:
    with pytest.raises(InvalidInput, match="count must be at least 1"):
        extend_testcases(start, ROUTE, count=0)


def test_seed_aims_spread_and_never_repeat() -> None:
    aims = [seed_aim(s) for s in range(1, 64)]
    assert seed_aim(0) is None
    assert aims[:4] == [0.5, 0.25, 0.75, 0.125]
    assert len(set(aims)) == len(aims) and all(0 < a < 1 for a in aims if a is not None)


def test_each_variant_is_described_by_what_tells_it_apart(five: Extensions) -> None:
    testcases = [e.testcase for e in five.found]
    lines = describe_variants(testcases)
    orders = {(signature(t).order, signature(t).cars[0].stops) for t in testcases}
    for line, testcase in zip(lines, testcases, strict=True):
        car = signature(testcase).cars[0]
        assert line.startswith("order ") and f" of {len(orders)}; " in line
        assert f"car1 ({ROUTE[0]}) {'stops' if car.stops else 'does not stop'}" in line
        assert f"arrives at {car.arrival:.2f} s, enters at {car.entry:.2f} s" in line
        violated = (testcase.provenance or {})["complexity_certificate_violates"]
        assert f"breaks {violated[0]['rule']} of car1" in line
        aimed = (testcase.provenance or {}).get("timing_aim")
        assert line.endswith("smoothest timing") == (aimed is None), line
    # variants of one order carry its number; another order gets the next
    numbers = [line.split(";")[0] for line in lines]
    keys = [(signature(t).order, signature(t).cars[0].stops) for t in testcases]
    assert all((numbers[i] == numbers[j]) == (keys[i] == keys[j])
               for i, j in itertools.combinations(range(len(lines)), 2))  # fmt: skip


def test_variants_that_read_alike_are_told_apart(five: Extensions) -> None:
    """Two variants whose lines differ only in their order's number (their times round
    alike; their orders differ in a relation the line does not name): each says which it
    reads like, its new car's lowest speed before entering and what its order holds."""
    first = five.found[0].testcase
    car = first.nonegos[-1]
    slower = [s.model_copy(update={"speed": max(0.0, s.speed - 0.2)}) for s in car.trajectory]
    provenance = dict(first.provenance or {})
    provenance["order"] = [*provenance["order"], 'lessThan(t("car1",0),t("car1",99))']
    second = first.model_copy(
        update={"nonegos": [*first.nonegos[:-1], car.model_copy(update={"trajectory": slower})],
                "provenance": provenance}
    )  # fmt: skip
    one, two = describe_variants([first, second])
    assert one.startswith("order 1 of 2; ") and two.startswith("order 2 of 2; ")
    assert (
        one.split("; reads like")[0][len("order 1 of 2") :]
        == two.split("; reads like")[0][len("order 2 of 2") :]
    )
    entry = signature(first).cars[0].entry
    lowest = min(s.speed for s in car.trajectory if s.t <= entry)
    assert one.endswith(f"; reads like variant 2 but: car1 slows to {lowest:.2f} m/s")
    assert two.endswith(
        f"; reads like variant 1 but: car1 slows to {max(0.0, lowest - 0.2):.2f} m/s, "
        "1 relation(s) of its order of events are not theirs"
    )
    alone = one.split("; reads like")[0].replace("order 1 of 2", "order 1 of 1")
    assert describe_variants([first]) == [alone]  # nothing reads like it


@pytest.mark.parametrize(
    ("name", "number", "expected"),
    [
        ("4way-stop C S2C_1:C2N_1 level 1", 2, "4way-stop C S2C_1:C2N_1 variant 2 level 1"),
        ("west variant 2 level 3", 1, "west variant 2 variant 1 level 3"),
        ("left", 3, "left variant 3"),
        (
            "x" * MAX_NAME_LENGTH + " level 12",
            7,
            "x" * (MAX_NAME_LENGTH - 19) + " variant 7 level 12",
        ),
    ],
)
def test_variant_names_keep_the_level_last(name: str, number: int, expected: str) -> None:
    named = variant_name(name, number)
    assert named == expected and len(named) <= MAX_NAME_LENGTH
    assert name_stem(named).endswith(f" variant {number}")  # the next level renames it


@pytest.mark.parametrize(
    ("network", "ego", "route"),
    [
        ("t-stop", "E2C_0:C2S_0", "W2C_0:C2E_0"),
        (str(JUNCTIONS / "y-uneven.net.xml"), "ESE2C_0:C2SW_0", "N2C_0:C2SW_0"),
    ],
    ids=["t-stop", "y-uneven"],
)
def test_count_aims_in_the_orders_alike_once_the_verified_ones_are_looked_through(
    network: str, ego: str, route: str
) -> None:
    """Here Step 2 verifies one order of the test-case's cars, and every point of its
    windows gives fewer than 20 test-cases (14 on the T, 16 on the uneven Y); the orders
    alike to it, where the certificates drive otherwise, open other windows of entry and
    arrival times: 20 distinct ones, each verified on its own, and each certificate
    replayed in SUMO as recorded (the T's variant 20 once crept over its line there and
    entered 0.36 s late, giving the oncoming car the right-of-way)."""
    start = new_testcase(network, ego, duration=25.0)
    twenty = extend_testcases(start, [route], count=20, seed=0, budget=600)
    testcases = [e.testcase for e in twenty.found]
    assert len(testcases) == 20, twenty.shortfall(20)
    assert twenty.alike_orders > 0
    assert distinct_count(testcases) == 20
    intersection = load_testcase_intersection(start)
    for testcase in testcases:
        assert_strictly_more_complex(start, testcase)
        solvable = evaluate(testcase, "certificate:solvability", intersection).verdict
        assert solvable.passed, (testcase.name, solvable.reasons)
        harder = evaluate(testcase, "certificate:complexity", intersection).verdict
        assert harder.goal_reached and not harder.passed, (testcase.name, harder.reasons)
