"""/extend: a strictly more complex, still solvable test-case, or the generator's outcome."""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

from fastapi import APIRouter, Response, status
from pydantic import BaseModel

from service.api import worker
from service.api.bodies import OffLoopValidation, stored_inline
from service.api.documents import document_thread, stored_network, streamed, testcase_body
from service.api.problems import WORK_PROBLEMS, Problem, documented
from service.api.schemas import Attempt, ExtendRequest, ExtensionPublic, ExtensionsPublic
from service.api.state import AppState, State, Token

router = APIRouter(tags=["extend"], route_class=OffLoopValidation)

# The generator stops itself at the request's deadline, but may finish the answer set in
# hand (and a worker takes a moment to start): it is killed this much later, so that an
# answer comes at most this long after the budget (the README promises budget + 2 s).
GRACE = 2.0


@router.post(
    "/extend",
    operation_id="extend_testcase",
    status_code=status.HTTP_201_CREATED,
    dependencies=[Token],
    response_model=ExtensionPublic | ExtensionsPublic,
    responses={
        **documented(*WORK_PROBLEMS),
        422: {"description": "invalid input, or no more complex test-case exists (problem+json)"},
        504: {"description": "the budget ran out before a test-case was found (problem+json)"},
    },
)
async def extend_testcase(state: State, body: ExtendRequest) -> Response:
    """Add cars on the given routes and pedestrians on the given walks so that the
    test-case becomes strictly harder: one
    extension (`ExtensionPublic`), or with `count` above 1 up to that many distinct ones
    (`ExtensionsPublic`), each stored."""
    started = time.monotonic()
    budget = body.budget or state.settings.extend_budget
    if budget > state.settings.max_budget:
        raise Problem(
            422,
            f"budget {budget:g} s exceeds the server's limit of {state.settings.max_budget:g} s",
        )
    old, document, network_file = await document_thread(_base, state, body)
    # The deadline is the request's: the wait for a free worker counts against it.
    deadline = time.time() + budget - (time.monotonic() - started)
    common = (document, network_file, state.cache_dir, body.routes)
    tail = (body.seed, budget, body.start_distance, deadline, body.pedestrians)
    if body.count > 1:
        result = await state.run(
            "extend", worker.extend_variants, (*common, body.count, *tail), budget, started, GRACE
        )
        return await document_thread(_store_variants, state, old, result)
    result = await state.run("extend", worker.extend, (*common, *tail), budget, started, GRACE)
    return await document_thread(_store, state, old, result)


class _Tail(BaseModel):
    """``ExtensionPublic``'s fields after the document."""

    new_cars: list[str]
    attempts: list[Attempt]
    seconds: dict[str, float]


class _VariantTail(_Tail):
    """``ExtensionVariantPublic``'s fields after the document."""

    difference: str


def _base(state: AppState, body: ExtendRequest) -> tuple[str, str, Path]:
    """The old test-case's id and document (an inline one is stored: nothing submitted is
    lost), and its network's file."""
    old = stored_inline(state.store, body.testcase)
    if old is None:
        old = state.testcase_named_in_body(str(body.testcase_id))
    network = stored_network(old.document)
    return old.id, old.document, state.store.network_file_of(network)


def _store(state: AppState, old: str, result: dict[str, Any]) -> Response:
    record = state.store.add_stored(result["stored"], parent=old)
    tail = _Tail(
        new_cars=result["new_cars"],
        attempts=[Attempt(**a) for a in result["attempts"]],
        seconds=result["seconds"],
    )
    location = {"Location": f"/testcases/{record.id}"}
    return streamed(testcase_body(record, tail), status.HTTP_201_CREATED, location)


def _store_variants(state: AppState, old: str, result: dict[str, Any]) -> Response:
    """Every extension stored (the old test-case its parent), answered as
    ``ExtensionsPublic``: each one's JSON spliced in as ``_store`` sends one."""
    bodies: list[bytes] = []
    for variant in result["extensions"]:
        record = state.store.add_stored(variant["stored"], parent=old)
        tail = _VariantTail(
            new_cars=variant["new_cars"],
            attempts=[Attempt(**a) for a in variant["attempts"]],
            seconds=variant["seconds"],
            difference=variant["difference"],
        )
        bodies += [b"," if bodies else b"", *testcase_body(record, tail)]
    shortfall = json.dumps(result["shortfall"]).encode()
    pieces = [b'{"extensions":[', *bodies, b'],"shortfall":' + shortfall + b"}"]
    return streamed(pieces, status.HTTP_201_CREATED)
