"""Benchmark: what one campaign step costs the shared services, PostgreSQL and Redis, beyond
its own work: the numbers behind docs/scaling.md's model of a campaign on k machines.

Run with `make bench-jobs` (after bench_jobs) or `python -m bench.bench_steps`. Needs the
machine's PostgreSQL and Redis (as the tests do). It replays a step's bookkeeping as the
Celery executor does it (service.jobs.celery_steps and service.jobs.step_runner), without
the step's own work: the coordinator reads the memo, posts the step, marks it sent, the
worker claims it, reads it and its item, stores a test-case, finishes it, renews a lease,
the coordinator reads the result, remembers it and records the progress. That cycle on
one thread gives its latency; on THREADS threads at once its throughput (the steps per
second this PostgreSQL carries). Then Celery's send_task to Redis, the message each step
costs the broker, alone.
"""

from __future__ import annotations

import os
import platform
import secrets
import statistics
import threading
import time
from datetime import date
from pathlib import Path
from tempfile import TemporaryDirectory

import psycopg
import redis

from service.jobs.batch import parse_batch
from service.jobs.celery_app import make_celery, step_task_id
from service.jobs.steps import StepStore
from service.jobs.store import JobStore
from service.settings import Settings
from service.store import Store

POSTGRES = "postgresql://postgres@127.0.0.1:5432/test"
BROKER = "redis://127.0.0.1:6379/10"
STEPS = 400  # bookkeeping cycles per measurement
THREADS = 4  # cycles at once for the throughput
MESSAGES = 2000
BATCH = {"items": [{"kind": "extend", "testcase_id": "x", "routes": ["a:b"]}]}


def cycle(jobs: JobStore, steps: StepStore, job: str, n: int) -> tuple[float, float]:
    """One step's bookkeeping, coordinator and worker, without its work: the seconds of
    the coordinator's part (the server's) and of the worker's."""
    clock = time.perf_counter()
    key = f"grow/parent/{n}/{secrets.token_hex(4)}"
    jobs.memo(job, 0, key)
    step = steps.post(job, 0, key, {"step": "grow", "parent": "p", "avoid": []}).step
    steps.mark_sent(job, 0, [step])
    coordinator = time.perf_counter() - clock
    clock = time.perf_counter()
    assert steps.claim(job, 0, step, f"worker{n}", 30)
    steps.get(job, 0, step)
    jobs.item(job, 0)
    steps.renew(job, 0, step, f"worker{n}", 30)
    result = {"testcase": secrets.token_hex(8), "route": "S2C_0:C2N_0"}
    steps.finish(job, 0, step, f"worker{n}", 0.5, result=result)
    worker = time.perf_counter() - clock
    clock = time.perf_counter()
    steps.of(job, 0, [step])
    jobs.remember(job, 0, "coordinator", key, result)
    jobs.record(job, 0, "coordinator", f"{n}/{STEPS}: level grown", [result["testcase"]])
    return coordinator + time.perf_counter() - clock, worker


def database_figures(url: str) -> dict[str, float]:
    """Milliseconds per cycle on one thread (median; the coordinator's and the worker's
    parts), cycles per second on THREADS, and the poller's look at 64 steps."""
    with TemporaryDirectory() as folder:
        store = Store(url, Path(folder))
        jobs, steps = JobStore(store), StepStore(store)
        job, _ = jobs.create(parse_batch(BATCH))
        assert jobs.claim(job.id, 0, "coordinator", 3600)
        parts = [cycle(jobs, steps, job.id, n) for n in range(STEPS)]

        def share(first: int) -> None:
            for n in range(first, first + STEPS // THREADS):
                cycle(jobs, steps, job.id, n)

        threads = [
            threading.Thread(target=share, args=(STEPS + t * STEPS // THREADS,))
            for t in range(THREADS)
        ]
        clock = time.perf_counter()
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
        rate = STEPS / (time.perf_counter() - clock)
        poll = []
        wanted = [s.step for s in steps.of(job.id, 0)][:64]
        for _ in range(200):
            clock = time.perf_counter()
            steps.of(job.id, 0, wanted)
            poll.append(time.perf_counter() - clock)
        store.close()
    return {
        "cycle": statistics.median(c + w for c, w in parts) * 1000,
        "coordinator": statistics.median(c for c, _ in parts) * 1000,
        "worker": statistics.median(w for _, w in parts) * 1000,
        "rate": rate,
        "poll": statistics.median(poll) * 1000,
    }


def broker_rate() -> float:
    """send_task messages per second into Redis."""
    redis.Redis.from_url(BROKER).flushdb()
    celery = make_celery(Settings(broker_url=BROKER, executor="celery"))
    clock = time.perf_counter()
    for n in range(MESSAGES):
        celery.send_task("scengen.bench", args=["job", 0, str(n)],
                         task_id=step_task_id("0" * 16, 0, "0" * 32))  # fmt: skip
    rate = MESSAGES / (time.perf_counter() - clock)
    redis.Redis.from_url(BROKER).flushdb()
    return rate


def main() -> None:
    print(f"# bench_steps {date.today()} on {platform.node()} ({os.cpu_count()} cores): "
          "a campaign step's bookkeeping, without its work")  # fmt: skip
    print("| measure | value |")
    print("|---|---|")
    name = f"scengen_bench_{secrets.token_hex(4)}"
    with psycopg.connect(POSTGRES, autocommit=True) as admin:
        admin.execute(f"CREATE DATABASE {name}")
    try:
        url = f"postgresql+psycopg://postgres@127.0.0.1:5432/{name}"
        found = database_figures(url)
    finally:
        with psycopg.connect(POSTGRES, autocommit=True) as admin:
            admin.execute(f"DROP DATABASE IF EXISTS {name} WITH (FORCE)")
    print(f"| one step's bookkeeping on PostgreSQL, one thread | {found['cycle']:.2f} ms |")
    print(f"| of which the coordinator's (the server's) | {found['coordinator']:.2f} ms |")
    print(f"| of which the worker's | {found['worker']:.2f} ms |")
    print(f"| steps per second PostgreSQL carries, {THREADS} threads | {found['rate']:.0f} |")
    print(f"| the coordinator's look at 64 steps | {found['poll']:.2f} ms |")
    print(f"| send_task messages per second into Redis, one thread | {broker_rate():.0f} |")


if __name__ == "__main__":
    main()
