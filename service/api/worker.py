"""The routes' calls that run in a worker process, around ``service.jobs.tasks``: each
answers in a form the server stores and sends without parsing (``service.api.documents``).

A worker parses the documents it works on anyway; here it also makes what the server
would otherwise make from them on its own process: an extension's stored form
(``stored_form``: canonical text, id, summary columns), a drive's JSON text, the check of
an uploaded network's XML. What it sends back is strings and small values, which pickle
at the speed of a copy.
"""

from __future__ import annotations

import io
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

from defusedxml import ElementTree as SafeElementTree
from defusedxml.common import DefusedXmlException

from service.core.errors import InvalidInput
from service.core.network.xml_depth import depth_refusal, too_deep
from service.core.testcase import parse_testcase


def extend(
    document: str,
    network_file: Path,
    cache_dir: Path,
    routes: list[str],
    seed: int,
    budget: float,
    start_distance: float | list[float | None] | None,
    deadline: float | None = None,
    walks: list[str] | None = None,
) -> dict[str, Any]:
    """``tasks.extend``, the new test-case in its stored form (``stored``) with the ids of
    its new road users (``new_cars``)."""
    from service.jobs import tasks
    from service.store import stored_form

    result = tasks.extend(
        document, network_file, cache_dir, routes, seed, budget, start_distance, deadline,
        walks or [],
    )  # fmt: skip
    new = parse_testcase(result.pop("document"))
    assert new.provenance is not None  # an extension always says which cars it added
    return {
        **result,
        "stored": stored_form(new),
        "new_cars": list(new.provenance["new_nonegos"]),
    }


def extend_variants(
    document: str,
    network_file: Path,
    cache_dir: Path,
    routes: list[str],
    count: int,
    seed: int,
    budget: float,
    start_distance: float | list[float | None] | None,
    deadline: float | None = None,
    walks: list[str] | None = None,
) -> dict[str, Any]:
    """``tasks.extend_variants``, each extension in its stored form with its new road users."""
    from service.jobs import tasks
    from service.store import stored_form

    result = tasks.extend_variants(
        document, network_file, cache_dir, routes, count, seed, budget, start_distance, deadline,
        walks or [],
    )  # fmt: skip
    variants = []
    for variant in result["extensions"]:
        new = parse_testcase(variant.pop("document"))
        assert new.provenance is not None
        variants.append(
            {**variant, "stored": stored_form(new), "new_cars": list(new.provenance["new_nonegos"])}
        )
    return {**result, "extensions": variants}


def evaluate(
    document: str, network_file: Path, cache_dir: Path, controller: str, budget: float
) -> dict[str, Any]:
    """``tasks.evaluate_controller``, the drive as the JSON text the store keeps."""
    from service.jobs import tasks

    result = tasks.evaluate_controller(document, network_file, cache_dir, controller, budget)
    return {**result, "drive": json.dumps(result["drive"], separators=(",", ":"))}


def on_file(function: Callable[..., Any], document_file: Path, *args: Any) -> Any:
    """``function(document, *args)`` with the document read here from ``document_file``:
    the server hands over a path, not 30 MB to pickle and pipe on its event loop."""
    return function(document_file.read_text(), *args)


def checked_upload(
    task: Callable[[Path, dict[str, str], Path], Any],
    staged: Path,
    overrides: dict[str, str],
    cache_dir: Path,
    kind: str | None,
) -> tuple[str, Any]:
    """``("refused", why)`` for an upload that is not XML this service reads (the server
    answers 400), else ``("ok", task(staged, overrides, cache_dir))``. An XML parser holds
    the GIL for as long as one token lasts (a 15 MB attribute: 1.5 s), so this runs here."""
    refusal = xml_refusal(staged.read_bytes(), kind)
    if refusal is not None:
        return "refused", refusal
    return "ok", task(staged, overrides, cache_dir)


ROOTS = {  # the root element of each kind of upload, and what it is
    None: ("net", "a SUMO <net>"),
    "opendrive": ("OpenDRIVE", "an OpenDRIVE map's <OpenDRIVE>"),
    "openstreetmap": ("osm", "an OpenStreetMap extract's <osm>"),
}


def xml_refusal(content: bytes, kind: str | None = None) -> str | None:
    """Why the upload is refused as XML (entities and DTDs are forbidden), or None; the
    root must be a SUMO <net> (or, for a map to convert, <OpenDRIVE> or <osm>), else
    InvalidInput. Its depth is read first, as a stream: a small file of deeply nested
    elements is refused at once, before a parser or netconvert works on it."""
    if too_deep(io.BytesIO(content)):
        return depth_refusal("the network")
    try:
        root = SafeElementTree.fromstring(content, forbid_dtd=True)
    except DefusedXmlException as error:
        return f"the network XML is refused: {type(error).__name__} ({error})"
    except SafeElementTree.ParseError as error:
        return f"the network is not well-formed XML: {error}"
    tag, what = ROOTS[kind]
    if root.tag != tag:
        raise InvalidInput(
            f"the upload's root element is <{root.tag}>, not {what} (the file name says "
            "which: .xodr for OpenDRIVE, .osm for OpenStreetMap, else a SUMO .net.xml)"
        )
    if kind is None and (root.find("junction") is None or root.find("edge") is None):
        raise InvalidInput("the SUMO <net> has no junctions or edges")
    if kind is None:
        _check_junction_ids(root)
    return None


def _check_junction_ids(root: Any) -> None:
    """A junction id is one segment of the junction's URL (/networks/{id}/junctions/{j}):
    a '/' in it would make the junction's own links point elsewhere."""
    slashed = [
        junction.get("id", "")
        for junction in root.iterfind("junction")
        if junction.get("type") != "internal" and "/" in junction.get("id", "")
    ]
    if slashed:
        shown = ", ".join(repr(ident[:80]) for ident in slashed[:5])
        more = f" and {len(slashed) - 5} more" if len(slashed) > 5 else ""
        raise InvalidInput(
            f"junction ids may not contain '/' (a junction's id is a segment of its URL): "
            f"{shown}{more}; rename them in the network (netconvert keeps the ids it is given)"
        )
