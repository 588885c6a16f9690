"""Issue 50: a small OpenStreetMap upload of 200,000 nested elements (1.4 MB) held a worker
for the whole work budget (504 after 120 s). Every upload's nesting is read first, as a
stream stopped at 64 levels (service.core.network.xml_depth; SUMO networks nest 4,
OpenStreetMap 3, OpenDRIVE about 10), and such a file is refused at once: 400 over HTTP,
exit 2 on the command line. The calls have a timeout of a few seconds: a refusal that
comes late fails them (no timed assertion)."""

from __future__ import annotations

import io
import os
import subprocess
import sys
from pathlib import Path

import httpx2 as httpx
import pytest

from service.core.network.xml_depth import MAX_XML_DEPTH, too_deep
from tests.conftest import DATA
from tests.servers import Server

pytestmark = pytest.mark.slow

DEPTH = 200_000


def nested(root: str, depth: int = DEPTH) -> bytes:
    return f'<{root} version="0.6">{"<n>" * depth}{"</n>" * depth}</{root}>'.encode()


@pytest.mark.parametrize(("filename", "root"), [("deep.osm", "osm"),
                                                ("deep.xodr", "OpenDRIVE"),
                                                ("deep.net.xml", "net")])  # fmt: skip
def test_a_deep_upload_is_refused_at_once(server: Server, filename: str, root: str) -> None:
    reply = httpx.post(
        f"{server.url}/networks", files={"file": (filename, nested(root))}, timeout=5
    )
    assert reply.status_code == 400, reply.text
    assert f"more than {MAX_XML_DEPTH} levels deep" in reply.json()["detail"]


def test_a_deep_map_on_the_command_line_is_refused(tmp_path: Path) -> None:
    (tmp_path / "deep.osm").write_bytes(nested("osm"))
    done = subprocess.run(
        [sys.executable, "-m", "service", "intersection", "deep.osm"],
        cwd=tmp_path, capture_output=True, text=True, timeout=30,
        env={**os.environ, "XDG_CACHE_HOME": str(tmp_path / "cache")},
    )  # fmt: skip
    assert done.returncode == 2, done.stderr
    assert f"deep.osm nests its XML elements more than {MAX_XML_DEPTH}" in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1


def test_the_real_files_are_far_from_the_limit() -> None:
    """The bound leaves room: every map and network in tests/data nests at most 4 deep, the
    OpenDRIVE export of the bundled four-way 8."""
    from service.core.export.openscenario import opendrive_text
    from service.core.network import bundled_networks, load_intersection

    files = [*DATA.glob("osm/*.osm"), *DATA.glob("maps/*.osm"), *DATA.glob("osm/*.net.xml")]
    assert files and not any(too_deep(path, 4) for path in files)
    assert too_deep(DATA / "maps" / "crossing.osm", 2)
    xodr = opendrive_text(load_intersection(bundled_networks()["4way-stop"], "C")).encode()
    assert not too_deep(io.BytesIO(xodr), 8) and too_deep(io.BytesIO(xodr), 7)
