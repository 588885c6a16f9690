"""The Celery side of batch jobs: one task, ``scengen.run_item``, run by ``scengen worker``.

Each worker process takes one task at a time and is replaced after it (libsumo and the
solvers are per-process singletons; a fresh process per task keeps items apart). The
message is acknowledged only after the task ends and given back when a worker dies; the
database claim makes a redelivered message that finds its item running or finished a
no-op, so nothing runs twice.
"""

from __future__ import annotations

from typing import Any

from celery import Celery

from service.settings import Settings, get_settings

ITEM_TIME_LIMIT = 6 * 3600  # seconds; every solver call inside has its own, smaller budget


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
        worker_max_tasks_per_child=1,
        worker_hijack_root_logger=False,
        broker_connection_retry_on_startup=True,
        broker_transport_options={"visibility_timeout": ITEM_TIME_LIMIT + 600},
    )
    app.task(name="scengen.run_item")(run_item_task)
    return app


def run_item_task(job: str, position: int) -> None:
    """Run one job item in this worker (settings from the environment)."""
    from service.jobs.runner import owner_name, run_item
    from service.store import Store

    settings = get_settings()
    store = Store(settings.database, settings.cache_dir, settings.max_samples)
    try:
        run_item(store, settings, job, position, owner_name("celery"))
    finally:
        store.close()


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
