"""``count`` in ``POST /extend`` and in a batch's extend items, through a real server: up
to N distinct extensions, each stored, each verified here by the checker itself."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from typing import Any

import httpx2 as httpx
import pytest

from service.core.generator.variety import distinct_count
from service.core.testcase import parse_testcase
from tests.api.test_errors import assert_problem
from tests.cli.test_extend_count import EGO, NEW, assert_verified
from tests.servers import Server

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def root(api: httpx.Client) -> dict[str, Any]:
    body = {"network": "4way-stop", "ego_route": EGO, "duration": 30.0, "name": "west"}
    reply = api.post("/testcases", json=body)
    assert reply.status_code == 201, reply.text
    return dict(reply.json())


def test_count_3_answers_3_distinct_stored_extensions(
    api: httpx.Client, root: dict[str, Any]
) -> None:
    body = {"testcase_id": root["id"], "routes": [NEW], "count": 3}
    reply = api.post("/extend", json=body)
    assert reply.status_code == 201, reply.text
    answer = reply.json()
    assert set(answer) == {"extensions", "shortfall"} and answer["shortfall"] is None
    extensions = answer["extensions"]
    made = [parse_testcase(e["testcase"]) for e in extensions]
    assert distinct_count(made) == 3
    old = parse_testcase(root["testcase"])
    for new in made:
        assert_verified(old, new)
    assert [e["name"] for e in extensions] == [f"west variant {k} level 1" for k in (1, 2, 3)]
    for extension in extensions:
        assert extension["parent"] == root["id"] and extension["new_cars"] == ["car1"]
        assert extension["attempts"] and set(extension["seconds"]) >= {"poses", "timing"}
        assert f"car1 ({NEW})" in extension["difference"]
        stored = api.get(f"/testcases/{extension['id']}").json()
        assert stored["testcase"] == extension["testcase"]
    children = api.get("/testcases", params={"parent": root["id"]}).json()["items"]
    assert {e["id"] for e in extensions} <= {c["id"] for c in children}
    again = api.post("/extend", json=body).json()
    assert [e["id"] for e in again["extensions"]] == [e["id"] for e in extensions]


def test_count_1_answers_as_without_a_count(api: httpx.Client, root: dict[str, Any]) -> None:
    body = {"testcase_id": root["id"], "routes": [NEW]}
    plain = api.post("/extend", json=body)
    counted = api.post("/extend", json={**body, "count": 1})
    assert plain.status_code == counted.status_code == 201, counted.text
    timed = [reply.json() for reply in (plain, counted)]
    for answer in timed:
        del answer["seconds"]  # the only part that is not the same bytes
    assert timed[0] == timed[1] and "extensions" not in timed[0]
    assert plain.headers["location"] == f"/testcases/{plain.json()['id']}"


@pytest.mark.parametrize(
    ("count", "words"),
    [(0, "greater than or equal to 1"), (51, "less than or equal to 50"), (2.5, "integer")],
)
def test_a_bad_count_is_refused(
    api: httpx.Client, root: dict[str, Any], count: object, words: str
) -> None:
    body = {"testcase_id": root["id"], "routes": [NEW], "count": count}
    assert_problem(api.post("/extend", json=body), 422, "invalid-request", "count", words)


def test_a_batch_extend_item_with_count_2(
    server: Server, api: httpx.Client, root: dict[str, Any]
) -> None:
    """Both extensions are the item's test-cases, each judged by the evaluation of the item
    and listed in the job's JUnit."""
    batch = {
        "name": "two variants",
        "items": [
            {"kind": "extend", "testcase_id": root["id"], "routes": [NEW], "count": 2},
            {"kind": "evaluate", "items": [0], "controllers": ["certificate:solvability"]},
        ],
    }
    reply = api.post("/jobs", json=batch)
    assert reply.status_code == 202, reply.text
    job = server.wait_for_job(reply.json()["id"])
    assert job["state"] == "succeeded", [i["error"] for i in job["items"]]
    extend, evaluate = job["items"]
    assert extend["progress"] == "done: 2 distinct extensions of 2 asked for"
    made = [api.get(f"/testcases/{ident}").json() for ident in extend["testcases"]]
    assert [m["name"] for m in made] == [f"west variant {k} level 1" for k in (1, 2)]
    assert all(m["parent"] == root["id"] for m in made)
    assert distinct_count([parse_testcase(m["testcase"]) for m in made]) == 2
    assert len(evaluate["evaluations"]) == 2
    suite = ET.fromstring(api.get(job["links"]["junit"]).text).find("testsuite")
    assert suite is not None
    names = sorted(case.get("name", "") for case in suite.findall("testcase"))
    assert names == [
        f"west variant {k} level 1 ({m['id']}) / certificate:solvability"
        for k, m in sorted(zip((1, 2), made, strict=True), key=lambda pair: pair[1]["name"])
    ]
