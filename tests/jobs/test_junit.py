"""A job's JUnit report: evaluations named by their test-case's name (which says the
level) with the id beside it, and every item that failed an error with its reason."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from xml.etree import ElementTree as ET

import pytest

from service.api.public import evaluation_public
from service.core.checker.verdict import CollisionRecord, Verdict
from service.core.testcase import new_testcase, readable_name, renamed
from service.jobs.batch import parse_batch
from service.jobs.junit import job_junit
from service.jobs.store import JobStore
from service.store import Store


@pytest.fixture
def store(tmp_path: Path) -> Iterator[Store]:
    opened = Store(f"sqlite:///{tmp_path}/store.sqlite3", tmp_path / "cache")
    yield opened
    opened.close()


def cases(store: Store, job: str) -> tuple[ET.Element, list[ET.Element]]:
    found = JobStore(store).job(job)
    assert found is not None
    suite = ET.fromstring(job_junit(store, found)).find("testsuite")
    assert suite is not None
    return suite, suite.findall("testcase")


def test_evaluations_are_named_by_the_testcase_and_failed_items_are_errors(store: Store) -> None:
    plain = new_testcase("4way-stop", "E2C_1:C2S_1")
    named = store.add_testcase(renamed(plain, readable_name(plain)))
    unnamed = store.add_testcase(new_testcase("t-stop", "E2C_0:C2S_0"))  # sent inline, say
    jobs = JobStore(store)
    batch = parse_batch({"name": "nightly", "items": [
        {"kind": "evaluate", "testcase_id": named.id, "controllers": ["sumo", "sumo-aggressive"]},
        {"kind": "evaluate", "testcase_id": unnamed.id, "controllers": ["sumo"]},
        {"kind": "extend", "testcase_id": named.id, "routes": ["S2C_1:C2N_1"]},
        {"kind": "extend", "testcase_id": named.id, "routes": ["W2C_1:C2E_1"]},
    ]})  # fmt: skip
    job, _ = jobs.create(batch)
    made = []
    for position, record, controller, passed in [
        (0, named, "sumo", True), (0, named, "sumo-aggressive", False), (1, unnamed, "sumo", True)
    ]:  # fmt: skip
        verdict = Verdict(record.testcase.name or "t-stop C E2C_0:C2S_0 level 0", controller,
                          passed, 5.0 if passed else None, duration=20.0)  # fmt: skip
        ident = job.items[position].evaluation_id(record.id, controller)
        made.append(store.add_evaluation(record.id, controller, verdict.to_dict(), 1.0, ident))
    for position, idents in ((0, [e.id for e in made[:2]]), (1, [made[2].id])):
        assert jobs.claim(job.id, position, "w", 30)
        jobs.record(job.id, position, "w", "done", None, idents)
        jobs.finish(job.id, position, "w", "succeeded")
    assert jobs.claim(job.id, 2, "w", 30)
    jobs.finish(job.id, 2, "w", "failed", "no new car makes this test-case more complex",
                error_kind="NoMoreComplexTestCase")  # fmt: skip
    jobs.cancel(job.id)
    suite, found = cases(store, job.id)
    assert suite.get("name") == "scengen job nightly"
    assert [(c.get("name"), [e.tag for e in c]) for c in found] == [
        (f"4way-stop C E2C_1:C2S_1 level 0 ({named.id}) / sumo", []),
        (f"4way-stop C E2C_1:C2S_1 level 0 ({named.id}) / sumo-aggressive", ["failure"]),
        (f"t-stop C E2C_0:C2S_0 level 0 ({unnamed.id}) / sumo", []),
        ("item 2 (extend)", ["error"]),
        ("item 3 (extend)", ["skipped"]),
    ]
    error = found[3].find("error")
    assert error is not None
    assert error.get("message") == "no new car makes this test-case more complex" == error.text
    counts = [suite.get(k) for k in ("tests", "failures", "errors", "skipped")]
    assert counts == ["5", "1", "1", "1"]


def test_a_job_whose_items_all_failed_reports_each(store: Store) -> None:
    jobs = JobStore(store)
    batch = parse_batch({"items": [
        {"kind": "evaluate", "testcase_id": "x", "controllers": ["sumo"]},
        {"kind": "chain", "testcase_id": "y", "levels": 1},
    ]})  # fmt: skip
    job, _ = jobs.create(batch)
    for position in (0, 1):
        assert jobs.claim(job.id, position, "w", 30)
        jobs.finish(
            job.id, position, "w", "failed", f"reason {position}", error_kind="InvalidInput"
        )
    suite, found = cases(store, job.id)
    assert (suite.get("tests"), suite.get("errors"), suite.get("failures")) == ("2", "2", "0")
    assert [c.find("error").get("message") for c in found] == ["reason 0", "reason 1"]  # type: ignore[union-attr]


def test_what_happened_after_the_goal_is_no_failure_and_shown_as_information(
    store: Store,
) -> None:
    """A stored verdict that passed with a collision after its goal: the job's JUnit case
    passed, and the API's evaluation lists the collision as information, not a reason."""
    record = store.add_testcase(new_testcase("4way-stop", "E2C_1:C2S_1"))
    late = CollisionRecord("car5", 40.525, 15.79, 117.01)
    verdict = Verdict(record.testcase.name, "sumo", True, 23.45, duration=45.0,
                      after_goal_collisions=(late,))  # fmt: skip
    jobs = JobStore(store)
    batch = parse_batch({"items": [
        {"kind": "evaluate", "testcase_id": record.id, "controllers": ["sumo"]}
    ]})  # fmt: skip
    job, _ = jobs.create(batch)
    ident = job.items[0].evaluation_id(record.id, "sumo")
    stored = store.add_evaluation(record.id, "sumo", verdict.to_dict(), 1.0, ident)
    assert jobs.claim(job.id, 0, "w", 30)
    jobs.record(job.id, 0, "w", "done", None, [stored.id])
    jobs.finish(job.id, 0, "w", "succeeded")
    _, found = cases(store, job.id)
    assert [[e.tag for e in case] for case in found] == [[]]  # passed: no failure
    public = evaluation_public(stored)
    assert public.passed and public.reasons == []
    assert public.information == [f"after its goal (not judged): {late.describe()}"]
    assert public.verdict["after_goal"]["collisions"][0]["other"] == "car5"
