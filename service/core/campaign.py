"""Campaigns: where does a controller start to fail as test-cases grow more complex?

A campaign grows ``chains`` chains per ego route, each to ``depth`` levels (one new car per
level, chosen the way ``service.core.generator.chain.grow`` chooses), and judges every level, the
ego-only root included, with every controller. ``run_campaign`` is the loop; the work it
asks for (a root, a level, a verdict) is done by a ``CampaignSteps`` that remembers what it
did, so that a campaign run again after a crash continues where it stopped: the loop is
deterministic, and every step it already took answers from memory.

Route choice is steered towards rules no complexity certificate has broken yet: a route
whose earlier certificates (for this ego route) broke only rules already covered is tried
after the others of its group. Chain ``c`` of every ego route has seed ``seed + c``.

``summarize`` turns the chains into the campaign's outcome: per level and controller the
share of test-cases it fails, the rules it breaks, its collisions and goal misses, and the
distribution of each criticality measure (``service.core.criticality_by_level``); per
controller whether criticality grows with the level; per chain the first level each
controller fails; and the rule coverage of the rule set. ``campaign_paper_table`` is the
outcome as the seed paper's table (``service.core.paper_table``).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

from service.core.checker.verdict import JUnitCase, junit_document, overall_properties
from service.core.criticality_by_level import (
    LABELS,
    MEASURES,
    UNITS,
    criticality_trend,
    level_criticality,
)
from service.core.errors import BudgetExceeded, NoMoreComplexTestCase, NoneFound
from service.core.paper_table import PaperTable, failure_cause, paper_table
from service.core.testcase import TestCase, name_stem, readable_name

CAMPAIGN_SCHEMA = "scengen/campaign/1"
REAR_END_RULE = "rearEnd"  # a complexity certificate that runs into a new car ahead of it
REAR_END_LAW = "21703"  # CVC: following too closely
# What ends a chain before its depth: no more complex test-case exists, none was found
# within the search's counts, or the level's budget ran out (the message says which).
CHAIN_ENDS = (NoMoreComplexTestCase, NoneFound, BudgetExceeded)
# Rules of the ego alone (no other car's right-of-way): a complexity certificate passes the
# old test-case, so it keeps them, and no new car can make a test-case test them. They are
# the rules asp/laws/ states as violatesRuleAt(V, Rule, ...) (tests/core/test_campaign.py).
EGO_ONLY_RULES = frozenset({"stopAtSign", "stopAtRed", "stopAtRedArrow", "stopBeforeRightOnRed"})


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


class CampaignSteps(Protocol):
    """The work of a campaign, each step remembered (a second call answers from memory)."""

    def root(self, ego: str) -> tuple[str, TestCase]:
        """The ego-only test-case of this ego route: its id and itself."""
        ...

    def grow(
        self, parent: str, testcase: TestCase, seed: int, last: tuple[str, ...], stem: str
    ) -> tuple[str, TestCase, str]:
        """The next level: id, test-case (named ``STEM level N``) and the route added;
        routes in ``last`` are tried after the others of their group. A chain ends at one
        of CHAIN_ENDS."""
        ...

    def evaluate(self, ident: str, testcase: TestCase, controller: str) -> dict[str, Any]:
        """The controller's verdict (``Verdict.to_dict``) with ``evaluation``: its id."""
        ...


Progress = Callable[[str, int, int], None]  # message, steps done, steps at most


def run_campaign(
    plan: CampaignPlan,
    steps: CampaignSteps,
    rules: Sequence[tuple[str, str]],
    progress: Progress | None = None,
    saved: Callable[[dict[str, Any]], None] | None = None,
) -> dict[str, Any]:
    """Grow and judge the campaign; its outcome (``summarize``). ``rules`` are the rule
    set's (rule, law) pairs; ``saved`` gets the outcome so far after every level."""
    chains: list[dict[str, Any]] = []
    done = 0
    total = plan.steps

    def tell(message: str) -> None:
        nonlocal done
        done += 1
        if progress is not None:
            progress(message, done, total)

    def publish() -> None:
        if saved is not None:
            saved(summarize(plan, chains, rules))

    for ego in plan.egos:
        root_id, root = steps.root(ego)
        root_verdicts = {}
        for controller in plan.controllers:
            root_verdicts[controller] = _compact(steps.evaluate(root_id, root, controller))
            tell(f"{ego}: level 0 / {controller}")
        for chain in range(plan.chains):
            seed = plan.seed + chain
            stem = chain_name(root, chain)
            record: dict[str, Any] = {"ego": ego, "chain": chain, "seed": seed, "end": None}
            record["name"] = stem
            record["levels"] = [_level(0, root_id, root, None, root_verdicts)]
            chains.append(record)
            parent_id, parent = root_id, root
            for level in range(1, plan.depth + 1):
                last = _covered_routes(chains, ego, rules)
                try:
                    parent_id, parent, route = steps.grow(parent_id, parent, seed, last, stem)
                except CHAIN_ENDS as end:
                    record["end"] = f"level {level}: {end.message}"
                    done += (plan.depth - level + 1) * (1 + len(plan.controllers))
                    break
                tell(f"{ego} chain {chain + 1}: level {level} grown ({route})")
                verdicts = {}
                for controller in plan.controllers:
                    verdicts[controller] = _compact(steps.evaluate(parent_id, parent, controller))
                    tell(f"{ego} chain {chain + 1}: level {level} / {controller}")
                record["levels"].append(_level(level, parent_id, parent, route, verdicts))
                publish()
            if record["end"] is not None:
                publish()
    outcome = summarize(plan, chains, rules)
    if saved is not None:
        saved(outcome)
    return outcome


def chain_name(root: TestCase, chain: int) -> str:
    """What the levels of chain ``chain`` (from 0) grown from ``root`` are named before
    their level: the root's name without its level, and the chain, as in
    ``4way-stop C S2C_0:C2N_0 chain 2`` (its level 3: ``... chain 2 level 3``)."""
    return f"{name_stem(root.name or readable_name(root))} chain {chain + 1}"


def _level(
    level: int, ident: str, testcase: TestCase, route: str | None, verdicts: dict[str, Any]
) -> dict[str, Any]:
    provenance = testcase.provenance or {}
    certificate = provenance.get("complexity_certificate", {})
    return {
        "level": level,
        "testcase": ident,
        "name": testcase.name,
        "duration": testcase.duration,
        "route": route,
        "new_cars": list(provenance.get("new_nonegos", [])),
        "breaks": _broken(testcase),
        "rear_end": list(certificate.get("rear_end", [])),
        "verdicts": verdicts,
    }


def _broken(testcase: TestCase) -> list[str]:
    """The rules the complexity certificate of ``testcase`` breaks against its new cars."""
    provenance = testcase.provenance or {}
    rules = {item["rule"] for item in provenance.get("complexity_certificate_violates", [])}
    if provenance.get("complexity_certificate", {}).get("rear_end"):
        rules.add(REAR_END_RULE)
    return sorted(rules)


def _compact(verdict: dict[str, Any]) -> dict[str, Any]:
    """What a campaign keeps of a verdict: the cause the paper's table shows, and the
    criticality measures and the guard's counts as the verdict has them (null if not)."""
    return {
        "evaluation": verdict.get("evaluation"),
        "passed": bool(verdict["passed"]),
        "rules": sorted({v["rule"] for v in verdict["violations"]}),
        "collisions": len(verdict["collisions"]),
        "goal_reached": bool(verdict["goal"]["reached"]),
        "errors": list(verdict["errors"]),
        "reasons": list(verdict["reasons"]),
        "cause": failure_cause(verdict),
        "criticality": verdict.get("criticality"),
        "guard": _guard_counts(verdict.get("guard")),
    }


def _guard_counts(guard: dict[str, Any] | None) -> dict[str, Any] | None:
    """The guard's record without its spans (they stay in the stored evaluation)."""
    if guard is None:
        return None
    return {key: value for key, value in guard.items() if key != "spans"}


def _covered_routes(
    chains: Sequence[dict[str, Any]], ego: str, rules: Sequence[tuple[str, str]]
) -> tuple[str, ...]:
    """Routes of this ego whose certificates so far broke only covered rules (tried last)."""
    covered = _covered(chains)
    if all(rule in covered or rule in EGO_ONLY_RULES for rule, _ in rules):
        return ()  # everything is covered: no route is held back
    seen: dict[str, set[str]] = {}
    for chain in chains:
        if chain["ego"] != ego:
            continue
        for level in chain["levels"][1:]:
            seen.setdefault(level["route"], set()).update(level["breaks"])
    return tuple(sorted(r for r, broken in seen.items() if broken <= covered))


def _covered(chains: Sequence[dict[str, Any]]) -> set[str]:
    return {rule for chain in chains for level in chain["levels"] for rule in level["breaks"]}


def summarize(
    plan: CampaignPlan, chains: Sequence[dict[str, Any]], rules: Sequence[tuple[str, str]]
) -> dict[str, Any]:
    """The campaign's outcome as one JSON document (``CAMPAIGN_SCHEMA``)."""
    by_level: dict[int, dict[str, dict[str, Any]]] = {}  # level -> test-case id -> level
    for chain in chains:
        for level in chain["levels"]:
            by_level.setdefault(level["level"], {})[level["testcase"]] = level
    levels: list[dict[str, Any]] = []
    for number in sorted(by_level):
        found = list(by_level[number].values())
        levels.append(
            {
                "level": number,
                "testcases": len(found),
                "controllers": {c: _share(c, found) for c in plan.controllers},
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


def _share(controller: str, found: Sequence[dict[str, Any]]) -> dict[str, Any]:
    verdicts = [level["verdicts"][controller] for level in found]
    failed = [v for v in verdicts if not v["passed"]]
    return {
        "evaluated": len(verdicts),
        "failed": len(failed),
        "share": round(len(failed) / len(verdicts), 4) if verdicts else None,
        "rules": dict(sorted(Counter(r for v in failed for r in v["rules"]).items())),
        "collisions": sum(1 for v in failed if v["collisions"]),
        "goal_misses": sum(1 for v in failed if not v["goal_reached"]),
        "criticality": level_criticality(verdicts),
    }


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
    by_level: dict[int, dict[str, dict[str, Any]]] = {}  # level -> test-case id -> verdicts
    for chain in outcome["chains"]:
        for level in chain["levels"]:
            by_level.setdefault(level["level"], {})[level["testcase"]] = level["verdicts"]
    controllers = outcome["plan"]["controllers"]
    levels = {
        number: {c: [found[c] for found in cases.values()] for c in controllers}
        for number, cases in by_level.items()
    }
    return paper_table(levels, controllers)


def failure_table(outcome: dict[str, Any]) -> list[list[str]]:
    """Rows of failure shares: level, test-cases, then one column per controller."""
    controllers = outcome["plan"]["controllers"]
    rows = [["level", "test-cases", *controllers]]
    for level in outcome["levels"]:
        cells = []
        for controller in controllers:
            share = level["controllers"][controller]
            cells.append(f"{share['failed']}/{share['evaluated']}")
        rows.append([str(level["level"]), str(level["testcases"]), *cells])
    return rows


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
