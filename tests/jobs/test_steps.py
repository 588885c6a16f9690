"""A campaign's steps in the database (service.jobs.steps) and how the coordinator reads
them back (service.jobs.celery_steps): posted once, claimed once, kept by their owner,
sent again when their worker dies, failed after too many starts; on SQLite and on the
machine's PostgreSQL."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from pathlib import Path
from types import SimpleNamespace

import pytest

from service.core.errors import NoneFound, ScengenError
from service.jobs.batch import parse_batch
from service.jobs.celery_steps import CelerySteps, StepFailed, step_answer
from service.jobs.steps import WORKER_LOST, StepStore, step_id
from service.jobs.store import JobStore
from service.store import Store

BATCH = parse_batch({"items": [{"kind": "extend", "testcase_id": "x", "routes": ["a:b"]}]})
GROW = {"step": "grow", "parent": "p", "seed": 1, "last": [], "stem": "s", "avoid": []}


@pytest.fixture(params=["sqlite", "postgresql"])
def stores(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[tuple[JobStore, StepStore]]:
    if request.param == "sqlite":
        url = f"sqlite:///{tmp_path}/jobs.sqlite3"
    else:
        url = request.getfixturevalue("postgres_url")
    store = Store(url, tmp_path / "cache")
    yield JobStore(store), StepStore(store)
    if request.param == "postgresql":
        with store.engine.begin() as connection:
            for table in ("job_steps", "job_items", "jobs"):
                connection.exec_driver_sql(f"DELETE FROM {table}")
    store.close()


def running_item(jobs: JobStore) -> str:
    job, _ = jobs.create(BATCH)
    assert jobs.claim(job.id, 0, "coordinator", 30)
    return job.id


def test_a_step_is_posted_once_and_of_two_claims_one_wins(
    stores: tuple[JobStore, StepStore],
) -> None:
    jobs, steps = stores
    job = running_item(jobs)
    first = steps.post(job, 0, "grow/p/1/x", GROW)
    again = steps.post(job, 0, "grow/p/1/x", {"step": "other"})  # a restarted coordinator
    assert first == again and first.step == step_id("grow/p/1/x")
    assert first.state == "queued" and first.request == GROW and first.attempts == 0
    wins: list[bool] = []
    racers = [
        threading.Thread(target=lambda n=n: wins.append(steps.claim(job, 0, first.step, n, 30)))
        for n in ("w1", "w2", "w3")
    ]
    for racer in racers:
        racer.start()
    for racer in racers:
        racer.join()
    assert sorted(wins) == [False, False, True]
    claimed = steps.get(job, 0, first.step)
    assert claimed is not None and claimed.state == "running" and claimed.attempts == 1
    owner = str(claimed.owner)
    assert not steps.finish(job, 0, first.step, "someone else", 1.0, result={"x": 1})
    assert steps.finish(job, 0, first.step, owner, 2.5, result={"testcase": "t", "route": "r"})
    done = steps.get(job, 0, first.step)
    assert done is not None and done.state == "done" and done.seconds == 2.5
    assert step_answer(done) == {"testcase": "t", "route": "r"}
    assert not steps.claim(job, 0, first.step, "late message", 30)  # delivered twice: no-op


def test_a_dead_workers_step_goes_back_to_queued_then_fails_after_its_attempts(
    stores: tuple[JobStore, StepStore],
) -> None:
    jobs, steps = stores
    job = running_item(jobs)
    step = steps.post(job, 0, "evaluate/e", {"step": "evaluate"}).step
    assert steps.claim(job, 0, step, "w1", 0.2)
    steps.reclaim(job, 0, step, attempts=2)  # its lease still runs: kept
    assert steps.get(job, 0, step).state == "running"  # type: ignore[union-attr]
    time.sleep(0.3)
    steps.reclaim(job, 0, step, attempts=2)
    back = steps.get(job, 0, step)
    assert back is not None and back.state == "queued" and back.owner is None
    assert back.sent_at is None  # to be sent again
    assert not steps.renew(job, 0, step, "w1", 30)  # the dead worker's lease is gone
    assert steps.claim(job, 0, step, "w2", 0.2)
    time.sleep(0.3)
    steps.reclaim(job, 0, step, attempts=2)
    failed = steps.get(job, 0, step)
    assert failed is not None and failed.state == "failed" and failed.attempts == 2
    assert failed.error_kind == WORKER_LOST  # not a bug on the worker: it was killed
    assert failed.error == "its worker stopped answering 2 times (killed or out of memory?); " \
        "last owner w2"  # fmt: skip
    with pytest.raises(ScengenError, match="campaign step evaluate/e: its worker stopped"):
        step_answer(failed)


def test_a_cancelled_jobs_steps_are_neither_claimed_nor_renewed(
    stores: tuple[JobStore, StepStore],
) -> None:
    jobs, steps = stores
    job = running_item(jobs)
    started = steps.post(job, 0, "root/a", {"step": "root"}).step
    waiting = steps.post(job, 0, "root/b", {"step": "root"}).step
    assert steps.claim(job, 0, started, "w1", 30)
    jobs.cancel(job)
    assert not steps.renew(job, 0, started, "w1", 30)  # the worker stops its child
    assert not steps.claim(job, 0, waiting, "w2", 30)
    assert [s.key for s in steps.of(job, 0)] == ["root/a", "root/b"]


def test_a_failed_step_raises_its_error_on_the_coordinator(
    stores: tuple[JobStore, StepStore],
) -> None:
    jobs, steps = stores
    job = running_item(jobs)
    failures = [
        ("a", "NoneFound", "none found in 3 answer sets"),
        ("b", None, "internal error (a bug; ...): KeyError('x')"),
    ]
    for key, kind, error in failures:
        step = steps.post(job, 0, key, {"step": "grow"}).step
        assert steps.claim(job, 0, step, "w", 30)
        steps.finish(job, 0, step, "w", 0.1, error=error, error_kind=kind)
    first, second = steps.of(job, 0)
    with pytest.raises(NoneFound, match="none found in 3 answer sets"):
        step_answer(first)
    with pytest.raises(StepFailed, match=r"campaign step b: internal error .*KeyError"):
        step_answer(second)


def test_a_step_whose_worker_kept_its_verdict_and_died_is_unfinished(
    stores: tuple[JobStore, StepStore],
) -> None:
    """A worker stores its verdict, then dies before finishing its step: the coordinator,
    which finds the verdict stored, must still see the step unfinished and have it done
    again (JobCampaign.evaluate), so that no step of a finished job is left running."""
    jobs, steps = stores
    job = running_item(jobs)
    work = SimpleNamespace(store=SimpleNamespace(engine=steps.engine),
                           item=SimpleNamespace(job=job, position=0), settings=None,
                           stop=threading.Event())  # fmt: skip
    coordinator = CelerySteps(work, broker=None)  # type: ignore[arg-type]
    key = "evaluate/e1"
    assert not coordinator.unfinished(key)  # never posted
    posted = steps.post(job, 0, key, {"step": "evaluate"})
    assert coordinator.unfinished(key)
    assert steps.claim(job, 0, posted.step, "w1", 30)
    assert coordinator.unfinished(key)  # w1 died here, its verdict stored
    assert steps.finish(job, 0, posted.step, "w1", 1.0, result={"passed": True})
    assert not coordinator.unfinished(key)
