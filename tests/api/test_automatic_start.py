"""An ego-only test-case made by the API starts where the road allows: 30 m before the
stop line by default, the whole road where it is shorter; a start given is never cut."""

from __future__ import annotations

import json

import httpx2 as httpx

from tests.conftest import TOWN07


def test_the_default_start_is_fitted_to_a_short_road(api: httpx.Client) -> None:
    upload = api.post(
        "/networks",
        files={"file": ("Town07.net.xml", TOWN07.read_bytes())},
        data={"controls": json.dumps({"725": "allway_stop"})},
    )
    assert upload.status_code == 201, upload.text
    body = {"network": upload.json()["id"], "junction": "725", "ego_route": "-26#1_0:14_0"}
    made = api.post("/testcases", json=body)
    assert made.status_code == 201, made.text
    start = made.json()["testcase"]["ego"]["start"]["distance"]
    assert 10 < start < 30  # the road before fork -26#1_0 is shorter than 30 m
    given = api.post("/testcases", json={**body, "start_distance": 30})
    assert given.status_code == 422
    assert "start distance 30 m is longer than the road before fork" in given.json()["detail"]


def test_a_duration_too_short_for_any_ego_is_refused_when_made(api: httpx.Client) -> None:
    body = {"network": "4way-stop", "ego_route": "E2C_1:C2S_1", "duration": 2}
    refused = api.post("/testcases", json=body)
    assert refused.status_code == 422, refused.text
    detail = refused.json()["detail"]
    assert "duration 2 s is too short for the ego to reach its exit" in detail
    assert "give a duration of 6.1 s or more" in detail
