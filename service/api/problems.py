"""Errors as ``application/problem+json`` (RFC 9457), mapped once for the whole API.

Every problem has a stable ``type``, a relative URI ``/problems/<slug>`` that the server
also answers with the problem's description. Domain errors (``service.core.errors``) keep
their message as ``detail`` and their context (step, routes, seed, ...) as extra members.
"""

from __future__ import annotations

import functools
import logging
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import sqlalchemy as sa
from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from starlette.exceptions import HTTPException as StarletteHTTPException

from service.core import errors

MEDIA_TYPE = "application/problem+json"
LOG = logging.getLogger("scengen.api")


@dataclass(frozen=True)
class ProblemType:
    slug: str
    status: int
    title: str
    description: str

    @property
    def uri(self) -> str:
        return f"/problems/{self.slug}"


def _type(slug: str, status: int, title: str, description: str) -> ProblemType:
    return ProblemType(slug, status, title, description)


# Domain errors, most specific class first where classes inherit.
DOMAIN: dict[type[errors.ScengenError], ProblemType] = {
    errors.UnknownNetwork: _type(
        "unknown-network",
        422,
        "Unknown network",
        "A network reference is neither bundled nor uploaded.",
    ),
    errors.UnknownJunction: _type(
        "unknown-junction",
        422,
        "Unknown junction",
        "The junction is not in the network, or one must be named.",
    ),
    errors.UnknownLane: _type(
        "unknown-lane",
        422,
        "Unknown lane",
        "A lane id is not a fork or an exit of the intersection.",
    ),
    errors.UnknownRoute: _type(
        "unknown-route",
        422,
        "Unknown route",
        "No connection of the junction links that fork and exit.",
    ),
    errors.UnknownWalk: _type(
        "unknown-walk",
        422,
        "Unknown walk",
        "No crossing of the junction is walked that way, or the junction has no crossings.",
    ),
    errors.InvalidTestCase: _type(
        "invalid-testcase", 422, "Invalid test-case", "The test-case document fails validation."
    ),
    errors.InvalidTrajectory: _type(
        "invalid-trajectory", 422, "Invalid trajectory", "An ego trajectory cannot be used."
    ),
    errors.InvalidInput: _type(
        "invalid-input", 422, "Invalid input", "The request names something that cannot be used."
    ),
    errors.UnsupportedIntersection: _type(
        "unsupported-intersection",
        422,
        "Unsupported intersection",
        "The junction's control type has no traffic-rule set; override it.",
    ),
    errors.NoMoreComplexTestCase: _type(
        "no-more-complex-testcase",
        422,
        "No more complex test-case exists",
        "An expected outcome: no extension on these routes is both harder and solvable.",
    ),
    errors.NoneFound: _type(
        "none-found",
        422,
        "None found",
        "Orders of events existed, but none became a verified test-case (try another seed).",
    ),
    errors.NetworkBuildFailed: _type(
        "network-build-failed",
        422,
        "Network build failed",
        "netconvert could not rebuild the network.",
    ),
    errors.SimulationFailed: _type(
        "simulation-failed", 422, "Simulation failed", "SUMO refused or broke off a drive."
    ),
    errors.ClientFault: _type(
        "client-fault",
        422,
        "Co-simulation client fault",
        "The driving stack of a co-simulation never came, left early or left its route.",
    ),
    errors.MemoryExceeded: _type(
        "memory-exceeded",
        504,
        "Memory budget exceeded",
        "The work needed more memory than a worker may use (SCENGEN_WORKER_MEMORY_MB).",
    ),
    errors.BudgetExceeded: _type(
        "budget-exceeded",
        504,
        "Budget exceeded",
        "The work ran out of its time budget and was stopped.",
    ),
    errors.ScengenError: _type(
        "worker-failed",
        502,
        "Worker failed",
        "A worker process died or crashed; the server is fine.",
    ),
}
NONE_FOUND_IN_BUDGET = _type(
    "none-found-within-budget",
    504,
    "None found within the budget",
    "The generator ran out of its budget before an order became a verified test-case.",
)

HTTP: dict[int, ProblemType] = {
    400: _type("malformed-request", 400, "Malformed request", "The body cannot be parsed."),
    401: _type("unauthorized", 401, "Unauthorized", "This request needs the API token."),
    404: _type("not-found", 404, "Not found", "No such resource."),
    405: _type("method-not-allowed", 405, "Method not allowed", "The resource has no such method."),
    406: _type("not-acceptable", 406, "Not acceptable", "No representation matches Accept."),
    409: _type("conflict", 409, "Conflict", "Other stored resources depend on this one."),
    413: _type("payload-too-large", 413, "Payload too large", "The body exceeds the upload cap."),
    415: _type("unsupported-media-type", 415, "Unsupported media type", "Send another type."),
    422: _type("invalid-request", 422, "Invalid request", "The body or query fails validation."),
    500: _type("internal-error", 500, "Internal error", "A bug: please report it."),
    503: _type("database-unavailable", 503, "Database unavailable", "The database did not answer."),
}

# What each status means where an operation documents it (GET /problems has the types).
STATUS_DESCRIPTIONS: dict[int, str] = {
    400: "the body cannot be parsed (not JSON, not well-formed XML, a bad form field)",
    401: "a token is set (SCENGEN_API_TOKEN) and the request does not carry it",
    404: "nothing of that id (the path names it)",
    406: "no representation matches ?format or Accept",
    409: "other stored resources depend on it, or the key was used with another body",
    413: "the body exceeds SCENGEN_MAX_UPLOAD_MB",
    422: "the input fails validation, or names something this service does not have",
    502: "a worker process died or crashed; the server is fine",
    503: "the database did not answer",
    504: "the work ran out of its time or memory budget and was stopped",
}
WORK_PROBLEMS = (502, 504)  # operations that run something in a worker process


def documented(*statuses: int) -> dict[int | str, dict[str, Any]]:
    """OpenAPI ``responses`` for the problems an operation answers with beyond those every
    operation of its kind has (app._document_problems adds those and the Problem body)."""
    return {status: {"description": STATUS_DESCRIPTIONS[status]} for status in statuses}


ALL_TYPES: dict[str, ProblemType] = {
    t.slug: t for t in [*DOMAIN.values(), NONE_FOUND_IN_BUDGET, *HTTP.values()]
}


class Problem(Exception):
    """An error of the API layer itself (unknown id, bad media type, missing token, ...)."""

    def __init__(self, status: int, detail: str, **extra: Any) -> None:
        super().__init__(detail)
        self.status = status
        self.detail = detail
        self.extra = extra


def problem_type_of(error: errors.ScengenError) -> ProblemType:
    if isinstance(error, errors.NoneFound) and error.context.get("budget_exhausted"):
        return NONE_FOUND_IN_BUDGET
    for cls in type(error).__mro__:
        if cls in DOMAIN:
            return DOMAIN[cls]
    return DOMAIN[errors.ScengenError]


def problem_response(
    kind: ProblemType,
    detail: str,
    instance: str,
    headers: dict[str, str] | None = None,
    **extra: Any,
) -> JSONResponse:
    body = {
        "type": kind.uri,
        "title": kind.title,
        "status": kind.status,
        "detail": detail,
        "instance": instance,
        **extra,
    }
    return JSONResponse(body, status_code=kind.status, media_type=MEDIA_TYPE, headers=headers)


def install_problem_handlers(app: FastAPI) -> None:
    """Every error the app can raise leaves as problem+json."""

    @app.exception_handler(errors.ScengenError)
    async def domain_error(request: Request, error: errors.ScengenError) -> JSONResponse:
        kind = problem_type_of(error)
        if "traceback" in error.context:
            LOG.error("worker crash on %s: %s", request.url.path, error.context["traceback"])
        hidden = ("budget_exhausted", "traceback", "why", "longer")  # why: in the detail
        context = {k: v for k, v in error.context.items() if k not in hidden}
        return problem_response(kind, _scrub(error.message), request.url.path, **_jsonable(context))

    @app.exception_handler(Problem)
    async def api_problem(request: Request, error: Problem) -> JSONResponse:
        headers = {"WWW-Authenticate": "Bearer"} if error.status == 401 else None
        return problem_response(
            HTTP[error.status], error.detail, request.url.path, headers, **error.extra
        )

    @app.exception_handler(RequestValidationError)
    async def invalid_request(request: Request, error: RequestValidationError) -> JSONResponse:
        items = error.errors()
        malformed = [item for item in items if item.get("type") == "json_invalid"]
        if malformed:
            detail = f"the body is not valid JSON: {malformed[0].get('ctx', {}).get('error', '')}"
            return problem_response(HTTP[400], detail.rstrip(": "), request.url.path)
        state = getattr(request.app.state, "scengen", None)
        limit = state.settings.max_reported_errors if state else DEFAULT_REPORTED_ERRORS
        total = getattr(error, "total", len(items))  # counted in a worker (api.bodies)
        found = [_describe_validation(item) for item in items[:limit]]
        if total > len(found):  # a million bad keys: not a 97 MB answer
            found.append(f"... and {total - len(found)} more errors")
        return problem_response(HTTP[422], "; ".join(found), request.url.path, errors=found)

    @app.exception_handler(StarletteHTTPException)
    async def http_error(request: Request, error: StarletteHTTPException) -> JSONResponse:
        kind = HTTP.get(error.status_code, HTTP[500])
        detail = str(error.detail) if error.detail else kind.description
        if error.status_code == 404 and detail == "Not Found":
            detail = f"no route {request.url.path}; the API is listed at /docs"
        headers = dict(error.headers or {})
        if error.status_code == 405:
            allowed = _allowed_methods(request)
            if allowed:  # Starlette names only the first route's methods
                headers["Allow"] = ", ".join(allowed)
            if detail == "Method Not Allowed":
                detail = f"{request.method} is not a method of {request.url.path}"
                if allowed:
                    detail += f"; it has {', '.join(allowed)}"
        return problem_response(kind, detail, request.url.path, headers)

    @app.exception_handler(sa.exc.DataError)
    @app.exception_handler(UnicodeError)
    async def unstorable(request: Request, error: Exception) -> JSONResponse:
        detail = (
            "a value in the request cannot be stored (a NUL character, an unpaired surrogate, "
            "or text too long?)"
        )
        return problem_response(DOMAIN[errors.InvalidInput], detail, request.url.path)

    @app.exception_handler(sa.exc.OperationalError)
    @app.exception_handler(sa.exc.InterfaceError)
    async def database_away(request: Request, error: Exception) -> JSONResponse:
        LOG.error("database error on %s: %s", request.url.path, error)
        return problem_response(HTTP[503], HTTP[503].description, request.url.path)

    @app.exception_handler(Exception)
    async def internal_error(request: Request, error: Exception) -> JSONResponse:
        LOG.exception("internal error on %s %s", request.method, request.url.path)
        detail = f"internal error ({type(error).__name__}); the server's log has the details"
        return problem_response(HTTP[500], detail, request.url.path)


def _allowed_methods(request: Request) -> list[str]:
    """Every method the API documents at this path (Starlette's 405 names only the first
    matching route's methods)."""
    path = request.url.path
    methods: set[str] = set()
    for template, operations in request.app.openapi().get("paths", {}).items():
        pattern = re.sub(r"\\\{[^/]+?\\\}", "[^/]+", re.escape(template))
        if re.fullmatch(pattern, path):
            methods |= {m.upper() for m in operations if m in HTTP_METHODS}
    if "GET" in methods:
        methods.add("HEAD")  # answered as GET without the body (api.edge)
    return sorted(methods)


HTTP_METHODS = frozenset({"get", "put", "post", "delete", "patch", "head", "options"})


def _describe_validation(item: Any) -> str:
    where = ".".join(str(part) for part in item.get("loc", ()) if part != "body")
    message = str(item.get("msg", "invalid")).removeprefix("Value error, ")  # our own checks
    return f"{where or 'body'}: {message}"


def _jsonable(context: dict[str, object]) -> dict[str, Any]:
    return {
        key: _scrub(value) if isinstance(value, str) else value
        for key, value in context.items()
        if isinstance(value, (str, int, float, bool, list))
    }


DEFAULT_REPORTED_ERRORS = 20  # validation errors listed in one answer

# an absolute path of two or more parts, not inside a relative one ("../../etc", "a/b")
_ABSOLUTE_PATH = re.compile(r"(?<![\w.])(/[^\s/'\"(),:]+)(?:/[^\s/'\"(),:]+)*/([^\s/'\"(),:]+)")


@functools.lru_cache(maxsize=64)
def _on_this_machine(top: str) -> bool:
    """Whether ``top`` ("/tmp", "/work") is a folder at the root of this machine."""
    return Path(top).is_dir()


def _scrub(text: str) -> str:
    """Server-side paths mean nothing to a client (and tell too much): keep the file name.
    Only paths that start in a folder of this machine's root count, so that what a client
    sent is echoed as it was (API paths such as /networks/ID/junctions, relative paths)."""

    def scrubbed(match: re.Match[str]) -> str:
        return match.group(2) if _on_this_machine(match.group(1)) else match.group(0)

    return _ABSOLUTE_PATH.sub(scrubbed, text)
