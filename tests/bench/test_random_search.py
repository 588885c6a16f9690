"""The random-search baseline: what it finds is verified, and the same seed finds the same."""

from __future__ import annotations

from bench.random_search import random_extension
from service.core.generator.variety import distinct_count, signature
from service.core.generator.verification import verify_extension
from service.core.testcase import dump_testcase, load_testcase_intersection, new_testcase

ROUTE = "SW2C_0:C2N_0"
TRIALS = 100  # bounded trials, never time: seed 0 finds its first extension at trial 72


def test_random_search_finds_a_verified_extension_deterministically() -> None:
    old = new_testcase("y-uncontrolled", "N2C_0:C2SE_0", duration=25.0)
    first = random_extension(old, ROUTE, seed=0, trials=TRIALS)
    assert first.testcase is not None, f"nothing verified in {first.trials} trials"
    assert first.trials <= TRIALS
    new = first.testcase
    assert new.nonegos[: len(old.nonegos)] == old.nonegos
    assert [(n.id, n.route.id, n.added_in) for n in new.nonegos] == [("car1", ROUTE, 1)]
    junction = load_testcase_intersection(new)
    assert verify_extension(old, new, junction, ["car1"]) is None

    again = random_extension(old, ROUTE, seed=0, trials=TRIALS)
    assert again.trials == first.trials
    assert again.testcase is not None
    assert dump_testcase(again.testcase) == dump_testcase(new)

    # bench_variety counts the sampler's finds as the generator's: by their signature,
    # read from the test-case (its new car's route, stop, arrival and entry)
    assert {e.kind for e in new.nonegos[0].events} >= {"arrived", "entered", "exited"}
    mark = signature(new)
    assert [(c.car, c.route) for c in mark.cars] == [("car1", ROUTE)]
    assert 0 < mark.cars[0].arrival < mark.cars[0].entry
    assert distinct_count([new, again.testcase]) == 1
