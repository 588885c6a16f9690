"""/evaluations and /controllers: drive a controller through a test-case and keep the verdict."""

from __future__ import annotations

import asyncio
import json
import time
from pathlib import Path
from typing import Annotated, Any

from fastapi import APIRouter, Query, Request, Response, status

from service.api import worker
from service.api.bodies import OffLoopValidation, stored_inline
from service.api.documents import document_thread, stored_network
from service.api.media import BINARY, VerdictFormat, wants_junit
from service.api.problems import WORK_PROBLEMS, Problem, documented
from service.api.public import evaluation_public
from service.api.routes.testcases import check_controller
from service.api.schemas import (
    MAX_OFFSET,
    Controller,
    EvaluationCreate,
    EvaluationPage,
    EvaluationPublic,
)
from service.api.state import State, Token, json_answer
from service.core.checker.verdict import Verdict
from service.core.sim.controllers import BUILT_IN, controller_names
from service.core.sumo.rss_guard import RSS_SUFFIX
from service.store import DRIVE_COLUMNS, EvaluationRecord

router = APIRouter(tags=["evaluations"], route_class=OffLoopValidation)
JUNIT = "application/xml"


def junit_response(status: int) -> dict[int | str, dict[str, Any]]:
    """The evaluation as JSON (the response model), or as JUnit XML when asked."""
    return {
        status: {
            "content": {"application/json": {}, JUNIT: {"schema": BINARY}},
            "description": "the evaluation; JUnit XML with Accept: application/xml or "
            "?format=junit",
        }
    }


def _answer(record: EvaluationRecord, junit: bool) -> Response:
    if junit:
        return Response(Verdict.from_dict(record.verdict).to_junit(), media_type=JUNIT)
    return json_answer(evaluation_public(record))


@router.get("/controllers", operation_id="list_controllers", tags=["evaluations"])
async def list_controllers() -> list[Controller]:
    """The ego controllers installed on this server."""
    return [Controller(name=n, description=_about(n)) for n in controller_names()]


def _about(name: str) -> str:
    """A controller's description: the built-in's, "plug-in", and under the RSS guard
    (with CARLA's RSS dynamics: the API takes no others)."""
    inner = name.removesuffix(RSS_SUFFIX)
    about = BUILT_IN[inner].about if inner in BUILT_IN else "plug-in"
    return about if inner == name else f"{about}, under the RSS guard (CARLA's RSS dynamics)"


@router.post(
    "/evaluations",
    operation_id="create_evaluation",
    status_code=status.HTTP_201_CREATED,
    dependencies=[Token],
    response_model=EvaluationPublic,
    responses={**junit_response(201), **documented(406, *WORK_PROBLEMS)},
)
async def create_evaluation(
    state: State,
    request: Request,
    body: EvaluationCreate,
    format: VerdictFormat = None,
) -> Any:
    """Replay a test-case in SUMO with a controller driving the ego, and judge it."""
    junit = wants_junit(format, request.headers.get("accept"))
    check_controller(body.controller)
    budget = body.budget or state.settings.evaluate_budget
    if budget > state.settings.max_budget:
        raise Problem(
            422,
            f"budget {budget:g} s exceeds the server's limit of {state.settings.max_budget:g} s",
        )
    started = time.monotonic()

    def base() -> tuple[str, str, Path]:
        record = stored_inline(state.store, body.testcase)
        if record is None:
            record = state.testcase_named_in_body(str(body.testcase_id))
        network = stored_network(record.document)
        return record.id, record.document, state.store.network_file_of(network)

    testcase, document, network_file = await document_thread(base)
    result = await state.run(
        "evaluate",
        worker.evaluate,
        (document, network_file, state.cache_dir, body.controller, budget),
        budget + state.settings.work_budget,
        started,
    )

    def stored() -> Response:
        kept = state.store.add_evaluation(
            testcase, body.controller, result["verdict"], result["seconds"], drive=result["drive"]
        )
        answer = _answer(kept, junit)
        answer.status_code = status.HTTP_201_CREATED
        answer.headers["Location"] = f"/evaluations/{kept.id}"
        return answer

    return await asyncio.to_thread(stored)


@router.get("/evaluations", operation_id="list_evaluations")
async def list_evaluations(
    state: State,
    testcase: Annotated[str | None, Query(description="only of this test-case")] = None,
    limit: Annotated[int, Query(ge=1, le=200)] = 50,
    offset: Annotated[int, Query(ge=0, le=MAX_OFFSET)] = 0,
) -> EvaluationPage:
    """List stored evaluations, newest first."""
    page = await asyncio.to_thread(state.store.list_evaluations, testcase, limit, offset)
    following = None
    if offset + limit < page.total:
        where = f"testcase={testcase}&" if testcase else ""
        following = f"/evaluations?{where}limit={limit}&offset={offset + limit}"
    return EvaluationPage(
        items=[evaluation_public(r) for r in page.items],
        total=page.total,
        limit=limit,
        offset=offset,
        next=following,
    )


@router.get(
    "/evaluations/{evaluation}",
    operation_id="get_evaluation",
    response_model=EvaluationPublic,
    responses={**junit_response(200), **documented(406)},
)
async def get_evaluation(
    state: State,
    request: Request,
    evaluation: str,
    format: VerdictFormat = None,
) -> Any:
    """One evaluation: verdict and reasons, or JUnit XML."""
    junit = wants_junit(format, request.headers.get("accept"))

    def answer() -> Response:
        record = state.store.evaluation(evaluation)
        if record is None:
            raise Problem(404, f"no evaluation {evaluation!r}; GET /evaluations lists them")
        return _answer(record, junit)

    return await asyncio.to_thread(answer)


@router.get(
    "/evaluations/{evaluation}/drive",
    operation_id="get_evaluation_drive",
    response_model=dict[str, Any],
)
async def get_evaluation_drive(state: State, evaluation: str) -> Response:
    """The ego's drive in the evaluation: rows of t, x, y, heading, speed, distance (the
    centre of its footprint; SUMO's coordinates and headings); empty when it was evaluated
    before drives were kept."""

    def found() -> Response:
        if state.store.evaluation(evaluation) is None:
            raise Problem(404, f"no evaluation {evaluation!r}; GET /evaluations lists them")
        # the stored rows spliced in as they are (the same bytes FastAPI would write)
        head = json.dumps({"evaluation": evaluation, "columns": DRIVE_COLUMNS, "trajectory": []},
                          ensure_ascii=False, separators=(",", ":"))  # fmt: skip
        rows = state.store.drive_text(evaluation) or "[]"
        body = f"{head[: -len('[]}')]}{rows}}}".encode()
        return Response(body, media_type="application/json")

    return await asyncio.to_thread(found)
