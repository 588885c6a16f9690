"""The Celery side of batch jobs: ``scengen.run_item`` (a job item) and ``scengen.run_step``
(a campaign's step, service.jobs.step_runner), run by ``scengen worker``.

Each worker process takes one task at a time and does its work in child processes of its
own (every solver or SUMO call is a fresh ``python -m service.core.budget``: libsumo and
the solvers are per-process singletons), so a pool process only claims, waits and writes;
it is kept for ``TASKS_PER_PROCESS`` tasks (replacing it after every one cost 4 to 5 s a
task, measured: more than most campaign steps take). Celery gives each pool process
PR_SET_PDEATHSIG (SIGKILL) and every solver child sets its own (service.core.budget): a
worker killed with -9 leaves no process behind. The message is acknowledged only after the
task ends and given back when a worker dies; the database claim makes a redelivered message
that finds its item (step) running or finished a no-op, so nothing runs twice.

A message can still be lost (Redis restarted empty, a worker killed while it held a message
it had not started): ``held_items`` (``held_steps``) tells which items' (steps') messages
the broker still holds, so that the dispatcher (the campaign's coordinator) sends the others
again, and only those, within the lease.
"""

from __future__ import annotations

import functools
import re
import secrets
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

import redis
from celery import Celery

from service.jobs.step_news import is_redis
from service.settings import Settings, get_settings

if TYPE_CHECKING:
    from service.store import Store

TASKS_PER_PROCESS = 100  # a pool process is replaced after this many tasks
ITEM_TIME_LIMIT = 6 * 3600  # seconds; every solver call inside has its own, smaller budget
QUEUE = "celery"  # Celery's default queue: a Redis list (one per priority step)
# kombu's Redis transport: the queue of priority p is QUEUE + SEPARATOR + p (0: QUEUE); a
# message delivered to a worker and not yet acknowledged is in UNACKED, by delivery tag,
# with its delivery time in UNACKED_INDEX
SEPARATOR, PRIORITIES = "\x06\x16", (0, 3, 6, 9)
UNACKED, UNACKED_INDEX = "unacked", "unacked_index"
TASK_ID = re.compile(rb"scengen-item\.([0-9a-f]+)\.(\d+)\.")
STEP_TASK_ID = re.compile(rb"scengen-step\.([0-9a-f]+)\.(\d+)\.([0-9a-f]+)\.")


def make_celery(settings: Settings) -> Celery:
    app = Celery("scengen", broker=settings.broker_url)
    app.conf.update(
        task_acks_late=True,
        task_reject_on_worker_lost=True,
        task_ignore_result=True,
        task_serializer="json",
        accept_content=["json"],
        task_time_limit=ITEM_TIME_LIMIT,
        worker_prefetch_multiplier=1,
        worker_max_tasks_per_child=TASKS_PER_PROCESS,
        worker_hijack_root_logger=False,
        broker_connection_retry_on_startup=True,
        broker_transport_options={"visibility_timeout": ITEM_TIME_LIMIT + 600},
    )
    app.task(name="scengen.run_item")(run_item_task)
    app.task(name="scengen.run_step")(run_step_task)
    return app


def run_item_task(job: str, position: int) -> None:
    """Run one job item in this worker (settings from the environment)."""
    from service.jobs.runner import owner_name, run_item

    settings = get_settings()
    run_item(_store(settings), settings, job, position, owner_name("celery"))


def run_step_task(job: str, position: int, step: str) -> None:
    """Do one campaign step in this worker (settings from the environment)."""
    from service.jobs.runner import owner_name
    from service.jobs.step_runner import run_step

    settings = get_settings()
    run_step(_store(settings), settings, job, position, step, owner_name("celery"))


@functools.cache
def _store_of(database: str, cache_dir: Path, max_samples: int) -> Store:
    from service.store import Store

    return Store(database, cache_dir, max_samples)


def _store(settings: Settings) -> Store:
    """The pool process's store, opened by its first task and kept for the next ones
    (opening one checks every table: 0.17 s, measured)."""
    return _store_of(settings.database, settings.cache_dir, settings.max_samples)


def worker_arguments(concurrency: int, name: str, loglevel: str = "INFO") -> list[str]:
    return [
        "worker",
        f"--concurrency={concurrency}",
        "--pool=prefork",
        f"--loglevel={loglevel}",
        "--without-gossip",
        "--without-mingle",
        f"--hostname={name}",
    ]


def start_worker(settings: Settings, concurrency: int, name: str) -> Any:
    """``scengen worker``: blocks until the worker stops."""
    return make_celery(settings).worker_main(worker_arguments(concurrency, name))


def task_id(job: str, position: int) -> str:
    """The id of an item's message: names the item, so that ``held_items`` can find it."""
    return f"scengen-item.{job}.{position}.{secrets.token_hex(4)}"


class CeleryStepBroker:
    """Campaign steps to Celery workers (service.jobs.celery_steps.StepBroker)."""

    def __init__(self, settings: Settings) -> None:
        self.celery = make_celery(settings)
        self.broker_url = settings.broker_url

    def send(self, job: str, position: int, step: str) -> None:
        self.celery.send_task("scengen.run_step", args=[job, position, step],
                              task_id=step_task_id(job, position, step))  # fmt: skip

    def held(self, fresh: float) -> set[str] | None:
        return held_steps(self.broker_url, fresh)


def step_task_id(job: str, position: int, step: str) -> str:
    """The id of a campaign step's message: names the step, for ``held_steps``."""
    return f"scengen-step.{job}.{position}.{step}.{secrets.token_hex(4)}"


def held_items(broker_url: str, fresh: float) -> set[tuple[str, int]] | None:
    """The items whose message the broker holds: waiting in the queue, or delivered to a
    worker less than ``fresh`` seconds ago (the worker has that long to claim the item).
    None when the broker is not Redis (the dispatcher then resends after ``fresh``; a
    duplicate message finds its item claimed and does nothing)."""
    messages = _held_messages(broker_url, fresh)
    if messages is None:
        return None
    return {(found[1].decode(), int(found[2])) for m in messages for found in TASK_ID.finditer(m)}


def held_steps(broker_url: str, fresh: float) -> set[str] | None:
    """The campaign steps (ids) whose message the broker holds, as ``held_items`` says."""
    messages = _held_messages(broker_url, fresh)
    if messages is None:
        return None
    return {found[3].decode() for m in messages for found in STEP_TASK_ID.finditer(m)}


def _held_messages(broker_url: str, fresh: float) -> list[bytes] | None:
    """The messages in the broker's queues and those delivered less than ``fresh``
    seconds ago; None when the broker is not Redis."""
    if not is_redis(broker_url):
        return None
    client = redis.Redis.from_url(broker_url)
    try:
        with client.pipeline(transaction=False) as pipe:
            for priority in PRIORITIES:
                pipe.lrange(QUEUE + (f"{SEPARATOR}{priority}" if priority else ""), 0, -1)
            pipe.zrangebyscore(UNACKED_INDEX, time.time() - fresh, "+inf")
            *queued, recent = pipe.execute()
        delivered = client.hmget(UNACKED, recent) if recent else []
    finally:
        client.close()
    return [m for queue in queued for m in queue] + [m for m in delivered if m]
