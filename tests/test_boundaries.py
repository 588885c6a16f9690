"""Architecture rules: the core imports no web, queue or settings code; public surfaces."""

from __future__ import annotations

import subprocess
import sys

import service.core.network as network

FORBIDDEN = (
    "fastapi", "uvicorn", "starlette", "celery", "redis", "pydantic_settings", "sqlalchemy",
)  # fmt: skip


def test_core_imports_no_adapter_libraries() -> None:
    code = (
        "import sys, service.core.network, service.core.motion.poses, service.core.motion.events, "
        "service.core.testcase, service.core.budget, service.core.generator.extension, "
        "service.core.sim.replay, service.core.export.bundle, service.core.checker.check; "
        f"print([m for m in {FORBIDDEN!r} if m in sys.modules])"
    )
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    )
    assert result.stdout.strip() == "[]"


def test_worker_tasks_import_no_web_code() -> None:
    """A worker process (local pool or remote) loads the core, not the web stack."""
    code = (
        "import sys, service.jobs.tasks, service.jobs.executor; "
        "print([m for m in ('fastapi', 'uvicorn', 'starlette') if m in sys.modules])"
    )
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    )
    assert result.stdout.strip() == "[]"


def test_core_does_not_import_libsumo_outside_a_drive() -> None:
    code = (
        "import sys, service.core.motion.poses, service.core.motion.events; "
        "print('libsumo' in sys.modules)"
    )
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    )
    assert result.stdout.strip() == "False"


def test_network_public_surface_is_complete() -> None:
    public = {name for name in vars(network) if not name.startswith("_")}
    submodules = {"load", "model", "lanes", "relations", "override", "describe", "convert"}
    assert set(network.__all__) == public - submodules
