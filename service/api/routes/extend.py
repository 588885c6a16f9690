"""/extend: a strictly more complex, still solvable test-case, or the generator's outcome."""

from __future__ import annotations

import asyncio
import json
import time
from pathlib import Path
from typing import Any

from fastapi import APIRouter, Response, status

from service.api.bodies import OffLoopValidation
from service.api.problems import WORK_PROBLEMS, Problem, documented
from service.api.public import testcase_public
from service.api.schemas import Attempt, ExtendRequest, ExtensionPublic
from service.api.state import AppState, State, Token, json_answer
from service.core.testcase import parse_testcase
from service.jobs import tasks
from service.store import TestCaseRecord

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
    response_model=ExtensionPublic,
    responses={
        **documented(*WORK_PROBLEMS),
        422: {"description": "invalid input, or no more complex test-case exists (problem+json)"},
        504: {"description": "the budget ran out before a test-case was found (problem+json)"},
    },
)
async def extend_testcase(state: State, body: ExtendRequest) -> Response:
    """Add cars on the given routes so that the test-case becomes strictly harder."""
    started = time.monotonic()
    budget = body.budget or state.settings.extend_budget
    if budget > state.settings.max_budget:
        raise Problem(
            422,
            f"budget {budget:g} s exceeds the server's limit of {state.settings.max_budget:g} s",
        )
    old, network_file = await asyncio.to_thread(_base, state, body)
    result = await state.run(
        "extend",
        tasks.extend,
        (
            old.document,
            network_file,
            state.cache_dir,
            body.routes,
            body.seed,
            budget,
            body.start_distance,
            # The deadline is the request's: the wait for a free worker counts against it.
            time.time() + budget - (time.monotonic() - started),
        ),
        budget,
        started,
        GRACE,
    )
    return await asyncio.to_thread(_store, state, old, result)


def _base(state: AppState, body: ExtendRequest) -> tuple[TestCaseRecord, Path]:
    """The old test-case (an inline one is stored: nothing submitted is lost) and its network."""
    if body.testcase is not None:
        old = state.store.keep_inline(body.testcase)
    else:
        old = state.testcase_named_in_body(str(body.testcase_id))
    return old, state.store.network_file_for(old.testcase)


def _store(state: AppState, old: TestCaseRecord, result: dict[str, Any]) -> Response:
    testcase = parse_testcase(result["document"])
    record = state.store.add_testcase(testcase, parent=old.id)
    old_ids = {car["id"] for car in json.loads(old.document).get("nonegos", [])}
    answer = ExtensionPublic(
        **testcase_public(record).model_dump(),
        new_cars=[car.id for car in testcase.nonegos if car.id not in old_ids],
        attempts=[Attempt(**a) for a in result["attempts"]],
        seconds=result["seconds"],
    )
    return json_answer(answer, status.HTTP_201_CREATED, f"/testcases/{record.id}")
