"""/networks: the bundled networks and uploads, their junctions, descriptions and pictures."""

from __future__ import annotations

import asyncio
import hashlib
import json
import time
from pathlib import Path
from typing import Annotated, Any
from urllib.parse import quote

from fastapi import APIRouter, File, Form, Query, Request, Response, UploadFile, status
from fastapi.responses import FileResponse, JSONResponse

from service.api import worker
from service.api.bodies import OFF_LOOP_BYTES
from service.api.media import IMAGE_RESPONSES, PictureFormat, cached, picture_format
from service.api.problems import WORK_PROBLEMS, Problem, documented
from service.api.public import network_public
from service.api.schemas import JunctionSummary, Links, NetworkPublic, RouteText
from service.api.state import AppState, State, Token
from service.core.errors import InvalidInput, UnknownJunction
from service.core.network import ControlType
from service.core.network.convert import source_format
from service.jobs import tasks
from service.store import NetworkRecord, network_id, safe_filename

MAX_ID_LENGTH = 1000  # a junction id in a path

GUESS_CROSSINGS = (
    "the network with guessed sidewalks and crossings (netconvert --sidewalks.guess "
    "--crossings.guess; car lanes' indices move up by one), as a test-case with "
    "crossings_guessed uses it"
)


router = APIRouter(prefix="/networks", tags=["networks"])
CONTROLS = [c.value for c in ControlType]
CONTROLS_FIELD = (
    'JSON object junction -> control type, e.g. {"J1": "allway_stop"}; control types: '
    + ", ".join(CONTROLS)
)


@router.get("", operation_id="list_networks")
async def list_networks(state: State) -> list[NetworkPublic]:
    """List the bundled and uploaded networks."""
    found = await asyncio.to_thread(state.store.list_networks)
    return [network_public(record) for record in found]


@router.post(
    "",
    operation_id="upload_network",
    status_code=status.HTTP_201_CREATED,
    dependencies=[Token],
    responses=documented(*WORK_PROBLEMS),
)
async def upload_network(
    state: State,
    response: Response,
    file: Annotated[
        UploadFile,
        File(description="a SUMO .net.xml, an OpenDRIVE .xodr or an OpenStreetMap .osm"),
    ],
    controls: Annotated[str, Form(description=CONTROLS_FIELD)] = "{}",
) -> NetworkPublic:
    """Upload a network, optionally overriding junctions' control types."""
    content = await file.read(state.settings.max_upload_bytes + 1)
    if len(content) > state.settings.max_upload_bytes:
        raise Problem(413, f"the network exceeds {state.settings.max_upload_mb:g} MB")
    overrides = _parse_controls(controls)
    filename = file.filename or "network.net.xml"
    kind = source_format(filename)
    if len(content) <= OFF_LOOP_BYTES:  # a small file is checked here, at once
        _refuse(await asyncio.to_thread(worker.xml_refusal, content, kind))
    ident = await asyncio.to_thread(network_id, filename, content, overrides)
    record = await asyncio.to_thread(state.store.network, ident)
    if record is None and kind is not None:  # a map: converted, stored with its original
        converted = await _run_staged(
            state, tasks.convert_upload, f"map{Path(filename).suffix.lower()}", content,
            overrides, kind,
        )  # fmt: skip
        record = await asyncio.to_thread(
            state.store.add_network, f"{Path(filename).name}.net.xml", converted, overrides,
            (kind, filename, content),
        )  # fmt: skip
    if record is None:
        await _run_staged(
            state, tasks.check_controls, safe_filename(filename), content, overrides, kind
        )
        record = await asyncio.to_thread(state.store.add_network, filename, content, overrides)
    response.headers["Location"] = f"/networks/{record.id}"
    return network_public(record)


def _refuse(refusal: str | None) -> None:
    if refusal is not None:
        raise Problem(400, refusal)


async def _run_staged(
    state: AppState,
    task: Any,
    name: str,
    content: bytes,
    overrides: dict[str, str],
    kind: str | None,
) -> Any:
    """``task(file, overrides, cache_dir)`` in a worker on the upload staged as ``name``,
    after the check of its XML (there too: parsing a large file holds the GIL)."""
    staged = state.cache_dir / "uploads" / str(time.monotonic_ns()) / name
    await asyncio.to_thread(_stage, staged, content)
    try:
        outcome, value = await state.run(
            "upload",
            worker.checked_upload,
            (task, staged, overrides, state.cache_dir, kind),
            state.settings.work_budget,
            time.monotonic(),
        )
    finally:
        await asyncio.to_thread(_unstage, staged)
    _refuse(value if outcome == "refused" else None)
    return value


@router.get(
    "/{network}/source",
    operation_id="get_network_source",
    response_class=Response,
    responses={
        200: {"content": {"application/xml": {}}, "description": "the .xodr or .osm uploaded"},
        **documented(404),
    },
)
async def get_network_source(state: State, network: str) -> Response:
    """The original file of a network imported from OpenDRIVE or OpenStreetMap (its SUMO
    network, converted by netconvert, is at /networks/{id}/file)."""
    record = await asyncio.to_thread(state.network_or_404, network)
    found = await asyncio.to_thread(state.store.network_source, record.id)
    if found is None:
        raise Problem(404, f"network {network!r} was uploaded as a SUMO network, not imported")
    name, content = found
    return Response(
        content,
        media_type="application/xml",
        headers={"Content-Disposition": f'attachment; filename="{name}"'},
    )


@router.get("/{network}", operation_id="get_network")
async def get_network(state: State, network: str) -> NetworkPublic:
    """One network."""
    return network_public(await asyncio.to_thread(state.network_or_404, network))


@router.get(
    "/{network}/file",
    operation_id="get_network_file",
    response_class=Response,
    responses={200: {"content": {"application/xml": {}}, "description": "the .net.xml"}},
)
async def get_network_file(state: State, network: str) -> Response:
    """The network's .net.xml as uploaded (`scengen ... --network FILE` takes it)."""
    record = await asyncio.to_thread(state.network_or_404, network)
    path = await asyncio.to_thread(state.store.network_file, record.id)
    return FileResponse(
        path,
        media_type="application/xml",
        headers={"Content-Disposition": f'attachment; filename="{record.filename}"'},
    )


@router.delete(
    "/{network}",
    operation_id="delete_network",
    status_code=status.HTTP_204_NO_CONTENT,
    dependencies=[Token],
    responses=documented(409),
)
async def delete_network(state: State, network: str) -> None:
    """Delete an uploaded network that no stored test-case uses."""

    def delete() -> None:
        record = state.network_or_404(network)
        if record.bundled:
            raise Problem(409, f"{network!r} is bundled with the service and cannot be deleted")
        used = state.store.count_testcases_on(network)
        if used:
            raise Problem(409, f"{used} stored test-case(s) use {network!r}; delete them first")
        state.store.delete_network(network)

    await asyncio.to_thread(delete)


@router.get(
    "/{network}/junctions", operation_id="list_junctions", responses=documented(*WORK_PROBLEMS)
)
async def list_junctions(state: State, network: str) -> list[JunctionSummary]:
    """The network's junctions with three or more approaches."""
    record, path = await asyncio.to_thread(_network_and_file, state, network)
    found = await cached(
        state,
        f"networks/{record.id}/junctions.json",
        lambda: state.run(
            "junctions", tasks.list_junctions, (path,), state.settings.work_budget, time.monotonic()
        ),
        json_cache=True,
    )
    supported = set(CONTROLS)
    return [
        JunctionSummary(
            id=item["id"],
            type=item["type"],
            control=record.controls.get(item["id"], item["type"]),
            supported=record.controls.get(item["id"], item["type"]) in supported,
            approaches=item["approaches"],
            links=Links(
                self=f"/networks/{record.id}/junctions/{quote(item['id'], safe='')}",
                plot=f"/networks/{record.id}/junctions/{quote(item['id'], safe='')}/plot",
            ),
        )
        for item in found
    ]


@router.get(
    "/{network}/junctions/{junction}",
    operation_id="describe_junction",
    responses=documented(*WORK_PROBLEMS),
)
async def describe_junction(
    state: State,
    network: str,
    junction: str,
    guess_crossings: Annotated[bool, Query(description=GUESS_CROSSINGS)] = False,
) -> JSONResponse:
    """The intersection: forks, exits, routes, conflicts and right-of-way relations, and
    the walks over its pedestrian crossings."""
    record, path = await asyncio.to_thread(_network_and_file, state, network)
    control = record.controls.get(junction)
    description = await _junction_work(
        state,
        record,
        junction,
        "description-crossings.json" if guess_crossings else "description.json",
        tasks.describe_junction,
        (path, junction, control, state.cache_dir, guess_crossings),
    )
    return JSONResponse(description)


@router.get(
    "/{network}/junctions/{junction}/plot",
    operation_id="plot_junction",
    response_class=Response,
    responses={**IMAGE_RESPONSES, **documented(406, *WORK_PROBLEMS)},
)
async def plot_junction(
    state: State,
    request: Request,
    network: str,
    junction: str,
    route: Annotated[list[RouteText], Query(description="routes to highlight")] = [],  # noqa: B006
    format: PictureFormat = None,
) -> Response:
    """A picture of the junction: connecting lanes by turn, forks, highlighted routes."""
    record, path = await asyncio.to_thread(_network_and_file, state, network)
    suffix, media = picture_format(format, request.headers.get("accept"))
    chosen = sorted(set(route))
    key = hashlib.sha256(json.dumps(chosen).encode()).hexdigest()[:16] if chosen else "all"
    content = await _junction_work(
        state,
        record,
        junction,
        f"plot-{key}.{suffix}",
        tasks.plot_junction,
        (path, junction, record.controls.get(junction), state.cache_dir, chosen, suffix),
    )
    return Response(content, media_type=media)


@router.get(
    "/{network}/junctions/{junction}/geometry",
    operation_id="get_junction_geometry",
    responses=documented(*WORK_PROBLEMS),
)
async def get_junction_geometry(
    state: State,
    network: str,
    junction: str,
    control: Annotated[
        ControlType | None, Query(description="a control type override (default: the stored)")
    ] = None,
    guess_crossings: Annotated[bool, Query(description=GUESS_CROSSINGS)] = False,
) -> JSONResponse:
    """The junction's shapes for drawing: roads, area, paths, stop lines, signal heads,
    pedestrian crossings and walking areas (m)."""
    record = await asyncio.to_thread(state.network_or_404, network)
    chosen = control.value if control else record.controls.get(junction)
    return JSONResponse(await junction_geometry(state, record, junction, chosen, guess_crossings))


async def junction_geometry(
    state: AppState,
    record: NetworkRecord,
    junction: str,
    control: str | None,
    guess_crossings: bool = False,
) -> Any:
    """The junction's shapes under ``control`` (None: the map's own), with guessed
    crossings or not, computed once per network, junction, control and that choice, then
    answered from the cache."""
    path = await asyncio.to_thread(state.store.network_file, record.id)
    name = f"geometry-{control or 'own'}{'-crossings' if guess_crossings else ''}.json"
    return await _junction_work(
        state, record, junction, name, tasks.junction_geometry,
        (path, junction, control, state.cache_dir, guess_crossings),
    )  # fmt: skip


async def _junction_work(
    state: State, record: NetworkRecord, junction: str, name: str, function: Any, args: Any
) -> Any:
    if len(junction) > MAX_ID_LENGTH or any(ord(c) < 32 for c in junction) or not junction:
        raise UnknownJunction(
            f"junction {junction[:80]!r}{'...' if len(junction) > 80 else ''} is not a "
            f"junction id (ids are 1 to {MAX_ID_LENGTH} printable characters); "
            f"GET /networks/{record.id}/junctions lists them"
        )
    # the cache folder is named by a hash of the id: no client-chosen string becomes a path
    folder = hashlib.sha256(junction.encode()).hexdigest()[:16]
    return await cached(
        state,
        f"networks/{record.id}/junction-{folder}/{name}",
        lambda: state.run("junction", function, args, state.settings.work_budget, time.monotonic()),
        json_cache=name.endswith(".json"),
    )


def _network_and_file(state: AppState, network: str) -> tuple[NetworkRecord, Path]:
    record = state.network_or_404(network)
    return record, state.store.network_file(record.id)


def _stage(path: Path, content: bytes) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(content)


def _unstage(path: Path) -> None:
    path.unlink(missing_ok=True)
    path.parent.rmdir()


def _parse_controls(text: str) -> dict[str, str]:
    try:
        value = json.loads(text or "{}")
    except json.JSONDecodeError as error:
        raise Problem(400, f"controls is not valid JSON: {error}") from None
    except RecursionError:
        raise Problem(400, "controls is nested too deeply to be junction -> control") from None
    if not isinstance(value, dict) or not all(
        isinstance(k, str) and isinstance(v, str) for k, v in value.items()
    ):
        raise InvalidInput('controls must be a JSON object of strings, e.g. {"J1": "allway_stop"}')
    for junction, control in value.items():
        if control not in CONTROLS:
            raise InvalidInput(
                f"controls: {control!r} for junction {junction!r} is not a control type; "
                f"valid choices: {', '.join(CONTROLS)}"
            )
    return dict(value)
