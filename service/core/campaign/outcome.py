"""A campaign's outcome: what its chains show about where a controller starts to fail.

``summarize`` turns the chains (service.core.campaign.growing grows them) into the
campaign's outcome: per level the distinct test-cases (by their signature; a campaign
stored before levels kept one counts by id) and their diversity, and per controller the
share of the distinct test-cases it fails with its Wilson score interval, the rules it
breaks, its collisions and goal misses, and the distribution of each criticality measure
(``service.core.campaign.criticality_by_level``); per controller whether criticality
grows with the level; per chain the first level each controller fails; and the rule
coverage of the rule set. ``campaign_junit`` is the outcome as JUnit,
``campaign_paper_table`` as the seed paper's table (``service.core.campaign.paper_table``),
and the other tables are what the command line prints.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from statistics import NormalDist
from typing import Any

from service.core.campaign.criticality_by_level import (
    LABELS,
    MEASURES,
    UNITS,
    criticality_trend,
    distribution,
    level_criticality,
)
from service.core.campaign.paper_table import PaperTable, paper_table
from service.core.checker.verdict import JUnitCase, junit_document, overall_properties
from service.core.generator.variety import Signature, is_new, order_key, signature
from service.core.testcase import TestCase

# 2: distinct test-cases per level (levels keep their signature), shares over them with a
# Wilson interval, diversity; every field of 1 is still there
CAMPAIGN_SCHEMA = "scengen/campaign/2"
CONFIDENCE = 0.95  # of the failure shares' Wilson score intervals
REAR_END_RULE = "rearEnd"  # a complexity certificate that runs into a new car ahead of it
REAR_END_LAW = "21703"  # CVC: following too closely
# Rules of one road user alone (no one else's right-of-way): the ego's stops, which a
# complexity certificate keeps since it passes the old test-case, and a pedestrian's own
# (21950 (b), 21456), which no ego can break; no new road user makes a test-case test them.
# They are the rules asp/laws/ states as violatesRuleAt(V, Rule, ...)
# (tests/core/campaign/test_campaign.py).
EGO_ONLY_RULES = frozenset(
    {"stopAtSign", "stopAtRed", "stopAtRedArrow", "stopBeforeRightOnRed",
     "leavesCurbIntoHazard", "walkAgainstSignal"}
)  # fmt: skip


@dataclass(frozen=True)
class CampaignPlan:
    """What a campaign grows and who it judges."""

    network: str
    junction: str
    control: str
    egos: tuple[str, ...]
    depth: int
    chains: int
    controllers: tuple[str, ...]
    seed: int = 0
    budget_per_level: float = 60.0

    def to_dict(self) -> dict[str, Any]:
        return {
            "network": self.network,
            "junction": self.junction,
            "control": self.control,
            "egos": list(self.egos),
            "depth": self.depth,
            "chains": self.chains,
            "controllers": list(self.controllers),
            "seed": self.seed,
            "budget_per_level": self.budget_per_level,
        }

    @property
    def steps(self) -> int:
        """Upper bound of the work: levels grown plus verdicts."""
        per_chain = self.depth * (1 + len(self.controllers))
        return len(self.egos) * (len(self.controllers) + self.chains * per_chain)


def summarize(
    plan: CampaignPlan, chains: Sequence[dict[str, Any]], rules: Sequence[tuple[str, str]]
) -> dict[str, Any]:
    """The campaign's outcome as one JSON document (``CAMPAIGN_SCHEMA``)."""
    levels: list[dict[str, Any]] = []
    for number, grown in _by_level(chains).items():
        found = distinct_levels(grown)
        levels.append(
            {
                "level": number,
                "testcases": len(found),
                "grown": len({level["testcase"] for level in grown}),
                "controllers": {c: _share(c, found) for c in plan.controllers},
                "diversity": diversity(found),
            }
        )
    trend = {
        c: criticality_trend([(lv["level"], lv["controllers"][c]["criticality"]) for lv in levels])
        for c in plan.controllers
    }
    return {
        "schema": CAMPAIGN_SCHEMA,
        "plan": plan.to_dict(),
        "levels": levels,
        "criticality_trend": trend,
        "chains": [_chain_outcome(plan, chain) for chain in chains],
        "coverage": _coverage(chains, rules),
        "finished": len(chains) == len(plan.egos) * plan.chains
        and all(c["end"] is not None or len(c["levels"]) == plan.depth + 1 for c in chains),
    }


def _by_level(chains: Sequence[Mapping[str, Any]]) -> dict[int, list[dict[str, Any]]]:
    """Every chain's level records by level number (in order), chain by chain."""
    found: dict[int, list[dict[str, Any]]] = {}
    for chain in chains:
        for level in chain["levels"]:
            found.setdefault(level["level"], []).append(level)
    return dict(sorted(found.items()))


def distinct_levels(records: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """The records of distinct test-cases among ``records`` (of one level), the first of
    each in the order given: one test-case id once, and of the others only those whose
    signature differs from every one kept (``variety.Signature``: a campaign stored before
    levels kept their signature tells its test-cases apart by id alone). A signature
    tells apart what levels added to a parent: roots (the ego-only level 0 of each ego
    route, no parent) are told apart by id alone, as their signatures are all empty."""
    kept: list[dict[str, Any]] = []
    marks: list[Signature] = []
    ids: set[str] = set()
    for record in records:
        if record["testcase"] in ids:
            continue
        ids.add(record["testcase"])
        if record.get("signature") is not None and record["signature"].get("parent"):
            mark = Signature.from_dict(record["signature"])
            if not is_new(mark, marks):
                continue
            marks.append(mark)
        kept.append(record)
    return kept


def diversity(found: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """How much of the space the distinct test-cases ``found`` of a level cover: how many
    orders of events (the signature's order among the test-case's cars, which leaves out
    the ego's certificates, and which new cars stop), how many combinations of routes the
    new cars take, the rules their complexity certificates break, and the distribution
    (``criticality_by_level.distribution``) of their new cars' arrival times at the stop
    line and entry times into the junction (s)."""
    marks = [Signature.from_dict(r["signature"]) for r in found if r.get("signature")]
    orders = {order_key(mark) for mark in marks}
    return {
        "orders": len(orders),
        "routes": len({tuple(car.route for car in mark.cars) for mark in marks}),
        "rules": sorted({rule for record in found for rule in record["breaks"]}),
        "arrival": distribution([car.arrival for mark in marks for car in mark.cars]),
        "entry": distribution([car.entry for mark in marks for car in mark.cars]),
    }


def wilson_interval(
    successes: int, trials: int, confidence: float = CONFIDENCE
) -> tuple[float, float] | None:
    """The Wilson score interval of the share ``successes / trials`` (None for no trial):
    the shares whose normal test at ``confidence`` does not reject the observation. Unlike
    the share plus or minus z standard errors it stays within 0 and 1 and is not empty at
    0/n or n/n, which small levels often are (Wilson, JASA 22, 1927)."""
    if trials == 0:
        return None
    z = NormalDist().inv_cdf(0.5 + confidence / 2)
    share, z2 = successes / trials, z * z
    centre = (share + z2 / (2 * trials)) / (1 + z2 / trials)
    half = z * math.sqrt(share * (1 - share) / trials + z2 / (4 * trials * trials))
    half /= 1 + z2 / trials
    # at 0/n and n/n the interval ends at 0 and 1 exactly (centre and half agree there)
    lower = 0.0 if successes == 0 else max(0.0, centre - half)
    upper = 1.0 if successes == trials else min(1.0, centre + half)
    return lower, upper


def _share(controller: str, found: Sequence[dict[str, Any]]) -> dict[str, Any]:
    verdicts = [level["verdicts"][controller] for level in found]
    failed = [v for v in verdicts if not v["passed"]]
    interval = wilson_interval(len(failed), len(verdicts))
    return {
        "evaluated": len(verdicts),
        "failed": len(failed),
        "share": round(len(failed) / len(verdicts), 4) if verdicts else None,
        "interval": None
        if interval is None
        else {"lower": round(interval[0], 4), "upper": round(interval[1], 4)},
        "rules": dict(sorted(Counter(r for v in failed for r in v["rules"]).items())),
        "collisions": sum(1 for v in failed if v["collisions"]),
        "goal_misses": sum(1 for v in failed if not v["goal_reached"]),
        "criticality": level_criticality(verdicts),
    }


def resummarized(
    outcome: dict[str, Any], testcase_of: Callable[[str], TestCase | None]
) -> dict[str, Any]:
    """An outcome stored before levels kept their signature (schema 1) summarized anew, its
    levels given the signatures of their test-cases (``testcase_of``: by id, None when one
    is gone, whose level then counts by its id), so that its shares count distinct
    test-cases too; an outcome whose levels have them, as it is."""
    if all("signature" in lv for chain in outcome["chains"] for lv in chain["levels"]):
        return outcome
    marks: dict[str, dict[str, Any] | None] = {}

    def signed(level: dict[str, Any]) -> dict[str, Any]:
        ident = level["testcase"]
        if ident not in marks:
            found = testcase_of(ident)
            marks[ident] = None if found is None else signature(found).to_dict()
        return {**level, "signature": level.get("signature", marks[ident])}

    chains = [{**chain, "levels": [signed(lv) for lv in chain["levels"]]}
              for chain in outcome["chains"]]  # fmt: skip
    stored = outcome["plan"]
    plan = CampaignPlan(**{**stored, "egos": tuple(stored["egos"]),
                           "controllers": tuple(stored["controllers"])})  # fmt: skip
    rules = [(c["rule"], c["law"]) for c in outcome["coverage"] if c["rule"] != REAR_END_RULE]
    return summarize(plan, chains, rules)


def _chain_outcome(plan: CampaignPlan, chain: dict[str, Any]) -> dict[str, Any]:
    first = {}
    for controller in plan.controllers:
        failing = [
            lv["level"] for lv in chain["levels"] if not lv["verdicts"][controller]["passed"]
        ]
        first[controller] = failing[0] if failing else None
    return {
        "ego": chain["ego"],
        "chain": chain["chain"],
        "seed": chain["seed"],
        "name": chain.get("name") or f"{chain['ego']} chain {chain['chain'] + 1}",
        "reached": len(chain["levels"]) - 1,
        "end": chain["end"],
        "first_failure": first,
        "levels": chain["levels"],
    }


def _coverage(
    chains: Sequence[dict[str, Any]], rules: Sequence[tuple[str, str]]
) -> list[dict[str, Any]]:
    known = [*rules, (REAR_END_RULE, REAR_END_LAW)]
    covering: dict[str, list[str]] = {rule: [] for rule, _ in known}
    for chain in chains:
        for level in chain["levels"]:
            for rule in level["breaks"]:
                ids = covering.setdefault(rule, [])
                if level["testcase"] not in ids:
                    ids.append(level["testcase"])
    laws = dict(known)
    return [
        {
            "rule": rule,
            "law": laws.get(rule, ""),
            "coverable": rule not in EGO_ONLY_RULES,
            "covered": bool(ids),
            "testcases": ids,
        }
        for rule, ids in covering.items()
    ]


def campaign_junit(outcome: dict[str, Any], suite_name: str = "scengen.campaign") -> str:
    """JUnit XML: one test case per chain, level and controller (failure: the reasons),
    each with its overall criticality measures as properties (``criticality.ttc`` ...)."""
    return junit_document(campaign_cases(outcome, suite_name), suite_name)


def campaign_cases(
    outcome: dict[str, Any], suite_name: str = "scengen.campaign"
) -> list[JUnitCase]:
    """The campaign's JUnit test cases: one per chain, level and controller, named by the
    chain's name, the level and the test-case's id beside them, and the controller
    (``4way-stop C S2C_0:C2N_0 chain 2 level 3 (491d462c96ddb575) / sumo``)."""
    cases = []
    for chain in outcome["chains"]:
        classname = f"{suite_name}.{chain['ego']}.chain{chain['chain'] + 1}"
        stem = chain.get("name") or f"{chain['ego']} chain {chain['chain'] + 1}"
        for level in chain["levels"]:
            for controller, verdict in level["verdicts"].items():
                name = f"{stem} level {level['level']} ({level['testcase']}) / {controller}"
                measured = verdict.get("criticality") or {}
                properties = overall_properties(measured.get("overall") or {})
                if verdict["passed"]:
                    cases.append(JUnitCase(classname, name, properties=properties))
                    continue
                reasons = verdict["reasons"] or ["failed"]
                cases.append(JUnitCase(classname, name, "failure", "; ".join(reasons),
                                       "\n".join(reasons), properties))  # fmt: skip
    return cases


def campaign_paper_table(outcome: dict[str, Any]) -> PaperTable:
    """The outcome as the paper's table: controllers against levels, a cell per level
    with the share of its test-cases each controller fails and their most common cause."""
    controllers = outcome["plan"]["controllers"]
    levels = {
        number: {c: [found["verdicts"][c] for found in distinct_levels(grown)]
                 for c in controllers}
        for number, grown in _by_level(outcome["chains"]).items()
    }  # fmt: skip
    return paper_table(levels, controllers)


def failure_table(outcome: dict[str, Any]) -> list[list[str]]:
    """Rows of failure shares: level, distinct test-cases, then one column per controller
    (``share_text``)."""
    controllers = outcome["plan"]["controllers"]
    rows = [["level", "test-cases", *controllers]]
    for level in outcome["levels"]:
        cells = [share_text(level["controllers"][controller]) for controller in controllers]
        rows.append([str(level["level"]), str(level["testcases"]), *cells])
    return rows


def share_text(share: Mapping[str, Any]) -> str:
    """A failure share with its Wilson interval, ``1/9 11% (2–44%)`` (an outcome stored
    before shares had one: ``1/9``)."""
    counted = f"{share['failed']}/{share['evaluated']}"
    interval = share.get("interval")
    if interval is None:
        return counted
    return (f"{counted} {_percent(share['share'])}% "
            f"({_percent(interval['lower'])}–{_percent(interval['upper'])}%)")  # fmt: skip


def _percent(share: float) -> str:
    return f"{100 * share:.0f}"


def diversity_table(outcome: dict[str, Any]) -> list[list[str]] | None:
    """Rows of each level's diversity: distinct test-cases, test-cases grown, orders of
    events, combinations of the new cars' routes, the rules the certificates break, and the
    new cars' arrival and entry times (median (min–max)); None for an outcome stored
    before levels had a diversity."""
    if any("diversity" not in level for level in outcome["levels"]):
        return None
    rows = [["level", "test-cases", "grown", "orders", "routes", "rules broken",
             "arrival (s)", "entry (s)"]]  # fmt: skip
    for level in outcome["levels"]:
        found = level["diversity"]
        rules = found["rules"]
        rows.append([
            str(level["level"]), str(level["testcases"]), str(level["grown"]),
            str(found["orders"]), str(found["routes"]),
            f"{len(rules)}: {', '.join(rules)}" if rules else "0",
            _spread(found["arrival"]), _spread(found["entry"]),
        ])  # fmt: skip
    return rows


def _spread(spread: Mapping[str, Any] | None) -> str:
    if spread is None:
        return "—"
    return f"{spread['median']:g} ({spread['min']:g}–{spread['max']:g})"


def criticality_table(outcome: dict[str, Any], controller: str) -> list[list[str]] | None:
    """Rows of one controller's criticality by level, beside its failure rate: each
    measure's median, its range and how many test-cases had it (``2.1 (1.2–3.4) n=9``);
    None when no verdict of the controller was measured."""
    found = [level["controllers"][controller] for level in outcome["levels"]]
    if not any((share.get("criticality") or {}).get("measured") for share in found):
        return None
    head = ["level", "failed", *(f"{LABELS[m]} ({UNITS[m]})" for m in MEASURES)]
    rows = [head]
    for level, share in zip(outcome["levels"], found, strict=True):
        measured = share.get("criticality") or {}
        cells = []
        for measure in MEASURES:
            spread = measured.get(measure)
            cells.append("—" if spread is None else f"{spread['median']:g} "
                         f"({spread['min']:g}–{spread['max']:g}) n={spread['count']}")  # fmt: skip
        rows.append([str(level["level"]), f"{share['failed']}/{share['evaluated']}", *cells])
    return rows
