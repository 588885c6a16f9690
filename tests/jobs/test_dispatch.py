"""The Celery dispatcher against a real Redis (a private redis-server) and no worker: a
message waiting in the queue is left alone however long it waits; one the broker lost is
sent again once a lease has passed since it was last seen there."""

from __future__ import annotations

import asyncio
from collections.abc import Iterator
from pathlib import Path

import pytest
import redis

from service.jobs.batch import parse_batch
from service.jobs.celery_app import UNACKED_INDEX, held_items
from service.jobs.dispatch import CeleryDispatcher
from service.jobs.store import items
from service.settings import Settings
from service.store import Store
from tests.jobs.conftest import PrivateRedis

LEASE = 5.0
BATCH = parse_batch(
    {
        "items": [
            {"kind": "extend", "testcase_id": "x", "routes": ["a:b"]},
            {"kind": "extend", "testcase_id": "x", "routes": ["c:d"]},
        ]
    }
)


@pytest.fixture
def dispatcher(tmp_path: Path, private_redis: PrivateRedis) -> Iterator[CeleryDispatcher]:
    settings = Settings(
        data_dir=tmp_path, executor="celery", broker_url=private_redis.url, lease_seconds=LEASE
    )
    store = Store(settings.database, settings.cache_dir)
    yield CeleryDispatcher(store, settings)
    store.close()


def a_lease_later(dispatcher: CeleryDispatcher) -> None:
    """As if a lease had passed since every item was sent or last seen."""
    with dispatcher.jobs.engine.begin() as connection:
        connection.execute(items.update().values(sent_at=items.c.sent_at - LEASE - 1))


def queued_messages(url: str) -> int:
    return int(redis.Redis.from_url(url).llen("celery"))


def test_a_waiting_message_is_left_alone_and_a_lost_one_sent_again(
    dispatcher: CeleryDispatcher, capsys: pytest.CaptureFixture[str]
) -> None:
    url = dispatcher.settings.broker_url
    job, _ = dispatcher.jobs.create(BATCH)
    asyncio.run(dispatcher.dispatch())
    assert queued_messages(url) == 2
    assert held_items(url, LEASE) == {(job.id, 0), (job.id, 1)}
    a_lease_later(dispatcher)
    asyncio.run(dispatcher.dispatch())  # both are still in the queue: no duplicate
    assert queued_messages(url) == 2 and "sent again" not in capsys.readouterr().err
    redis.Redis.from_url(url).flushall()  # Redis lost everything
    asyncio.run(dispatcher.dispatch())  # not a lease yet since they were last seen
    assert queued_messages(url) == 0
    a_lease_later(dispatcher)
    asyncio.run(dispatcher.dispatch())
    assert queued_messages(url) == 2
    assert held_items(url, LEASE) == {(job.id, 0), (job.id, 1)}
    said = capsys.readouterr().err
    assert f"job {job.id} item 0: its message is not in the broker" in said
    assert f"job {job.id} item 1: its message is not in the broker" in said


def test_a_message_a_worker_took_counts_for_a_lease(dispatcher: CeleryDispatcher) -> None:
    """A message delivered to a worker (unacknowledged) is held for a lease: the worker
    has that long to claim its item; after that, its worker is taken for dead."""
    url = dispatcher.settings.broker_url
    job, _ = dispatcher.jobs.create(BATCH)
    asyncio.run(dispatcher.dispatch())
    broker = redis.Redis.from_url(url)
    with dispatcher.celery.connection_for_read() as connection:  # a worker, alive
        taken = connection.SimpleQueue("celery", no_ack=False).get(timeout=10)
        assert queued_messages(url) == 1
        assert held_items(url, LEASE) == {(job.id, 0), (job.id, 1)}
        delivered = broker.zscore(UNACKED_INDEX, taken.delivery_tag)
        assert delivered is not None  # delivered, not acknowledged
        # a lease later, its worker still silent (killed before it claimed the item)
        broker.zadd(UNACKED_INDEX, {taken.delivery_tag: delivered - LEASE - 1})
        position = int(taken.headers["id"].split(".")[2])  # scengen-item.JOB.POSITION.x
        assert held_items(url, LEASE) == {(job.id, 1 - position)}  # the one in the queue
