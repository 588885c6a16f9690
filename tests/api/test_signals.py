"""Signalized junctions through a real server: a test-case with the network's program or
one of the client's (the `signals` field), extended, evaluated, exported and drawn; bad
programs refused with a problem that names what is wrong and what is valid."""

from __future__ import annotations

import io
import re
import zipfile
from typing import Any

import httpx2 as httpx
import pytest

from service.core.network import bundled_networks
from tests.conftest import DATA

pytestmark = pytest.mark.slow

EGO = "S2C_1:C2W_1"  # the bundled four-way: a left turn on a permissive green
PROGRAM = {"tls": "C", "program": "mine", "offset": 5.0, "phases": [
    {"duration": 15.0, "state": "GGGgrrrrGGGgrrrr"}, {"duration": 4.0, "state": "yyyyrrrryyyyrrrr"},
    {"duration": 1.0, "state": "rrrrrrrrrrrrrrrr"}, {"duration": 15.0, "state": "rrrrGGGgrrrrGGGg"},
    {"duration": 4.0, "state": "rrrryyyyrrrryyyy"}, {"duration": 1.0, "state": "rrrrrrrrrrrrrrrr"},
]}  # fmt: skip


def _phases(count: int, **first: object) -> list[dict[str, Any]]:
    phases: list[dict[str, Any]] = [dict(p) for p in PROGRAM["phases"]][:count]  # type: ignore[index]
    phases[0].update(first)
    return phases


@pytest.fixture(scope="module")
def levels(api: httpx.Client) -> list[dict[str, Any]]:
    """A test-case under the client's program and its extension, as the server answered."""
    root = api.post("/testcases", json={"network": "4way-signal", "ego_route": EGO,
                                        "duration": 45, "signals": PROGRAM})  # fmt: skip
    assert root.status_code == 201, root.text
    body = {"testcase_id": root.json()["id"], "routes": ["N2C_0:C2S_0"], "seed": 0}
    level1 = api.post("/extend", json=body)
    assert level1.status_code == 201, level1.text
    return [root.json(), level1.json()]


def test_a_testcase_takes_the_networks_program_or_the_clients(
    api: httpx.Client, levels: list[dict[str, Any]]
) -> None:
    own = api.post("/testcases", json={"network": "4way-signal", "ego_route": EGO})
    assert own.status_code == 201, own.text
    signals = own.json()["testcase"]["signals"]
    assert (signals["tls"], signals["program"], signals["offset"]) == ("C", "0", 0.0)
    assert [p["duration"] for p in signals["phases"]] == [20, 3, 2, 20, 3, 2]
    assert levels[0]["testcase"]["signals"] == PROGRAM


def test_an_extension_keeps_the_program_and_is_judged_under_it(
    api: httpx.Client, levels: list[dict[str, Any]]
) -> None:
    root, level1 = levels
    assert level1["parent"] == root["id"] and level1["new_cars"] == ["car1"]
    assert level1["testcase"]["signals"] == PROGRAM
    verdicts = {}
    for controller in ("sumo", "certificate:solvability", "certificate:complexity"):
        reply = api.post("/evaluations", json={"testcase_id": level1["id"],
                                               "controller": controller})  # fmt: skip
        assert reply.status_code == 201, reply.text
        verdicts[controller] = reply.json()["verdict"]
    assert verdicts["certificate:solvability"]["passed"]
    complexity = verdicts["certificate:complexity"]
    assert not complexity["passed"] and {v["other"] for v in complexity["violations"]} == {"car1"}
    assert not verdicts["sumo"]["errors"]


def test_the_bundle_and_the_picture_carry_the_program(
    api: httpx.Client, levels: list[dict[str, Any]]
) -> None:
    ident = levels[1]["id"]
    reply = api.get(f"/testcases/{ident}/bundle")
    assert reply.status_code == 200, reply.text
    archive = zipfile.ZipFile(io.BytesIO(reply.content))
    logic = archive.read("testcase.signals.xml").decode()
    assert re.search(r'<tlLogic id="C" programID="mine" offset="5" type="static">', logic)
    assert logic.count("<phase ") == 6 and 'duration="15" state="GGGgrrrrGGGgrrrr"' in logic
    assert "testcase.signals.xml" in archive.read("testcase.sumocfg").decode()
    picture = api.get(f"/testcases/{ident}/plot", params={"format": "png"})
    assert picture.status_code == 200 and picture.content[:4] == b"\x89PNG"


def _nema(api: httpx.Client) -> str:
    """The bundled four-way uploaded with its program's type made NEMA (no time line)."""
    text = bundled_networks()["4way-signal"].read_text().replace('type="static"', 'type="NEMA"')
    reply = api.post("/networks", files={"file": ("nema.net.xml", text, "application/xml")})
    assert reply.status_code == 201, reply.text
    return str(reply.json()["id"])


BAD = [  # (network, signals, problem type, what the detail says)
    ("4way-signal", {**PROGRAM, "phases": _phases(6, state="GGGgrrrrGGGgrrr")}, "invalid-request",
     "signals: phases.0.state has 15 colours where the other phases have 16"),
    ("4way-signal", {**PROGRAM, "phases": _phases(1, state="GGGG")}, "invalid-input",
     "states have 4 colours, but traffic light 'C' controls 16 links (indices 0 to 15"),
    ("4way-signal", {**PROGRAM, "phases": _phases(2, state="GGGGzzzzGGGGrrrr")},
     "invalid-request", "unknown colours 'z'; valid colours: G protected green"),
    ("4way-signal", {**PROGRAM, "tls": "J7"}, "invalid-input",
     "the signal program is for traffic light 'J7', but junction 'C' is controlled by"),
    ("4way-signal", {**PROGRAM, "phases": _phases(6, duration=1e-6)}, "invalid-request",
     "phases.0.duration: Input should be greater than or equal to 0.1"),
    ("4way-signal", {**PROGRAM, "phases": _phases(6, duration=5e-324)}, "invalid-request",
     "phases.0.duration: Input should be greater than or equal to 0.1"),
    ("4way-signal", {**PROGRAM, "phases": [{"duration": 0.001, "state": "G" * 16}] * 1000},
     "invalid-request", "phases: List should have at most 64 items"),
    ("4way-signal", {**PROGRAM, "phases": [{"duration": 0.3, "state": "G" * 16}] * 3},
     "invalid-request", "the cycle (the phases' durations added) is 0.9 s; a cycle lasts at "
     "least 1 s"),
    ("4way-stop", PROGRAM, "invalid-input",
     "without traffic lights: a signal program applies to a junction of type traffic_light"),
    ("nema", None, "invalid-input", "program '0' is of type 'NEMA', which scengen cannot read "
     "as a time line of phases; it reads types static, actuated, delay_based"),
]  # fmt: skip


@pytest.mark.parametrize(("network", "signals", "kind", "detail"), BAD, ids=range(len(BAD)))
def test_a_bad_program_is_a_problem_that_names_it(
    api: httpx.Client, network: str, signals: Any, kind: str, detail: str
) -> None:
    body = {"network": _nema(api) if network == "nema" else network, "ego_route": EGO}
    reply = api.post("/testcases", json=body | ({"signals": signals} if signals else {}))
    assert reply.status_code == 422, reply.text
    problem = reply.json()
    assert problem["type"] == f"/problems/{kind}" and detail in problem["detail"], problem
    assert "Value error" not in problem["detail"]


def test_an_actuated_network_makes_a_testcase_that_records_the_reading(
    api: httpx.Client,
) -> None:
    """POST /testcases on a network whose light runs an actuated program: the test-case's
    signals hold each phase's duration and a note saying it was read as fixed-time."""
    text = (DATA / "signals" / "tee-actuated.net.xml").read_text()
    upload = api.post("/networks", files={"file": ("tee.net.xml", text, "application/xml")})
    assert upload.status_code == 201, upload.text
    reply = api.post("/testcases", json={"network": upload.json()["id"],
                                         "ego_route": "N2J_0:J2A_0", "duration": 30})  # fmt: skip
    assert reply.status_code == 201, reply.text
    signals = reply.json()["testcase"]["signals"]
    assert [p["duration"] for p in signals["phases"]] == [20, 3, 15, 3]
    assert "actuated program '0' read as fixed-time" in signals["note"]
