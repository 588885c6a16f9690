"""The HTTP examples of the docs (docs/http-api.md, docs/jobs.md) work as written, against a
real server: the blocks marked ``curl-example`` or ``example: server``."""

from __future__ import annotations

import io
import json
import subprocess
import sys
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

import pytest

from tests.doc_examples import DOCS, ROOT, blocks, set_up
from tests.servers import Server

pytestmark = pytest.mark.slow

HTTP_API = DOCS / "http-api.md"
JOBS = DOCS / "jobs.md"


def shell_blocks() -> list[str]:
    """The ```sh blocks of the HTTP API's page that are marked to run against a server, in
    order."""
    return [b.body for b in blocks(HTTP_API) if b.language == "sh" and b.runs_on_a_server]


def run_block(block: str, server: Server, cwd: Path) -> None:
    script = block.replace("B=http://127.0.0.1:8000", f"B={server.url}")
    if "B=" not in script:
        script = f"B={server.url}\n{script}"
    result = subprocess.run(
        ["bash", "-euo", "pipefail", "-c", script],
        cwd=cwd, capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr + result.stdout


def test_curl_examples_work_as_written(server: Server, tmp_path: Path) -> None:
    extend, _upload, _signals = shell_blocks()
    run_block(extend, server, tmp_path)
    root, level1, level2 = (json.loads((tmp_path / f"{n}.json").read_text())
                            for n in ("root", "level1", "level2"))  # fmt: skip
    assert level1["parent"] == root["id"] and level1["new_cars"] == ["car1"]
    assert level2["parent"] == level1["id"] and level2["new_cars"] == ["car2"]
    inline = json.loads((tmp_path / "inline.json").read_text())
    assert inline["id"] == level2["id"]  # inline or by id: the same bytes
    assert (
        "testcase.sumocfg"
        in zipfile.ZipFile(io.BytesIO((tmp_path / "level2.zip").read_bytes())).namelist()
    )
    assert (tmp_path / "level2.png").read_bytes()[:4] == b"\x89PNG"
    assert ET.parse(tmp_path / "sumo.junit.xml").getroot().tag == "testsuites"


def test_upload_example_gives_the_id_the_page_names(server: Server, tmp_path: Path) -> None:
    _, upload, _ = shell_blocks()
    set_up(HTTP_API, tmp_path)  # the page's example set-up: CARLA's Town05
    run_block(upload, server, tmp_path)
    town05 = json.loads((tmp_path / "town05.json").read_text())
    assert town05["id"] in upload
    assert json.loads((tmp_path / "town05-root.json").read_text())["network"] == town05["id"]


def test_signals_example_keeps_its_program_and_names_a_bad_one(
    server: Server, tmp_path: Path
) -> None:
    *_, signals = shell_blocks()
    script = signals.replace("jq -r .detail", "jq -r .detail > detail.txt")
    run_block(script, server, tmp_path)
    level1 = json.loads((tmp_path / "signal-level1.json").read_text())
    root = json.loads((tmp_path / "signal-root.json").read_text())
    assert level1["parent"] == root["id"] and level1["new_cars"] == ["car1"]
    assert level1["testcase"]["signals"] == root["testcase"]["signals"]
    assert root["testcase"]["signals"]["program"] == "short-cycle"
    detail = (tmp_path / "detail.txt").read_text()
    assert "states have 4 colours, but traffic light 'C' controls 16 links" in detail


def test_the_batch_example_runs_as_the_docs_show(server: Server, tmp_path: Path) -> None:
    created = server.client.post(
        "/testcases", json={"network": "4way-stop", "ego_route": "E2C_1:C2S_1"}
    )
    assert created.json()["id"] == "c2de5a280aab66bd"  # the id the batch file names
    assert created.json()["name"] == "4way-stop C E2C_1:C2S_1 level 0"
    page = JOBS.read_text()
    example = (ROOT / "examples" / "regression.yaml").read_text()
    assert example.split("name:", 1)[1] in page  # the page shows the file as it is
    shown = [b for b in blocks(JOBS) if b.runs_on_a_server and "scengen submit" in b.body]
    assert len(shown) == 1 and "evaluations 4 passed 4 failed" in shown[0].body
    done = subprocess.run(
        [sys.executable, "-m", "service", "submit", str(ROOT / "examples" / "regression.yaml"),
         "--server", server.url, "--junit", "report.xml"],
        cwd=tmp_path, capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert "succeeded: 3/3 items, evaluations 4 passed 4 failed" in done.stderr, done.stderr
    assert done.returncode == 1  # the rolling-stop variant fails, as the page says
    suite = ET.parse(tmp_path / "report.xml").getroot().find("testsuite")
    assert suite is not None and suite.get("tests") == "8" and suite.get("failures") == "4"
