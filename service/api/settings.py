"""The server's settings, from ``SCENGEN_*`` environment variables (documented in README)."""

from __future__ import annotations

import os
from functools import lru_cache
from pathlib import Path

from pydantic import Field
from pydantic_settings import BaseSettings, SettingsConfigDict


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
        description="worker processes running at once (default: one per core)",
    )
    extend_budget: float = Field(60.0, gt=0, description="default budget of POST /extend (s)")
    evaluate_budget: float = Field(60.0, gt=0, description="default budget of an evaluation (s)")
    max_budget: float = Field(600.0, gt=0, description="largest budget a request may ask for (s)")
    work_budget: float = Field(120.0, gt=0, description="budget of uploads, pictures, bundles (s)")
    api_token: str = Field("", description="when set, creating or deleting needs this bearer token")
    max_upload_mb: float = Field(20.0, gt=0, description="largest request body (MB)")

    @property
    def database(self) -> str:
        return self.database_url or f"sqlite:///{self.data_dir.resolve()}/scengen.sqlite3"

    @property
    def cache_dir(self) -> Path:
        return self.data_dir.resolve() / "cache"

    @property
    def max_upload_bytes(self) -> int:
        return int(self.max_upload_mb * 1024 * 1024)


@lru_cache
def get_settings() -> Settings:
    return Settings()
