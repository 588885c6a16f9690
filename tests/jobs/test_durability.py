"""kill -9 in the middle of a job loses nothing: the server (embedded executor) and a
Celery worker are killed for real, restarted, and the job completes with every result once.
Redis restarted empty loses the queued messages: they are sent again within the lease. A
killed worker leaves no process behind. Then the same batch on Celery with two workers
(PostgreSQL, Redis) gives the same results as on the embedded executor."""

from __future__ import annotations

import contextlib
import os
import signal
import time
from pathlib import Path
from typing import Any

import pytest
import redis

from tests.jobs.batches import regression_batch, results
from tests.jobs.conftest import LEASE, PrivateRedis
from tests.servers import Server, Worker

pytestmark = pytest.mark.slow


def wait_until(condition: Any, timeout: float = 120) -> Any:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        found = condition()
        if found:
            return found
        time.sleep(0.2)
    raise TimeoutError("the condition never held")


def chain_halfway(server: Server, job: str) -> dict[str, Any] | None:
    """The job once its chain has made its first level and works on the second."""
    found: dict[str, Any] = server.client.get(f"/jobs/{job}").json()
    chain = found["items"][1]
    return found if chain["state"] == "running" and len(chain["testcases"]) == 1 else None


def assert_complete_once(server: Server, job: dict[str, Any], before: dict[str, Any]) -> None:
    assert job["state"] == "succeeded", [i["error"] for i in job["items"]]
    chain = job["items"][1]
    assert chain["testcases"][0] == before["items"][1]["testcases"][0]  # kept, not remade
    assert chain["attempts"] >= 2  # it was interrupted and resumed
    evaluations = server.client.get("/evaluations", params={"limit": 200}).json()
    assert evaluations["total"] == 6 == len(job["items"][2]["evaluations"])
    made = [t for item in job["items"] for t in item["testcases"]]
    assert len(made) == 3 == len(set(made))


def test_the_embedded_executor_survives_a_killed_server(tmp_path: Path) -> None:
    server = Server(tmp_path, workers="2", lease_seconds=LEASE)
    try:
        job = server.client.post("/jobs", json=regression_batch()).json()["id"]
        before = wait_until(lambda: chain_halfway(server, job))
        server.kill()
        server.start()  # the same data directory: the same SQLite file
        after = server.wait_for_job(job)
        assert_complete_once(server, after, before)
        assert "item 1: resuming after 1 test-case(s)" in server.log.read_text()
    finally:
        server.stop()


def test_celery_survives_a_killed_worker(tmp_path: Path, celery_settings: dict[str, str]) -> None:
    server = Server(tmp_path / "server", **celery_settings)
    workers = [Worker(tmp_path / f"w{n}", f"w{n}", **celery_settings) for n in (1, 2)]
    try:
        job = server.client.post("/jobs", json=regression_batch()).json()["id"]
        before = wait_until(lambda: chain_halfway(server, job))
        for worker in workers:  # whichever runs the chain: kill -9 both, mid-item
            worker.kill()
        workers = [Worker(tmp_path / f"w{n}", f"w{n}b", **celery_settings) for n in (1, 2)]
        after = server.wait_for_job(job)
        assert_complete_once(server, after, before)
        logs = " ".join(w.log.read_text() for w in workers)
        assert "item 1: resuming after 1 test-case(s)" in logs
    finally:
        for worker in workers:
            worker.stop()
        server.stop()


def test_messages_lost_with_redis_are_sent_again_within_the_lease(
    tmp_path: Path, celery_settings: dict[str, str], private_redis: PrivateRedis
) -> None:
    """Redis restarted empty while one item runs and three wait in its queue: the waiting
    items' messages are gone; the dispatcher finds them missing a lease (5 s) after they
    were last seen there and sends them again; every item runs once. (Before: 600 s.)"""
    settings = {**celery_settings, "broker_url": private_redis.url, "lease_seconds": "5"}
    root = regression_batch()["items"][0]["testcase"]
    batch = {"items": [
        {"kind": "chain", "testcase": root, "levels": 2, "seed": 3},
        *({"kind": "evaluate", "testcase": root, "controllers": [controller]}
          for controller in ("sumo", "sumo-cautious", "sumo-aggressive")),
    ]}  # fmt: skip
    server = Server(tmp_path / "server", **settings)
    worker = Worker(tmp_path / "w1", "w1", **settings)  # one task at a time: three wait
    try:
        job = server.client.post("/jobs", json=batch).json()["id"]
        wait_until(lambda: item_states(server, job)[0] == "running")
        assert item_states(server, job)[1:] == ["queued"] * 3
        private_redis.kill()
        private_redis.start()  # empty
        restarted = time.time()
        broker = redis.Redis.from_url(private_redis.url)
        # back in the queue, or already taken from it by the worker (the chain may be done
        # by then: the worker takes a message the moment it is back, between two looks)
        back = wait_until(
            lambda: (
                (broker.llen("celery") > 0 or item_states(server, job)[1:] != ["queued"] * 3)
                and time.time()
            ),
            timeout=300,
        )
        after = server.wait_for_job(job, timeout=300)  # before: 600 s and more
        assert after["state"] == "succeeded", [i["error"] for i in after["items"]]
        assert [item["attempts"] for item in after["items"]] == [1, 1, 1, 1]  # each ran once
        assert [len(item["evaluations"]) for item in after["items"][1:]] == [1, 1, 1]
        resent = server.log.read_text().count("(lost?): sent again")
        assert resent >= 1
        waited = min(started(item) for item in after["items"][1:]) - restarted
        print(f"lease 5 s: {resent} message(s) sent again, back in the queue {back - restarted:.1f}"
              f" s after Redis restarted empty; the first waiting item started {waited:.1f} s "
              f"after it; the job took {finished(after) - started(after):.1f} s")  # fmt: skip
    finally:
        worker.stop()
        server.stop()


def item_states(server: Server, job: str) -> list[str]:
    return [item["state"] for item in server.client.get(f"/jobs/{job}").json()["items"]]


def started(record: dict[str, Any]) -> float:
    from datetime import datetime

    return datetime.fromisoformat(record["started_at"]).timestamp()


def finished(record: dict[str, Any]) -> float:
    from datetime import datetime

    return datetime.fromisoformat(record["finished_at"]).timestamp()


def descendants(pid: int) -> dict[int, int]:
    """Every living process under ``pid``, with its parent (zombies are dead)."""
    parents: dict[int, int] = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text()
            except OSError:
                continue
            state, parent = stat.rsplit(")", 1)[1].split()[:2]
            if state != "Z":
                parents[int(entry.name)] = int(parent)
    found: dict[int, int] = {}
    frontier = [pid]
    while frontier:
        current = frontier.pop()
        for child, parent in parents.items():
            if parent == current and child not in found:
                found[child] = parent
                frontier.append(child)
    return found


def solver_running(worker: int) -> dict[int, int] | None:
    """The worker's processes once a solver child runs (a grandchild of the worker: the
    pool process is its parent)."""
    found = descendants(worker)
    return found if any(parent != worker for parent in found.values()) else None


def alive(pid: int) -> bool:
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


def test_a_worker_killed_with_9_leaves_no_process_behind(
    tmp_path: Path, celery_settings: dict[str, str]
) -> None:
    """kill -9 of ``scengen worker``'s main process only: its pool process, which was
    running an item, and that item's solver child end too (they ran on for minutes)."""
    server = Server(tmp_path / "server", **celery_settings)
    worker = Worker(tmp_path / "w1", "w1", **celery_settings)
    try:
        root = regression_batch()["items"][0]["testcase"]
        batch = {"items": [{"kind": "chain", "testcase": root, "levels": 4, "seed": 5}]}
        server.client.post("/jobs", json=batch)
        main = worker.process.pid
        tree = wait_until(lambda: solver_running(main))
        os.kill(main, signal.SIGKILL)
        worker.process.wait()
        wait_until(lambda: not any(alive(pid) for pid in tree), timeout=60)
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(worker.process.pid, signal.SIGKILL)  # whatever was left, if it failed
        worker.stop()
        server.stop()


def test_local_and_celery_give_the_same_results(
    tmp_path: Path, celery_settings: dict[str, str]
) -> None:
    local = Server(tmp_path / "local", workers="2")
    try:
        on_local = results(local.wait_for_job(local.client.post("/jobs", json=regression_batch())
                                              .json()["id"]), local.client)  # fmt: skip
    finally:
        local.stop()
    server = Server(tmp_path / "celery", **celery_settings)
    workers = [Worker(tmp_path / f"w{n}", f"w{n}", **celery_settings) for n in (1, 2)]
    try:
        job = server.wait_for_job(server.client.post("/jobs", json=regression_batch()).json()["id"])
        assert job["state"] == "succeeded", [i["error"] for i in job["items"]]
        on_celery = results(job, server.client)
        ran = [w.log.read_text().count("Task scengen.run_item[") for w in workers]
        assert all(count >= 1 for count in ran), ran  # both workers ran items
    finally:
        for worker in workers:
            worker.stop()
        server.stop()
    assert on_celery == on_local
    assert len(on_local["verdicts"]) == 6
