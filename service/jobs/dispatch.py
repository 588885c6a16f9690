"""Two executors of job items behind one interface: ``Dispatcher.run`` (a task of the server).

Both look at the database every ``period`` seconds (or at once when nudged): items whose
lease ran out are given back (or failed after too many attempts), and runnable items are
started. ``LocalDispatcher`` runs them in this machine's worker threads, each solver call in
a child process; ``CeleryDispatcher`` sends them to Celery workers (``scengen worker``).
"""

from __future__ import annotations

import asyncio
import contextlib
import functools
import sys
import threading
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from typing import Any

from service.jobs.celery_steps import StepBroker
from service.jobs.runner import owner_name, run_item
from service.jobs.store import ItemRecord, JobStore
from service.settings import Settings
from service.store import Store


class Dispatcher:
    """Starts runnable items; subclasses say where they run."""

    period = 0.5

    def __init__(self, store: Store, settings: Settings) -> None:
        self.store, self.settings = store, settings
        self.jobs = JobStore(store)
        self._nudge = asyncio.Event()

    def nudge(self) -> None:
        """A job was created or cancelled: look now."""
        self._nudge.set()

    async def run(self) -> None:
        while True:
            try:
                await asyncio.to_thread(self.jobs.reclaim_expired, self.settings.item_attempts)
                await self.dispatch()
            except Exception as error:  # the database is away: try again next period
                print(f"scengen: dispatcher: {type(error).__name__}: {error}")
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(self._nudge.wait(), self.period)
            self._nudge.clear()

    async def dispatch(self) -> None:
        raise NotImplementedError

    async def close(self) -> None:
        """Stop (the server is going away)."""


class ItemThreads:
    """Job items run in threads of this process, at most ``slots`` at once (each item's
    solver and SUMO calls in child processes); with a ``step_broker``, campaign items send
    their steps to Celery workers and wait for them (service.jobs.celery_steps)."""

    def __init__(self, store: Store, settings: Settings, kind: str,
                 step_broker: StepBroker | None, nudge: Callable[[], None]) -> None:  # fmt: skip
        self.store, self.settings, self.nudge = store, settings, nudge
        self.slots = settings.job_slots
        self.pool = ThreadPoolExecutor(self.slots, thread_name_prefix="scengen-item")
        self.running: set[tuple[str, int]] = set()
        self.owner = owner_name(kind)
        self.step_broker = step_broker
        self.shutdown = threading.Event()

    def free(self) -> int:
        return self.slots - len(self.running)

    def start(self, items: list[ItemRecord]) -> None:
        loop = asyncio.get_running_loop()
        for item in items:
            key = (item.job, item.position)
            if key in self.running or len(self.running) >= self.slots:
                continue
            self.running.add(key)
            future = loop.run_in_executor(
                self.pool, run_item, self.store, self.settings, item.job, item.position,
                self.owner, self.shutdown, self.step_broker,
            )  # fmt: skip
            future.add_done_callback(functools.partial(self._finished, key))

    def _finished(self, key: tuple[str, int], _: object) -> None:
        self.running.discard(key)
        self.nudge()

    async def close(self, jobs: JobStore) -> None:
        """Stop the running items and give their claims back: a restart costs no attempt."""
        self.shutdown.set()
        await asyncio.to_thread(self.pool.shutdown, True, cancel_futures=True)
        await asyncio.to_thread(jobs.release, self.owner)


class LocalDispatcher(Dispatcher):
    """Items run in threads of the server, at most ``job_slots`` at once (each item's
    solver and SUMO calls in child processes)."""

    def __init__(self, store: Store, settings: Settings) -> None:
        super().__init__(store, settings)
        self.threads = ItemThreads(store, settings, "local", None, self.nudge)

    async def dispatch(self) -> None:
        free = self.threads.free()
        if free <= 0:
            return
        ready = await asyncio.to_thread(self.jobs.runnable, free + len(self.threads.running))
        self.threads.start(ready)

    async def close(self) -> None:
        await self.threads.close(self.jobs)


class CeleryDispatcher(Dispatcher):
    """Items go to Celery workers through the broker; the database still decides who runs
    what, so a message delivered twice, or sent again after a lost lease, runs once.

    A message the broker lost (Redis restarted empty, a worker killed holding a message it
    had not started) is sent again within the lease: an item sent (or last seen in the
    broker) more than ``SCENGEN_LEASE_SECONDS`` ago is looked for in the broker, and sent
    again only when it is not there; one that waits its turn behind busy workers is
    found there and left alone.

    A campaign item is coordinated here, in a thread of the server (at most ``job_slots``
    at once), and its steps go to the workers (service.jobs.celery_steps): a campaign
    uses every worker, and a worker never waits for another."""

    def __init__(self, store: Store, settings: Settings) -> None:
        super().__init__(store, settings)
        from service.jobs.celery_app import CeleryStepBroker, make_celery

        self.celery: Any = make_celery(settings)
        broker = CeleryStepBroker(settings)
        self.coordinators = ItemThreads(store, settings, "coordinator", broker, self.nudge)

    async def dispatch(self) -> None:
        lease = self.settings.lease_seconds
        ready = await asyncio.to_thread(self.jobs.runnable, 100, True, lease)
        campaigns = [item for item in ready if item.kind == "campaign"]
        if campaigns and self.coordinators.free() > 0:
            self.coordinators.start(campaigns)
        ready = [item for item in ready if item.kind != "campaign"]
        if any(item.sent_at is not None for item in ready):
            from service.jobs.celery_app import held_items

            held = await asyncio.to_thread(held_items, self.settings.broker_url, lease)
            if held:
                waiting = [(i.job, i.position) for i in ready if (i.job, i.position) in held]
                await asyncio.to_thread(self.jobs.mark_sent, waiting)
                ready = [item for item in ready if (item.job, item.position) not in held]
        for item in ready:
            if item.sent_at is not None:
                print(
                    f"scengen: dispatcher: job {item.job} item {item.position}: its message "
                    f"is not in the broker {time.time() - item.sent_at:.0f} s after it was "
                    "sent (lost?): sent again",
                    file=sys.stderr,
                )
            await asyncio.to_thread(self._send, item.job, item.position)

    def _send(self, job: str, position: int) -> None:
        from service.jobs.celery_app import task_id

        self.celery.send_task("scengen.run_item", args=[job, position],
                              task_id=task_id(job, position))  # fmt: skip
        self.jobs.mark_sent([(job, position)])

    async def close(self) -> None:
        await self.coordinators.close(self.jobs)


def make_dispatcher(store: Store, settings: Settings) -> Dispatcher:
    if settings.executor == "celery":
        return CeleryDispatcher(store, settings)
    return LocalDispatcher(store, settings)
