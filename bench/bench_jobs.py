"""Benchmark: batch throughput on Celery with one and with two workers (same run, same batch),
and a campaign on this machine with one and with two workers.

Run with `make bench-jobs` (part of `make bench`). Needs the machine's PostgreSQL and Redis
(as the tests do). For each worker count it creates a fresh database, starts `scengen serve`
(SCENGEN_EXECUTOR=celery) and that many `scengen worker --concurrency 1` processes, submits
one batch of independent extensions (the four-way example, seeds 0..N-1) and times it from
submission to the last item. Then `scengen campaign` (CAMPAIGN: 8 chains of depth 3 on the
four-way stop, judged by SUMO's driver) with `--workers 1` and `--workers 2`, each in a
fresh folder, timed from start to end, and their outcomes compared (`python -m
bench.bench_jobs --campaign`: that part alone); and the same campaign as a job on a Celery
deployment with one and two workers, its steps spread over them, with what a step costs
beyond its own work (`--celery-campaign`: that part alone, after one local run to compare
with). The ratios go into docs/benchmarks.md.
"""

from __future__ import annotations

import contextlib
import json
import os
import platform
import secrets
import signal
import socket
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from datetime import date
from pathlib import Path
from typing import Any

import httpx2 as httpx
import psycopg
import redis

from service.api.schemas import EXAMPLE_NEW_ROUTE, example_testcase

ITEMS = 12
CAMPAIGN = ["campaign", "4way-stop", "--ego", "S2C_0:C2N_0", "--depth", "3", "--chains", "8",
            "--controller", "sumo", "--duration", "45", "--seed", "0"]  # fmt: skip
CAMPAIGN_JOB = {"kind": "campaign", "network": "4way-stop", "egos": ["S2C_0:C2N_0"], "depth": 3,
                "chains": 8, "controllers": ["sumo"], "duration": 45, "seed": 0}  # fmt: skip
POSTGRES = "postgresql://postgres@127.0.0.1:5432/test"
BROKER = "redis://127.0.0.1:6379/9"


def batch() -> dict[str, Any]:
    root = example_testcase()
    return {
        "name": "throughput",
        "items": [
            {"kind": "extend", "testcase": root, "routes": [EXAMPLE_NEW_ROUTE], "seed": seed,
             "budget": 60}
            for seed in range(ITEMS)
        ],
    }  # fmt: skip


def start(args: list[str], env: dict[str, str], log: Path) -> subprocess.Popen[bytes]:
    return subprocess.Popen(
        [sys.executable, "-m", "service", *args],
        env=env, stdout=log.open("w"), stderr=subprocess.STDOUT, start_new_session=True,
    )  # fmt: skip


@contextlib.contextmanager
def deployment(workers: int, folder: Path, tag: str) -> Iterator[tuple[str, str]]:
    """A fresh database, `scengen serve` (SCENGEN_EXECUTOR=celery) and ``workers``
    `scengen worker --concurrency 1` processes: the server's URL and the database's."""
    name = f"scengen_bench_{secrets.token_hex(4)}"
    with psycopg.connect(POSTGRES, autocommit=True) as admin:
        admin.execute(f"CREATE DATABASE {name}")
    redis.Redis.from_url(BROKER).flushdb()
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    database = f"postgresql://postgres@127.0.0.1:5432/{name}"
    env = {
        **{k: v for k, v in os.environ.items() if not k.startswith("SCENGEN_")},
        "SCENGEN_EXECUTOR": "celery",
        "SCENGEN_BROKER_URL": BROKER,
        "SCENGEN_DATABASE_URL": database.replace("postgresql:", "postgresql+psycopg:"),
        "SCENGEN_DATA_DIR": str(folder / f"data-{tag}-{workers}"),
    }
    logs = [folder / f"worker-{tag}-{workers}-{n}.log" for n in range(workers)]
    processes = [start(["serve", "--port", str(port)], env, folder / f"serve-{tag}-{workers}.log")]
    processes += [start(["worker", "--name", f"bench{n}"], env, log) for n, log in enumerate(logs)]
    url = f"http://127.0.0.1:{port}"
    try:
        for log in logs:
            while " ready." not in log.read_text():
                time.sleep(0.2)
        while True:
            try:
                httpx.get(f"{url}/healthz").raise_for_status()
                break
            except httpx.TransportError:
                time.sleep(0.2)
        yield url, database
    finally:
        for process in processes:
            os.killpg(process.pid, signal.SIGTERM)
        for process in processes:
            try:
                process.wait(20)
            except subprocess.TimeoutExpired:
                os.killpg(process.pid, signal.SIGKILL)
        with psycopg.connect(POSTGRES, autocommit=True) as admin:
            admin.execute(f"DROP DATABASE IF EXISTS {name} WITH (FORCE)")


def finished_job(url: str, body: dict[str, Any]) -> dict[str, Any]:
    """The job of ``body``, submitted and waited for; the seconds it took under "seconds"."""
    clock = time.monotonic()
    job = httpx.post(f"{url}/jobs", json=body).json()
    while job["state"] not in ("succeeded", "failed", "cancelled"):
        time.sleep(0.2)
        job = httpx.get(f"{url}/jobs/{job['id']}").json()
    if job["state"] != "succeeded":
        raise RuntimeError(f"the job {job['state']}: {[i['error'] for i in job['items']]}")
    return {**job, "seconds": time.monotonic() - clock}


def run(workers: int, folder: Path) -> float:
    """Seconds from submission to the last finished item."""
    with deployment(workers, folder, "batch") as (url, _):
        return float(finished_job(url, batch())["seconds"])


def main() -> None:
    print(f"# bench_jobs {date.today()} on {platform.node()} ({os.cpu_count()} cores): "
          f"{ITEMS} independent extensions on Celery workers (concurrency 1 each)")  # fmt: skip
    print("| workers | batch wall time | items per minute |")
    print("|---|---|---|")
    throughput = {}
    with tempfile.TemporaryDirectory(prefix="scengen-bench-jobs-") as folder:
        for workers in (1, 2):
            seconds = run(workers, Path(folder))
            throughput[workers] = ITEMS / seconds * 60
            print(f"| {workers} | {seconds:.1f} s | {throughput[workers]:.1f} |")
    print(f"ratio two/one workers: {throughput[2] / throughput[1]:.2f}")
    campaigns()


def campaigns() -> None:
    """The campaign with one and two local workers: wall time, speed-up, same outcome."""
    print()
    print(f"# scengen {' '.join(CAMPAIGN)} --workers W")
    print("| workers | wall time | CPU time (children) | outcome |")
    print("|---|---|---|---|")
    seconds, outcomes = {}, {}
    with tempfile.TemporaryDirectory(prefix="scengen-bench-campaign-") as folder:
        for workers in (1, 2):
            out = Path(folder) / f"w{workers}"
            before = os.times()
            clock = time.perf_counter()
            done = subprocess.run(
                [sys.executable, "-m", "service", *CAMPAIGN, "--workers", str(workers),
                 "-o", str(out)], capture_output=True, text=True, check=False,
            )  # fmt: skip
            seconds[workers] = time.perf_counter() - clock
            after = os.times()
            cpu = after.children_user + after.children_system
            cpu -= before.children_user + before.children_system
            if done.returncode not in (0, 1):
                raise SystemExit(f"the campaign failed: {done.stderr[-2000:]}")
            outcome = json.loads((out / "campaign.json").read_text())
            outcomes[workers] = _without_evaluations(outcome)
            same = "the same as 1" if outcomes[workers] == outcomes[1] else "DIFFERS from 1"
            print(f"| {workers} | {seconds[workers]:.1f} s | {cpu:.1f} s | {same} |", flush=True)
    print(f"speed-up two/one workers: {seconds[1] / seconds[2]:.2f}")
    celery_campaigns(outcomes[1])


def celery_campaigns(local: dict[str, Any]) -> None:
    """The same campaign as a job on Celery with one and two workers: wall time, speed-up,
    the same outcome as the local one, and what a step costs beyond its own work."""
    print()
    print(f"# the same campaign as a job ({CAMPAIGN_JOB}) on Celery workers")
    print("| workers | wall time | steps | work per step (median) | overhead per step | outcome |")
    print("|---|---|---|---|---|---|")
    seconds = {}
    with tempfile.TemporaryDirectory(prefix="scengen-bench-celery-campaign-") as folder:
        for workers in (1, 2):
            with deployment(workers, Path(folder), "campaign") as (url, database):
                job = finished_job(url, {"name": "campaign", "items": [CAMPAIGN_JOB]})
                outcome = httpx.get(f"{url}/jobs/{job['id']}/campaign").json()
                with psycopg.connect(database) as connection:
                    work = [row[0] for row in connection.execute(
                        "SELECT seconds FROM job_steps WHERE state = 'done'")]  # fmt: skip
            seconds[workers] = job["seconds"]
            median = statistics.median(work)
            # one worker does one step at a time: what the wall time holds beyond the
            # steps' own work is what running them as tasks cost (dispatch, polling, claims,
            # storage, the coordinator's own work)
            overhead = (job["seconds"] - sum(work)) / len(work) if workers == 1 else None
            said = "—" if overhead is None else f"{overhead:.2f} s ({overhead / median:.1%})"
            same = "the same as local" if _without_evaluations(outcome) == local else "DIFFERS"
            print(f"| {workers} | {job['seconds']:.1f} s | {len(work)} | {median:.2f} s | "
                  f"{said} | {same} |", flush=True)  # fmt: skip
    print(f"speed-up two/one Celery workers: {seconds[1] / seconds[2]:.2f}")


def _without_evaluations(outcome: dict[str, Any]) -> dict[str, Any]:
    """The outcome less its evaluations' ids (they name the job, which each run makes)."""
    for chain in outcome["chains"]:
        for level in chain["levels"]:
            for verdict in level["verdicts"].values():
                verdict.pop("evaluation", None)
    return outcome


if __name__ == "__main__":
    if sys.argv[1:] == ["--campaign"]:
        campaigns()
    elif sys.argv[1:] == ["--celery-campaign"]:
        with tempfile.TemporaryDirectory(prefix="scengen-bench-campaign-") as folder:
            out = Path(folder) / "local"
            subprocess.run([sys.executable, "-m", "service", *CAMPAIGN, "-o", str(out)],
                           capture_output=True, check=False)  # fmt: skip
            celery_campaigns(_without_evaluations(json.loads((out / "campaign.json").read_text())))
    else:
        main()
