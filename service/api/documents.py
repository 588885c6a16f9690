"""Stored test-case documents answered without parsing them in the server.

A stored document can be 30 MB (60,000 samples per car). Parsing it takes the GIL for
about a second, and a thread does not help: ``json.loads`` and pydantic hold the GIL from
start to end, so every other request, ``/healthz`` included, waits (issue 31). So the
server never parses one: the routes send the stored text as it is (``/document``), or
its compact form made here in small steps (``compact_json``: a string operation on 256 KB
at a time, so a thread running it gives the GIL back every few milliseconds), and find its
network in its first lines (``stored_network``). Whatever needs the test-case itself (an
export, a picture, an extension) runs in a worker process, which gets the text.

Answers are sent in pieces (``streamed``): a 30 MB body written at once is copied several
times on the event loop (the HTTP writer joins it, the transport buffers it). And a route
prepares a document in ``document_thread``, one thread for all: five threads that each
compact a document keep the loop waiting for the GIL far longer than one thread does.
"""

from __future__ import annotations

import asyncio
import functools
import json
import re
from collections.abc import AsyncIterator, Callable, Mapping
from concurrent.futures import ThreadPoolExecutor
from typing import Any, TypeVar

from fastapi.responses import StreamingResponse
from pydantic import BaseModel

from service.api.public import testcase_summary
from service.core.testcase import NetworkRef, parse_testcase
from service.store import TestCaseRecord

T = TypeVar("T")
CHUNK = 256 * 1024  # bytes of document per step: a few milliseconds of work each
PIECE = 1024 * 1024  # bytes of an answer sent at a time
HEAD = 64 * 1024  # the network is named in a document's first lines (after its name)
# A key and its separator in ``json.dumps(..., indent=2)``: a string at the start of a
# line followed by ': '. (A string cannot hold a raw newline, so a line starts outside one.)
KEY = re.compile(rb'^( *"(?:[^"\\\n]|\\.)*"): ', re.MULTILINE)
NETWORK = re.compile(r'^  "network": (\{$.*?^  \})', re.MULTILINE | re.DOTALL)


def compact_json(document: str) -> list[bytes]:
    """The stored (two-space indented) document as compact JSON, in pieces, equal to
    ``json.dumps(json.loads(document), separators=(",", ":"))`` and made without parsing.

    In indented JSON from ``json.dumps`` every newline and the spaces after it are layout
    (strings hold ``\\n``, never a newline), and so is the space after each key's colon.
    A string that holds ``": `` has its quote escaped (``\\": ``); only a piece with that
    needs the slower rule that finds the keys."""
    if not document.startswith("{\n  "):  # not the store's layout: parse it (small, old)
        return [json.dumps(json.loads(document), separators=(",", ":")).encode()]
    text = document.encode()
    pieces, start = [], 0
    while start < len(text):
        end = text.find(b"\n", min(start + CHUNK, len(text)))
        end = len(text) if end < 0 else end
        piece = text[start:end]
        keyed = KEY.sub(rb"\1:", piece) if b'\\": ' in piece else piece.replace(b'": ', b'":')
        pieces.append(b"".join([line.lstrip(b" ") for line in keyed.split(b"\n")]))
        start = end
    return pieces


def stored_network(document: str) -> NetworkRef:
    """The network a stored document names, read from its first lines (the whole
    document is parsed only when it is not laid out as the store writes documents)."""
    found = NETWORK.search(document, 0, HEAD)
    if found is None:
        return parse_testcase(document).network
    return NetworkRef.model_validate_json(found.group(1))


_DOCUMENTS = ThreadPoolExecutor(1, thread_name_prefix="scengen-documents")


async def document_thread(function: Callable[..., T], *args: Any) -> T:
    """``function(*args)`` in the thread that reads, stores and prepares whole documents."""
    loop = asyncio.get_running_loop()
    return await loop.run_in_executor(_DOCUMENTS, functools.partial(function, *args))


def streamed(
    pieces: list[bytes],
    status: int = 200,
    headers: Mapping[str, str] | None = None,
    media_type: str = "application/json",
) -> StreamingResponse:
    """An answer sent piece by piece, its length declared (not chunked)."""

    async def body() -> AsyncIterator[bytes]:
        for piece in pieces:
            yield piece

    length = {"Content-Length": str(sum(len(piece) for piece in pieces))}
    return StreamingResponse(body(), status, {**(headers or {}), **length}, media_type)


def pieces_of(text: str) -> list[bytes]:
    """A stored document's bytes in pieces of ``PIECE``, as they are."""
    data = text.encode()
    return [data[start : start + PIECE] for start in range(0, len(data), PIECE)] or [b""]


def testcase_body(record: TestCaseRecord, tail: BaseModel | None = None) -> list[bytes]:
    """The JSON of ``TestCasePublic`` (``ExtensionPublic`` with ``tail``: its fields after
    the document) in pieces, the document spliced in compact rather than parsed and written
    again.
    The same JSON as the model's, but for how numbers are spelled: as in the document
    (``1e-05``), not as pydantic spells them (``0.00001``)."""
    summary = testcase_summary(record).model_dump_json().encode()
    after = b"}" if tail is None else b"," + tail.model_dump_json().encode()[1:]
    return [summary[:-1] + b',"testcase":', *compact_json(record.document), after]
