"""Settings of the server and the workers, from ``SCENGEN_*`` environment variables
(documented in the README); the core never reads them."""

from __future__ import annotations

import os
from functools import lru_cache
from pathlib import Path
from typing import Literal

from pydantic import Field, field_validator, model_validator
from pydantic_settings import BaseSettings, SettingsConfigDict

from service.core.budget import DEFAULT_MEMORY_MB
from service.core.testcase import MAX_SAMPLES

MIN_WORKER_MEMORY_MB = 512
MAX_JOB_STEPS = 2000  # at 2 to 5 s a step on two workers: one to three hours


class Settings(BaseSettings):
    """Every setting has an embedded default: ``scengen serve`` needs no other service."""

    model_config = SettingsConfigDict(env_prefix="SCENGEN_", extra="ignore")

    data_dir: Path = Field(
        Path("scengen-data"), description="SQLite file, network cache, rebuilt networks"
    )
    database_url: str = Field(
        "", description="SQLAlchemy URL; empty: sqlite:///<data_dir>/scengen.sqlite3"
    )
    workers: int = Field(
        default_factory=lambda: os.cpu_count() or 2,
        ge=1,
        le=64,
        description="worker processes of interactive calls (/extend, evaluations, pictures) "
        "running at once, and the steps of a campaign at once (default: one per core)",
    )
    job_workers: int = Field(
        0,
        ge=0,
        le=64,
        description="job items the local executor runs at once, each with its own worker "
        "process (0, the default: as many as workers); on top of the interactive ones",
    )
    extend_budget: float = Field(60.0, gt=0, description="default budget of POST /extend (s)")
    evaluate_budget: float = Field(60.0, gt=0, description="default budget of an evaluation (s)")
    max_budget: float = Field(600.0, gt=0, description="largest budget a request may ask for (s)")
    work_budget: float = Field(120.0, gt=0, description="budget of uploads, pictures, bundles (s)")
    api_token: str = Field("", description="when set, creating or deleting needs this bearer token")
    protect_reads: bool = Field(
        False,
        description="with api_token: reads and the results browser need the token too "
        "(all but /healthz and the API's docs)",
    )
    max_upload_mb: float = Field(20.0, gt=0, description="largest request body (MB)")
    max_samples: int = Field(
        MAX_SAMPLES,
        ge=1,
        le=MAX_SAMPLES,
        description="samples per car a test-case may have (duration / time step), at most "
        f"{MAX_SAMPLES}",
    )
    max_reported_errors: int = Field(
        20, ge=1, le=1000, description="validation errors listed in one problem answer"
    )
    worker_memory_mb: int = Field(
        DEFAULT_MEMORY_MB,
        ge=0,
        description=f"data segment each worker process may use (MB): 0 (no cap) or at least "
        f"{MIN_WORKER_MEMORY_MB}",
    )
    max_job_steps: int = Field(
        MAX_JOB_STEPS,
        ge=1,
        description="steps (extensions, levels, evaluations) one job may run at most, "
        "counted when it is submitted: a bigger one is refused (422)",
    )
    executor: Literal["local", "celery"] = Field(
        "local", description="where batch jobs run: local worker processes, or Celery workers"
    )
    broker_url: str = Field(
        "redis://127.0.0.1:6379/0", description="Celery's broker (executor=celery)"
    )
    item_attempts: int = Field(
        3, ge=1, le=10, description="times a job item is started before it is marked failed"
    )
    lease_seconds: float = Field(
        30.0,
        gt=1,
        description="a running item whose worker is silent this long is retried; a queued "
        "item whose message the broker lost is sent again this long after it was last seen",
    )

    @field_validator("worker_memory_mb")
    @classmethod
    def _enough_to_start(cls, value: int) -> int:
        if 0 < value < MIN_WORKER_MEMORY_MB:
            raise ValueError(
                f"a worker needs at least {MIN_WORKER_MEMORY_MB} MB to load its libraries "
                "(SUMO, clingo, z3, numpy); 0 turns the cap off"
            )
        return value

    @model_validator(mode="after")
    def _reads_need_a_token(self) -> Settings:
        if self.protect_reads and not self.api_token:
            raise ValueError(
                "SCENGEN_PROTECT_READS needs SCENGEN_API_TOKEN: there is no token to ask for"
            )
        return self

    @property
    def database(self) -> str:
        return self.database_url or f"sqlite:///{self.data_dir.resolve()}/scengen.sqlite3"

    @property
    def job_slots(self) -> int:
        """How many job items run at once on the local executor."""
        return self.job_workers or self.workers

    @property
    def cache_dir(self) -> Path:
        return self.data_dir.resolve() / "cache"

    @property
    def max_upload_bytes(self) -> int:
        return int(self.max_upload_mb * 1024 * 1024)


@lru_cache
def get_settings() -> Settings:
    return Settings()
