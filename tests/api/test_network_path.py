"""A test-case the command line wrote carries its network's path on the client's disk: the
server takes it, keeps no such path, and gives it the id it has without one."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import httpx2 as httpx

from service.core.testcase import dump_testcase, new_testcase, with_network_path
from tests.conftest import DATA

SKEWED = DATA / "junctions" / "skewed-allway.net.xml"


def test_a_written_testcase_is_stored_without_its_path(api: httpx.Client, tmp_path: Path) -> None:
    upload = api.post("/networks", files={"file": ("skewed-allway.net.xml", SKEWED.read_bytes())})
    assert upload.status_code == 201, upload.text
    plain = new_testcase(SKEWED, "SSW2C_0:C2WSW_0")
    written = with_network_path(plain, SKEWED, tmp_path / "suite")
    assert written.network.path is not None
    document = json.loads(dump_testcase(written))
    reply = api.post(
        "/extend",
        json={"testcase": document, "routes": ["WSW2C_0:C2ENE_0"], "seed": 0, "budget": 60},
    )
    assert reply.status_code == 201, reply.text
    extended = reply.json()
    assert "path" not in extended["testcase"]["network"]
    parent = api.get(f"/testcases/{extended['parent']}/document").json()
    assert parent["network"] == {"ref": plain.network.ref, "sha256": plain.network.sha256}
    parent_hash = hashlib.sha256(dump_testcase(plain).encode()).hexdigest()
    assert extended["testcase"]["provenance"]["parent"] == parent_hash
