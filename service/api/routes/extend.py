"""/extend: a strictly more complex, still solvable test-case, or the generator's outcome."""

from __future__ import annotations

import json
import time

from fastapi import APIRouter, Response, status

from service.api.problems import Problem
from service.api.routes.testcases import public, store_inline
from service.api.schemas import Attempt, ExtendRequest, ExtensionPublic
from service.api.state import State, Token
from service.core.testcase import parse_testcase
from service.jobs import tasks

router = APIRouter(tags=["extend"])

# Beyond its own budget the generator may finish the answer set in hand; the worker is
# killed after this much more.
GRACE = 10.0


@router.post(
    "/extend",
    operation_id="extend_testcase",
    status_code=status.HTTP_201_CREATED,
    dependencies=[Token],
    responses={
        422: {"description": "invalid input, or no more complex test-case exists (problem+json)"},
        504: {"description": "the budget ran out before a test-case was found (problem+json)"},
    },
)
async def extend_testcase(state: State, body: ExtendRequest, response: Response) -> ExtensionPublic:
    """Add cars on the given routes so that the test-case becomes strictly harder."""
    started = time.monotonic()
    budget = body.budget or state.settings.extend_budget
    if budget > state.settings.max_budget:
        raise Problem(
            422,
            f"budget {budget:g} s exceeds the server's limit of {state.settings.max_budget:g} s",
        )
    if body.testcase is not None:
        old = store_inline(state, body.testcase)
    else:
        old = state.testcase_or_404(str(body.testcase_id))
    network_file = state.network_file_of(old.testcase)
    result = await state.run(
        "extend",
        tasks.extend,
        (
            old.document,
            network_file,
            state.cache_dir,
            body.routes,
            body.seed,
            # The generator's own deadline counts from when it starts, after any wait.
            max(1.0, budget - (time.monotonic() - started)),
            body.start_distance,
        ),
        budget + GRACE,
        started,
    )
    testcase = parse_testcase(result["document"])
    record = state.store.add_testcase(testcase, parent=old.id)
    response.headers["Location"] = f"/testcases/{record.id}"
    old_ids = {car["id"] for car in json.loads(old.document).get("nonegos", [])}
    return ExtensionPublic(
        **public(record).model_dump(),
        new_cars=[car.id for car in testcase.nonegos if car.id not in old_ids],
        attempts=[Attempt(**a) for a in result["attempts"]],
        seconds=result["seconds"],
    )
