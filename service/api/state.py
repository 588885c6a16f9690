"""What every route shares: settings, store, executor, metrics; and the FastAPI dependencies
that hand them out (``State``, ``Token``)."""

from __future__ import annotations

import secrets
import time
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any

from fastapi import Depends, Request, Response
from fastapi.security import HTTPAuthorizationCredentials, HTTPBearer
from pydantic import BaseModel

from service.api.problems import Problem
from service.core.errors import InvalidInput, UnknownNetwork, choices
from service.jobs.dispatch import Dispatcher
from service.jobs.executor import LocalExecutor
from service.settings import Settings
from service.store import NetworkRecord, Store, TestCaseRecord

LAG_BUCKETS = (0.01, 0.05, 0.1)


@dataclass
class Metrics:
    """Request counters for ``/metrics`` (one server process; Prometheus text format)."""

    started: float = field(default_factory=time.time)
    requests: dict[tuple[str, str, int], int] = field(default_factory=dict)
    seconds: dict[tuple[str, str], float] = field(default_factory=dict)
    outcomes: dict[tuple[str, str], int] = field(default_factory=dict)  # (work, outcome)
    lag_max: float = 0.0  # the event loop's worst late wake-up (s)
    lag_over: dict[float, int] = field(default_factory=lambda: dict.fromkeys(LAG_BUCKETS, 0))

    def observe(self, method: str, route: str, status: int, seconds: float) -> None:
        key = (method, route, status)
        self.requests[key] = self.requests.get(key, 0) + 1
        self.seconds[(method, route)] = self.seconds.get((method, route), 0.0) + seconds

    def loop_lag(self, seconds: float) -> None:
        self.lag_max = max(self.lag_max, seconds)
        for bucket in LAG_BUCKETS:
            if seconds > bucket:
                self.lag_over[bucket] += 1

    def outcome(self, work: str, outcome: str) -> None:
        self.outcomes[(work, outcome)] = self.outcomes.get((work, outcome), 0) + 1


@dataclass
class AppState:
    settings: Settings
    store: Store
    executor: LocalExecutor
    metrics: Metrics
    dispatcher: Dispatcher

    @property
    def cache_dir(self) -> Path:
        return self.settings.cache_dir

    def network_or_404(self, ident: str) -> NetworkRecord:
        record = self.store.network(ident)
        if record is None:
            known = [n.id for n in self.store.list_networks()]
            raise Problem(404, f"no network {ident!r}; known networks: {choices(known)}")
        return record

    def testcase_or_404(self, ident: str) -> TestCaseRecord:
        record = self.store.testcase(ident)
        if record is None:
            raise Problem(404, f"no test-case {ident!r}; GET /testcases lists them")
        return record

    def network_named_in_body(self, ident: str) -> NetworkRecord:
        """A network a request body names: unknown is 422 ``unknown-network``, not a
        missing page (404 is for ids in the path)."""
        record = self.store.network(ident)
        if record is None:
            known = [n.id for n in self.store.list_networks()]
            raise UnknownNetwork(
                f"network: no network {ident!r}; known networks: {choices(known)}",
                network=ident,
            )
        return record

    def testcase_named_in_body(self, ident: str) -> TestCaseRecord:
        """A test-case a request body names: unknown is invalid input (422), not a missing
        page (404 is for ids in the path)."""
        record = self.store.testcase(ident)
        if record is None:
            raise InvalidInput(f"testcase_id: no test-case {ident!r}; GET /testcases lists them")
        return record

    async def run(
        self,
        work: str,
        function: Any,
        args: tuple[Any, ...],
        budget: float,
        started: float,
        grace: float = 0.0,
    ) -> Any:
        """A call in a worker, counted in the metrics by outcome."""
        try:
            result = await self.executor.run(function, args, budget, work, started, grace)
        except Exception as error:
            self.metrics.outcome(work, type(error).__name__)
            raise
        self.metrics.outcome(work, "ok")
        return result


def json_answer(model: BaseModel, status: int = 200, location: str | None = None) -> Response:
    """A model as JSON, serialised here (in a worker thread when called from one) rather
    than by FastAPI on the event loop: test-cases are large."""
    headers = {"Location": location} if location else None
    return Response(model.model_dump_json(), status, headers, media_type="application/json")


def get_state(request: Request) -> AppState:
    state: AppState = request.app.state.scengen
    return state


State = Annotated[AppState, Depends(get_state)]

# Declares the scheme in the OpenAPI document; the token itself is read by token_matches,
# the one parser that the body-limit middleware and the routes share.
_bearer = HTTPBearer(
    auto_error=False,
    description="the server's SCENGEN_API_TOKEN: an operation that lists it needs it. A "
    "server serves the document of its settings at /openapi.json: without a token no "
    "operation lists it, with SCENGEN_PROTECT_READS every one but /healthz does",
)


def token_matches(headers: Iterable[tuple[bytes, bytes]], expected: str) -> bool:
    """Whether a request's raw headers carry ``expected``: exactly one Authorization header,
    ``Bearer <token>`` (the scheme in any case, one space, nothing else around the token)."""
    values = [value for name, value in headers if name.lower() == b"authorization"]
    if len(values) != 1:
        return False
    scheme, _, given = values[0].decode("latin-1").partition(" ")
    if scheme.lower() != "bearer" or not given or given != given.strip() or " " in given:
        return False
    return secrets.compare_digest(given.encode("latin-1"), expected.encode())


def require_token(
    state: State,
    request: Request,
    _scheme: Annotated[HTTPAuthorizationCredentials | None, Depends(_bearer)],
) -> None:
    """Creating or deleting needs ``Authorization: Bearer <token>`` when a token is set."""
    expected = state.settings.api_token
    if not expected:
        return
    headers = request.scope.get("headers", [])
    if not any(name.lower() == b"authorization" for name, _ in headers):
        raise Problem(401, "this request creates or deletes; send Authorization: Bearer <token>")
    if not token_matches(headers, expected):
        raise Problem(
            401,
            "the Authorization header is not 'Bearer <the server's API token>' "
            "(one header, one space)",
        )


Token = Depends(require_token)
