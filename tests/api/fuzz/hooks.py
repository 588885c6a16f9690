"""Schemathesis hooks of the fuzz test: after every request the server must still answer
``/healthz`` (a request that wedges the event loop, kills the database or the worker pool
fails here, not only its own check)."""

from __future__ import annotations

import os
from typing import Any

import httpx2 as httpx
import schemathesis

HEALTH_TIMEOUT = 30.0  # seconds: generous on a loaded machine; a wedged loop takes longer


@schemathesis.check
def server_stays_healthy(ctx: Any, response: Any, case: Any) -> bool:
    url = os.environ["SCENGEN_FUZZ_URL"]
    try:
        answer = httpx.get(f"{url}/healthz", timeout=HEALTH_TIMEOUT)
    except httpx.TransportError as error:
        raise AssertionError(f"/healthz did not answer after this request: {error}") from None
    if answer.status_code != 200:
        raise AssertionError(f"/healthz answered {answer.status_code} after this request")
    return True
