"""The FastAPI application: routers combined, errors mapped, docs served from local assets."""

from __future__ import annotations

import asyncio
import contextlib
import copy
import ctypes
import os
import shutil
import time
from collections.abc import AsyncIterator, Awaitable, Callable, MutableMapping
from contextlib import asynccontextmanager
from functools import lru_cache
from pathlib import Path
from typing import Any

import fastapi_offline
from fastapi import FastAPI, Request, Response
from fastapi.dependencies.models import Dependant
from fastapi.openapi.docs import get_redoc_html, get_swagger_ui_html
from fastapi.openapi.utils import get_openapi
from fastapi.responses import HTMLResponse, RedirectResponse
from fastapi.routing import APIRoute
from fastapi.staticfiles import StaticFiles

from service.api.document import tighten
from service.api.edge import Edge
from service.api.problems import (
    HTTP,
    STATUS_DESCRIPTIONS,
    WORK_PROBLEMS,
    install_problem_handlers,
    problem_response,
)
from service.api.routes import evaluations, extend, health, jobs, networks, testcases
from service.api.schemas import (
    EXAMPLE_NETWORK,
    EXAMPLE_NEW_ROUTE,
    example_document,
    example_testcase,
)
from service.api.state import AppState, Metrics, get_state, token_matches
from service.core.budget import MEMORY_VARIABLE
from service.core.version import package_version
from service.jobs.dispatch import make_dispatcher
from service.jobs.executor import LocalExecutor
from service.pictures.report import UI
from service.settings import Settings, get_settings
from service.store import Store, testcase_id

DOCS_ASSETS = Path(fastapi_offline.__file__).parent / "static"
TITLE = "scengen"
DESCRIPTION = """Intersection test-cases for autonomous vehicles, each provably more complex
than the last.

Start with **POST /testcases** (an ego on a bundled network), grow it with **POST /extend**
(new cars that make it strictly harder yet solvable, with two certificate trajectories),
download **/testcases/{id}/bundle** to run any ego controller in SUMO, and judge one with
**POST /evaluations**. Errors are `application/problem+json`; `GET /problems` lists them.
"""

EXAMPLE_BUDGET = 60  # s: the /extend example's, or the server's largest if that is smaller
ROUTE_MODULES = (extend, testcases, networks, evaluations, jobs, health)
KNOWN_METHODS = ("GET", "HEAD", "POST", "PUT", "PATCH", "DELETE", "OPTIONS")
ASGIApp = Callable[
    [MutableMapping[str, Any], Callable[[], Awaitable[Any]], Callable[[Any], Awaitable[None]]],
    Awaitable[None],
]


def create_app(settings: Settings | None = None) -> FastAPI:
    """The app; ``settings`` default to the environment (``SCENGEN_*``)."""
    chosen = settings or get_settings()

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        chosen.data_dir.mkdir(parents=True, exist_ok=True)
        return_large_blocks_to_the_system()
        # every worker process this server starts (calls, job items) reads its cap here
        memory_before = os.environ.get(MEMORY_VARIABLE)
        os.environ[MEMORY_VARIABLE] = str(chosen.worker_memory_mb)
        remove_stale_uploads(chosen.cache_dir / "uploads", chosen.work_budget)
        store = Store(chosen.database, chosen.cache_dir, chosen.max_samples)
        executor = LocalExecutor(chosen.workers)
        metrics = Metrics()
        dispatcher = make_dispatcher(store, chosen)
        app.state.scengen = AppState(chosen, store, executor, metrics, dispatcher)
        background = [
            asyncio.create_task(_watch_loop_lag(metrics)),
            asyncio.create_task(dispatcher.run()),
        ]
        try:
            yield
        finally:
            for task in background:
                task.cancel()
            await dispatcher.close()
            await executor.shutdown()
            store.close()
            if memory_before is None:
                os.environ.pop(MEMORY_VARIABLE, None)
            else:
                os.environ[MEMORY_VARIABLE] = memory_before

    app = FastAPI(
        title=TITLE,
        description=DESCRIPTION,
        version=package_version(),
        lifespan=lifespan,
        docs_url=None,
        redoc_url=None,
    )
    for module in ROUTE_MODULES:
        for route in module.router.routes:  # the handler's one-line docstring is its summary
            if isinstance(route, APIRoute) and route.endpoint.__doc__:
                route.summary = route.endpoint.__doc__.strip().splitlines()[0].rstrip(".")
        app.include_router(module.router)
    install_problem_handlers(app)
    _serve_docs(app)
    _serve_ui(app)
    app.middleware("http")(_count_requests)
    app.add_middleware(BodyLimit, limit=chosen.max_upload_bytes, token=chosen.api_token)
    app.add_middleware(Edge, token=chosen.api_token, protect_reads=chosen.protect_reads)
    app.openapi = lambda: _openapi(app, chosen)  # type: ignore[method-assign]
    return app


M_MMAP_THRESHOLD = -3  # glibc's mallopt parameter (malloc.h)
MMAP_THRESHOLD = 128 * 1024


def return_large_blocks_to_the_system() -> bool:
    """Every block of 128 KB or more is mapped on its own and unmapped when it is freed
    (glibc; elsewhere nothing changes). glibc's default raises that threshold to the largest
    block freed so far, up to 32 MB: after one 30 MB document, the next ones came from the
    heap and stayed there, and the server kept 300-750 MB after the requests (issue 31).
    Whether the setting took."""
    try:
        libc = ctypes.CDLL("libc.so.6")
        return bool(libc.mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD))
    except (OSError, AttributeError):
        return False


async def _watch_loop_lag(metrics: Metrics, period: float = 0.05) -> None:
    """How late the event loop wakes up: a blocked loop shows here before clients see it."""
    while True:
        clock = time.monotonic()
        await asyncio.sleep(period)
        metrics.loop_lag(time.monotonic() - clock - period)


async def _count_requests(
    request: Request, call_next: Callable[[Request], Awaitable[Response]]
) -> Response:
    clock = time.monotonic()
    status = 500
    try:
        response = await call_next(request)
        status = response.status_code
        return response
    finally:
        route = request.scope.get("route")
        template = getattr(route, "path", "unmatched")
        method = request.method if request.method in KNOWN_METHODS else "OTHER"
        state: AppState | None = getattr(request.app.state, "scengen", None)
        if state is not None:
            state.metrics.observe(method, template, status, time.monotonic() - clock)


class BodyLimit:
    """Refuses a request body over the cap with 413, and a write without the API token with
    401, before any of the body is read, parsed or spooled. (The routes check the token
    too: that is what documents it in OpenAPI.)"""

    def __init__(self, app: ASGIApp, limit: int, token: str = "") -> None:
        self.app = app
        self.limit = limit
        self.token = token

    async def __call__(
        self,
        scope: MutableMapping[str, Any],
        receive: Callable[[], Awaitable[Any]],
        send: Callable[[Any], Awaitable[None]],
    ) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        headers = dict(scope.get("headers", []))
        writes = scope.get("method") in ("POST", "PUT", "PATCH", "DELETE")
        if writes and self.token and not token_matches(scope.get("headers", []), self.token):
            await self.app(scope, _no_body, send)  # the route's own check answers 401
            return
        if scope.get("method") not in ("POST", "PUT", "PATCH"):
            await self.app(scope, receive, send)  # no route reads their bodies
            return
        declared = headers.get(b"content-length")
        if declared is not None and declared.isdigit() and int(declared) > self.limit:
            await self._refuse(scope, receive, send)
            return
        # Read the whole body first (chunked bodies declare no length): over the cap is a
        # 413 here, not an error somewhere inside the body parser.
        parts, seen, more = [], 0, True
        while more:
            message = await receive()
            if message["type"] != "http.request":
                return  # the client went away
            parts.append(message.get("body", b""))
            seen += len(parts[-1])
            if seen > self.limit:
                await self._refuse(scope, receive, send)
                return
            more = message.get("more_body", False)
        replayed = False

        async def replay() -> Any:
            nonlocal replayed
            if replayed:
                return await receive()
            replayed = True
            return {"type": "http.request", "body": b"".join(parts), "more_body": False}

        await self.app(scope, replay, send)

    async def _refuse(
        self,
        scope: MutableMapping[str, Any],
        receive: Callable[[], Awaitable[Any]],
        send: Callable[[Any], Awaitable[None]],
    ) -> None:
        mb = self.limit / 1024 / 1024
        response = problem_response(
            HTTP[413],
            f"the request body exceeds {mb:g} MB (SCENGEN_MAX_UPLOAD_MB)",
            scope.get("path", ""),
        )
        await response(scope, receive, send)


def remove_stale_uploads(folder: Path, budget: float) -> list[Path]:
    """Staged uploads left by a server killed while it checked them (kill -9 runs no
    cleanup): those older than an upload check may take. Younger ones may belong to
    another server on the same data directory. The folders removed."""
    removed: list[Path] = []
    if not folder.is_dir():
        return removed
    cutoff = time.time() - budget - 60.0
    for staged in folder.iterdir():
        with contextlib.suppress(OSError):
            if staged.stat().st_mtime < cutoff:
                shutil.rmtree(staged)
                removed.append(staged)
    return removed


async def _no_body() -> dict[str, Any]:
    return {"type": "http.request", "body": b"", "more_body": False}


def _serve_ui(app: FastAPI) -> None:
    """The results browser at /ui: static pages that read the API (service/pictures/ui)."""

    app.mount("/ui", StaticFiles(directory=UI, html=True), name="ui")


def _serve_docs(app: FastAPI) -> None:
    """Swagger UI at /docs and ReDoc at /redoc, from assets inside the installation."""

    @app.get("/docs-assets/redoc.standalone.js", include_in_schema=False)
    async def redoc_script() -> Response:
        return Response(_offline_redoc(), media_type="text/javascript")

    app.mount("/docs-assets", StaticFiles(directory=DOCS_ASSETS), name="docs-assets")

    @app.get("/", include_in_schema=False)
    async def root() -> RedirectResponse:
        return RedirectResponse("/docs")

    @app.get("/docs", include_in_schema=False)
    async def swagger_ui() -> HTMLResponse:
        return get_swagger_ui_html(
            openapi_url="/openapi.json",
            title=f"{TITLE} - Swagger UI",
            swagger_js_url="/docs-assets/swagger-ui-bundle.js",
            swagger_css_url="/docs-assets/swagger-ui.css",
            swagger_favicon_url="/docs-assets/favicon.png",
            swagger_ui_parameters={"displayRequestDuration": True, "defaultModelsExpandDepth": 0},
        )

    @app.get("/redoc", include_in_schema=False)
    async def redoc() -> HTMLResponse:
        return get_redoc_html(
            openapi_url="/openapi.json",
            title=f"{TITLE} - ReDoc",
            redoc_js_url="/docs-assets/redoc.standalone.js",
            redoc_favicon_url="/docs-assets/favicon.png",
            with_google_fonts=False,
        )


@lru_cache
def _offline_redoc() -> bytes:
    """ReDoc's bundle fetches its "by Redocly" logo from a CDN: point it at a local image."""
    script = (DOCS_ASSETS / "redoc.standalone.js").read_bytes()
    return script.replace(REDOC_LOGO, b"/docs-assets/favicon.png")


REDOC_LOGO = b"https://cdn.redoc.ly/redoc/logo-mini.svg"


def _openapi(app: FastAPI, settings: Settings) -> dict[str, Any]:
    """The schema of this server (its token, limits and controllers: api.document), with
    request examples that work as they stand (built once)."""
    if app.openapi_schema is None:
        schema = get_openapi(
            title=app.title,
            version=app.version,
            description=app.description,
            routes=app.routes,
        )
        tighten(schema, settings)
        _add_examples(schema, settings)
        _add_parameter_examples(schema)
        _document_problems(schema, [r for m in ROUTE_MODULES for r in m.router.routes])
        _drop_repeated_descriptions(schema)
        app.openapi_schema = schema
    return app.openapi_schema


def _add_examples(schema: dict[str, Any], settings: Settings) -> None:
    testcase = example_testcase()
    bodies = {
        ("/extend", "post"): {
            "four-way": {
                "summary": "4-way stop: ego turns left, a new car goes straight from the south",
                "value": {
                    "testcase": testcase,
                    "routes": [EXAMPLE_NEW_ROUTE],
                    "seed": 0,
                    "budget": min(EXAMPLE_BUDGET, settings.max_budget),
                },
            }
        },
        ("/evaluations", "post"): {
            "four-way": {
                "summary": "SUMO's driver on the ego-only four-way test-case",
                "value": {"testcase": copy.deepcopy(testcase), "controller": "sumo"},
            }
        },
    }
    for (path, method), examples in bodies.items():
        content = schema["paths"][path][method]["requestBody"]["content"]["application/json"]
        content["examples"] = examples


PROBLEM_SCHEMA = {
    "type": "object",
    "description": "RFC 9457 problem details; GET /problems lists every type",
    "properties": {
        "type": {"type": "string", "examples": ["/problems/no-more-complex-testcase"]},
        "title": {"type": "string"},
        "status": {"type": "integer"},
        "detail": {"type": "string", "description": "what went wrong, naming the input"},
        "instance": {"type": "string"},
    },
    "required": ["type", "title", "status", "detail"],
    "additionalProperties": True,
}


def _document_problems(schema: dict[str, Any], routes: list[Any]) -> None:
    """Errors leave as problem+json, not FastAPI's default validation body; every status an
    operation can answer with is documented (the fuzz test holds the server to it)."""
    schema.setdefault("components", {}).setdefault("schemas", {})["Problem"] = PROBLEM_SCHEMA
    for name in ("HTTPValidationError", "ValidationError"):
        schema["components"]["schemas"].pop(name, None)
    reference = {"application/problem+json": {"schema": {"$ref": "#/components/schemas/Problem"}}}
    stateful = {
        route.operation_id
        for route in routes
        if isinstance(route, APIRoute) and _depends_on(route.dependant, get_state)
    }
    for operations in schema["paths"].values():
        for operation in operations.values():
            responses = operation.setdefault("responses", {})
            for status in _kind_problems(operation, operation.get("operationId") in stateful):
                responses.setdefault(str(status), {"description": STATUS_DESCRIPTIONS[status]})
            for code, response in responses.items():
                if code.startswith(("4", "5")):
                    response["content"] = reference
            operation["responses"] = dict(sorted(responses.items()))


def _kind_problems(operation: dict[str, Any], stateful: bool) -> list[int]:
    """The problems every operation of this kind can answer with."""
    statuses = []
    parameters = operation.get("parameters", [])
    if operation.get("requestBody"):
        # a body over OFF_LOOP_BYTES is validated in a worker process (502, 504)
        statuses += [400, 413, 422, *WORK_PROBLEMS]
    if parameters:
        statuses.append(422)
    if any(parameter["in"] == "path" for parameter in parameters):
        statuses.append(404)
    if "security" in operation:
        statuses.append(401)
    if stateful:
        statuses.append(503)
    return statuses


def _depends_on(dependant: Dependant, call: Callable[..., Any]) -> bool:
    return any(sub.call is call or _depends_on(sub, call) for sub in dependant.dependencies)


def _add_parameter_examples(schema: dict[str, Any]) -> None:
    """Path parameters prefilled in "Try it out": the bundled four-way stop, and the
    example test-case (stored once POST /testcases or POST /extend has run its example)."""
    values = {
        "network": EXAMPLE_NETWORK,
        "junction": "C",
        "testcase": testcase_id(example_document()),
    }
    for operations in schema["paths"].values():
        for operation in operations.values():
            for parameter in operation.get("parameters", []):
                if parameter["in"] == "path" and parameter["name"] in values:
                    parameter["example"] = values[parameter["name"]]


def _drop_repeated_descriptions(schema: dict[str, Any]) -> None:
    """A one-line docstring is the summary; the UI need not show it twice."""
    for operations in schema["paths"].values():
        for operation in operations.values():
            if operation.get("description", "").rstrip(".") == operation.get("summary"):
                del operation["description"]
