"""/jobs: batches for CI pipelines, run by the local pool or Celery workers."""

from __future__ import annotations

import asyncio
import time
from typing import Annotated, Any, Literal, get_args

from fastapi import APIRouter, Header, Query, Response, status
from fastapi.responses import Response as PlainResponse

from service.api.bodies import OffLoopValidation
from service.api.documents import document_thread, stored_network
from service.api.problems import WORK_PROBLEMS, Problem, documented
from service.api.public import job_public, store_fetch
from service.api.routes.networks import junction_geometry
from service.api.schemas import MAX_OFFSET, JobPage, JobPublic
from service.api.state import AppState, State, Token, json_answer
from service.core.campaign.outcome import campaign_junit
from service.core.export import Flavour
from service.jobs import tasks
from service.jobs.batch import Batch, CampaignItem
from service.jobs.campaign_steps import outcome_of
from service.jobs.junit import job_junit
from service.jobs.references import check_references
from service.jobs.size import check_job_size
from service.jobs.store import IdempotencyConflict, JobRecord, JobStore
from service.pictures.report import campaign_paths, campaign_title, report_html

router = APIRouter(prefix="/jobs", tags=["jobs"], route_class=OffLoopValidation)
JobState = Literal["queued", "running", "succeeded", "failed", "cancelled"]
STATES: tuple[str, ...] = get_args(JobState)  # the store's: a test holds them equal


def _jobs(state: AppState) -> JobStore:
    return JobStore(state.store)


def _job_or_404(state: AppState, ident: str) -> JobRecord:
    job = _jobs(state).job(ident)
    if job is None:
        raise Problem(404, f"no job {ident!r}; GET /jobs lists them")
    return job


@router.post(
    "",
    operation_id="create_job",
    status_code=status.HTTP_202_ACCEPTED,
    dependencies=[Token],
    response_model=JobPublic,
    responses={
        200: {"model": JobPublic, "description": "the job that this Idempotency-Key made"},
        **documented(409),
    },
)
async def create_job(
    state: State,
    batch: Batch,
    idempotency_key: Annotated[
        str | None,
        Header(max_length=255, description="the same key and batch: the same job, not a new one"),
    ] = None,
) -> Response:
    """Submit a batch; it runs in the background (202, Location: the job).

    A batch that names a test-case id, a network or a controller this server does not have,
    or an inline test-case it cannot take, is refused at once (422 `invalid-input`, its
    `errors` naming each, with the valid choices)."""
    limit = state.settings.max_budget
    for position, item in enumerate(batch.items):
        budgets = {"budget": item.budget}
        if isinstance(item, CampaignItem):
            budgets["budget_per_level"] = item.budget_per_level
        for field, budget in budgets.items():
            if budget is not None and budget > limit:
                raise Problem(
                    422,
                    f"items[{position}].{field} {budget:g} s exceeds the server's limit of "
                    f"{limit:g} s",
                )

    await _check_size(state, batch)

    def create() -> Response:
        jobs = _jobs(state)
        if idempotency_key is None or jobs.by_key(idempotency_key) is None:
            check_references(batch, state.store)  # a repeated key gets its job back as it was
        try:
            job, created = jobs.create(batch, idempotency_key)
        except IdempotencyConflict:
            raise Problem(
                409, f"Idempotency-Key {idempotency_key!r} was used with another batch"
            ) from None
        code = status.HTTP_202_ACCEPTED if created else status.HTTP_200_OK
        return json_answer(job_public(state.store, job), code, f"/jobs/{job.id}")

    answer = await asyncio.to_thread(create)
    state.dispatcher.nudge()
    return answer


async def _check_size(state: AppState, batch: Batch) -> None:
    """InvalidInput (422) when ``batch`` runs more than ``SCENGEN_MAX_JOB_STEPS`` steps
    (service.jobs.size). An ``all_egos`` campaign counts the routes of its junction, read in
    a worker as the campaign reads them: an upper bound of the routes its egos take."""
    routes: dict[int, int] = {}  # id() of an all_egos item -> its junction's routes
    for item in batch.items:
        if isinstance(item, CampaignItem) and item.all_egos:
            record = await asyncio.to_thread(state.store.network, item.network)
            if record is None:
                continue  # check_references names it
            junction, control = record.junction_and_control(item.junction, item.control)
            path = await asyncio.to_thread(state.store.network_file, record.id)
            description = await state.run(
                "junction", tasks.describe_junction, (path, junction, control, state.cache_dir),
                state.settings.work_budget, time.monotonic(),
            )  # fmt: skip
            routes[id(item)] = len(description["routes"])
    check_job_size(batch, lambda item: routes.get(id(item), 1), state.settings.max_job_steps)


@router.get("", operation_id="list_jobs")
async def list_jobs(
    state: State,
    job_state: Annotated[JobState | None, Query(alias="state", description="only these")] = None,
    limit: Annotated[int, Query(ge=1, le=200)] = 20,
    offset: Annotated[int, Query(ge=0, le=MAX_OFFSET)] = 0,
) -> JobPage:
    """List jobs, newest first."""

    def page() -> JobPage:
        found = _jobs(state).list_jobs(job_state, limit, offset)
        following = None
        if offset + limit < found.total:
            where = f"state={job_state}&" if job_state else ""
            following = f"/jobs?{where}limit={limit}&offset={offset + limit}"
        return JobPage(
            items=[job_public(state.store, j) for j in found.items],
            total=found.total, limit=limit, offset=offset, next=following,
        )  # fmt: skip

    return await asyncio.to_thread(page)


@router.get("/{job}", operation_id="get_job", response_model=JobPublic)
async def get_job(state: State, job: str) -> Response:
    """A job: state, per-item progress, results, timestamps."""
    return await asyncio.to_thread(
        lambda: json_answer(job_public(state.store, _job_or_404(state, job)))
    )


@router.delete(
    "/{job}",
    operation_id="cancel_job",
    status_code=status.HTTP_202_ACCEPTED,
    dependencies=[Token],
    response_model=JobPublic,
)
async def cancel_job(state: State, job: str) -> Response:
    """Cancel a job: queued items never start, running ones are stopped."""

    def cancel() -> Response:
        _job_or_404(state, job)
        _jobs(state).cancel(job)
        return json_answer(
            job_public(state.store, _job_or_404(state, job)), status.HTTP_202_ACCEPTED
        )

    answer = await asyncio.to_thread(cancel)
    state.dispatcher.nudge()
    return answer


@router.get(
    "/{job}/junit",
    operation_id="get_job_junit",
    response_class=PlainResponse,
    responses={200: {"content": {"application/xml": {}}, "description": "JUnit XML"}},
)
async def get_job_junit(state: State, job: str) -> Response:
    """The job so far as one JUnit XML report.

    A test case per evaluation (`NAME (ID) / CONTROLLER`, the name saying the level), a
    campaign's own cases (chain and level in each name), and an error for every item that
    failed, with its reason."""
    found = await asyncio.to_thread(_job_or_404, state, job)
    report = await asyncio.to_thread(job_junit, state.store, found)
    return Response(report, media_type="application/xml")


def _campaign_or_404(state: AppState, job: str) -> dict[str, Any]:
    _job_or_404(state, job)
    try:
        return outcome_of(state.store, job)
    except KeyError:
        raise Problem(
            404,
            f"job {job!r} has no campaign outcome (no campaign item, or none has finished "
            "a level yet)",
        ) from None


@router.get("/{job}/campaign", operation_id="get_job_campaign")
async def get_job_campaign(state: State, job: str) -> dict[str, Any]:
    """The campaign's outcome so far (schema scengen/campaign/2).

    Per level its distinct test-cases and their diversity (orders of events, rules the
    certificates break, the new cars' arrival and entry times); per level and controller
    the failure share over the distinct test-cases with its Wilson 95 % interval and the
    distribution of each criticality measure; whether criticality grows with the level
    per controller, chains with their first failing levels, rule coverage."""
    return await asyncio.to_thread(_campaign_or_404, state, job)


@router.get(
    "/{job}/campaign/junit",
    operation_id="get_job_campaign_junit",
    response_class=PlainResponse,
    responses={200: {"content": {"application/xml": {}}, "description": "JUnit XML"}},
)
async def get_job_campaign_junit(state: State, job: str) -> Response:
    """The campaign as JUnit XML: a test case per chain, level and controller.

    Each test case has its verdict's criticality measures as properties."""
    outcome = await asyncio.to_thread(_campaign_or_404, state, job)
    return Response(campaign_junit(outcome), media_type="application/xml")


@router.get(
    "/{job}/campaign/report",
    operation_id="get_job_campaign_report",
    response_class=PlainResponse,
    responses={200: {"content": {"text/html": {}}, "description": "the report"}},
)
async def get_job_campaign_report(state: State, job: str) -> Response:
    """The campaign's self-contained HTML report (`scengen report`), to save and publish."""
    outcome = await asyncio.to_thread(_campaign_or_404, state, job)
    plan = outcome["plan"]
    record = await asyncio.to_thread(state.network_or_404, plan["network"])
    geometry = await junction_geometry(state, record, plan["junction"], plan["control"])

    def build() -> str:
        try:
            data = campaign_paths(job, outcome, store_fetch(state.store, lambda *_: geometry))
        except KeyError as missing:  # a test-case of the campaign was deleted since
            raise Problem(404, f"the campaign's report needs what is gone: {missing}") from None
        return report_html(job, data, campaign_title(outcome))

    return Response(await asyncio.to_thread(build), media_type="text/html")


async def _zip_of(state: State, job: str, flavour: str | None, filename: str) -> Response:
    """A zip of every test-case the job made, a folder each: the SUMO bundles, or with
    ``flavour`` the OpenSCENARIO exports."""

    def made_by() -> list[tuple[str, str, Any]]:
        found = _job_or_404(state, job)
        records = [
            r for i in found.items for r in map(state.store.testcase, i.testcases) if r is not None
        ]
        return [
            (r.id, r.document, state.store.network_file_of(stored_network(r.document)))
            for r in records
        ]

    listed = await document_thread(made_by)
    content = await state.run(
        "bundles" if flavour is None else "openscenario", tasks.bundles,
        (listed, state.cache_dir, flavour), state.settings.work_budget, time.monotonic(),
    )  # fmt: skip
    return Response(
        content,
        media_type="application/zip",
        headers={"Content-Disposition": f'attachment; filename="{filename}"'},
    )


@router.get(
    "/{job}/bundles",
    operation_id="get_job_bundles",
    response_class=PlainResponse,
    responses={
        200: {"content": {"application/zip": {}}, "description": "the SUMO bundles"},
        **documented(*WORK_PROBLEMS),
    },
)
async def get_job_bundles(state: State, job: str) -> Response:
    """A zip with the SUMO bundle of every test-case the job made, one folder each."""
    return await _zip_of(state, job, None, f"job-{job}.zip")


@router.get(
    "/{job}/openscenario",
    operation_id="get_job_openscenario",
    response_class=PlainResponse,
    responses={
        200: {"content": {"application/zip": {}}, "description": "the OpenSCENARIO exports"},
        **documented(*WORK_PROBLEMS),
    },
)
async def get_job_openscenario(
    state: State,
    job: str,
    flavour: Annotated[Flavour, Query(description="asam (default) or carla")] = "asam",
) -> Response:
    """A zip with the OpenSCENARIO export (`GET /testcases/{id}/openscenario`) of every
    test-case the job made, one folder each."""
    return await _zip_of(state, job, flavour, f"job-{job}-openscenario.zip")
