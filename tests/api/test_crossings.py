"""Guessed crossings through a real server: POST /testcases with guess_crossings, and the
junction's description and geometry with ?guess_crossings=true."""

from __future__ import annotations

import httpx2 as httpx
import pytest

pytestmark = pytest.mark.slow


def test_a_testcase_with_guessed_crossings_keeps_them(api: httpx.Client) -> None:
    made = api.post("/testcases", json={"network": "4way-stop", "ego_route": "S2C_2:C2W_2",
                                        "guess_crossings": True})  # fmt: skip
    assert made.status_code == 201, made.text
    assert made.json()["testcase"]["crossings_guessed"] is True
    plain = api.post("/testcases", json={"network": "4way-stop", "ego_route": "S2C_1:C2W_1"})
    assert plain.status_code == 201, plain.text
    assert "crossings_guessed" not in plain.json()["testcase"]
    refused = api.post("/testcases", json={"network": "4way-stop", "ego_route": "S2C_1:C2W_1",
                                           "guess_crossings": True})  # fmt: skip
    assert refused.status_code == 422, refused.text
    assert "every car lane's index is one higher" in refused.json()["detail"]


def test_the_junction_with_guessed_crossings_has_walks_and_crosswalks(api: httpx.Client) -> None:
    own = api.get("/networks/4way-stop/junctions/C")
    assert own.status_code == 200 and own.json()["walks"] == []
    guessed = api.get("/networks/4way-stop/junctions/C", params={"guess_crossings": "true"})
    assert guessed.status_code == 200, guessed.text
    assert guessed.json()["crossings_guessed"] and len(guessed.json()["walks"]) == 8
    shapes = api.get("/networks/4way-stop/junctions/C/geometry?guess_crossings=true").json()
    assert [c["id"] for c in shapes["crossings"]] == [":C_c0", ":C_c1", ":C_c2", ":C_c3"]
    assert api.get("/networks/4way-stop/junctions/C/geometry").json()["crossings"] == []
    signal = api.get("/networks/crosswalk-signal/junctions/C/geometry").json()
    assert [c["link_index"] for c in signal["crossings"]] == [16, 17, 18, 19]
