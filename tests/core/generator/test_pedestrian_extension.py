"""The generator adds people on foot (docs/pedestrians.md): real SUMO, clingo and z3, and
every result checked independently of the search, on the skewed all-way stop with
crosswalks, its signalized sibling and a Y of our own."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from service.core.checker.check import check_testcase
from service.core.errors import NoMoreComplexTestCase, UnknownWalk
from service.core.generator.chain import grow
from service.core.generator.extension import Extension, extend_testcase
from service.core.motion.invariants import motion_fault
from service.core.network import load_intersection
from service.core.testcase import TestCase, dump_testcase, new_testcase
from tests.conftest import TOWN05
from tests.core.generator.test_extension import assert_strictly_more_complex, samples
from tests.helpers import off_road_samples, off_walkable_samples

JUNCTIONS = Path(__file__).parents[2] / "data" / "junctions"


def assert_lawful_pedestrians(old: TestCase, new: TestCase) -> None:
    """The new pedestrians walk within their bounds on walkable ground, break no rule of
    people on foot, and the complexity certificate fails by one of their right-of-ways."""
    added = [p for p in new.pedestrians if p.id not in {q.id for q in old.pedestrians}]
    assert added
    walking = new.params.walk
    for person in added:
        assert motion_fault(samples(person.trajectory), walking, new.timestep) is None
    assert off_walkable_samples(new) == []
    assert new.certificates is not None
    verdict = check_testcase(new, samples(new.certificates.solvability), "solvability")
    assert verdict.passed and not verdict.pedestrians_broke, verdict.reasons


@pytest.fixture(scope="module")
def right_turn() -> tuple[TestCase, Extension]:
    """The ego turns right into the north arm while a pedestrian walks over it towards
    the ego's exit lane."""
    old = new_testcase("crosswalk-stop", "E2C_1:C2N_1", duration=30.0)
    return old, extend_testcase(old, [], walks=["C_c0-"])


def test_a_pedestrian_makes_the_right_turn_strictly_more_complex(
    right_turn: tuple[TestCase, Extension],
) -> None:
    old, extension = right_turn
    new = extension.testcase
    assert new.schema_ == "scengen/testcase/2"
    assert [(p.id, p.walk, p.added_in) for p in new.pedestrians] == [("ped1", "C_c0-", 1)]
    assert_strictly_more_complex(old, new)
    assert_lawful_pedestrians(old, new)
    provenance = new.provenance or {}
    assert provenance["new_nonegos"] == ["ped1"]
    assert provenance["complexity_certificate_violates"] == [
        {"car": "ped1", "rule": "yieldToPedestrian"}
    ]
    # she steps onto the crosswalk before the complexity certificate reaches it
    assert new.certificates is not None
    verdict = check_testcase(new, samples(new.certificates.complexity), "complexity")
    (violation,) = verdict.violations
    assert violation.law == "21950(a)" and violation.other == "ped1"


def test_the_same_seed_gives_the_same_bytes(right_turn: tuple[TestCase, Extension]) -> None:
    old, extension = right_turn
    again = extend_testcase(old, [], walks=["C_c0-"])
    assert dump_testcase(again.testcase) == dump_testcase(extension.testcase)


def test_certificates_pass_scengen_check_as_a_separate_process(
    right_turn: tuple[TestCase, Extension], tmp_path: Path
) -> None:
    new = right_turn[1].testcase
    assert new.certificates is not None
    (tmp_path / "t.json").write_text(dump_testcase(new))
    for kind, expected in (("solvability", 0), ("complexity", 1)):
        rows = [s.model_dump() for s in getattr(new.certificates, kind)]
        (tmp_path / f"{kind}.json").write_text(json.dumps(rows))
        run = subprocess.run(
            [sys.executable, "-m", "service", "check", "t.json", "--ego", f"{kind}.json",
             "--json"],
            capture_output=True, text=True, cwd=tmp_path, timeout=120,
        )  # fmt: skip
        assert run.returncode == expected, run.stderr
        verdict = json.loads(run.stdout)
        if kind == "complexity":
            assert [v["other"] for v in verdict["violations"]] == ["ped1"]


def test_a_car_and_a_pedestrian_in_one_extension() -> None:
    old = new_testcase("crosswalk-stop", "S2C_2:C2W_2", duration=30.0)
    new = extend_testcase(old, ["N2C_1:C2S_1"], walks=["C_c3-"]).testcase
    assert [n.id for n in new.nonegos] == ["car1"]
    assert [p.id for p in new.pedestrians] == ["ped1"]
    assert_strictly_more_complex(old, new)
    assert_lawful_pedestrians(old, new)
    assert off_road_samples(new) == []


def test_a_car_joins_a_level_with_a_pedestrian_free_to_stop_at_its_sign_or_not(
    right_turn: tuple[TestCase, Extension],
) -> None:
    """At a sign Step 2 lets a new car stop or not, with pedestrians as without them; the
    verification held it to its sign once a pedestrian was there, and every order failed
    ("car1 breaks stopAtSign"). It still holds it to the rules of people on foot."""
    _, extension = right_turn
    level1 = extension.testcase
    level2 = extend_testcase(level1, ["S2C_1:C2N_1"]).testcase
    assert [n.id for n in level2.nonegos] == ["car1"]
    assert level2.pedestrians == level1.pedestrians  # old road users kept exactly
    assert_strictly_more_complex(level1, level2)
    assert off_road_samples(level2) == []
    assert level2.certificates is not None
    verdict = check_testcase(level2, samples(level2.certificates.solvability), "solvability")
    assert verdict.passed and not verdict.pedestrians_broke, verdict.reasons


def test_at_a_signal_the_turning_car_yields_to_a_pedestrian_on_her_walk_signal() -> None:
    old = new_testcase("crosswalk-signal", "S2C_2:C2W_2", duration=45.0)
    new = extend_testcase(old, [], walks=["C_c3-"]).testcase
    assert_strictly_more_complex(old, new)
    assert_lawful_pedestrians(old, new)
    junction = load_intersection("crosswalk-signal")
    crossing = junction.crossings[junction.walk("C_c3-").crossing]
    (person,) = new.pedestrians
    stepped = next(e.t for e in person.events if e.kind == "entered")
    assert junction.signals is not None
    assert junction.signals.colour(crossing.link_index, stepped) in "Gg"  # on walk
    provenance = new.provenance or {}
    assert provenance["complexity_certificate_violates"] == [
        {"car": "ped1", "rule": "yieldToPedestrianOnGreen"}
    ]


def test_on_a_y_junction_of_our_own() -> None:
    old = new_testcase(JUNCTIONS / "y-crosswalk.net.xml", "SW2C_1:C2N_1", duration=30.0)
    new = extend_testcase(old, [], walks=["C_c2+"]).testcase
    assert_strictly_more_complex(old, new)
    assert_lawful_pedestrians(old, new)


def test_a_second_pedestrian_joins_a_level_with_one() -> None:
    old = new_testcase("crosswalk-stop", "W2C_1:C2E_1", duration=30.0)
    level1 = extend_testcase(old, [], walks=["C_c1-"]).testcase
    level2 = extend_testcase(level1, [], walks=["C_c3+"]).testcase
    assert [p.id for p in level2.pedestrians] == ["ped1", "ped2"]
    assert level2.pedestrians[0] == level1.pedestrians[0]  # old road users kept exactly
    assert_strictly_more_complex(level1, level2)
    assert_lawful_pedestrians(level1, level2)


def test_walks_that_cannot_matter_or_do_not_exist_are_refused() -> None:
    stop = new_testcase("crosswalk-stop", "E2C_1:C2N_1", duration=30.0)
    with pytest.raises(UnknownWalk, match=r"valid walks: C_c0\+, C_c0-"):
        extend_testcase(stop, [], walks=["C_c9+"])
    with pytest.raises(NoMoreComplexTestCase, match="no walk crosses it"):
        extend_testcase(stop, [], walks=["C_c2+"])  # the south arm: the ego never gets there
    plain = new_testcase("4way-stop", "S2C_1:C2W_1")
    with pytest.raises(UnknownWalk, match=r"no pedestrian crossings.*--guess-crossings"):
        extend_testcase(plain, [], walks=["C_c0+"])


def test_a_chain_grows_cars_and_pedestrians_each_on_a_way_no_one_takes_yet() -> None:
    """chain.grow offers the walks over the ego's route beside the car routes; a walk a
    pedestrian already takes waits, like a fork in use, until the free ones gave nothing."""
    current = new_testcase("crosswalk-stop", "S2C_2:C2W_2", duration=45.0)
    added = []
    for _ in range(4):
        growth = grow(current, seed=0, budget=120)
        assert_strictly_more_complex(current, growth.extension.testcase)
        current = growth.extension.testcase
        added.append(growth.route)
    walks = [a for a in added if ":" not in a]
    assert walks and len(walks) < len(added)  # cars and pedestrians
    assert len(set(added)) == len(added)  # each on a way no one took before
    assert_lawful_pedestrians(new_testcase("crosswalk-stop", "S2C_2:C2W_2"), current)


@pytest.mark.parametrize(
    ("junction", "control", "ego", "walk", "rule"),
    [
        ("396", "allway_stop", "-44_2:-9_2", "396_c3-", "yieldToPedestrian"),
        ("1126", None, "-6_2:-47_2", "1126_c1+", "yieldToPedestrianOnGreen"),
    ],
)
def test_on_a_real_map_with_guessed_crosswalks(
    junction: str, control: str | None, ego: str, walk: str, rule: str, cache_dir: Path
) -> None:
    """CARLA's Town05 with sidewalks and crossings guessed by netconvert (the car lanes'
    indices move up by one): an all-way stop and a signal of the town."""
    old = new_testcase(TOWN05, ego, junction=junction, control=control, duration=45.0,
                       cache_dir=cache_dir, guess_crossings=True)  # fmt: skip
    new = extend_testcase(old, [], walks=[walk]).testcase
    assert new.crossings_guessed
    assert_strictly_more_complex(old, new)
    assert_lawful_pedestrians(old, new)
    provenance = new.provenance or {}
    assert provenance["complexity_certificate_violates"] == [{"car": "ped1", "rule": rule}]
