"""The whole service through a real uvicorn server: upload CARLA's Town05 with a junction
made an all-way stop, create a test-case, extend it twice, download and run the bundle in
SUMO, evaluate a controller, fetch the pictures. Every generated test-case is re-checked
here by the checker itself, not trusted from the server."""

from __future__ import annotations

import io
import itertools
import json
import subprocess
import sys
import threading
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path
from typing import Any

import httpx2 as httpx
import pytest

from service.api.schemas import EXAMPLE_EGO, EXAMPLE_NEW_ROUTE
from service.core.checker.check import check_testcase
from service.core.motion.poses import PoseSample
from service.core.network import load_intersection
from service.core.sumo.binaries import sumo_binary
from service.core.testcase import TestCase, dump_testcase, new_testcase, parse_testcase
from tests.conftest import TOWN05

pytestmark = pytest.mark.slow

EGO = "-44_1:-9_1"  # Town05 junction 396: a left turn
CHAIN = ["9_1:8_1", "-8_1:-9_1"]  # oncoming straight, then from the right


def samples(rows: Any) -> list[PoseSample]:
    return [PoseSample(**row.model_dump()) for row in rows]


@pytest.fixture(scope="module")
def town05(api: httpx.Client) -> dict[str, Any]:
    reply = api.post(
        "/networks",
        files={"file": ("Town05.net.xml", TOWN05.read_bytes(), "application/xml")},
        data={"controls": json.dumps({"396": "allway_stop"})},
    )
    assert reply.status_code == 201, reply.text
    assert reply.headers["location"] == f"/networks/{reply.json()['id']}"
    return dict(reply.json())


@pytest.fixture(scope="module")
def chain(api: httpx.Client, town05: dict[str, Any]) -> list[dict[str, Any]]:
    """The root and its two extensions, as the server answered them."""
    root = api.post(
        "/testcases", json={"network": town05["id"], "junction": "396", "ego_route": EGO}
    )
    assert root.status_code == 201, root.text
    levels = [root.json()]
    for route in CHAIN:
        reply = api.post(
            "/extend",
            json={"testcase_id": levels[-1]["id"], "routes": [route], "seed": 0, "budget": 60},
        )
        assert reply.status_code == 201, reply.text
        levels.append(reply.json())
    return levels


@pytest.fixture(scope="module")
def local_town05(cache_dir: Path) -> Any:
    return load_intersection(TOWN05, "396", "allway_stop", cache_dir)


def test_upload_is_listed_with_its_override(api: httpx.Client, town05: dict[str, Any]) -> None:
    assert town05["controls"] == {"396": "allway_stop"} and not town05["bundled"]
    assert town05["id"] in [n["id"] for n in api.get("/networks").json()]
    junctions = {j["id"]: j for j in api.get(f"/networks/{town05['id']}/junctions").json()}
    assert junctions["396"]["type"] == "priority" and junctions["396"]["control"] == "allway_stop"
    described = api.get(f"/networks/{town05['id']}/junctions/396").json()
    assert described["control"] == "allway_stop" and described["control_overridden"]
    assert EGO in [r["id"] for r in described["routes"]]


def test_uploading_again_gives_the_same_network(api: httpx.Client, town05: dict[str, Any]) -> None:
    again = api.post(
        "/networks",
        files={"file": ("Town05.net.xml", TOWN05.read_bytes())},
        data={"controls": json.dumps({"396": "allway_stop"})},
    )
    assert again.status_code == 201 and again.json()["id"] == town05["id"]


def test_each_extension_is_strictly_more_complex(
    chain: list[dict[str, Any]], local_town05: Any
) -> None:
    testcases = [parse_testcase(level["testcase"]) for level in chain]
    assert [len(t.nonegos) for t in testcases] == [0, 1, 2]
    for old, new in itertools.pairwise(testcases):
        _assert_strictly_more_complex(old, new, local_town05)
    assert [level["parent"] for level in chain] == [None, chain[0]["id"], chain[1]["id"]]
    assert chain[2]["new_cars"] == ["car2"] and chain[2]["attempts"][-1]["outcome"].startswith(
        "verified"
    )


def _assert_strictly_more_complex(old: TestCase, new: TestCase, intersection: Any) -> None:
    assert new.certificates is not None
    solvable = check_testcase(new, samples(new.certificates.solvability), "s", intersection)
    assert solvable.passed, solvable.reasons
    complexity = samples(new.certificates.complexity)
    assert check_testcase(old, complexity, "c", intersection).passed
    failed = check_testcase(new, complexity, "c", intersection)
    assert not failed.passed and failed.goal_reached and failed.violations


def test_stored_testcases_and_lineage(api: httpx.Client, chain: list[dict[str, Any]]) -> None:
    leaf = chain[-1]
    fetched = api.get(f"/testcases/{leaf['id']}").json()
    assert fetched["testcase"] == leaf["testcase"]
    document = api.get(leaf["links"]["document"])
    assert document.headers["content-type"] == "application/json"
    assert json.loads(document.text) == leaf["testcase"]
    lineage = api.get(f"/testcases/{leaf['id']}/lineage").json()
    assert [a["id"] for a in lineage["ancestors"]] == [chain[1]["id"], chain[0]["id"]]
    assert lineage["children"] == []
    children = api.get("/testcases", params={"parent": chain[0]["id"]}).json()
    assert [c["id"] for c in children["items"]] == [chain[1]["id"]]
    on_town05 = api.get("/testcases", params={"network": chain[0]["network"], "limit": 2}).json()
    assert on_town05["total"] == 3 and len(on_town05["items"]) == 2
    assert on_town05["next"] is not None
    rest = api.get(on_town05["next"]).json()
    assert {i["id"] for i in on_town05["items"] + rest["items"]} == {c["id"] for c in chain}


def test_names_say_network_junction_route_and_level(
    api: httpx.Client, chain: list[dict[str, Any]]
) -> None:
    """Made through the API, every test-case has the readable default name (the uploaded
    file's short name, not the server's network id); the summaries give level and duration."""
    names = [f"Town05 396 {EGO} level {level}" for level in range(3)]
    assert [level["name"] for level in chain] == names
    assert [level["testcase"]["name"] for level in chain] == names
    listed = api.get("/testcases", params={"network": chain[0]["network"]}).json()["items"]
    mine = {t["id"]: (t["name"], t["level"], t["duration"]) for t in listed}
    assert [mine[level["id"]] for level in chain] == [(n, i, 20.0) for i, n in enumerate(names)]
    lineage = api.get(f"/testcases/{chain[2]['id']}/lineage").json()
    assert [(a["level"], a["duration"]) for a in lineage["ancestors"]] == [(1, 20.0), (0, 20.0)]


def test_a_given_name_is_kept_and_extensions_carry_it(api: httpx.Client) -> None:
    """A name given to POST /testcases is kept, and its extensions add the level; an
    extension of a document sent inline without a name gets the readable default."""
    named = api.post(
        "/testcases", json={"network": "4way-stop", "ego_route": EXAMPLE_EGO, "name": "left"}
    )
    assert named.status_code == 201, named.text
    assert named.json()["name"] == "left" and named.json()["level"] == 0
    body = {"testcase_id": named.json()["id"], "routes": [EXAMPLE_NEW_ROUTE], "seed": 1}
    extended = api.post("/extend", json=body)
    assert extended.status_code == 201, extended.text
    assert extended.json()["name"] == "left level 1" and extended.json()["level"] == 1
    unnamed = json.loads(dump_testcase(new_testcase("4way-stop", EXAMPLE_EGO)))
    assert unnamed["name"] == ""
    body = {"testcase": unnamed, "routes": [EXAMPLE_NEW_ROUTE], "seed": 1}
    inline = api.post("/extend", json=body)
    assert inline.status_code == 201, inline.text
    assert inline.json()["name"] == "4way-stop C E2C_1:C2S_1 level 1"


def test_extending_is_deterministic(api: httpx.Client, chain: list[dict[str, Any]]) -> None:
    """The same request again gives the same bytes, hence the same stored id."""
    reply = api.post(
        "/extend", json={"testcase": chain[0]["testcase"], "routes": [CHAIN[0]], "budget": 60}
    )
    assert reply.status_code == 201 and reply.json()["id"] == chain[1]["id"]


def test_the_openscenario_export_of_an_uploaded_map(
    api: httpx.Client, chain: list[dict[str, Any]], tmp_path: Path
) -> None:
    leaf = chain[-1]
    reply = api.get(leaf["links"]["openscenario"])
    assert reply.status_code == 200 and reply.headers["content-type"] == "application/zip"
    archive = zipfile.ZipFile(io.BytesIO(reply.content))
    assert set(archive.namelist()) == {"testcase.xodr", "testcase.xosc", "verdict-rules.md",
        "testcase.solvability.xosc", "testcase.complexity.xosc"}  # fmt: skip
    scenario = ET.fromstring(archive.read("testcase.xosc"))
    assert scenario.find("RoadNetwork/LogicFile").get("filepath") == "testcase.xodr"  # type: ignore[union-attr]
    first = leaf["testcase"]["nonegos"][0]["trajectory"][0]
    vertex = next(scenario.iter("Vertex")).find("Position/WorldPosition")
    assert vertex is not None
    assert abs(float(vertex.get("x", 0)) - first["x"]) < 1e-3
    assert abs(float(vertex.get("y", 0)) - first["y"]) < 1e-3
    carla = api.get(leaf["links"]["openscenario"], params={"flavour": "carla"})
    network = ET.fromstring(zipfile.ZipFile(io.BytesIO(carla.content)).read("testcase.xosc"))
    assert network.find("RoadNetwork/LogicFile").get("filepath") == "Town05"  # type: ignore[union-attr]
    bad = api.get(leaf["links"]["openscenario"], params={"flavour": "vtd"})
    assert bad.status_code == 422 and "'asam' or 'carla'" in bad.text


def test_opendrive_and_openstreetmap_uploads_are_converted_and_extended(
    api: httpx.Client, tmp_path: Path
) -> None:
    """An .xodr (the export of the bundled four-way stop) and an .osm extract: each stored
    with its original, described, and extended; the extension re-checked here."""
    from service.core.export.openscenario import opendrive_text
    from service.core.network import bundled_networks

    xodr = opendrive_text(load_intersection(bundled_networks()["4way-stop"], "C")).encode()
    osm = (Path(__file__).parents[1] / "data" / "maps" / "crossing.osm").read_bytes()
    cases = [("4way.xodr", xodr, "allway_stop", "-54_1:-52_1", "-55_1:-50_1", "opendrive"),
             ("crossing.osm", osm, "priority_stop", "11_0:10#1_0", "-10#1_0:-10#0_0",
              "openstreetmap")]  # fmt: skip
    for filename, content, control, ego, route, kind in cases:
        reply = api.post(
            "/networks",
            files={"file": (filename, content, "application/xml")},
            data={"controls": json.dumps({"1": control})},
        )
        assert reply.status_code == 201, reply.text
        network = reply.json()
        assert network["source"]["format"] == kind and network["source"]["filename"] == filename
        assert network["filename"] == f"{filename}.net.xml"
        assert api.get(network["links"]["source"]).content == content
        converted = api.get(network["links"]["file"]).content
        assert converted.lstrip().startswith(b"<?xml") and b"<net " in converted
        root = api.post(
            "/testcases", json={"network": network["id"], "junction": "1", "ego_route": ego}
        )
        assert root.status_code == 201, root.text
        extended = api.post(
            "/extend", json={"testcase_id": root.json()["id"], "routes": [route], "budget": 60}
        )
        assert extended.status_code == 201, extended.text
        new = parse_testcase(extended.json()["testcase"])
        assert new.certificates is not None
        (tmp_path / f"{filename}.net.xml").write_bytes(converted)
        junction = load_intersection(tmp_path / f"{filename}.net.xml", "1", control)
        solvable = samples(new.certificates.solvability)
        assert check_testcase(new, solvable, intersection=junction).passed
        again = api.post("/networks", files={"file": (filename, content)},
                          data={"controls": json.dumps({"1": control})})  # fmt: skip
        assert again.json()["id"] == network["id"]  # the same upload, the same network
    wrong = api.post("/networks", files={"file": ("x.xodr", b"<net><edge/></net>")})
    assert wrong.status_code == 422 and "<OpenDRIVE>" in wrong.text


def test_the_bundle_runs_in_sumo(
    api: httpx.Client, chain: list[dict[str, Any]], tmp_path: Path
) -> None:
    reply = api.get(chain[-1]["links"]["bundle"])
    assert reply.headers["content-type"] == "application/zip"
    zipfile.ZipFile(io.BytesIO(reply.content)).extractall(tmp_path)
    bundled_document = json.loads((tmp_path / "testcase.json").read_text())
    # the stored test-case, and the path of the network file beside it in the bundle
    assert bundled_document["network"].pop("path") == f"{chain[-1]['network']}.net.xml"
    assert bundled_document == chain[-1]["testcase"]
    subprocess.run(
        [sumo_binary("sumo"), "-c", "testcase.sumocfg", "--fcd-output", "run.fcd.xml"],
        cwd=tmp_path, check=True, capture_output=True, timeout=120,
    )  # fmt: skip
    seen = {
        vehicle.get("id")
        for step in ET.parse(tmp_path / "run.fcd.xml").getroot().iter("timestep")
        for vehicle in step.iter("vehicle")
    }
    assert {"ego", "car1", "car2"} <= seen
    # The bundle's test-case names the server's network id; the bundle holds the uploaded
    # file under that id, so the command line finds it and judges the run of run.py (the
    # service's own replay) exactly as the service does.
    bundled = tmp_path / f"{chain[-1]['network']}.net.xml"
    assert bundled.read_bytes() == TOWN05.read_bytes()
    subprocess.run(
        [sys.executable, "run.py", "--controller", "sumo"],
        cwd=tmp_path, check=True, capture_output=True, timeout=120,
    )  # fmt: skip
    checked = subprocess.run(
        [sys.executable, "-m", "service", "check", "testcase.json", "--ego", "run.fcd.xml",
         "--json"],
        cwd=tmp_path, capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert checked.returncode in (0, 1), checked.stderr
    assert "(its path from the test-case)" in checked.stderr
    verdict = json.loads(checked.stdout)
    served = api.post("/evaluations", json={"testcase_id": chain[-1]["id"], "controller": "sumo"})
    assert served.status_code == 201, served.text
    assert verdict["passed"] == served.json()["verdict"]["passed"] == (checked.returncode == 0)
    assert verdict["goal"] == served.json()["verdict"]["goal"]
    assert verdict["violations"] == served.json()["verdict"]["violations"]
    # without the file, the error asks for it
    bundled.unlink()
    refused = subprocess.run(
        [sys.executable, "-m", "service", "check", "testcase.json", "--ego", "run.fcd.xml"],
        cwd=tmp_path, capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert refused.returncode == 2 and "--network FILE" in refused.stderr


def test_evaluations_are_stored_with_junit(api: httpx.Client, chain: list[dict[str, Any]]) -> None:
    leaf = chain[-1]["id"]
    created = {}
    for controller in ("certificate:solvability", "certificate:complexity"):
        reply = api.post("/evaluations", json={"testcase_id": leaf, "controller": controller})
        assert reply.status_code == 201, reply.text
        created[controller] = reply.json()
    assert created["certificate:solvability"]["passed"]
    assert not created["certificate:complexity"]["passed"]
    assert any("car2" in reason for reason in created["certificate:complexity"]["reasons"])
    failing = created["certificate:complexity"]["id"]
    junit = api.get(f"/evaluations/{failing}", headers={"accept": "application/xml"})
    assert junit.headers["content-type"].startswith("application/xml")
    suite = ET.fromstring(junit.text).find("testsuite")
    assert suite is not None and suite.get("failures") == "1"
    listed = api.get("/evaluations", params={"testcase": leaf}).json()
    ids = {e["id"] for e in listed["items"]}  # and the bundle test's sumo evaluation
    assert {e["id"] for e in created.values()} <= ids and len(ids) <= len(created) + 1


def test_sumo_driver_is_judged(api: httpx.Client, chain: list[dict[str, Any]]) -> None:
    reply = api.post(
        "/evaluations?format=junit", json={"testcase_id": chain[-1]["id"], "controller": "sumo"}
    )
    assert reply.status_code == 201 and reply.headers["location"].startswith("/evaluations/")
    assert ET.fromstring(reply.text).find("testsuite") is not None


def test_a_guarded_controller_is_listed_and_judged(
    api: httpx.Client, chain: list[dict[str, Any]]
) -> None:
    listed = {c["name"]: c["description"] for c in api.get("/controllers").json()}
    assert "under the RSS guard" in listed["sumo+rss"]
    reply = api.post(
        "/evaluations", json={"testcase_id": chain[-1]["id"], "controller": "sumo+rss"}
    )
    assert reply.status_code == 201, reply.text
    guard = reply.json()["verdict"]["guard"]
    assert guard["kind"] == "rss" and guard["steps"] > 0 and guard["fallback"] is None


def test_pictures(api: httpx.Client, chain: list[dict[str, Any]], town05: dict[str, Any]) -> None:
    png = api.get(chain[-1]["links"]["plot"])
    assert png.headers["content-type"] == "image/png" and png.content[:8] == b"\x89PNG\r\n\x1a\n"
    svg = api.get(chain[-1]["links"]["plot"], headers={"accept": "image/svg+xml"})
    assert svg.headers["content-type"] == "image/svg+xml" and b"<svg" in svg.content[:500]
    replay = api.get(chain[-1]["links"]["plot"], params={"controller": "sumo", "format": "svg"})
    assert replay.status_code == 200 and b"<svg" in replay.content[:500]
    junction = api.get(
        f"/networks/{town05['id']}/junctions/396/plot", params={"route": [EGO, *CHAIN]}
    )
    assert junction.headers["content-type"] == "image/png" and len(junction.content) > 10_000


def test_server_answers_health_while_a_worker_runs(
    api: httpx.Client, chain: list[dict[str, Any]]
) -> None:
    body = {"testcase_id": chain[1]["id"], "routes": ["45_1:44_1"], "seed": 7, "budget": 8}
    answers: list[httpx.Response] = []
    worker = threading.Thread(target=lambda: answers.append(api.post("/extend", json=body)))
    worker.start()
    busy = []
    while worker.is_alive():
        health = api.get("/healthz")
        assert health.status_code == 200
        busy.append(health.json()["running"])
    worker.join()
    assert max(busy) >= 1
    assert answers[0].status_code in (201, 422, 504), answers[0].text
    metrics = api.get("/metrics").text
    assert 'scengen_http_requests_total{method="POST",route="/extend",status="201"}' in metrics
    assert "scengen_workers 2" in metrics


def test_a_used_network_cannot_be_deleted(api: httpx.Client, town05: dict[str, Any]) -> None:
    reply = api.delete(f"/networks/{town05['id']}")
    assert reply.status_code == 409
    assert reply.headers["content-type"] == "application/problem+json"
    assert api.delete("/networks/4way-stop").status_code == 409


def test_a_testcase_made_from_a_file_finds_the_upload_by_its_hash(
    api: httpx.Client, town05: dict[str, Any]
) -> None:
    """Made by the CLI or the library from a path, a test-case names its network by file
    name; the server finds the uploaded network with the same content hash."""
    local = new_testcase(TOWN05, EGO, junction="396", control="allway_stop")
    assert local.network.ref == "Town05.net.xml"
    document = json.loads(dump_testcase(local))
    reply = api.post(
        "/extend", json={"testcase": document, "routes": [CHAIN[0]], "seed": 0, "budget": 60}
    )
    assert reply.status_code == 201, reply.text
    assert reply.json()["testcase"]["network"] == document["network"]
