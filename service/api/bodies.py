"""Large JSON bodies are parsed and validated in a worker process, not on the event loop.

FastAPI parses and validates a body on the event loop. For a body of a few kilobytes that
takes microseconds; for 14 MB of unknown keys it took ten seconds (a million errors to build),
and every other request, ``/healthz`` included, waited. Threads do not help: the parser and
pydantic hold the GIL. So a JSON body over ``OFF_LOOP_BYTES`` is checked in a worker process
under the work budget, exactly as FastAPI would check it (``json.loads``, then the model),
and only a bounded list of errors comes back. A valid body comes back as the validated model
and is handed to FastAPI as the request's parsed JSON, which an instance of the model passes
at once. An inline test-case in it comes back in its stored form (``stored_inline``).
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Coroutine
from typing import Any

from fastapi import Request, Response, params
from fastapi.exceptions import RequestValidationError
from fastapi.routing import APIRoute
from pydantic import BaseModel, ValidationError

from service.core.testcase import check_samples, first_errors, parse_testcase
from service.store import Store, StoredTestCase, TestCaseRecord, stored_form

OFF_LOOP_BYTES = 256 * 1024


class BoundedValidationError(RequestValidationError):
    """The first errors of a body that has ``total`` of them."""

    def __init__(self, errors: list[dict[str, Any]], total: int) -> None:
        super().__init__(errors)
        self.total = total


def validate_body(model: type[BaseModel], raw: bytes, max_errors: int) -> tuple[str, Any]:
    """In a worker: ``("valid", model)``, ``("malformed", message)`` or
    ``("invalid", (first errors, how many there are))``."""
    try:
        parsed = json.loads(raw)
    except json.JSONDecodeError as error:
        return "malformed", error.msg
    except UnicodeDecodeError as error:
        return "malformed", f"the body is not UTF-8 ({error.reason})"
    except RecursionError:
        return "malformed", "the body is nested too deeply"
    try:
        validated = model.model_validate(parsed)
    except ValidationError as error:
        shown = [
            {"loc": ("body", *item["loc"]), "msg": item["msg"], "type": item["type"]}
            for item in first_errors(error, max_errors)
        ]
        return "invalid", (shown, error.error_count())
    inline = getattr(validated, "testcase", None)
    if isinstance(inline, dict):
        # checked here too (InvalidTestCase), and sent back in its stored form: a string
        # the server unpickles and stores as it is, not a tree it would parse again
        stored = stored_form(parse_testcase(inline))
        validated = validated.model_copy(update={"testcase": stored})
    return "valid", validated


def stored_inline(
    store: Store, inline: dict[str, Any] | StoredTestCase | None
) -> TestCaseRecord | None:
    """A body's inline test-case, checked against this server's limits and networks and
    stored (nothing submitted is lost); None when the body has none. A large body's comes
    from ``validate_body`` in its stored form, and is not parsed here (call in a thread)."""
    if inline is None:
        return None
    if isinstance(inline, StoredTestCase):
        check_samples(inline.duration, inline.timestep, store.max_samples)
        store.network_id_of(inline.network)
        return store.add_stored(inline)
    return store.keep_inline(inline)


class OffLoopValidation(APIRoute):
    """An operation whose JSON body, when large, is validated in a worker process."""

    def get_route_handler(self) -> Callable[[Request], Coroutine[Any, Any, Response]]:
        handler = super().get_route_handler()
        model = _body_model(self)
        if model is None:
            return handler

        async def validated_off_loop(request: Request) -> Response:
            raw = await request.body()
            if len(raw) > OFF_LOOP_BYTES and _is_json(request.headers.get("content-type")):
                request._json = await _validate_in_worker(request, model, raw)
            return await handler(request)

        return validated_off_loop


async def _validate_in_worker(request: Request, model: type[BaseModel], raw: bytes) -> Any:
    state = request.app.state.scengen
    settings = state.settings
    outcome, value = await state.run(
        "body validation",
        validate_body,
        (model, raw, settings.max_reported_errors),
        settings.work_budget,
        time.monotonic(),
    )
    if outcome == "malformed":
        raise RequestValidationError(
            [
                {
                    "type": "json_invalid",
                    "loc": ("body", 0),
                    "msg": "JSON decode error",
                    "ctx": {"error": value},
                }
            ]
        )
    if outcome == "invalid":
        shown, total = value
        raise BoundedValidationError(shown, total)
    return value


def _body_model(route: APIRoute) -> type[BaseModel] | None:
    field = route.body_field
    if field is None or isinstance(field.field_info, params.Form):
        return None
    annotation = getattr(field.field_info, "annotation", None)
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    return None


def _is_json(content_type: str | None) -> bool:
    """Whether FastAPI would parse the body as JSON (not without a type: strict by default)."""
    if not content_type:
        return False
    main, _, subtype = content_type.partition(";")[0].strip().lower().partition("/")
    return main == "application" and (subtype == "json" or subtype.endswith("+json"))
