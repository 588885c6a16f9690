"""docker/ cannot be built here (no Docker engine): check that its files agree with the
code, the settings and the Makefile instead."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
import yaml

from service.cli.commands import parser
from service.settings import Settings

ROOT = Path(__file__).parents[1]
COMPOSE = yaml.safe_load((ROOT / "docker" / "compose.yaml").read_text())
DOCKERFILE = (ROOT / "docker" / "Dockerfile").read_text()


def subcommands() -> set[str]:
    actions = [a for a in parser()._actions if a.dest == "command"]
    return set(actions[0].choices)  # type: ignore[arg-type]


def test_compose_has_api_worker_redis_and_postgres() -> None:
    assert set(COMPOSE["services"]) == {"api", "worker", "redis", "postgres"}


def test_compose_commands_are_scengen_commands() -> None:
    for name in ("api", "worker"):
        command = COMPOSE["services"][name]["command"]
        assert command[0] == "scengen" and command[1] in subcommands()
        options = [word.split("=")[0] for word in command[2:] if word.startswith("--")]
        command_parser = parser()._subparsers._group_actions[0].choices[command[1]]  # type: ignore[union-attr]
        known = {s for action in command_parser._actions for s in action.option_strings}
        assert set(options) <= known, command


def test_compose_variables_are_settings() -> None:
    fields = {f"SCENGEN_{name.upper()}" for name in Settings.model_fields}
    for name in ("api", "worker"):
        variables = set(COMPOSE["services"][name]["environment"])
        assert variables <= fields, variables - fields
    assert "SCENGEN_DATABASE_URL" in variables and "SCENGEN_BROKER_URL" in variables
    broker = COMPOSE["services"]["api"]["environment"]["SCENGEN_BROKER_URL"]
    assert broker.startswith("redis://redis:")
    database = COMPOSE["services"]["api"]["environment"]["SCENGEN_DATABASE_URL"]
    assert database.startswith("postgresql+psycopg://")


def test_the_image_installs_what_the_package_needs() -> None:
    for folder in ("service", "asp", "sumo_nets"):
        assert re.search(rf"^COPY {folder} ", DOCKERFILE, flags=re.M), folder
    assert '"scengen", "serve"' in DOCKERFILE and "SCENGEN_DATA_DIR" in DOCKERFILE
    assert "python:3.11" in DOCKERFILE


def test_job_items_and_interactive_calls_have_their_own_worker_counts(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    from service.jobs.dispatch import LocalDispatcher
    from service.store import Store

    monkeypatch.setenv("SCENGEN_WORKERS", "3")
    assert Settings().job_slots == 3  # by default as many as the interactive ones
    monkeypatch.setenv("SCENGEN_JOB_WORKERS", "1")
    settings = Settings()
    assert (settings.workers, settings.job_slots) == (3, 1)

    store = Store(f"sqlite:///{tmp_path}/scengen.sqlite3", tmp_path / "cache")
    try:
        assert LocalDispatcher(store, settings).threads.pool._max_workers == 1
    finally:
        store.close()
