"""Growing a campaign: its chains level by level, every level judged, the work spread over
workers.

``run_campaign`` grows ``chains`` chains per ego route, each to ``depth`` levels (one new
car per level, chosen the way ``service.core.generator.chain.grow`` chooses), and judges
every level, the ego-only root included, with every controller. The work it asks for (a
root, a level, a verdict) is done by a ``CampaignSteps`` that remembers what it did, so that
a campaign run again after a crash continues where it stopped: the campaign is
deterministic, and every step it already took answers from memory.

The chains grow in waves, one level of every chain at a time. Within a wave the steps are
independent and run at once on up to ``workers`` threads (each step's own work runs in a
process of its own, service.jobs.runner): every chain first grows its level alone, as if no
other chain grew from its parent; then the chains that share a parent settle in chain order:
a chain keeps its level when it differs from what the chains before it took there
(``service.core.generator.variety``; children of different parents always differ), and else
grows it again, avoiding those, so no two chains hold the same test-case at a level. Chains
with different parents settle at once. A level's verdicts are asked for as soon as it is
grown, beside the next wave. Route choice is steered towards rules no complexity certificate
has broken yet: a route whose certificates so far (for this ego route, in the levels before
the wave) broke only rules already covered is tried after the others of its group. Chain
``c`` of every ego route has seed ``seed + c``. Every choice depends on the waves before,
never on which step finished first: the outcome is the same for any number of workers.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ThreadPoolExecutor, wait
from dataclasses import dataclass
from typing import Any, Protocol

from service.core.campaign.outcome import (
    EGO_ONLY_RULES,
    REAR_END_RULE,
    CampaignPlan,
    summarize,
)
from service.core.campaign.paper_table import failure_cause
from service.core.errors import BudgetExceeded, NoMoreComplexTestCase, NoneFound, ScengenError
from service.core.generator.variety import is_new, signature
from service.core.testcase import TestCase, name_stem, readable_name


class CampaignSteps(Protocol):
    """The work of a campaign, each step remembered (a second call answers from memory)."""

    def root(self, ego: str) -> tuple[str, TestCase]:
        """The ego-only test-case of this ego route: its id and itself."""
        ...

    def grow(
        self,
        parent: str,
        testcase: TestCase,
        seed: int,
        last: tuple[str, ...],
        stem: str,
        avoid: Sequence[tuple[str, TestCase]],
    ) -> tuple[str, TestCase, str]:
        """The next level: id, test-case (named ``STEM level N``) and the route added;
        routes in ``last`` are tried after the others of their group; it differs from every
        test-case of ``avoid`` (id and test-case: service.core.generator.chain.grow). A
        chain ends at one of CHAIN_ENDS."""
        ...

    def evaluate(self, ident: str, testcase: TestCase, controller: str) -> dict[str, Any]:
        """The controller's verdict (``Verdict.to_dict``) with ``evaluation``: its id."""
        ...


# What ends a chain before its depth: no more complex test-case exists, none was found
# within the search's counts, or the level's budget ran out (the message says which).
CHAIN_ENDS = (NoMoreComplexTestCase, NoneFound, BudgetExceeded)
Progress = Callable[[str, int, int], None]  # message, steps done, steps at most
Grown = tuple[str, TestCase, "str | None"]  # a level: its id, its test-case, the route added


@dataclass
class _Chain:
    """One chain while it grows: its levels (id, test-case, route; the root first) and why
    it ended, if it did."""

    ego: str
    number: int  # from 0
    seed: int
    name: str
    levels: list[Grown]
    end: str | None = None


def run_campaign(
    plan: CampaignPlan,
    steps: CampaignSteps,
    rules: Sequence[tuple[str, str]],
    progress: Progress | None = None,
    saved: Callable[[dict[str, Any]], None] | None = None,
    workers: int = 1,
) -> dict[str, Any]:
    """Grow and judge the campaign on up to ``workers`` steps at once; its outcome
    (``summarize``), the same for any ``workers``. ``rules`` are the rule set's (rule, law)
    pairs; ``saved`` gets the outcome so far after every wave."""
    if workers < 1:
        raise ValueError(f"workers must be at least 1, got {workers}")
    return _Campaign(plan, steps, rules, progress, saved).run(workers)


class _Campaign:
    def __init__(
        self,
        plan: CampaignPlan,
        steps: CampaignSteps,
        rules: Sequence[tuple[str, str]],
        progress: Progress | None,
        saved: Callable[[dict[str, Any]], None] | None,
    ) -> None:
        self.plan, self.steps, self.rules = plan, steps, rules
        self.progress, self.saved = progress, saved
        self.chains: list[_Chain] = []
        self.verdicts: dict[tuple[str, str], dict[str, Any]] = {}  # (test-case, controller)
        self.done, self.total = 0, plan.steps
        self.lock = threading.Lock()
        self.judging: list[Future[None]] = []

    def run(self, workers: int) -> dict[str, Any]:
        with ThreadPoolExecutor(workers, thread_name_prefix="campaign") as self.pool:
            try:
                self._grow_all()
                for future in self.judging:
                    future.result()
            except BaseException:
                self.pool.shutdown(wait=False, cancel_futures=True)
                raise
        outcome = summarize(self.plan, self._records(), self.rules)
        if self.saved is not None:
            self.saved(outcome)
        return outcome

    def _grow_all(self) -> None:
        plan = self.plan
        roots = list(self.pool.map(self.steps.root, plan.egos))
        for ego, (root_id, root) in zip(plan.egos, roots, strict=True):
            self._judge(root_id, root, f"{ego}: level 0")
            for number in range(plan.chains):
                name = chain_name(root, number)
                self.chains.append(
                    _Chain(ego, number, plan.seed + number, name, [(root_id, root, None)])
                )
        for level in range(1, plan.depth + 1):
            growing = [chain for chain in self.chains if chain.end is None]
            if not growing:
                break
            groups: dict[tuple[str, str], list[_Chain]] = {}
            for chain in growing:
                groups.setdefault((chain.ego, chain.levels[-1][0]), []).append(chain)
            held_back = {ego: self._covered_routes(ego) for ego in plan.egos}
            # every chain's first attempt at once, as if no other chain grew from its parent
            firsts = [self.pool.submit(self._attempt, chain, held_back[chain.ego], [])
                      for chain in growing]  # fmt: skip
            attempts = dict(zip(map(id, growing), _results(firsts), strict=True))
            _results([
                self.pool.submit(self._settle, level, group, [attempts[id(c)] for c in group],
                                 held_back[ego])
                for (ego, _), group in groups.items()
            ])  # fmt: skip
            self._publish()

    def _attempt(self, chain: _Chain, held_back: tuple[str, ...],
                 avoid: list[tuple[str, TestCase]]) -> Grown | ScengenError:  # fmt: skip
        """The chain's next level grown from its parent (differing from ``avoid``), or what
        ended it."""
        parent_id, parent, _ = chain.levels[-1]
        try:
            return self.steps.grow(parent_id, parent, chain.seed, held_back, chain.name, avoid)
        except CHAIN_ENDS as end:
            return end

    def _settle(
        self,
        level: int,
        group: list[_Chain],
        firsts: list[Grown | ScengenError],
        held_back: tuple[str, ...],
    ) -> None:
        """Level ``level`` of the chains of ``group`` (one parent), in chain order: a
        chain's first attempt stands when it differs from what the chains before it took
        here (``variety.signature``), or when it ended the chain (avoiding more finds no
        more); else the chain grows again, avoiding those. Each level is judged as soon as
        it stands."""
        taken: list[tuple[str, TestCase]] = []
        for chain, first in zip(group, firsts, strict=True):
            found = first
            if not isinstance(found, ScengenError) and not _differs(found, taken):
                found = self._attempt(chain, held_back, list(taken))
            if isinstance(found, ScengenError):
                chain.end = f"level {level}: {found.message}"
                self._tell(None, (self.plan.depth - level + 1) * (1 + len(self.plan.controllers)))
                continue
            child_id, child, route = found
            chain.levels.append(found)
            if all(child_id != ident for ident, _ in taken):
                taken.append((child_id, child))
            where = f"{chain.ego} chain {chain.number + 1}: level {level}"
            self._tell(f"{where} grown ({route})")
            self._judge(child_id, child, where)

    def _judge(self, ident: str, testcase: TestCase, where: str) -> None:
        """Every controller's verdict on ``ident``, each a step of its own (once per
        test-case: chains that hold the same one share it)."""
        for controller in self.plan.controllers:
            key = (ident, controller)
            with self.lock:
                asked = key in self.verdicts
                self.verdicts.setdefault(key, {})  # claimed: asked for once
            if asked:  # two chains hold the same test-case: one verdict serves both
                self._tell(f"{where} / {controller}")
                continue
            self.judging.append(self.pool.submit(self._verdict, ident, testcase, controller, where))

    def _verdict(self, ident: str, testcase: TestCase, controller: str, where: str) -> None:
        verdict = _compact(self.steps.evaluate(ident, testcase, controller))
        with self.lock:
            self.verdicts[(ident, controller)] = verdict
        self._tell(f"{where} / {controller}")

    def _tell(self, message: str | None, steps: int = 1) -> None:
        with self.lock:  # told in the order counted
            self.done += steps
            if message is not None and self.progress is not None:
                self.progress(message, self.done, self.total)

    def _publish(self) -> None:
        if self.saved is not None:
            self.saved(summarize(self.plan, self._records(), self.rules))

    def _records(self) -> list[dict[str, Any]]:
        """The chains as the outcome keeps them: each level whose every verdict is in (and
        those before it), in chain order."""
        records = []
        for chain in self.chains:
            levels = []
            for number, (ident, testcase, route) in enumerate(chain.levels):
                with self.lock:
                    verdicts = {c: self.verdicts.get((ident, c)) for c in self.plan.controllers}
                if not all(verdicts.values()):
                    break
                levels.append(_level(number, ident, testcase, route, verdicts))
            records.append({"ego": chain.ego, "chain": chain.number, "seed": chain.seed,
                            "end": chain.end, "name": chain.name, "levels": levels})  # fmt: skip
        return records

    def _covered_routes(self, ego: str) -> tuple[str, ...]:
        """Routes of this ego whose certificates so far broke only covered rules (tried
        last), from the levels grown before this wave."""
        broken = {ident: set(_broken(testcase)) for chain in self.chains
                  for ident, testcase, _ in chain.levels[1:]}  # fmt: skip
        covered = set().union(*broken.values())
        if all(rule in covered or rule in EGO_ONLY_RULES for rule, _ in self.rules):
            return ()  # everything is covered: no route is held back
        seen: dict[str, set[str]] = {}
        for chain in self.chains:
            if chain.ego != ego:
                continue
            for ident, _, route in chain.levels[1:]:
                assert route is not None
                seen.setdefault(route, set()).update(broken[ident])
        return tuple(sorted(r for r, broken in seen.items() if broken <= covered))


def _results(futures: Sequence[Future[Any]]) -> list[Any]:
    """The futures' results in their order; the first error (of any that failed first)
    ends the campaign."""
    pending = set(futures)
    while pending:
        finished, pending = wait(pending, return_when=FIRST_COMPLETED)
        for future in finished:
            future.result()
    return [future.result() for future in futures]


def _differs(grown: Grown, taken: Sequence[tuple[str, TestCase]]) -> bool:
    """Whether a level grown differs from every test-case of ``taken`` (by id, and as
    service.core.generator.variety tells test-cases apart)."""
    ident, testcase, _ = grown
    if any(ident == other for other, _ in taken):
        return False
    return is_new(signature(testcase), [signature(other) for _, other in taken])


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
        "signature": signature(testcase).to_dict(),
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
    criticality measures and the guard's counts as the verdict has them (null if not).
    Its collisions and rules are those until the goal, where the judgement ends;
    ``after_goal`` counts the records after it (information, never a failure)."""
    after = verdict.get("after_goal") or {}
    return {
        "evaluation": verdict.get("evaluation"),
        "passed": bool(verdict["passed"]),
        "rules": sorted({v["rule"] for v in verdict["violations"]}),
        "collisions": len(verdict["collisions"]),
        "goal_reached": bool(verdict["goal"]["reached"]),
        "after_goal": len(after.get("collisions", ())) + len(after.get("violations", ())),
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
