"""A job as one JUnit report for CI: every evaluation so far, named by its test-case's name
(which says the level) with the id beside it; a campaign item's own cases (chain and level
in each name); and every item that failed as an error with its reason."""

from __future__ import annotations

from service.core.campaign.outcome import campaign_cases
from service.core.checker.verdict import JUnitCase, Verdict, junit_document, verdict_case
from service.jobs.campaign_steps import OUTCOME
from service.jobs.store import ItemRecord, JobRecord, JobStore
from service.store import Store


def job_junit(store: Store, job: JobRecord) -> str:
    """The JUnit XML of ``job`` so far (items still queued or running add what they made)."""
    names: dict[str, str] = {}  # test-case id -> name
    cases: list[JUnitCase] = []
    for item in job.items:
        if item.kind == "campaign":
            outcome = JobStore(store).memo(job.id, item.position, OUTCOME)
            cases += campaign_cases(outcome) if outcome is not None else []
        else:
            cases += _evaluation_cases(store, item, names)
        if item.state == "failed":
            why = item.error or "failed"
            cases.append(JUnitCase("scengen.job", _item_name(item), "error", why))
        elif item.state == "cancelled":
            cases.append(JUnitCase("scengen.job", _item_name(item), "skipped", "cancelled"))
    return junit_document(cases, f"scengen job {job.name or job.id}")


def _evaluation_cases(store: Store, item: ItemRecord, names: dict[str, str]) -> list[JUnitCase]:
    """A case per stored evaluation of ``item``: ``NAME (ID) / CONTROLLER``."""
    cases = []
    for ident in item.evaluations:
        record = store.evaluation(ident)
        if record is None:
            continue
        verdict = Verdict.from_dict(record.verdict)
        if record.testcase not in names:
            stored = store.testcase(record.testcase)
            # a test-case without a name: the verdict's label (its readable default)
            names[record.testcase] = stored.name if stored and stored.name else verdict.testcase
        label = f"{names[record.testcase]} ({record.testcase}) / {record.controller}"
        cases.append(verdict_case(verdict, label))
    return cases


def _item_name(item: ItemRecord) -> str:
    return f"item {item.position} ({item.kind})"
