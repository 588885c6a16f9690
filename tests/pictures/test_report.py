"""The self-contained report: the browser's page with the answers inlined, safely."""

from __future__ import annotations

import json
import re

from service.pictures.report import geometry_path, report_html


def test_embedded_answers_cannot_end_the_script_or_open_markup() -> None:
    hostile = {"/testcases/abc": {"name": "</script><!--<script>alert(1)</script>"}}
    page = report_html("j1", hostile, "a <title>")
    embedded = re.search(r"window\.SCENGEN_REPORT = (.*?);</script>", page, re.S)
    assert embedded is not None and "<" not in embedded.group(1)
    assert json.loads(embedded.group(1))["answers"] == hostile  # the same data in the page
    assert "<title>a &lt;title&gt;</title>" in page
    assert 'src="/ui/ui.js"' not in page and 'href="/ui/ui.css"' not in page  # inlined


def test_geometry_paths_are_quoted_as_the_browser_quotes_them() -> None:
    document = {"network": {"ref": "my net%"}, "junction": "cluster_1_#2more",
                "control": "allway_stop"}  # fmt: skip
    assert geometry_path(document) == (
        "/networks/my%20net%25/junctions/cluster_1_%232more/geometry?control=allway_stop"
    )
    guessed = {**document, "crossings_guessed": True}  # the network rebuilt with crosswalks
    assert geometry_path(guessed) == geometry_path(document) + "&guess_crossings=true"
