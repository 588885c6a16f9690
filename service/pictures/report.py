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
from urllib.parse import quote

UI = Path(__file__).resolve().parent / "ui"  # the results browser's pages

URI_COMPONENT_SAFE = "!~*'()"  # what encodeURIComponent leaves as it is (with A-Z a-z 0-9 -_.)
Fetch = Callable[[str], Any]  # an API path -> its JSON answer


def campaign_paths(job: str, outcome: dict[str, Any], fetch: Fetch) -> dict[str, Any]:
    """Every API answer the report's pages need, through ``fetch`` (the server's, or the
    store's, service.api.public.store_fetch), keyed by path."""
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
    JavaScript's encodeURIComponent quotes: the page looks its answers up by this path),
    on its network with guessed crosswalks where the test-case has them (ui.js's
    geometryOf)."""
    network = quote(document["network"]["ref"], safe=URI_COMPONENT_SAFE)
    junction = quote(document["junction"], safe=URI_COMPONENT_SAFE)
    guessed = "&guess_crossings=true" if document.get("crossings_guessed") else ""
    query = f"control={document['control']}{guessed}"
    return f"/networks/{network}/junctions/{junction}/geometry?{query}"


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
