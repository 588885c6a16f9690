"""The campaign loop over fake steps (the solver and SUMO layers are tested elsewhere):
what it asks for, in which order, how it steers route choice towards uncovered rules, and
what it reports. One test grows a real level to check that held-back routes come last."""

from __future__ import annotations

import hashlib
import json
import re
import threading
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any
from xml.etree import ElementTree as ET

import pytest

from service.core.campaign.growing import run_campaign
from service.core.campaign.outcome import (
    EGO_ONLY_RULES,
    CampaignPlan,
    campaign_junit,
    campaign_paper_table,
    criticality_table,
    distinct_levels,
    diversity,
    diversity_table,
    failure_table,
    resummarized,
    wilson_interval,
)
from service.core.errors import NoMoreComplexTestCase, ScengenError
from service.core.generator.additions import candidate_routes
from service.core.generator.chain import grow
from service.core.network import Intersection
from service.core.testcase import TestCase, new_testcase

RULES = [("yieldToInside", "21800(a)"), ("yieldToRight", "21800(c)"), ("stopAtSign", "22450(a)")]
BREAKS = {"r1": "yieldToInside", "r2": "yieldToInside", "r3": "yieldToRight"}


class FakeSteps:
    """Routes r1, r2, r3 in that order unless held back; r1 and r2 break yieldToInside, r3
    yieldToRight; a level's signature is its parent and its route. Test-cases to avoid are
    passed over unless ``avoiding`` is False (the fake then repeats them, as a campaign did
    before it avoided). The controller 'weak' fails from level 2 on, 'strong' never. With
    ``measured``, verdicts beyond level 0 carry criticality: weak's TTC falls with the level
    (a chain of seed s 0.5 (s - 7) s above another) and so does its distance (2 m per
    second of TTC); strong has no TTC and keeps 5 m from every car."""

    def __init__(
        self, end_at: int | None = None, measured: bool = False, avoiding: bool = True
    ) -> None:
        self.measured, self.avoiding = measured, avoiding
        self.avoided: list[list[str]] = []
        self.made: dict[str, TestCase] = {}
        self.base = new_testcase("4way-stop", "S2C_0:C2N_0")
        self.grown: list[tuple[str, int, tuple[str, ...]]] = []
        self.evaluated: list[tuple[str, str]] = []
        self.stems: list[str] = []
        self.end_at = end_at

    def root(self, ego: str) -> tuple[str, TestCase]:
        self.made[f"root-{ego}"] = self.base
        return f"root-{ego}", self.base

    def grow(
        self,
        parent: str,
        testcase: TestCase,
        seed: int,
        last: tuple[str, ...],
        stem: str,
        avoid: Sequence[tuple[str, TestCase]],
    ) -> tuple[str, TestCase, str]:
        self.grown.append((parent, seed, last))
        self.avoided.append([ident for ident, _ in avoid])
        self.stems.append(stem)
        level = (testcase.provenance or {}).get("level", 0) + 1
        if self.end_at is not None and level >= self.end_at:
            raise NoMoreComplexTestCase("no new car makes this test-case more complex")
        routes = sorted(BREAKS, key=lambda r: r in last)
        if self.avoiding:
            routes = [r for r in routes if f"{parent}/{r}" not in self.avoided[-1]]
        route = routes[0]
        provenance = {
            "level": level,
            "seed": seed,
            "parent": parent,
            "order": [f"before({route}, ego)"],
            "new_nonegos": [f"car{level}"],
            "complexity_certificate_violates": [{"car": f"car{level}", "rule": BREAKS[route]}],
            "complexity_certificate": {"rear_end": []},
        }
        grown = testcase.model_copy(
            update={"provenance": provenance, "name": f"{stem} level {level}"}
        )
        self.made[f"{parent}/{route}"] = grown
        return f"{parent}/{route}", grown, route

    def evaluate(self, ident: str, testcase: TestCase, controller: str) -> dict[str, Any]:
        self.evaluated.append((ident, controller))
        level = (testcase.provenance or {}).get("level", 0)
        failed = controller == "weak" and level >= 2
        violations = (
            [{"rule": "yieldToInside", "law": "21800(a)", "other": "car2"}] if failed else []
        )
        criticality = None
        if self.measured and level:
            ttc = 4 - level + 0.5 * ((testcase.provenance or {})["seed"] - 7)
            at = {"car": "car1", "t": 3.0}
            weak = controller == "weak"
            distance = {"value": 2 * ttc if weak else 5.0, **at}
            overall = {"ttc": {"value": ttc, **at} if weak else None, "pet": None,
                       "drac": None, "distance": distance}  # fmt: skip
            criticality = {"others": {}, "overall": overall}
        return {
            "criticality": criticality,
            "passed": not failed,
            "violations": violations,
            "collisions": [],
            "goal": {"reached": True},
            "errors": [],
            "reasons": ["violated yieldToInside"] if failed else [],
            "evaluation": f"e-{ident}-{controller}",
        }


def plan(**changes: Any) -> CampaignPlan:
    fields = {"network": "4way-stop", "junction": "C", "control": "allway_stop",
              "egos": ("S2C_0:C2N_0",), "depth": 3, "chains": 2,
              "controllers": ("strong", "weak"), "seed": 7}  # fmt: skip
    return CampaignPlan(**{**fields, **changes})


def test_every_level_is_judged_by_every_controller_and_summarised() -> None:
    steps, told, saved = FakeSteps(), [], []
    outcome = run_campaign(plan(), steps, RULES, lambda *a: told.append(a), saved.append)
    # the root is judged once per ego; each chain's levels by each controller
    assert len(steps.evaluated) == 2 + 2 * 3 * 2
    # level by level (a wave of every chain), chain c with seed 7 + c; at level 1 chain 2
    # first grew chain 1's level (r1) and grew again avoiding it
    assert [seed for _, seed, _ in steps.grown] == [7, 8, 8, 7, 8, 7, 8]
    assert told[-1][1] == told[-1][2] == plan().steps  # the progress reaches its total
    assert saved[-1] == outcome and len(saved) > 2  # saved after every wave
    weak = [level["controllers"]["weak"] for level in outcome["levels"]]
    assert [lv["testcases"] for lv in outcome["levels"]] == [1, 2, 2, 2]  # distinct ones
    assert [s["failed"] for s in weak] == [0, 0, 2, 2]
    assert weak[2]["rules"] == {"yieldToInside": 2} and weak[2]["share"] == 1.0
    assert [c["first_failure"] for c in outcome["chains"]] == [{"strong": None, "weak": 2}] * 2
    assert outcome["finished"]
    rows = failure_table(outcome)
    assert rows[0] == ["level", "test-cases", "strong", "weak"]
    assert rows[3][3] == "2/2 100% (34–100%)"  # the share and its Wilson interval


def test_criticality_by_level_and_the_papers_table_in_the_outcome() -> None:
    outcome = run_campaign(plan(), FakeSteps(measured=True), RULES)
    weak = [level["controllers"]["weak"]["criticality"] for level in outcome["levels"]]
    assert weak[0] == {"measured": 0, "ttc": None, "pet": None, "drac": None, "distance": None}
    assert weak[2]["measured"] == 2 and weak[2]["ttc"] == {
        "count": 2, "min": 2.0, "q1": 2.125, "median": 2.25, "q3": 2.375, "max": 2.5,
        "values": [2.0, 2.5],
    }  # fmt: skip
    trend = outcome["criticality_trend"]
    assert trend["weak"]["grows"] is True  # TTC and distance fall, the others never arose
    # TTC 4 - level + 0.5 (seed - 7): seeds 7 and 8 at every level
    assert trend["weak"]["measures"]["ttc"]["medians"] == [[1, 3.25], [2, 2.25], [3, 1.25]]
    assert trend["strong"]["grows"] is False  # 5 m at every level: no closer call
    assert trend["strong"]["measures"]["distance"]["flat"] == [[1, 2], [2, 3]]
    assert trend["strong"]["measures"]["distance"]["breaks"] == []
    kept = outcome["chains"][0]["levels"][2]["verdicts"]["weak"]
    assert kept["cause"] == {"kind": "rule", "rule": "yieldToInside", "law": "21800(a)",
                             "car": "car2"}  # fmt: skip
    assert kept["criticality"]["overall"]["ttc"]["value"] == 2.0 and kept["guard"] is None
    assert campaign_paper_table(outcome).text() == (
        "controller  level 0  level 1   level 2            level 3\n"
        "strong      pass     pass 2/2  pass 2/2           pass 2/2\n"
        "weak        pass     pass 2/2  2/2 FAIL 21800(a)  2/2 FAIL 21800(a)\n"
    )
    rows = criticality_table(outcome, "weak")
    assert rows is not None and rows[0][:3] == ["level", "failed", "TTC (s)"]
    assert rows[3][:3] == ["2", "2/2", "2.25 (2–2.5) n=2"] and rows[1][2] == "—"
    suite = ET.fromstring(campaign_junit(outcome)).find("testsuite")
    assert suite is not None
    cases = suite.findall("testcase")
    assert cases[0].find("properties") is None  # the root: nothing measured
    properties = cases[-1].find("properties")  # chain 2 level 3 / weak
    assert properties is not None and cases[-1][0] is properties  # the schema's order
    assert {p.get("name"): p.get("value") for p in properties} == {
        "criticality.ttc": "1.5", "criticality.ttc.car": "car1", "criticality.ttc.t": "3",
        "criticality.distance": "3", "criticality.distance.car": "car1",
        "criticality.distance.t": "3",
    }  # fmt: skip


def test_a_campaign_without_criticality_says_so_and_keeps_its_tables() -> None:
    outcome = run_campaign(plan(chains=1), FakeSteps(), RULES)
    assert outcome["criticality_trend"]["weak"] == {
        "grows": None, "summary": "not measured on two levels or more",
        "measures": {m: {"medians": [], "grows": None, "breaks": [], "flat": []}
                     for m in ("ttc", "pet", "drac", "distance")},
    }  # fmt: skip
    assert criticality_table(outcome, "weak") is None
    assert "<properties>" not in campaign_junit(outcome)
    # an outcome stored before verdicts kept their cause still gives the paper's table
    for level in outcome["chains"][0]["levels"]:
        for verdict in level["verdicts"].values():
            del verdict["cause"], verdict["criticality"], verdict["guard"]
    assert campaign_paper_table(outcome).cells()[2] == [
        "weak", "pass", "pass", "FAIL yieldToInside", "FAIL yieldToInside"
    ]  # fmt: skip


def test_route_choice_holds_back_routes_whose_rules_are_covered() -> None:
    steps = FakeSteps()
    outcome = run_campaign(plan(), steps, RULES)
    routes = [[lv["route"] for lv in chain["levels"][1:]] for chain in outcome["chains"]]
    # Level 1: nothing is known, chain 1 takes r1 and chain 2, avoiding it, r2; both break
    # yieldToInside only, so in the next wave both wait and r3 covers yieldToRight. Once
    # every rule a new car can make harder is covered, nothing is held back.
    assert routes == [["r1", "r3", "r1"], ["r2", "r3", "r1"]]
    assert [last for _, _, last in steps.grown] == [
        (), (), (), ("r1", "r2"), ("r1", "r2"), (), ()
    ]  # fmt: skip
    coverage = {c["rule"]: c for c in outcome["coverage"]}
    assert coverage["yieldToInside"]["covered"] and coverage["yieldToRight"]["covered"]
    assert not coverage["stopAtSign"]["coverable"]  # the ego's own rule
    assert not coverage["rearEnd"]["covered"] and coverage["rearEnd"]["coverable"]


def test_ego_only_rules_are_the_laws_of_the_ego_alone() -> None:
    # a rule the laws state as violatesRuleAt(V, Rule, ...) names no other car: no new car
    # can make a test-case test it more, so a campaign never counts it as uncovered
    laws = Path(__file__).resolve().parents[3] / "asp" / "laws"
    heads = {
        rule
        for path in laws.glob("*.lp")
        for rule in re.findall(r"^violatesRuleAt\(\w+, (\w+),", path.read_text(), re.M)
    }
    assert heads == EGO_ONLY_RULES
    assert {"stopAtSign", "stopAtRed"} <= heads


def test_a_chain_that_cannot_grow_ends_with_its_reason() -> None:
    outcome = run_campaign(plan(chains=1), FakeSteps(end_at=2), RULES)
    chain = outcome["chains"][0]
    assert chain["reached"] == 1
    assert chain["end"] == "level 2: no new car makes this test-case more complex"
    assert outcome["finished"]


def test_junit_has_a_case_per_chain_level_and_controller() -> None:
    outcome = run_campaign(plan(), FakeSteps(), RULES)
    suite = ET.fromstring(campaign_junit(outcome)).find("testsuite")
    assert suite is not None
    cases = suite.findall("testcase")
    assert len(cases) == int(suite.get("tests", "0")) == 2 * 4 * 2
    failed = [c for c in cases if c.find("failure") is not None]
    assert len(failed) == int(suite.get("failures", "0")) == 2 * 2  # weak at levels 2 and 3
    assert all("/ weak" in c.get("name", "") for c in failed)
    names = [c.get("name") for c in cases]
    # every case says the chain and the level, with the test-case's id beside them; the
    # shared root is level 0 of each chain
    assert names[:3] == [
        "4way-stop C S2C_0:C2N_0 chain 1 level 0 (root-S2C_0:C2N_0) / strong",
        "4way-stop C S2C_0:C2N_0 chain 1 level 0 (root-S2C_0:C2N_0) / weak",
        "4way-stop C S2C_0:C2N_0 chain 1 level 1 (root-S2C_0:C2N_0/r1) / strong",
    ]
    assert names[-1] == "4way-stop C S2C_0:C2N_0 chain 2 level 3 (root-S2C_0:C2N_0/r2/r3/r1) / weak"
    assert len(set(names)) == len(names)


def test_levels_are_named_by_chain_and_level() -> None:
    """The root keeps its own name (it is level 0 of every chain); each level grown is named
    after the root, its chain and its level."""
    steps = FakeSteps()
    outcome = run_campaign(plan(), steps, RULES)
    one, two = "4way-stop C S2C_0:C2N_0 chain 1", "4way-stop C S2C_0:C2N_0 chain 2"
    assert steps.stems == [one, two, two, one, two, one, two]  # chain 2 grew level 1 twice
    second = outcome["chains"][1]
    assert second["name"] == "4way-stop C S2C_0:C2N_0 chain 2"
    assert [level["name"] for level in second["levels"]] == [
        "",  # the fake root has no name of its own
        "4way-stop C S2C_0:C2N_0 chain 2 level 1",
        "4way-stop C S2C_0:C2N_0 chain 2 level 2",
        "4way-stop C S2C_0:C2N_0 chain 2 level 3",
    ]
    assert all(level["duration"] == 20.0 for level in second["levels"])


def test_held_back_routes_are_tried_after_the_others(four_way: Intersection) -> None:
    old = new_testcase("4way-stop", "S2C_0:C2N_0")
    candidates = candidate_routes(old, four_way)
    free = grow(old, 0, 60.0, four_way).route
    held = grow(old, 0, 60.0, four_way, last=[free]).route
    assert held != free and held in candidates


def test_a_level_avoids_what_earlier_chains_grew_from_the_same_parent() -> None:
    steps = FakeSteps(avoiding=False)  # repeats what it should avoid: counted once
    outcome = run_campaign(plan(), steps, RULES)
    # in every wave both chains first grow alone and take the same level; chain 2 then
    # grows again, told to avoid chain 1's (the fake repeats it, and they share the parent
    # of the next wave)
    assert steps.avoided == [[], [], ["root-S2C_0:C2N_0/r1"], [], [],
                             ["root-S2C_0:C2N_0/r1/r2"], [], [],
                             ["root-S2C_0:C2N_0/r1/r2/r3"]]  # fmt: skip
    assert [lv["grown"] for lv in outcome["levels"]] == [1, 1, 1, 1]
    assert len(steps.evaluated) == 2 * 4  # one verdict per test-case and controller
    avoiding = FakeSteps()
    apart = run_campaign(plan(chains=3, depth=2), avoiding, RULES)
    assert avoiding.avoided == [
        [], [], [],  # each alone: all three take r1
        ["root-S2C_0:C2N_0/r1"], ["root-S2C_0:C2N_0/r1", "root-S2C_0:C2N_0/r2"],
        [], [], [],  # three parents of their own at level 2: each stands as grown
    ]  # fmt: skip
    firsts = [chain["levels"][1]["testcase"] for chain in apart["chains"]]
    assert len(set(firsts)) == 3 and [lv["testcases"] for lv in apart["levels"]] == [1, 3, 3]


def test_wilson_score_intervals_match_known_values() -> None:
    # Wilson's formula worked by hand: centre (p + z²/2n) / (1 + z²/n), half-width
    # z √(p(1-p)/n + z²/4n²) / (1 + z²/n), z = 1.959964 (95 %) or 1.644854 (90 %)
    assert wilson_interval(5, 10) == pytest.approx((0.236593, 0.763407), abs=1e-6)
    assert wilson_interval(1, 9) == pytest.approx((0.019891, 0.435000), abs=1e-6)
    assert wilson_interval(0, 10) == (0.0, pytest.approx(0.277533, abs=1e-6))
    assert wilson_interval(10, 10) == (pytest.approx(0.722467, abs=1e-6), 1.0)
    assert wilson_interval(0, 1) == (0.0, pytest.approx(0.793451, abs=1e-6))
    assert wilson_interval(3, 4, confidence=0.9) == pytest.approx((0.3562, 0.9421), abs=1e-4)
    assert wilson_interval(0, 0) is None


def _record(ident: str, arrival: float, order: str, breaks: list[str]) -> dict[str, Any]:
    car = {"car": "n2", "route": "E2C_0:C2W_0", "stops": True, "arrival": arrival,
           "entry": arrival + 2.0}  # fmt: skip
    mark = {"parent": "p", "level": 2, "cars": [car], "order": [order]}
    return {"testcase": ident, "breaks": breaks, "signature": mark}


def test_distinct_test_cases_and_their_diversity() -> None:
    records = [
        _record("a", 3.0, "n2 before ego", ["yieldToInside"]),
        _record("b", 3.6, "n2 before ego", ["yieldToInside"]),  # a, half a second later
        _record("a", 3.0, "n2 before ego", ["yieldToInside"]),  # a again
        _record("c", 5.0, "n2 before ego", ["yieldToRight"]),
        _record("d", 3.0, "ego before n2", ["rearEnd"]),
    ]
    found = distinct_levels(records)
    assert [r["testcase"] for r in found] == ["a", "c", "d"]
    assert diversity(found) == {
        "orders": 2,
        "routes": 1,
        "rules": ["rearEnd", "yieldToInside", "yieldToRight"],
        "arrival": {"count": 3, "min": 3.0, "q1": 3.0, "median": 3.0, "q3": 4.0, "max": 5.0,
                    "values": [3.0, 3.0, 5.0]},
        "entry": {"count": 3, "min": 5.0, "q1": 5.0, "median": 5.0, "q3": 6.0, "max": 7.0,
                  "values": [5.0, 5.0, 7.0]},
    }  # fmt: skip
    unsigned = [{k: v for k, v in r.items() if k != "signature"} for r in records]
    assert [r["testcase"] for r in distinct_levels(unsigned)] == ["a", "b", "c", "d"]
    assert diversity([]) == {"orders": 0, "routes": 0, "rules": [], "arrival": None,
                             "entry": None}  # fmt: skip


def test_the_roots_of_several_ego_routes_are_distinct_test_cases() -> None:
    """Level 0 holds one ego-only test-case per ego route: no parent, no new car, the same
    empty signature; each is a test-case of its own (a campaign over three egos once
    counted one)."""
    root = {"parent": None, "level": 0, "cars": [], "order": []}
    roots = [{"testcase": ident, "breaks": [], "signature": root} for ident in "xyzx"]
    assert [r["testcase"] for r in distinct_levels(roots)] == ["x", "y", "z"]


def test_shares_count_distinct_test_cases_with_their_interval() -> None:
    steps = FakeSteps()
    outcome = run_campaign(plan(), steps, RULES)
    assert outcome["schema"] == "scengen/campaign/2"
    level_one = outcome["levels"][1]
    assert level_one["controllers"]["weak"]["interval"] == {"lower": 0.0, "upper": 0.6576}
    assert outcome["levels"][2]["controllers"]["weak"]["interval"] == {"lower": 0.3424,
                                                                        "upper": 1.0}  # fmt: skip
    assert level_one["diversity"] == {"orders": 2, "routes": 1, "rules": ["yieldToInside"],
                                      "arrival": None, "entry": None}  # fmt: skip
    rows = diversity_table(outcome)
    assert rows is not None and rows[0][:6] == ["level", "test-cases", "grown", "orders",
                                                "routes", "rules broken"]  # fmt: skip
    assert rows[2][5] == "1: yieldToInside"  # r1 and r2
    assert rows[3] == ["2", "2", "2", "1", "1", "1: yieldToRight", "—", "—"]  # r3 twice
    # an outcome stored before levels kept their signature is counted anew from the
    # test-cases (by id where one is gone), and so are its intervals and its diversity
    stored = json.loads(json.dumps(outcome))
    for chain in stored["chains"]:
        for level in chain["levels"]:
            del level["signature"]
    for level in stored["levels"]:
        del level["diversity"], level["grown"]
    assert diversity_table(stored) is None
    assert resummarized(stored, steps.made.get) == outcome
    assert resummarized(outcome, steps.made.get) is outcome
    by_id = resummarized(stored, lambda _: None)
    assert [lv["testcases"] for lv in by_id["levels"]] == [1, 2, 2, 2]


class ShuffledSteps(FakeSteps):
    """FakeSteps whose steps take a while, longer or shorter by the step (so that with
    several workers they finish in another order than they were asked in)."""

    def __init__(self, fail_at: str | None = None, **options: Any) -> None:
        super().__init__(**options)
        self.fail_at = fail_at
        self.lock = threading.Lock()
        self.running, self.most = 0, 0

    def _wait(self, key: str) -> None:
        with self.lock:
            self.running += 1
            self.most = max(self.most, self.running)
        time.sleep(0.002 * (int(hashlib.sha256(key.encode()).hexdigest(), 16) % 10))
        with self.lock:
            self.running -= 1

    def grow(self, parent: str, testcase: TestCase, *args: Any) -> tuple[str, TestCase, str]:
        self._wait(f"{parent}/{args[0]}")
        return super().grow(parent, testcase, *args)

    def evaluate(self, ident: str, testcase: TestCase, controller: str) -> dict[str, Any]:
        self._wait(f"{ident}/{controller}")
        if ident == self.fail_at:
            raise ScengenError(f"the replay of {ident} failed")
        return super().evaluate(ident, testcase, controller)


def test_the_outcome_is_the_same_for_any_number_of_workers() -> None:
    one = run_campaign(plan(chains=3), ShuffledSteps(measured=True), RULES, workers=1)
    for workers in (2, 4):
        steps = ShuffledSteps(measured=True)
        told: list[tuple[str, int, int]] = []
        many = run_campaign(plan(chains=3), steps, RULES,
                            lambda *a, told=told: told.append(a), workers=workers)  # fmt: skip
        assert json.dumps(many) == json.dumps(one)  # byte for byte
        assert steps.most > 1  # steps did run at once
        assert [done for _, done, _ in told] == sorted(done for _, done, _ in told)
        assert told[-1][1] == told[-1][2] == plan(chains=3).steps


def test_a_failing_step_ends_the_campaign_with_its_error() -> None:
    steps = ShuffledSteps(fail_at="root-S2C_0:C2N_0/r2")
    with pytest.raises(ScengenError, match="the replay of root-S2C_0:C2N_0/r2 failed"):
        run_campaign(plan(), steps, RULES, workers=2)
    with pytest.raises(ValueError, match="workers must be at least 1"):
        run_campaign(plan(), FakeSteps(), RULES, workers=0)
