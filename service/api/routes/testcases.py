"""/testcases: create ego-only test-cases, list, fetch, lineage, SUMO bundle and picture."""

from __future__ import annotations

import asyncio
import time
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any

from fastapi import APIRouter, Query, Request, Response, status
from fastapi.responses import FileResponse, JSONResponse

from service.api import worker
from service.api.bodies import OffLoopValidation
from service.api.documents import (
    document_thread,
    pieces_of,
    stored_network,
    streamed,
    testcase_body,
)
from service.api.media import (
    IMAGE_RESPONSES,
    PictureFormat,
    cached_file,
    picture_format,
    write_atomically,
)
from service.api.problems import WORK_PROBLEMS, Problem, documented
from service.api.public import testcase_summary
from service.api.schemas import (
    MAX_OFFSET,
    Lineage,
    TestCaseCreate,
    TestCasePage,
    TestCasePublic,
)
from service.api.state import AppState, State, Token
from service.core.errors import InvalidInput, choices
from service.core.export import Flavour
from service.core.sim.controllers import controller_names
from service.core.testcase import NetworkRef, check_samples, parse_testcase
from service.jobs import tasks
from service.store import TestCaseRecord

router = APIRouter(prefix="/testcases", tags=["testcases"], route_class=OffLoopValidation)


@router.post(
    "",
    operation_id="create_testcase",
    status_code=status.HTTP_201_CREATED,
    dependencies=[Token],
    responses=documented(*WORK_PROBLEMS),
    response_model=TestCasePublic,
)
async def create_testcase(state: State, body: TestCaseCreate) -> Response:
    """Create an ego-only test-case on a network."""
    check_samples(body.duration, body.timestep, state.settings.max_samples)
    network = await asyncio.to_thread(state.network_named_in_body, body.network)
    junction, control = network.junction_and_control(
        body.junction, body.control.value if body.control else None
    )
    request = body.model_dump(exclude={"network", "junction", "control", "params"})
    request["params"] = None if body.params is None else body.params.model_dump()
    request.update(junction=junction, control=control)
    document = await state.run(
        "create",
        tasks.create_testcase,
        (
            await asyncio.to_thread(state.store.network_file, network.id),
            NetworkRef(ref=network.id, sha256=network.sha256),
            state.cache_dir,
            request,
        ),
        state.settings.work_budget,
        time.monotonic(),
    )

    def stored() -> Response:
        record = state.store.add_testcase(parse_testcase(document))
        location = {"Location": f"/testcases/{record.id}"}
        return streamed(testcase_body(record), status.HTTP_201_CREATED, location)

    return await document_thread(stored)


@router.get("", operation_id="list_testcases")
async def list_testcases(
    state: State,
    network: Annotated[str | None, Query(description="only on this network")] = None,
    parent: Annotated[str | None, Query(description="only extensions of this test-case")] = None,
    roots: Annotated[bool, Query(description="only test-cases without a parent")] = False,
    limit: Annotated[int, Query(ge=1, le=200)] = 50,
    offset: Annotated[int, Query(ge=0, le=MAX_OFFSET)] = 0,
) -> TestCasePage:
    """List stored test-cases, newest first."""
    page = await asyncio.to_thread(
        state.store.list_testcases, network, parent, roots, limit, offset
    )
    following = None
    if offset + limit < page.total:
        query = "&".join(
            f"{key}={value}"
            for key, value in (("network", network), ("parent", parent))
            if value is not None
        )
        following = (
            f"/testcases?{query + '&' if query else ''}limit={limit}&offset={offset + limit}"
        )
        if roots:
            following += "&roots=true"
    return TestCasePage(
        items=[testcase_summary(r) for r in page.items],
        total=page.total,
        limit=limit,
        offset=offset,
        next=following,
    )


@router.get("/{testcase}", operation_id="get_testcase", response_model=TestCasePublic)
async def get_testcase(state: State, testcase: str) -> Response:
    """One test-case with its document and links."""

    def answer() -> Response:
        return streamed(testcase_body(state.testcase_or_404(testcase)))

    return await document_thread(answer)


@router.get(
    "/{testcase}/document",
    operation_id="get_testcase_document",
    response_class=JSONResponse,
    responses={200: {"content": {"application/json": {}}, "description": "the document"}},
)
async def get_testcase_document(state: State, testcase: str) -> Response:
    """The bare test-case document, as `scengen` commands read it."""

    def answer() -> Response:
        record = state.testcase_or_404(testcase)
        disposition = {"Content-Disposition": f'attachment; filename="{record.id}.json"'}
        return streamed(pieces_of(record.document), headers=disposition)

    return await document_thread(answer)


@router.delete(
    "/{testcase}",
    operation_id="delete_testcase",
    status_code=status.HTTP_204_NO_CONTENT,
    dependencies=[Token],
    responses=documented(409),
)
async def delete_testcase(state: State, testcase: str) -> None:
    """Delete a test-case without extensions, and its evaluations."""

    def delete() -> None:
        head_or_404(state, testcase)
        children = state.store.children(testcase)
        if children:
            raise Problem(
                409,
                f"{len(children)} extension(s) descend from {testcase!r}; delete them first",
                children=[c.id for c in children],
            )
        state.store.delete_testcase(testcase)

    await asyncio.to_thread(delete)


@router.get("/{testcase}/lineage", operation_id="get_lineage")
async def get_lineage(state: State, testcase: str) -> Lineage:
    """Ancestors (parent first) and children of a test-case."""

    def lineage() -> Lineage:
        head_or_404(state, testcase)
        return Lineage(
            id=testcase,
            ancestors=[testcase_summary(r) for r in state.store.ancestors(testcase)],
            children=[testcase_summary(r) for r in state.store.children(testcase)],
        )

    return await asyncio.to_thread(lineage)


@router.get(
    "/{testcase}/bundle",
    operation_id="get_bundle",
    response_class=Response,
    responses={
        200: {"content": {"application/zip": {}}, "description": "the SUMO bundle"},
        **documented(*WORK_PROBLEMS),
    },
)
async def get_bundle(state: State, testcase: str) -> Response:
    """The SUMO export as a zip: network, routes, FCD of the non-egos, .sumocfg, README."""
    return await _export(state, testcase, None)


@router.get(
    "/{testcase}/openscenario",
    operation_id="get_openscenario",
    response_class=Response,
    responses={
        200: {
            "content": {"application/zip": {}},
            "description": "testcase.xodr, testcase.xosc, one .xosc per certificate, "
            "verdict-rules.md",
        },
        **documented(*WORK_PROBLEMS),
    },
)
async def get_openscenario(
    state: State,
    testcase: str,
    flavour: Annotated[
        Flavour,
        Query(
            description="asam: OpenSCENARIO 1.2, a vertex per time step; carla: 1.0 for "
            "CARLA's ScenarioRunner, 20 Hz vertices, the CARLA town by name"
        ),
    ] = "asam",
) -> Response:
    """The ASAM OpenSCENARIO XML export on an ASAM OpenDRIVE network, as a zip: the non-egos
    on their trajectories, the ego (`type = ego_vehicle`) left to the system under test; at a
    signalized junction, a signal head per link in the network and the test-case's program
    as a TrafficSignalController (README, the OpenSCENARIO export)."""
    return await _export(state, testcase, flavour)


async def _export(state: State, testcase: str, flavour: str | None) -> Response:
    """The SUMO bundle (``flavour`` None) or the OpenSCENARIO export as a zip, cached."""
    record = await asyncio.to_thread(head_or_404, state, testcase)
    key = "bundle.zip" if flavour is None else f"openscenario-{flavour}.zip"
    name = f"{record.id}.zip" if flavour is None else f"{record.id}-openscenario.zip"

    async def work() -> bytes:
        document, network_file = await document_thread(document_and_network, state, testcase)
        args: tuple[Any, ...] = (document, network_file, state.cache_dir)
        function: Callable[..., bytes] = tasks.bundle
        if flavour is not None:
            args, function = (*args, flavour), tasks.openscenario
        work = "bundle" if flavour is None else "openscenario"
        content: bytes = await state.run(
            work, worker.on_file, (function, *args), state.settings.work_budget, time.monotonic()
        )
        return content

    path = await cached_file(state, f"testcases/{record.id}/{key}", work)
    return FileResponse(
        path,
        media_type="application/zip",
        headers={"Content-Disposition": f'attachment; filename="{name}"'},
    )


def head_or_404(state: AppState, testcase: str) -> TestCaseRecord:
    """The stored test-case's record without its document (in a thread)."""
    record = state.store.testcase_head(testcase)
    if record is None:
        raise Problem(404, f"no test-case {testcase!r}; GET /testcases lists them")
    return record


def document_and_network(state: AppState, testcase: str) -> tuple[Path, Path]:
    """A file with a stored test-case's document, and its network's file (in a thread): a
    worker gets the document's path, not 30 MB to pickle and pipe on the event loop."""
    record = state.testcase_or_404(testcase)
    network = state.store.network_file_of(stored_network(record.document))
    path = state.cache_dir / "artifacts" / "testcases" / record.id / "document.json"
    if not path.is_file():  # a content address: the file never changes once written
        write_atomically(path, record.document.encode())
    return path, network


@router.get(
    "/{testcase}/plot",
    operation_id="plot_testcase",
    response_class=Response,
    responses={**IMAGE_RESPONSES, **documented(406, *WORK_PROBLEMS)},
)
async def plot_testcase(
    state: State,
    request: Request,
    testcase: str,
    format: PictureFormat = None,
    controller: Annotated[
        str | None, Query(description="also replay this controller and show its verdict")
    ] = None,
) -> Response:
    """A picture of the test-case: paths, certificates, and a time-distance panel."""
    record = await asyncio.to_thread(head_or_404, state, testcase)
    suffix, media = picture_format(format, request.headers.get("accept"))
    if controller is not None:
        check_controller(controller)
    budget = state.settings.work_budget + (state.settings.evaluate_budget if controller else 0)

    async def work() -> bytes:
        document, network_file = await document_thread(document_and_network, state, testcase)
        content: bytes = await state.run(
            "plot",
            worker.on_file,
            (
                tasks.plot_testcase,
                document,
                network_file,
                state.cache_dir,
                suffix,
                controller,
                state.settings.evaluate_budget,
            ),
            budget,
            time.monotonic(),
        )
        return content

    path = await cached_file(
        state, f"testcases/{record.id}/plot-{controller or 'testcase'}.{suffix}", work
    )
    return FileResponse(path, media_type=media)


def check_controller(name: str) -> None:
    """Only installed controllers by name: the server never imports a module a client names."""
    known = controller_names()
    if name not in known:
        raise InvalidInput(
            f"controller {name!r} is not installed here; valid choices: {choices(known)}"
        )
