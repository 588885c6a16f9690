"""The HTTP API: FastAPI routes over ``service.core``, errors as problem+json.

``create_app`` is imported on first use: a worker process that runs one of the routes'
calls (``service.api.worker``, ``service.api.bodies``) imports this package without the
web framework's start-up cost.
"""

from __future__ import annotations

from typing import Any

__all__ = ["create_app"]


def __getattr__(name: str) -> Any:
    if name == "create_app":
        from service.api.app import create_app

        return create_app
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
