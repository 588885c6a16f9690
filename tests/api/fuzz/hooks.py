"""Schemathesis hooks of the fuzz test: after every request the server must still answer
``/healthz`` (a request that wedges the event loop, kills the database or the worker pool
fails here, not only its own check); and no schema-valid request is refused by the server's
own request validation (``invalid-request``): where schemathesis.toml lets an operation
answer a schema-valid request with 422 (it names something this server does not have),
the 422 must say so, not that the request is malformed.

Also a mend of the fuzzer's own process: on CPython 3.11, two threads in ``ast.parse`` at
once can corrupt the interpreter's AST recursion counter (a garbage collection inside one
parse runs Python code, the other thread parses meanwhile) and raise ``SystemError: AST
constructor recursion depth mismatch`` (python/cpython#106905). Hypothesis parses lambdas'
sources to describe filtered strategies, and schemathesis runs two workers, so the
fuzzer's coverage phase failed now and then on a loaded machine, before any request was
judged. Parsing one at a time removes the race; the server is not touched.
"""

from __future__ import annotations

import ast
import json
import os
import threading
from typing import Any

import httpx2 as httpx
import schemathesis

HEALTH_TIMEOUT = 30.0  # seconds: generous on a loaded machine; a wedged loop takes longer
# One client for every check: a new one per request builds an SSL context each time (two
# thirds of the fuzzer's own CPU). httpx's clients are safe to share between threads.
_HEALTH = httpx.Client(timeout=HEALTH_TIMEOUT)

_PARSING = threading.RLock()
_parse = ast.parse


def _parse_alone(*args: Any, **options: Any) -> Any:
    with _PARSING:
        return _parse(*args, **options)


ast.parse = _parse_alone


@schemathesis.check
def server_stays_healthy(ctx: Any, response: Any, case: Any) -> bool:
    url = os.environ["SCENGEN_FUZZ_URL"]
    try:
        answer = _HEALTH.get(f"{url}/healthz")
    except httpx.TransportError as error:
        raise AssertionError(f"/healthz did not answer after this request: {error}") from None
    if answer.status_code != 200:
        raise AssertionError(f"/healthz answered {answer.status_code} after this request")
    return True


@schemathesis.check
def schema_as_strict_as_the_server(ctx: Any, response: Any, case: Any) -> bool | None:
    meta = case.meta
    if meta is None or not meta.generation.mode.is_positive:
        return None
    if response.status_code not in (400, 422):
        return None
    try:
        kind = json.loads(response.text).get("type")
    except ValueError:
        kind = None
    if kind not in ("/problems/invalid-request", "/problems/malformed-request"):
        return None
    if _is_upload(case) or _beyond_json_schema(case, response):
        return None
    raise AssertionError(
        f"a schema-valid request was refused as {kind}: the schema is looser than the "
        f"server ({response.text[:500]})"
    )


def _is_upload(case: Any) -> bool:
    """An upload's file is XML that no schema describes: not well-formed is a 400 there."""
    return bool(case.operation.method.upper() == "POST" and case.operation.path == "/networks")


# Rules that relate one field to another, which JSON Schema cannot state (each is in the
# field's description instead): (operation, what the refusal says, the rule).
BEYOND_JSON_SCHEMA = [
    ("*", "speeds must satisfy v_stop < v_run < v_max", "an order of three params"),
    ("*", "one entry per route", "start_distance as a list is as long as routes"),
    ("*", "new road users in one extension", "routes and pedestrians together at most 6"),
    ("*", "name at least one new car (routes) or pedestrian", "routes or pedestrians not empty"),
    ("POST /jobs", "give exactly one of", "an item's base: an id, a document or an item"),
    ("*", "every state has one colour per link", "a signal program's states are equally long"),
    ("*", "a cycle lasts at least", "a signal program's phases add up to a cycle of 1 s or more"),
    ("POST /jobs", "refers to item", "an item refers to an earlier item that makes test-cases"),
    # JSON Schema's integer is any number without a fraction, 8.0 too; the server's
    # numbers are strict (docs/http-api.md), so 8.0 for a count or a seed is refused: a
    # difference in how the number is written, which no schema can state.
    ("*", "Input should be a valid integer", "an integer written as 8.0"),
]


def _beyond_json_schema(case: Any, response: Any) -> bool:
    """Whether every error of the refusal is a rule of BEYOND_JSON_SCHEMA."""
    label = f"{case.operation.method.upper()} {case.operation.path}"
    rules = [text for where, text, _ in BEYOND_JSON_SCHEMA if where in ("*", label)]
    try:
        errors = json.loads(response.text).get("errors") or []
    except ValueError:
        return False
    listed = [e for e in errors if not e.startswith("... and ")]  # "... and 80 more errors"
    return bool(listed) and all(any(rule in error for rule in rules) for error in listed)
