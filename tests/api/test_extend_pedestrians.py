"""People on foot through the HTTP API: ``pedestrians`` in ``POST /extend`` and in a
batch's extend items, through a real server; every result verified here by the checker."""

from __future__ import annotations

from typing import Any

import httpx2 as httpx
import pytest

from service.core.testcase import parse_testcase
from tests.api.test_errors import assert_problem
from tests.core.generator.test_extension import assert_strictly_more_complex
from tests.servers import Server

pytestmark = pytest.mark.slow

EGO, WALK = "E2C_1:C2N_1", "C_c0-"  # a right turn over the north crosswalk, walked eastwards


@pytest.fixture(scope="module")
def root(api: httpx.Client) -> dict[str, Any]:
    body = {"network": "crosswalk-stop", "ego_route": EGO, "duration": 30.0}
    reply = api.post("/testcases", json=body)
    assert reply.status_code == 201, reply.text
    return dict(reply.json())


def test_extend_adds_a_pedestrian(api: httpx.Client, root: dict[str, Any]) -> None:
    reply = api.post("/extend", json={"testcase_id": root["id"], "pedestrians": [WALK]})
    assert reply.status_code == 201, reply.text
    answer = reply.json()
    new = parse_testcase(answer["testcase"])
    assert answer["new_cars"] == ["ped1"] and answer["parent"] == root["id"]
    assert [(p.id, p.walk) for p in new.pedestrians] == [("ped1", WALK)]
    assert answer["testcase"]["schema"] == "scengen/testcase/2"
    assert_strictly_more_complex(parse_testcase(root["testcase"]), new)


@pytest.mark.parametrize(
    ("body", "status", "slug", "words"),
    [
        ({"pedestrians": ["C_c9+"]}, 422, "unknown-walk", ("valid walks", "C_c0+")),
        ({"pedestrians": ["C_c0"]}, 422, "invalid-request", ("pedestrians",)),
        ({}, 422, "invalid-request", ("routes", "pedestrians")),
        ({"pedestrians": [WALK] * 4, "routes": ["N2C_1:C2S_1"] * 3}, 422, "invalid-request",
         ("at most 6",)),
    ],
)  # fmt: skip
def test_bad_pedestrians_are_refused_naming_the_problem(
    api: httpx.Client, root: dict[str, Any], body: dict[str, Any], status: int, slug: str,
    words: tuple[str, ...],
) -> None:  # fmt: skip
    reply = api.post("/extend", json={"testcase_id": root["id"], **body})
    assert_problem(reply, status, slug, *words)


def test_a_batch_extend_item_adds_a_pedestrian(server: Server, root: dict[str, Any]) -> None:
    api = server.client
    batch = {"items": [{"kind": "extend", "testcase_id": root["id"], "pedestrians": [WALK]}]}
    reply = api.post("/jobs", json=batch)
    assert reply.status_code == 202, reply.text
    job = server.wait_for_job(reply.json()["id"])
    assert job["state"] == "succeeded", job
    (item,) = job["items"]
    (made,) = item["testcases"]
    new = parse_testcase(api.get(f"/testcases/{made}").json()["testcase"])
    assert [p.walk for p in new.pedestrians] == [WALK]
    assert_strictly_more_complex(parse_testcase(root["testcase"]), new)
