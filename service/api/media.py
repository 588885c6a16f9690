"""Content negotiation and the artifact cache (pictures, bundles, descriptions).

Artifacts derive from immutable things (a content-addressed test-case, an uploaded network),
so a file cached under the data directory never goes stale; it is written atomically. An
artifact is produced once however many ask for it at the same time (a page reloaded while
its first load waits for the workers, two tabs): the later requests wait for the first's.

A failure is remembered too, beside where the artifact would be (``NAME.failed.json``: its
error class and message): the same request within ``FAILURE_SECONDS`` answers the same
problem at once instead of holding a worker for the whole budget again (issue 50: a
picture of a test-case whose signal program cannot be drawn was 504 after 88 s on every
read). Only failures of the work itself are remembered: the input refused, SUMO or
netconvert refusing it, the time or memory budget run out; a worker that crashed or died is
the server's fault, and the next request tries again. A budget that ran out is remembered
for a while only (``FAILURE_SECONDS``), not for good: the wait for a free worker counts
against it, so on a busy server it may be bad luck.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import secrets
import time
from collections.abc import Awaitable, Callable
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

from fastapi import Query
from pydantic import WithJsonSchema

from service.api.problems import Problem
from service.core import errors

if TYPE_CHECKING:
    from service.api.state import AppState

PICTURES = {"png": "image/png", "svg": "image/svg+xml"}
BINARY = {"type": "string", "format": "binary"}  # a file: generated clients keep its bytes
IMAGE_RESPONSES: dict[int | str, dict[str, Any]] = {
    200: {
        "content": {"image/png": {"schema": BINARY}, "image/svg+xml": {"schema": BINARY}},
        "description": "the picture",
    }
}
# The schema names the values the server takes; any other is 406 naming them (a format
# is a representation asked for, like Accept), not a validation error.
PictureFormat = Annotated[
    str | None,
    WithJsonSchema({"type": "string", "enum": list(PICTURES)}),
    Query(description="png or svg (default: by Accept)"),
]
VerdictFormat = Annotated[
    str | None,
    WithJsonSchema({"type": "string", "enum": ["json", "junit"]}),
    Query(description="json or junit (default: by Accept)"),
]


def picture_format(requested: str | None, accept: str | None) -> tuple[str, str]:
    """(suffix, media type): the query parameter wins, then Accept, then PNG."""
    if requested is not None:
        if requested not in PICTURES:
            raise Problem(406, f"format {requested!r} is not offered; valid choices: png, svg")
        return requested, PICTURES[requested]
    wanted = (accept or "").lower()
    if "image/svg+xml" in wanted and "image/png" not in wanted:
        return "svg", PICTURES["svg"]
    if not wanted or any(m in wanted for m in ("image/png", "image/*", "*/*")):
        return "png", PICTURES["png"]
    raise Problem(
        406, f"Accept {accept!r} matches no picture type; offered: image/png, image/svg+xml"
    )


def wants_junit(requested: str | None, accept: str | None) -> bool:
    """Whether an evaluation should be answered as JUnit XML rather than JSON."""
    if requested is not None:
        if requested not in ("json", "junit"):
            raise Problem(406, f"format {requested!r} is not offered; valid choices: json, junit")
        return requested == "junit"
    wanted = (accept or "").lower()
    # A browser asks for text/html first and XML only as a fallback: it gets JSON.
    xml = "application/xml" in wanted or "application/junit+xml" in wanted
    return xml and "application/json" not in wanted and "text/html" not in wanted


async def cached(
    state: AppState,
    name: str,
    produce: Callable[[], Awaitable[Any]],
    json_cache: bool = False,
) -> Any:
    """The artifact ``name`` from the cache, or produced (in a worker) and cached; while it
    is being produced, a second request for it waits for that work rather than repeating it.
    With ``json_cache``, the value as JSON; else the bytes (``cached_file`` for large ones)."""
    path = await cached_file(state, name, produce, json_cache)
    content = await asyncio.to_thread(path.read_bytes)
    return await asyncio.to_thread(json.loads, content) if json_cache else content


async def cached_file(
    state: AppState,
    name: str,
    produce: Callable[[], Awaitable[Any]],
    json_cache: bool = False,
) -> Path:
    """The file of the artifact ``name`` in the cache, produced first if it is not there
    (``cached``): a route answers it with a ``FileResponse``, which streams it, rather than
    holding it in memory."""
    root = (state.cache_dir / "artifacts").resolve()
    path = (root / name).resolve()
    if not path.is_relative_to(root) or len(path.name) > 200:
        raise Problem(404, "no such artifact")  # never a path outside the cache
    if await asyncio.to_thread(path.is_file):
        return path
    remembered = await asyncio.to_thread(_remembered_failure, path)
    if remembered is not None:
        raise remembered
    making = _MAKING.get(path)
    if making is None or making.get_loop() is not asyncio.get_running_loop():
        making = asyncio.ensure_future(_produce(path, produce, json_cache))
        _MAKING[path] = making
        making.add_done_callback(lambda done: _made(path, done))
    # shielded: a request that goes away leaves the work to those that still wait (and the
    # cache), rather than cancelling it for them
    return await asyncio.shield(making)


_MAKING: dict[Path, asyncio.Future[Path]] = {}  # artifacts being produced, by their file


FAILURE_SECONDS = 600.0  # how long a failed artifact's problem is answered without new work
REMEMBERED = (  # failures of the work itself (MemoryExceeded is a BudgetExceeded)
    errors.InvalidInput, errors.UnsupportedIntersection, errors.NetworkBuildFailed,
    errors.SimulationFailed, errors.BudgetExceeded,
)  # fmt: skip


def failure_file(path: Path) -> Path:
    """Where the failure of the artifact at ``path`` is remembered."""
    return path.with_name(f"{path.name}.failed.json")


def _remembered_failure(path: Path) -> errors.ScengenError | None:
    """The error the artifact at ``path`` failed with less than ``FAILURE_SECONDS`` ago,
    raised again with what it was (None: not remembered, or forgotten)."""
    try:
        failure = json.loads(failure_file(path).read_bytes())
        kind = getattr(errors, failure["error"])
        ago = time.time() - float(failure["at"])
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return None
    if not (isinstance(kind, type) and issubclass(kind, REMEMBERED)) or ago >= FAILURE_SECONDS:
        return None
    return kind(
        f"{failure['message']} (remembered: this request failed {ago:.0f} s ago, and is "
        f"answered so without new work until {FAILURE_SECONDS:g} s have passed)"
    )


def _remember_failure(path: Path, error: errors.ScengenError) -> None:
    with contextlib.suppress(OSError):  # a cache that cannot be written is no cache
        write_atomically(
            failure_file(path),
            json.dumps(
                {"error": type(error).__name__, "message": str(error), "at": time.time()}
            ).encode(),
        )


async def _produce(path: Path, produce: Callable[[], Awaitable[Any]], json_cache: bool) -> Path:
    try:
        value = await produce()
    except REMEMBERED as error:
        await asyncio.to_thread(_remember_failure, path, error)
        raise
    content = json.dumps(value).encode() if json_cache else value
    await asyncio.to_thread(write_atomically, path, content)
    await asyncio.to_thread(failure_file(path).unlink, missing_ok=True)  # forgotten, now made
    return path


def write_atomically(path: Path, content: bytes) -> None:
    """``content`` at ``path``, whole or not at all (a reader never sees half a file)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    partial = path.with_name(f".{path.name}.{secrets.token_hex(4)}")
    partial.write_bytes(content)
    partial.replace(path)


def _made(path: Path, done: asyncio.Future[Path]) -> None:
    if _MAKING.get(path) is done:
        del _MAKING[path]
    if not done.cancelled():
        done.exception()  # retrieved: every waiter may have gone, the error is theirs to see
