"""The paper's table from hand-made verdicts: the one cause a failed verdict shows, a
level's cell for one verdict and for several, and the text and Markdown renderings."""

from __future__ import annotations

from typing import Any

import pytest

from service.core.campaign.paper_table import cause_text, failure_cause, paper_cell, paper_table


def verdict(**changes: Any) -> dict[str, Any]:
    """A verdict as ``Verdict.to_dict`` writes it: a pass unless changed."""
    fields: dict[str, Any] = {"passed": True, "collisions": [], "violations": [], "errors": [],
                              "goal": {"reached": True, "time": 9.0}}  # fmt: skip
    fields.update(changes)
    return fields


def violation(rule: str, law: str, other: str | None) -> dict[str, Any]:
    return {"rule": rule, "law": law, "other": other, "events": []}


COLLISION = [{"other": "car3", "t": 7.0, "x": 0, "y": 0, "kind": "crossing"},
             {"other": "car2", "t": 5.5, "x": 0, "y": 0, "kind": "crossing"}]  # fmt: skip
YIELD = violation("yieldToInside", "21800(a)", "car2")


def test_a_failed_verdict_shows_a_collision_first_then_a_rule_an_error_the_goal() -> None:
    both = verdict(passed=False, collisions=COLLISION, violations=[YIELD])
    assert failure_cause(both) == {"kind": "collision", "car": "car2"}  # the earliest
    rule = failure_cause(verdict(passed=False, violations=[YIELD]))
    assert rule == {"kind": "rule", "rule": "yieldToInside", "law": "21800(a)", "car": "car2"}
    stop = violation("stopAtSign", "22450(a)", None)
    assert cause_text(failure_cause(verdict(passed=False, violations=[stop])) or {}) == "22450(a)"
    raised = verdict(passed=False, errors=["the controller raised"], goal={"reached": False})
    assert failure_cause(raised) == {"kind": "error"}
    assert failure_cause(verdict(passed=False, goal={"reached": False})) == {"kind": "goal"}
    assert failure_cause(verdict()) is None


def test_a_campaigns_compact_verdict_gives_its_kept_cause_or_what_an_older_one_knows() -> None:
    kept = {"passed": False, "cause": {"kind": "collision", "car": "car4"}}
    assert failure_cause(kept) == {"kind": "collision", "car": "car4"}
    older = {"passed": False, "rules": ["yieldToRight"], "collisions": 0, "errors": [],
             "goal_reached": True}  # fmt: skip
    assert cause_text(failure_cause(older) or {}) == "yieldToRight"  # no law, no car stored
    assert cause_text(failure_cause({**older, "collisions": 1}) or {}) == "collision"


def test_a_cell_is_a_verdict_or_the_share_failed_and_the_most_common_cause() -> None:
    failed = verdict(passed=False, violations=[YIELD])
    crashed = verdict(passed=False, collisions=COLLISION[:1])
    assert paper_cell([verdict()]) == "pass"
    assert paper_cell([failed]) == "FAIL 21800(a) car2"
    assert paper_cell([crashed]) == "FAIL collision car3"
    assert paper_cell([verdict(passed=False, goal={"reached": False})]) == "FAIL goal"
    other_car = verdict(passed=False, violations=[violation("yieldToInside", "21800(a)", "car1")])
    # car2 of one chain is not car2 of the next: the cause is counted without the car
    assert paper_cell([failed, crashed, other_car, verdict()]) == "3/4 FAIL 21800(a)"
    assert paper_cell([verdict(), verdict()]) == "pass 2/2"
    assert paper_cell([]) == "—"
    with pytest.raises(ValueError, match="unknown failure cause 'crash'"):
        cause_text({"kind": "crash"})


def test_the_table_reads_as_the_papers_in_text_and_markdown() -> None:
    failed = verdict(passed=False, violations=[YIELD])
    levels = {
        1: {"sumo": [verdict()], "sumo+rss": [verdict()]},
        0: {"sumo": [verdict()], "sumo+rss": [verdict()]},
        2: {"sumo": [failed]},  # no sumo+rss verdict at level 2
    }
    table = paper_table(levels, ["sumo", "sumo+rss"])
    assert table.text() == (
        "controller  level 0  level 1  level 2\n"
        "sumo        pass     pass     FAIL 21800(a) car2\n"
        "sumo+rss    pass     pass     —\n"
    )
    assert table.markdown() == (
        "| controller | level 0 | level 1 | level 2 |\n"
        "|---|---|---|---|\n"
        "| sumo | pass | pass | FAIL 21800(a) car2 |\n"
        "| sumo+rss | pass | pass | — |\n"
    )


def test_a_cell_of_one_run_says_how_close_it_came_and_how_often_the_guard_stepped_in() -> None:
    verdict = {
        "passed": True,
        "criticality": {"overall": {"ttc": {"value": 2.58, "car": "car3", "t": 5.0}}},
        "guard": {"kind": "rss", "steps": 199, "interventions": 8, "fallback": None},
    }
    assert paper_cell([verdict]) == "pass (TTC 2.6 s, RSS 8/199)"
    fallen_back = {**verdict, "guard": {**verdict["guard"], "fallback": "ad_rss missing"}}
    assert paper_cell([fallen_back]) == "pass (TTC 2.6 s, RSS time-gap 8/199)"
    assert paper_cell([verdict, verdict]) == "pass 2/2"  # several runs: the shares only
