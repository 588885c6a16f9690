"""kill -9 in the middle of a job loses nothing: the server (embedded executor) and a
Celery worker are killed for real, restarted, and the job completes with every result once.
Then the same batch on Celery with two workers (PostgreSQL, Redis) gives the same results
as on the embedded executor."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import pytest

from tests.jobs.batches import regression_batch, results
from tests.jobs.conftest import LEASE
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
