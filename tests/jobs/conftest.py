"""A throwaway PostgreSQL database per test session (the machine's server, trust auth);
a private Redis server that a test may restart empty."""

from __future__ import annotations

import contextlib
import os
import secrets
import shutil
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path

import psycopg
import pytest
import redis

from tests.servers import free_port

LEASE = "3"  # seconds: a killed worker's items come back quickly
POSTGRES = os.environ.get("SCENGEN_TEST_POSTGRES", "postgresql://postgres@127.0.0.1:5432/test")


@contextlib.contextmanager
def throwaway_postgres(prefix: str) -> Iterator[str]:
    """``postgresql+psycopg://.../PREFIX_<random>``: a new empty database, dropped after."""
    name = f"{prefix}_{secrets.token_hex(4)}"
    with psycopg.connect(POSTGRES, autocommit=True) as admin:
        admin.execute(f"CREATE DATABASE {name}")
    base = POSTGRES.rsplit("/", 1)[0].replace("postgresql://", "postgresql+psycopg://")
    try:
        yield f"{base}/{name}"
    finally:
        with psycopg.connect(POSTGRES, autocommit=True) as admin:
            admin.execute(f"DROP DATABASE IF EXISTS {name} WITH (FORCE)")


@pytest.fixture(scope="session")
def postgres_url() -> Iterator[str]:
    """A throwaway database for the session's PostgreSQL tests."""
    with throwaway_postgres("scengen_test") as url:
        yield url


def redis_database(worker_id: str) -> int:
    """Redis database 7 for a serial run, 7 + n for pytest-xdist's worker gw<n>: two workers
    never share (or flush) each other's Celery queue."""
    return 7 if worker_id == "master" else 7 + int(worker_id.removeprefix("gw"))


@pytest.fixture
def celery_settings(postgres_url: str, tmp_path: Path, worker_id: str) -> Iterator[dict[str, str]]:
    broker = f"redis://127.0.0.1:6379/{redis_database(worker_id)}"
    redis.Redis.from_url(broker).flushdb()
    yield {
        "executor": "celery",
        "broker_url": broker,
        "database_url": postgres_url,
        "lease_seconds": LEASE,
    }
    redis.Redis.from_url(broker).flushdb()
    from sqlalchemy import create_engine

    engine = create_engine(postgres_url)
    with engine.begin() as connection:
        for table in (
            "job_items",
            "job_item_memos",
            "job_steps",
            "jobs",
            "evaluation_drives",
            "evaluations",
            "testcases",
            "networks",
        ):
            connection.exec_driver_sql(f"DELETE FROM {table}")
    engine.dispose()


class PrivateRedis:
    """``redis-server`` on a free port, keeping nothing on disk: a restart starts empty."""

    def __init__(self, folder: Path) -> None:
        self.folder, self.port = folder, free_port()
        self.url = f"redis://127.0.0.1:{self.port}/0"
        self.process: subprocess.Popen[bytes] | None = None
        self.start()

    def start(self) -> None:
        self.process = subprocess.Popen(
            ["redis-server", "--port", str(self.port), "--bind", "127.0.0.1", "--save", "",
             "--appendonly", "no", "--dir", str(self.folder)],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
        )  # fmt: skip
        client = redis.Redis.from_url(self.url)
        deadline = time.monotonic() + 30
        while True:
            with contextlib.suppress(redis.ConnectionError):
                if client.ping():
                    break
            if time.monotonic() > deadline:
                raise RuntimeError("redis-server did not come up")
            time.sleep(0.1)
        client.close()

    def kill(self) -> None:
        """kill -9: everything it held is gone."""
        if self.process is not None:
            self.process.kill()
            self.process.wait()
            self.process = None


@pytest.fixture
def private_redis(tmp_path: Path) -> Iterator[PrivateRedis]:
    if shutil.which("redis-server") is None:
        pytest.skip("redis-server is not installed")
    server = PrivateRedis(tmp_path)
    yield server
    server.kill()
