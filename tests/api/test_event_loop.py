"""No route reads the store, parses or writes a test-case, or checks an upload's XML on the
event loop (issue 31): each such call is recorded with whether an event loop runs in the
thread that makes it, and every route family is driven through a real app and its real
workers. Nothing here is timed: a call is on the loop or it is not."""

from __future__ import annotations

import asyncio
import functools
import json
from collections.abc import Callable, Iterator
from typing import Any

import pytest
from fastapi.testclient import TestClient

from service.api import create_app, documents, worker
from service.api.bodies import OFF_LOOP_BYTES
from service.api.schemas import EXAMPLE_EGO, EXAMPLE_NEW_ROUTE
from service.core.network import bundled_networks
from service.core.testcase import TestCase
from service.settings import Settings
from service.store import Store

pytestmark = pytest.mark.slow  # 14 s of work or more: `make test-fast` leaves it out

HEALTH_PROBE = {"ping"}  # /healthz's SELECT 1 stays on the loop: it is what the probe measures


def _on_loop() -> bool:
    try:
        asyncio.get_running_loop()
    except RuntimeError:
        return False
    return True


class Watch:
    """Every watched call, by name, with whether it ran on an event loop's thread."""

    def __init__(self) -> None:
        self.calls: list[tuple[str, bool]] = []

    def wrap(self, name: str, function: Callable[..., Any]) -> Callable[..., Any]:
        @functools.wraps(function)
        def watched(*args: Any, **kwargs: Any) -> Any:
            self.calls.append((name, _on_loop()))
            return function(*args, **kwargs)

        return watched

    def on_loop(self) -> list[str]:
        return [name for name, on_loop in self.calls if on_loop]

    def names(self) -> set[str]:
        return {name for name, _ in self.calls}


@pytest.fixture(scope="module")
def watched(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[TestClient, Watch]]:
    settings = Settings(data_dir=tmp_path_factory.mktemp("loop"), workers=2)
    watch = Watch()
    patch = pytest.MonkeyPatch()
    with TestClient(create_app(settings)) as client:
        store = client.app.state.scengen.store  # type: ignore[attr-defined]
        for name, member in vars(Store).items():
            if callable(member) and not name.startswith("_") and name not in HEALTH_PROBE:
                patch.setattr(store, name, watch.wrap(f"Store.{name}", getattr(store, name)))
        for name in ("model_validate", "model_validate_json", "model_dump", "model_dump_json"):
            method = getattr(TestCase, name)
            wrapped = watch.wrap(f"TestCase.{name}", method)
            patch.setattr(TestCase, name, wrapped if "dump" in name else classmethod(
                lambda _cls, *a, _w=wrapped, **k: _w(*a, **k)))  # fmt: skip
        patch.setattr(documents, "compact_json", watch.wrap("compact_json", documents.compact_json))
        patch.setattr(worker, "xml_refusal", watch.wrap("xml_refusal", worker.xml_refusal))
        yield client, watch
    patch.undo()


@pytest.fixture(scope="module")
def made(watched: tuple[TestClient, Watch]) -> dict[str, str]:
    """A root test-case and its extension (made before the families are watched)."""
    client, _ = watched
    root = client.post("/testcases", json={"network": "4way-stop", "ego_route": EXAMPLE_EGO})
    assert root.status_code == 201, root.text
    grown = client.post(
        "/extend",
        json={"testcase_id": root.json()["id"], "routes": [EXAMPLE_NEW_ROUTE], "budget": 60},
    )
    assert grown.status_code == 201, grown.text
    return {"root": root.json()["id"], "leaf": grown.json()["id"], "document": grown.text}


def _padded(body: dict[str, Any]) -> bytes:
    """A JSON body over OFF_LOOP_BYTES (white space), validated in a worker process."""
    return (json.dumps(body) + " " * (OFF_LOOP_BYTES + 1)).encode()


def _testcases(client: TestClient, made: dict[str, str]) -> None:
    leaf = made["leaf"]
    fetched = client.get(f"/testcases/{leaf}").json()
    extended = json.loads(made["document"])
    assert fetched == {key: extended[key] for key in fetched}
    assert json.loads(client.get(f"/testcases/{leaf}/document").text) == fetched["testcase"]
    assert client.get("/testcases").json()["total"] >= 2
    assert [a["id"] for a in client.get(f"/testcases/{leaf}/lineage").json()["ancestors"]] == [
        made["root"]
    ]
    for path in ("bundle", "openscenario", "plot?format=svg"):
        assert client.get(f"/testcases/{leaf}/{path}").status_code == 200, path
    assert client.get(f"/testcases/{leaf}/bundle").content[:2] == b"PK"  # from the cache
    other = client.post("/testcases", json={"network": "4way-stop", "ego_route": EXAMPLE_NEW_ROUTE})
    assert client.delete(f"/testcases/{made['root']}").status_code == 409
    assert client.delete(f"/testcases/{other.json()['id']}").status_code == 204


def _extend(client: TestClient, made: dict[str, str]) -> None:
    by_id = {"testcase_id": made["root"], "routes": ["W2C_1:C2E_1"], "budget": 60}
    inline = {"testcase": json.loads(made["document"])["testcase"], "routes": ["W2C_1:C2E_1"]}
    for body, parent in ((by_id, made["root"]), (inline | {"budget": 60}, made["leaf"])):
        reply = client.post(
            "/extend", content=_padded(body), headers={"content-type": "application/json"}
        )
        assert reply.status_code in (201, 422), reply.text  # 422: no more complex test-case
        if reply.status_code == 201:
            assert reply.json()["parent"] == parent, reply.text


def _evaluations(client: TestClient, made: dict[str, str]) -> None:
    inline = json.loads(made["document"])["testcase"]
    by_id = client.post("/evaluations", json={"testcase_id": made["leaf"], "controller": "sumo"})
    assert by_id.status_code == 201, by_id.text
    sent = client.post(
        "/evaluations",
        content=_padded({"testcase": inline, "controller": "certificate:solvability"}),
        headers={"content-type": "application/json"},
    )
    assert sent.status_code == 201 and sent.json()["testcase"] == made["leaf"], sent.text
    ident = by_id.json()["id"]
    assert client.get(f"/evaluations/{ident}").json() == by_id.json()
    assert client.get(f"/evaluations/{ident}?format=junit").text.startswith("<")
    drive = client.get(f"/evaluations/{ident}/drive").json()
    assert drive["columns"][0] == "t" and len(drive["trajectory"]) > 10
    assert client.get(f"/evaluations?testcase={made['leaf']}").json()["total"] == 2


def _networks(client: TestClient, made: dict[str, str]) -> None:
    net = bundled_networks()["4way-stop"].read_bytes()
    large = net + b"<!--" + b" " * OFF_LOOP_BYTES + b"-->"  # checked in a worker
    for content in (net, large):
        reply = client.post("/networks", files={"file": ("four.net.xml", content)})
        assert reply.status_code == 201, reply.text
        uploaded = reply.json()["id"]
        assert client.get(f"/networks/{uploaded}/file").content == content
        assert client.get(f"/networks/{uploaded}/source").status_code == 404
        assert client.delete(f"/networks/{uploaded}").status_code == 204
    refused = client.post(
        "/networks", files={"file": ("bad.net.xml", b"<net " + b"a" * OFF_LOOP_BYTES)}
    )
    assert refused.status_code == 400, refused.text
    assert "4way-stop" in [n["id"] for n in client.get("/networks").json()]
    assert client.get("/networks/4way-stop").json()["bundled"]
    for path in ("junctions", "junctions/C", "junctions/C/plot?format=svg", "junctions/C/geometry"):
        assert client.get(f"/networks/4way-stop/{path}").status_code == 200, path


def _jobs(client: TestClient, made: dict[str, str]) -> None:
    batch = {"items": [{"kind": "evaluate", "testcase_id": made["leaf"], "controllers": ["sumo"]}]}
    job = client.post("/jobs", json=batch).json()["id"]
    assert client.get(f"/jobs/{job}").json()["total"] == 1
    assert job in [j["id"] for j in client.get("/jobs").json()["items"]]
    assert client.get(f"/jobs/{job}/junit").status_code == 200
    assert client.get(f"/jobs/{job}/campaign").status_code == 404
    assert client.delete(f"/jobs/{job}").status_code == 202
    assert client.get(f"/jobs/{job}/bundles").status_code == 200
    assert client.get("/metrics").status_code == 200


FAMILIES = {
    "testcases": (_testcases, {"Store.testcase", "Store.testcase_head", "compact_json"}),
    "extend": (_extend, {"Store.testcase", "Store.add_stored"}),
    "evaluations": (_evaluations, {"Store.add_evaluation", "Store.drive_text"}),
    "networks": (_networks, {"Store.add_network", "Store.network_file", "xml_refusal"}),
    "jobs": (_jobs, {"Store.testcase"}),
}


@pytest.mark.parametrize("family", FAMILIES)
def test_a_route_family_reads_and_parses_off_the_event_loop(
    watched: tuple[TestClient, Watch], made: dict[str, str], family: str
) -> None:
    client, watch = watched
    drive, expected = FAMILIES[family]
    watch.calls.clear()
    drive(client, made)
    assert expected <= watch.names(), sorted(watch.names())  # the routes were watched
    assert watch.on_loop() == []


def test_the_watch_sees_a_call_on_the_loop(
    watched: tuple[TestClient, Watch], made: dict[str, str]
) -> None:
    client, watch = watched
    store = client.app.state.scengen.store  # type: ignore[attr-defined]
    document = json.dumps(json.loads(made["document"])["testcase"])
    watch.calls.clear()

    async def on_the_loop() -> None:
        store.testcase_head("nothing")
        TestCase.model_validate_json(document)

    asyncio.run(on_the_loop())
    store.testcase_head("nothing")
    assert watch.calls == [
        ("Store.testcase_head", True),
        ("TestCase.model_validate_json", True),
        ("Store.testcase_head", False),
    ]
