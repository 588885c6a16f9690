"""Job state in the database: claims, leases, retries, cancellation, idempotency; on SQLite
and on the machine's PostgreSQL."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from service.jobs.batch import parse_batch
from service.jobs.store import IdempotencyConflict, JobStore, items
from service.store import Store

BATCH = parse_batch(
    {
        "items": [
            {"kind": "extend", "testcase_id": "x", "routes": ["a:b"]},
            {"kind": "extend", "testcase_id": "x", "routes": ["c:d"]},
            {"kind": "evaluate", "items": [0, 1], "controllers": ["sumo"]},
        ]
    }
)


@pytest.fixture(params=["sqlite", "postgresql"])
def jobs(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[JobStore]:
    if request.param == "sqlite":
        url = f"sqlite:///{tmp_path}/jobs.sqlite3"
    else:
        url = request.getfixturevalue("postgres_url")
    store = Store(url, tmp_path / "cache")
    yield JobStore(store)
    if request.param == "postgresql":
        with store.engine.begin() as connection:
            for table in ("job_items", "jobs", "evaluations", "testcases", "networks"):
                connection.exec_driver_sql(f"DELETE FROM {table}")
    store.close()


def test_items_run_in_dependency_order(jobs: JobStore) -> None:
    job, created = jobs.create(BATCH)
    assert created and job.state == "queued" and [i.state for i in job.items] == ["queued"] * 3
    assert [i.position for i in jobs.runnable(10)] == [0, 1]
    for position in (0, 1):
        assert jobs.claim(job.id, position, "w", 30)
        jobs.finish(job.id, position, "w", "succeeded")
    assert [i.position for i in jobs.runnable(10)] == [2]
    assert jobs.claim(job.id, 2, "w", 30)
    jobs.finish(job.id, 2, "w", "succeeded")
    finished = jobs.job(job.id)
    assert finished is not None and finished.state == "succeeded" and finished.finished_at


def test_of_concurrent_claims_one_wins(jobs: JobStore) -> None:
    job, _ = jobs.create(BATCH)
    wins: list[bool] = []
    racers = [
        threading.Thread(target=lambda n=n: wins.append(jobs.claim(job.id, 0, f"w{n}", 30)))
        for n in range(8)
    ]
    for racer in racers:
        racer.start()
    for racer in racers:
        racer.join()
    assert sorted(wins) == [False] * 7 + [True]


def test_an_item_sent_longer_ago_than_the_lease_is_offered_again(jobs: JobStore) -> None:
    """The dispatcher sees again an item sent (or last seen in the broker) more than a
    lease ago, to look for its message; seeing it there re-arms it for another lease. A
    second message for an item that was claimed meanwhile is no second run."""
    job, _ = jobs.create(BATCH)
    assert [i.position for i in jobs.runnable(10, True, 5.0)] == [0, 1]
    jobs.mark_sent([(job.id, 0), (job.id, 1)])
    assert jobs.runnable(10, True, 5.0) == []
    with jobs.engine.begin() as connection:  # a lease later
        connection.execute(items.update().values(sent_at=items.c.sent_at - 6.0))
    again = jobs.runnable(10, True, 5.0)
    assert [i.position for i in again] == [0, 1] and all(i.sent_at for i in again)
    jobs.mark_sent([(job.id, 0)])  # found in the broker: waits its turn
    assert [i.position for i in jobs.runnable(10, True, 5.0)] == [1]
    assert jobs.claim(job.id, 1, "w1", 30)
    assert not jobs.claim(job.id, 1, "w2", 30)  # the first message's worker has it
    assert [i.position for i in jobs.runnable(10, True, 5.0)] == []


def test_an_expired_lease_is_retried_then_failed(jobs: JobStore) -> None:
    job, _ = jobs.create(BATCH)
    for attempt in (1, 2):
        assert jobs.claim(job.id, 0, f"w{attempt}", 0.01)
        time.sleep(0.05)
        assert jobs.reclaim_expired(attempts=2) == [(job.id, 0)]
        item = jobs.item(job.id, 0)
        assert item is not None and item.attempts == attempt
    item = jobs.item(job.id, 0)
    assert (
        item is not None
        and item.state == "failed"
        and "stopped answering 2 times" in str(item.error)
    )
    # A late answer from the first worker changes nothing.
    jobs.finish(job.id, 0, "w1", "succeeded")
    assert (jobs.item(job.id, 0) or item).state == "failed"
    assert [i.position for i in jobs.runnable(10)] == [1]
    after = jobs.item(job.id, 2)
    assert after is not None and after.state == "failed" and "item 0" in str(after.error)


def test_a_lost_lease_cannot_be_renewed(jobs: JobStore) -> None:
    job, _ = jobs.create(BATCH)
    assert jobs.claim(job.id, 0, "old", 0.01)
    time.sleep(0.05)
    jobs.reclaim_expired(attempts=3)
    assert jobs.claim(job.id, 0, "new", 30)
    assert not jobs.renew(job.id, 0, "old", 30)
    assert jobs.renew(job.id, 0, "new", 30)


def test_results_recorded_so_far_are_kept(jobs: JobStore) -> None:
    job, _ = jobs.create(BATCH)
    assert jobs.claim(job.id, 0, "w", 0.01)
    jobs.record(job.id, 0, "w", "level 1/2", ["t1"])
    time.sleep(0.05)
    jobs.reclaim_expired(attempts=3)
    item = jobs.item(job.id, 0)
    assert item is not None and item.state == "queued" and item.testcases == ["t1"]


def test_cancel_stops_everything_unfinished(jobs: JobStore) -> None:
    job, _ = jobs.create(BATCH)
    assert jobs.claim(job.id, 0, "w", 30)
    jobs.finish(job.id, 0, "w", "succeeded")
    assert jobs.claim(job.id, 1, "w", 30)
    jobs.cancel(job.id)
    cancelled = jobs.job(job.id)
    assert cancelled is not None and cancelled.state == "cancelled"
    assert [i.state for i in cancelled.items] == ["succeeded", "cancelled", "cancelled"]
    assert not jobs.renew(job.id, 1, "w", 30)  # the running worker learns it must stop
    assert jobs.runnable(10) == []


def test_idempotency_key(jobs: JobStore) -> None:
    first, created = jobs.create(BATCH, key="pipeline-41")
    again, created_again = jobs.create(BATCH, key="pipeline-41")
    assert created and not created_again and again.id == first.id
    with pytest.raises(IdempotencyConflict):
        jobs.create(parse_batch({"items": [{"kind": "extend", "testcase_id": "y",
                                            "routes": ["a:b"]}]}), key="pipeline-41")  # fmt: skip
    assert jobs.create(BATCH)[0].id != first.id
    assert jobs.list_jobs().total == 2


def test_a_job_whose_last_item_finished_unrecorded_is_finalised(jobs: JobStore) -> None:
    from service.jobs.store import items

    job, _ = jobs.create(BATCH)
    with jobs.engine.begin() as connection:  # as if the worker died between the two writes
        connection.execute(items.update().where(items.c.job == job.id).values(state="succeeded"))
    assert (jobs.job(job.id) or job).state == "queued"
    jobs.reclaim_expired(attempts=3)
    assert (jobs.job(job.id) or job).state == "succeeded"


def test_a_clean_shutdown_gives_claims_back_without_an_attempt(jobs: JobStore) -> None:
    job, _ = jobs.create(BATCH)
    assert jobs.claim(job.id, 0, "server-1", 30)
    assert jobs.release("server-1") == 1
    item = jobs.item(job.id, 0)
    assert item is not None and item.state == "queued" and item.attempts == 0


def test_nothing_is_recorded_into_a_cancelled_item(jobs: JobStore) -> None:
    job, _ = jobs.create(BATCH)
    assert jobs.claim(job.id, 0, "w", 30)
    jobs.cancel(job.id)
    jobs.record(job.id, 0, "w", "late", ["t-after-cancel"])
    item = jobs.item(job.id, 0)
    assert item is not None and item.testcases == [] and item.state == "cancelled"


def test_the_same_key_at_the_same_moment_gives_one_job(jobs: JobStore) -> None:
    made: list[str] = []
    racers = [
        threading.Thread(target=lambda: made.append(jobs.create(BATCH, key="race")[0].id))
        for _ in range(6)
    ]
    for racer in racers:
        racer.start()
    for racer in racers:
        racer.join()
    assert len(made) == 6 and len(set(made)) == 1


def test_older_jobs_run_first(jobs: JobStore) -> None:
    created = [jobs.create(BATCH)[0].id for _ in range(4)]
    assert [i.job for i in jobs.runnable(2)] == [created[0], created[0]]


OLD_SCHEMA = [  # the two tables as a version before test-case levels and error kinds made them
    """CREATE TABLE testcases (id VARCHAR(32) PRIMARY KEY, network VARCHAR(80) NOT NULL,
       junction VARCHAR(255) NOT NULL, parent VARCHAR(32), name TEXT NOT NULL,
       nonegos INTEGER NOT NULL, document TEXT NOT NULL,
       created_at TIMESTAMP WITH TIME ZONE NOT NULL)""",
    """CREATE TABLE job_items (job VARCHAR(32), position INTEGER, kind VARCHAR(16) NOT NULL,
       spec TEXT NOT NULL, needs TEXT NOT NULL, state VARCHAR(16) NOT NULL,
       attempts INTEGER NOT NULL, owner VARCHAR(255), lease_until FLOAT, sent_at FLOAT,
       progress TEXT NOT NULL, testcases TEXT NOT NULL, evaluations TEXT NOT NULL,
       error TEXT, started_at TIMESTAMP WITH TIME ZONE, finished_at TIMESTAMP WITH TIME ZONE,
       PRIMARY KEY (job, position))""",
]


@pytest.fixture(params=["sqlite", "postgresql"])
def empty_database(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[str]:
    """The URL of a database of its own, empty."""
    if request.param == "sqlite":
        yield f"sqlite:///{tmp_path}/old.sqlite3"
        return
    from tests.jobs.conftest import throwaway_postgres

    with throwaway_postgres("scengen_old") as url:
        yield url


def test_a_database_of_an_older_version_is_read(empty_database: str, tmp_path: Path) -> None:
    """The columns added since (a test-case's level and duration, an item's error kind) are
    added when a store opens the database; the rows stored before read as if stored now:
    the level and duration from the document, the class name out of the error's words."""
    import sqlalchemy as sa

    from service.core.testcase import dump_testcase, new_testcase

    document = dump_testcase(new_testcase("4way-stop", "E2C_1:C2S_1", duration=31.5))
    old = sa.create_engine(empty_database)
    with old.begin() as connection:
        for statement in OLD_SCHEMA:
            connection.exec_driver_sql(statement)
        connection.execute(
            sa.text("INSERT INTO testcases VALUES ('t0', '4way-stop', 'C', NULL, '', 0, :doc, "
                    "CURRENT_TIMESTAMP)"), {"doc": document},
        )  # fmt: skip
        connection.execute(
            sa.text("INSERT INTO job_items VALUES ('j', 0, 'extend', '{}', '[]', 'failed', 1, "
                    "NULL, NULL, NULL, '', '[]', '[]', :error, NULL, NULL)"),
            {"error": "ScengenError: no stored test-case 'nope'"},
        )  # fmt: skip
    old.dispose()
    store = Store(empty_database, tmp_path / "cache")
    try:
        Store(empty_database, tmp_path / "cache").close()  # a second process: nothing to add
        listed = store.list_testcases().items
        assert [(t.id, t.level, t.duration) for t in listed] == [("t0", 0, 31.5)]
        fetched = store.testcase("t0")
        assert fetched is not None and (fetched.level, fetched.duration) == (0, 31.5)
        item = JobStore(store).item("j", 0)
        assert item is not None
        assert (item.error, item.error_kind) == ("no stored test-case 'nope'", "ScengenError")
    finally:
        store.close()
