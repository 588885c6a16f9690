"""A test-case's network.path names a file only a network may be (issue 50): one that is not
a network's file by its name, or not a regular file, is never read, and no error shows the
digest of a file other than a network (/etc/shadow's was printed)."""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from service.core.errors import UnknownNetwork
from service.core.testcase import (
    dump_testcase,
    find_network_file,
    network_path,
    new_testcase,
    read_testcase,
)
from tests.conftest import DATA

SKEWED = DATA / "junctions" / "skewed-allway.net.xml"  # not bundled: found only by its path
PASSWD = Path("/etc/passwd")


@pytest.fixture(scope="module")
def document() -> dict[str, object]:
    return json.loads(dump_testcase(new_testcase(SKEWED, "SSW2C_0:C2WSW_0")))


def _written(folder: Path, document: dict[str, object], path: str) -> Path:
    """The test-case as a file in ``folder`` whose network.path is ``path``."""
    edited = json.loads(json.dumps(document))
    edited["network"]["path"] = path
    written = folder / "t0.json"
    written.write_text(json.dumps(edited))
    return written


@pytest.mark.parametrize("named", ["/etc/passwd", "../../../../../../etc/passwd", "link"])
def test_a_path_to_a_file_that_is_no_network_is_not_read(
    named: str, document: dict[str, object], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """By its name, and by the name a link points to (shadow.net.xml -> /etc/passwd)."""
    monkeypatch.setattr(network_path, "_READ_FROM", {})  # this process made it: forgotten
    if named == "link":
        named = "shadow.net.xml"
        (tmp_path / named).symlink_to(PASSWD)
    written = _written(tmp_path, document, named)
    with pytest.raises(UnknownNetwork) as refused:
        find_network_file(read_testcase(written), near=tmp_path)
    message = str(refused.value)
    why = "(its path from the test-case) was not read: a network's file name ends in"
    assert f"{named} {why}" in message
    assert ".net.xml, .xodr, .osm" in message and named in message, message
    assert hashlib.sha256(PASSWD.read_bytes()).hexdigest() not in message
    assert "\n" not in message


def test_a_fifo_named_like_a_network_is_not_read(tmp_path: Path) -> None:
    """Reading a FIFO would hang: a subprocess timeout (not a timed assertion) fails the
    test if the command opens it; the command says it is not a regular file, exit 2."""
    os.mkfifo(tmp_path / "x.net.xml")
    made = tmp_path / "made.json"
    subprocess.run([sys.executable, "-m", "service", "new", str(SKEWED), "--ego",
                    "SSW2C_0:C2WSW_0", "-o", str(made)], check=True, timeout=120)  # fmt: skip
    written = _written(tmp_path, json.loads(made.read_text()), "x.net.xml")
    result = subprocess.run(
        [sys.executable, "-m", "service", "evaluate", str(written)],
        capture_output=True, text=True, check=False, cwd=tmp_path, timeout=60,
    )  # fmt: skip
    lines = result.stderr.strip().splitlines()
    assert result.returncode == 2 and len(lines) == 1, result.stderr
    assert "x.net.xml (its path from the test-case) was not read: not a regular file" in lines[0]


def test_a_reference_that_is_no_networks_file_is_not_read_as_a_path(
    document: dict[str, object], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """network.ref /etc/passwd: looked for as a network beside the test-case only."""
    monkeypatch.setattr(network_path, "_READ_FROM", {})
    monkeypatch.chdir(tmp_path)
    edited = json.loads(json.dumps(document))
    edited["network"]["ref"] = str(PASSWD)
    (tmp_path / "t0.json").write_text(json.dumps(edited))
    with pytest.raises(UnknownNetwork) as refused:
        find_network_file(read_testcase(tmp_path / "t0.json"), near=tmp_path)
    message = str(refused.value)
    assert f"is not at {tmp_path / 'passwd.net.xml'} (next to the test-case):" in message
    assert hashlib.sha256(PASSWD.read_bytes()).hexdigest() not in message
