"""The resource limits (docs/http-api.md, "Settings") at their edges: samples per test-case, request
body size, validation errors reported, worker memory; and large bodies validated in a worker
process, off the event loop."""

from __future__ import annotations

import json
from collections.abc import Iterator
from typing import Any

import pytest
from fastapi.testclient import TestClient
from pydantic import ValidationError

from service.api import create_app
from service.api.bodies import OFF_LOOP_BYTES
from service.api.schemas import EXAMPLE_EGO, EXAMPLE_NETWORK, EXAMPLE_NEW_ROUTE, example_testcase
from service.settings import MIN_WORKER_MEMORY_MB, Settings

UPLOAD_MB = 0.5
MAX_SAMPLES = 200
REPORTED = 3


@pytest.fixture(scope="module")
def client(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    settings = Settings(
        data_dir=tmp_path_factory.mktemp("limits"),
        max_upload_mb=UPLOAD_MB,
        max_samples=MAX_SAMPLES,
        max_reported_errors=REPORTED,
        workers=2,
    )
    with TestClient(create_app(settings), raise_server_exceptions=False) as test_client:
        yield test_client


def post_json(client: TestClient, path: str, text: str) -> Any:
    return client.post(path, content=text.encode(), headers={"content-type": "application/json"})


def padded(body: dict[str, Any], size: int) -> str:
    """``body`` as JSON of exactly ``size`` bytes (trailing spaces are still valid JSON)."""
    text = json.dumps(body)
    assert len(text) <= size
    return text + " " * (size - len(text))


def body_validations(client: TestClient) -> int:
    """How many bodies were validated in a worker process (from /metrics)."""
    total = 0
    for line in client.get("/metrics").text.splitlines():
        if line.startswith('scengen_work_total{work="body validation"'):
            total += int(float(line.rsplit(" ", 1)[1]))
    return total


CREATE = {"network": EXAMPLE_NETWORK, "ego_route": EXAMPLE_EGO}


def test_a_testcase_at_the_sample_limit_is_created_one_sample_more_is_not(
    client: TestClient,
) -> None:
    at_limit = client.post("/testcases", json={**CREATE, "duration": 20.0, "timestep": 0.1})
    assert at_limit.status_code == 201, at_limit.text
    over = client.post("/testcases", json={**CREATE, "duration": 20.1, "timestep": 0.1})
    assert over.status_code == 422, over.text
    assert "201 samples per car; at most 200" in over.json()["detail"]


def test_an_inline_testcase_over_the_sample_limit_is_refused_before_any_work(
    client: TestClient,
) -> None:
    stored = client.get("/testcases").json()["total"]
    document = {**example_testcase(), "duration": 20.1}
    reply = client.post("/extend", json={"testcase": document, "routes": [EXAMPLE_NEW_ROUTE]})
    assert reply.status_code == 422, reply.text
    assert reply.json()["type"] == "/problems/invalid-testcase"
    assert "at most 200" in reply.json()["detail"]
    assert client.get("/testcases").json()["total"] == stored


def test_a_body_at_the_upload_cap_is_read_one_byte_more_is_413(client: TestClient) -> None:
    cap = int(UPLOAD_MB * 1024 * 1024)
    at_cap = post_json(client, "/testcases", padded(CREATE, cap))
    assert at_cap.status_code == 201, at_cap.text
    over = post_json(client, "/testcases", padded(CREATE, cap + 1))
    assert over.status_code == 413, over.text
    assert over.json()["type"] == "/problems/payload-too-large"


@pytest.mark.parametrize("large", [False, True], ids=["on the loop", "in a worker"])
def test_validation_errors_are_listed_up_to_the_setting(client: TestClient, large: bool) -> None:
    def errors_of(unknown_keys: int) -> list[str]:
        body = {**CREATE, "params": {f"unknown{k}": 1 for k in range(unknown_keys)}}
        text = padded(body, OFF_LOOP_BYTES + 1) if large else json.dumps(body)
        reply = post_json(client, "/testcases", text)
        assert reply.status_code == 422, reply.text
        listed: list[str] = reply.json()["errors"]
        return listed

    exactly = errors_of(REPORTED)
    assert len(exactly) == REPORTED and not any("more errors" in e for e in exactly)
    assert exactly[0] == "params.unknown0: Extra inputs are not permitted"
    over = errors_of(REPORTED + 1)
    assert over[:REPORTED] == exactly and over[REPORTED:] == ["... and 1 more errors"]


def test_a_large_body_is_validated_in_a_worker_and_small_ones_are_not(
    client: TestClient,
) -> None:
    before = body_validations(client)
    flood = {**CREATE, "params": {f"k{k}": 1 for k in range(30_000)}}
    text = json.dumps(flood)
    assert len(text) > OFF_LOOP_BYTES
    reply = post_json(client, "/testcases", text)
    assert reply.status_code == 422
    assert reply.json()["errors"][-1] == f"... and {30_000 - REPORTED} more errors"
    assert body_validations(client) == before + 1
    small = post_json(client, "/testcases", json.dumps(CREATE))
    assert small.status_code == 201
    assert body_validations(client) == before + 1
    valid_large = post_json(client, "/testcases", padded(CREATE, OFF_LOOP_BYTES + 1))
    assert valid_large.status_code == 201
    assert valid_large.json()["id"] == small.json()["id"]  # the same test-case, validated once
    assert body_validations(client) == before + 2


def test_a_large_malformed_body_is_400(client: TestClient) -> None:
    reply = post_json(client, "/testcases", '{"network": ' + " " * OFF_LOOP_BYTES + "[")
    assert reply.status_code == 400, reply.text
    assert reply.json()["type"] == "/problems/malformed-request"


def test_a_large_body_with_booleans_for_numbers_is_refused(client: TestClient) -> None:
    """Numbers are strict: ``false`` is not 0 (the fuzzer found start_distance: false)."""
    body = {**CREATE, "start_distance": False}
    for text in (json.dumps(body), padded(body, OFF_LOOP_BYTES + 1)):
        reply = post_json(client, "/testcases", text)
        assert reply.status_code == 422, reply.text
        assert reply.json()["errors"] == ["start_distance: Input should be a valid number"]


@pytest.mark.parametrize("megabytes", [0, MIN_WORKER_MEMORY_MB, 4096])
def test_worker_memory_is_off_or_enough_to_start(megabytes: int) -> None:
    assert Settings(worker_memory_mb=megabytes).worker_memory_mb == megabytes


@pytest.mark.parametrize("megabytes", [-1, 1, MIN_WORKER_MEMORY_MB - 1])
def test_worker_memory_too_small_to_start_is_refused(megabytes: int) -> None:
    with pytest.raises(ValidationError, match="worker_memory_mb"):
        Settings(worker_memory_mb=megabytes)


@pytest.mark.parametrize(
    ("setting", "value"),
    [("max_samples", 0), ("max_samples", 60_001), ("max_reported_errors", 0)],
)
def test_limits_outside_their_range_are_refused(setting: str, value: int) -> None:
    with pytest.raises(ValidationError, match=setting):
        Settings(**{setting: value})  # type: ignore[arg-type]


def test_a_large_body_nested_too_deeply_is_400(client: TestClient) -> None:
    reply = post_json(client, "/testcases", "[" * (OFF_LOOP_BYTES + 1))
    assert reply.status_code == 400, reply.text
    assert "nested too deeply" in reply.json()["detail"]


def test_a_large_inline_testcase_is_checked_in_the_worker(client: TestClient) -> None:
    before = body_validations(client)
    stored = client.get("/testcases").json()["total"]
    document = {**example_testcase(), "params": {f"k{k}": 1 for k in range(30_000)}}
    reply = client.post("/extend", json={"testcase": document, "routes": [EXAMPLE_NEW_ROUTE]})
    assert reply.status_code == 422, reply.text
    assert reply.json()["type"] == "/problems/invalid-testcase"
    assert reply.json()["detail"].endswith("(and 29995 more)")
    assert body_validations(client) == before + 1
    assert client.get("/testcases").json()["total"] == stored


def test_a_get_with_a_large_declared_body_is_answered(client: TestClient) -> None:
    """Only bodies that a route reads count against the cap (413 is documented on those)."""
    reply = client.request("GET", "/networks", content=b"x" * (int(UPLOAD_MB * 2**20) + 1))
    assert reply.status_code == 200
