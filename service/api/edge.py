"""What every request and response passes through, outermost: the read policy, HEAD, and
the security headers.

- With ``SCENGEN_PROTECT_READS`` (and a token), a request that is not a write and not for
  ``PUBLIC`` paths (the health check, the API's own docs) needs the token: 401 otherwise.
  Writes keep their own check (``BodyLimit`` and the routes').
- HEAD is answered as GET without the body, on every route that has GET.
- Every response says ``X-Content-Type-Options: nosniff`` and ``X-Frame-Options: DENY``,
  and carries a Content-Security-Policy unless its route set one: an HTML page may run its
  own scripts (from the server, and its inline ones by their sha256: the campaign report
  inlines its script and data, Swagger UI its set-up) and nothing else; anything else is
  no page at all (an SVG picture opened on its own runs no script). A 304 (not modified)
  carries none: the browser would lay it over the policy of the page it keeps.
"""

from __future__ import annotations

import base64
import hashlib
import re
from collections.abc import Awaitable, Callable, MutableMapping
from typing import Any

from starlette.datastructures import MutableHeaders

from service.api.problems import HTTP, problem_response
from service.api.state import token_matches

Scope = MutableMapping[str, Any]
Receive = Callable[[], Awaitable[Any]]
Send = Callable[[Any], Awaitable[None]]
ASGIApp = Callable[[Scope, Receive, Send], Awaitable[None]]

WRITES = frozenset({"POST", "PUT", "PATCH", "DELETE"})
PUBLIC = ("/healthz", "/openapi.json", "/docs", "/redoc", "/docs-assets/")  # and "/"
FIXED_HEADERS = {"x-content-type-options": "nosniff", "x-frame-options": "DENY"}
PAGE_POLICY = (
    "default-src 'self'; script-src 'self'{hashes}; style-src 'self' 'unsafe-inline'; "
    "img-src 'self' data: blob:; font-src 'self' data:; connect-src 'self'; "
    "worker-src 'self' blob:; object-src 'none'; base-uri 'none'; form-action 'self'; "
    "frame-ancestors 'none'"
)
OTHER_POLICY = (
    "default-src 'none'; style-src 'unsafe-inline'; img-src data:; frame-ancestors 'none'"
)
INLINE_SCRIPT = re.compile(rb"<script(?![^>]*\bsrc\s*=)[^>]*>(.*?)</script\s*>", re.S | re.I)


def page_policy(page: bytes) -> str:
    """The policy of an HTML page: its inline scripts allowed by their hashes."""
    hashes = "".join(
        f" 'sha256-{base64.b64encode(hashlib.sha256(body).digest()).decode()}'"
        for body in INLINE_SCRIPT.findall(page)
    )
    return PAGE_POLICY.format(hashes=hashes)


def is_public(path: str) -> bool:
    return path == "/" or any(
        path == prefix or (prefix.endswith("/") and path.startswith(prefix)) for prefix in PUBLIC
    )


class Edge:
    """The outermost middleware (see the module's docstring)."""

    def __init__(self, app: ASGIApp, token: str = "", protect_reads: bool = False) -> None:
        self.app = app
        self.token = token
        self.protect_reads = protect_reads and bool(token)

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        head = scope["method"] == "HEAD"
        if head:
            scope = {**scope, "method": "GET"}
        answer = _Answer(send, head)
        if (
            self.protect_reads
            and scope["method"] not in WRITES
            and not is_public(scope["path"])
            and not token_matches(scope.get("headers", []), self.token)
        ):
            refusal = problem_response(
                HTTP[401],
                "this server's reads need the API token too (SCENGEN_PROTECT_READS); send "
                "Authorization: Bearer <token>",
                scope["path"],
                {"WWW-Authenticate": "Bearer"},
            )
            await refusal(scope, receive, answer.send)
            return
        await self.app(scope, receive, answer.send)


class _Answer:
    """Adds the headers to a response, holding an HTML page back until its inline scripts
    are hashed; sends no body for HEAD."""

    def __init__(self, send: Send, head: bool) -> None:
        self._send = send
        self._head = head
        self._start: MutableMapping[str, Any] | None = None
        self._page: list[bytes] = []

    async def send(self, message: MutableMapping[str, Any]) -> None:
        if message["type"] == "http.response.start":
            message.setdefault("headers", [])  # optional in ASGI
            headers = MutableHeaders(scope=message)
            for name, value in FIXED_HEADERS.items():
                headers.setdefault(name, value)
            if message["status"] == 304:  # the cached response's policy stands: a 304's
                await self._send(message)  # headers replace the cached ones (RFC 9111)
                return
            html = headers.get("content-type", "").startswith("text/html")
            if "content-security-policy" in headers or not html:
                headers.setdefault("content-security-policy", OTHER_POLICY)
                await self._send(message)
            else:
                self._start = message  # sent with the whole page
            return
        if message["type"] != "http.response.body":  # a file sent by the server itself
            if self._start is not None:  # (pathsend): a page whose inline scripts are unseen
                MutableHeaders(scope=self._start)["content-security-policy"] = page_policy(b"")
                await self._send(self._start)
                self._start = None
            await self._send(message)
            return
        if self._start is not None:
            self._page.append(message.get("body", b""))
            if message.get("more_body", False):
                return
            page = b"".join(self._page)
            MutableHeaders(scope=self._start)["content-security-policy"] = page_policy(page)
            await self._send(self._start)
            self._start = None
            message = {**message, "body": page}
        if self._head:
            message = {**message, "body": b""}
        await self._send(message)
