"""A campaign's report as one self-contained HTML file (``scengen report``).

The report is the results browser (``/ui``) itself, its script and style inlined, with the
answers to every request its pages make embedded (keyed by the API path they answer), so
that it opens from disk or a CI artifact store without a server or a network: the failure
rate plot, the tables, and every test-case's animation and every controller's replay.
"""

from __future__ import annotations

import html
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any
from urllib.parse import quote, unquote

from service.jobs.campaign_steps import OUTCOME
from service.jobs.store import JobStore
from service.store import DRIVE_COLUMNS, Store

UI = Path(__file__).resolve().parent / "ui"  # the results browser's pages

URI_COMPONENT_SAFE = "!~*'()"  # what encodeURIComponent leaves as it is (with A-Z a-z 0-9 -_.)
Fetch = Callable[[str], Any]  # an API path -> its JSON answer


def campaign_paths(job: str, outcome: dict[str, Any], fetch: Fetch) -> dict[str, Any]:
    """Every API answer the report's pages need, through ``fetch`` (the server's, or the
    store's ``store_fetch``), keyed by path."""
    data: dict[str, Any] = {"/jobs/" + job: fetch("/jobs/" + job)}
    data[f"/jobs/{job}/campaign"] = outcome
    idents = []
    for chain in outcome["chains"]:
        idents += [lv["testcase"] for lv in chain["levels"] if lv["testcase"] not in idents]
    for ident in idents:
        record = fetch(f"/testcases/{ident}")
        data[f"/testcases/{ident}"] = record
        document = record["testcase"]
        geometry = geometry_path(document)
        if geometry not in data:
            data[geometry] = fetch(geometry)
        listed = data[evaluations_path(ident)] = fetch(evaluations_path(ident))
        for evaluation in listed["items"]:
            data[f"/evaluations/{evaluation['id']}"] = evaluation
            data[f"/evaluations/{evaluation['id']}/drive"] = fetch(
                f"/evaluations/{evaluation['id']}/drive"
            )
    return data


def evaluations_path(testcase: str) -> str:
    """Where the browser asks for a test-case's evaluations."""
    return f"/evaluations?testcase={testcase}&limit=200"


def geometry_path(document: dict[str, Any]) -> str:
    """Where the browser asks for the picture data of a test-case's junction (quoted as
    JavaScript's encodeURIComponent quotes: the page looks its answers up by this path)."""
    network = quote(document["network"]["ref"], safe=URI_COMPONENT_SAFE)
    junction = quote(document["junction"], safe=URI_COMPONENT_SAFE)
    return f"/networks/{network}/junctions/{junction}/geometry?control={document['control']}"


Shapes = Callable[[Path, str, str], dict[str, Any]]  # network file, junction, control


def store_fetch(store: Store, shapes: Shapes) -> Fetch:
    """The answers a server on ``store`` gives (its own response models), for the paths a
    report needs; ``shapes`` draws a junction (``tasks.junction_geometry``)."""
    from service.api.routes.evaluations import evaluation_public
    from service.api.routes.jobs import job_public
    from service.api.routes.testcases import public

    jobs = JobStore(store)

    def fetch(path: str) -> Any:
        where, _, query = path.partition("?")
        parts = [unquote(part) for part in where.strip("/").split("/")]
        asked = dict(pair.split("=", 1) for pair in query.split("&") if pair)
        answer: Any
        if parts[0] == "jobs":
            answer = job_public(store, _found(jobs.job(parts[1]), path))
        elif parts[0] == "testcases":
            answer = public(_found(store.testcase(parts[1]), path))
        elif parts[0] == "networks":
            return shapes(store.network_file(parts[1]), parts[3], asked["control"])
        elif parts == ["evaluations"]:
            found = store.list_evaluations(asked["testcase"], int(asked.get("limit", 50)))
            return {
                "items": [evaluation_public(e).model_dump(mode="json") for e in found.items],
                "total": found.total,
            }
        elif parts[0] == "evaluations" and parts[2:] == ["drive"]:
            return {"evaluation": parts[1], "columns": DRIVE_COLUMNS,
                    "trajectory": store.drive(parts[1]) or []}  # fmt: skip
        else:
            raise KeyError(path)
        return answer.model_dump(mode="json")

    return fetch


def _found(record: Any, path: str) -> Any:
    if record is None:
        raise KeyError(f"nothing stored at {path}")
    return record


def outcome_of(store: Store, job: str) -> dict[str, Any]:
    """The campaign outcome (so far) of ``job``'s first campaign item."""
    jobs = JobStore(store)
    record = jobs.job(job)
    if record is None:
        raise KeyError(job)
    for item in record.items:
        if item.kind == "campaign":
            found = jobs.memo(job, item.position, OUTCOME)
            if found is not None:
                return dict(found)
    raise KeyError(f"job {job} has no campaign outcome yet")


def campaign_title(outcome: dict[str, Any]) -> str:
    plan = outcome["plan"]
    return f"scengen campaign: {plan['network']} junction {plan['junction']}"


def report_html(job: str, data: dict[str, Any], title: str) -> str:
    """The self-contained report: the browser's page with ``data`` inlined, opening on the
    campaign."""
    page = (UI / "index.html").read_text()
    style = (UI / "ui.css").read_text()
    script = (UI / "ui.js").read_text()
    embedded = json.dumps({"start": f"#/jobs/{job}", "answers": data}, separators=(",", ":"))
    embedded = embedded.replace("<", "\\u003c")  # no markup inside the script element
    page = page.replace('<link rel="stylesheet" href="/ui/ui.css">', f"<style>\n{style}</style>")
    page = page.replace(
        '<script src="/ui/ui.js"></script>',
        f"<script>window.SCENGEN_REPORT = {embedded};</script>\n<script>\n{script}</script>",
    )
    return page.replace("<title>scengen</title>", f"<title>{html.escape(title)}</title>")
