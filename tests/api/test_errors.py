"""Bad input gets a 4xx problem+json that names the problem; nothing reaches a 500."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from service.api import create_app
from service.api.problems import ALL_TYPES, DOMAIN, problem_type_of
from service.api.schemas import EXAMPLE_EGO, EXAMPLE_NEW_ROUTE, example_testcase
from service.core import errors
from service.core.testcase import new_testcase
from service.settings import Settings

TOKEN = "s3cret"
AUTH = {"authorization": f"Bearer {TOKEN}"}


@pytest.fixture(scope="module")
def client(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    settings = Settings(
        data_dir=tmp_path_factory.mktemp("api"), api_token=TOKEN, max_upload_mb=1.0, workers=2
    )
    with TestClient(create_app(settings), raise_server_exceptions=False) as test_client:
        yield test_client


def assert_problem(reply: Any, status: int, slug: str, *words: str) -> dict[str, Any]:
    assert reply.status_code == status, reply.text
    assert reply.headers["content-type"] == "application/problem+json"
    body: dict[str, Any] = reply.json()
    assert body["type"] == f"/problems/{slug}" and body["status"] == status
    for word in words:
        assert word in body["detail"], body["detail"]
    return body


def _subclasses(root: type[errors.ScengenError]) -> list[type[errors.ScengenError]]:
    """The core's error classes (service.core.errors and the core's modules; the command
    line's own errors, such as service.cli.submit's, never reach the API)."""
    found = [root]
    for child in root.__subclasses__():
        found += _subclasses(child)
    return [error for error in found if error.__module__.startswith("service.core")]


@pytest.mark.parametrize("error", _subclasses(errors.ScengenError), ids=lambda e: e.__name__)
def test_every_domain_error_has_its_own_problem_type(error: type[errors.ScengenError]) -> None:
    assert error in DOMAIN
    kind = problem_type_of(error("x"))
    assert kind.status in (422, 502, 504) and kind.slug in ALL_TYPES


def test_none_found_splits_by_budget() -> None:
    assert problem_type_of(errors.NoneFound("x", budget_exhausted=True)).status == 504
    assert problem_type_of(errors.NoneFound("x", budget_exhausted=False)).status == 422


def test_problem_types_are_documented(client: TestClient) -> None:
    catalogue = client.get("/problems").json()
    assert set(catalogue) == {f"/problems/{slug}" for slug in ALL_TYPES}
    assert client.get("/problems/budget-exceeded").json()["status"] == 504
    assert_problem(client.get("/problems/nope"), 404, "not-found", "GET /problems")


@pytest.mark.parametrize(
    ("method", "path"),
    [
        ("post", "/testcases"),
        ("post", "/extend"),
        ("post", "/evaluations"),
        ("post", "/networks"),
        ("delete", "/testcases/abc"),
        ("delete", "/networks/abc"),
    ],
)
def test_creating_or_deleting_needs_the_token(client: TestClient, method: str, path: str) -> None:
    reply = client.request(method, path, json={})
    assert_problem(reply, 401, "unauthorized", "Bearer")
    assert reply.headers["www-authenticate"] == "Bearer"
    wrong = client.request(method, path, json={}, headers={"authorization": "Bearer nope"})
    assert_problem(wrong, 401, "unauthorized", "not 'Bearer <the server's API token>'")
    # one parser for the middleware and the route: near misses are 401 everywhere (two
    # spaces used to pass the route but not the middleware: 422 for a POST, a DELETE done)
    for near in (f"Bearer  {TOKEN}", f"Bearer {TOKEN} ", f"bearer\t{TOKEN}", TOKEN):
        reply = client.request(method, path, json={}, headers={"authorization": near})
        assert_problem(reply, 401, "unauthorized")
    twice = client.request(
        method, path, json={},
        headers=[("authorization", f"Bearer {TOKEN}"), ("authorization", "Bearer nope")],
    )  # fmt: skip
    assert_problem(twice, 401, "unauthorized")


def test_reading_needs_no_token(client: TestClient) -> None:
    assert client.get("/networks").status_code == 200
    assert client.get("/testcases").json()["items"] == []


def test_malformed_json_is_a_400(client: TestClient) -> None:
    reply = client.post(
        "/extend", content=b'{"routes": [', headers={**AUTH, "content-type": "application/json"}
    )
    assert_problem(reply, 400, "malformed-request", "not valid JSON")


@pytest.mark.parametrize(
    ("body", "words"),
    [
        ({"routes": [EXAMPLE_NEW_ROUTE]}, ["exactly one of testcase"]),
        ({"testcase_id": "x", "routes": []}, ["at least one new car (routes) or pedestrian"]),
        ({"testcase_id": "x", "routes": ["a"], "colour": 1}, ["colour", "Extra inputs"]),
        (
            {"testcase_id": "x", "routes": ["a:b", "c:d"], "start_distance": [12, None, 3]},
            ["start_distance", "one entry per route", "2 routes, 3 start distances"],
        ),
        (
            {"testcase_id": "x", "routes": ["a:b"], "start_distance": -1},
            ["start_distance: ", ">= 0 m, got -1"],
        ),
        (
            {"testcase_id": "x", "routes": ["a:b", "c:d"], "start_distance": [None, -2.5]},
            ["start_distance: entry 1 (for routes[1]) is -2.5", ">= 0"],
        ),
        (
            {"testcase_id": "x", "routes": ["a:b"], "start_distance": "auto"},
            ["start_distance: ", "or a list with one number or null per route, not 'auto'"],
        ),
    ],
)
def test_invalid_extend_bodies_are_named(
    client: TestClient, body: dict[str, Any], words: list[str]
) -> None:
    assert_problem(client.post("/extend", json=body, headers=AUTH), 422, "invalid-request", *words)


def test_unknown_ids_in_the_path_are_404_in_a_body_422(client: TestClient) -> None:
    for path in ("/testcases/nope", "/testcases/nope/bundle", "/evaluations/nope",
                 "/networks/nope", "/networks/nope/junctions",
                 "/networks/nope/junctions/C/geometry",
                 "/jobs/nope/campaign", "/jobs/nope/campaign/report",
                 "/nothing-here"):  # fmt: skip
        assert_problem(client.get(path), 404, "not-found", "nope" if "nope" in path else "/docs")
    for path in ("/extend", "/evaluations"):
        body = {"testcase_id": "nope", "routes": ["a:b"]} if path == "/extend" else {
            "testcase_id": "nope"}  # fmt: skip
        reply = client.post(path, json=body, headers=AUTH)
        assert_problem(reply, 422, "invalid-input", "testcase_id: no test-case 'nope'")
    reply = client.post("/testcases", json={"network": "nope", "ego_route": "a:b"}, headers=AUTH)
    assert_problem(reply, 422, "unknown-network", "network: no network 'nope'", "4way-stop")


def test_inline_testcase_errors_name_the_field(client: TestClient) -> None:
    broken = {**example_testcase(), "timestep": -1}
    reply = client.post("/extend", json={"testcase": broken, "routes": ["a:b"]}, headers=AUTH)
    assert_problem(reply, 422, "invalid-testcase", "timestep")
    elsewhere = {**example_testcase(), "network": {"ref": "/etc/x.net.xml", "sha256": "0" * 64}}
    reply = client.post("/extend", json={"testcase": elsewhere, "routes": ["a:b"]}, headers=AUTH)
    body = assert_problem(reply, 422, "unknown-network", "POST /networks", "4way-stop")
    assert "/etc" not in body["detail"]


def test_domain_errors_from_a_worker(client: TestClient) -> None:
    base = {"testcase": example_testcase()}
    reply = client.post("/extend", json={**base, "routes": ["X:Y"]}, headers=AUTH)
    assert_problem(reply, 422, "unknown-lane", "'X'", "valid forks")
    reply = client.post("/extend", json={**base, "routes": ["W2C_1:C2N_1"]}, headers=AUTH)
    assert_problem(reply, 422, "no-more-complex-testcase", "crosses or merges")
    short = new_testcase("4way-stop", "S2C_1:C2W_1", duration=10.0)
    document = short.model_dump(mode="json", by_alias=True)
    reply = client.post("/extend", json={"testcase": document, "routes": ["N2C_0:C2S_0"]},
                        headers=AUTH)  # fmt: skip
    body = assert_problem(reply, 422, "no-more-complex-testcase", "the duration is what limits")
    assert body["detail"].split("\n")[1].startswith("  car route N2C_0:C2S_0: ")
    assert body["detail"].split("\n")[2].startswith("  to try: a longer test-case")
    assert "why" not in body and "longer" not in body  # said in the detail
    reply = client.post(
        "/testcases",
        json={"network": "4way-stop", "ego_route": EXAMPLE_EGO, "start_distance": 900},
        headers=AUTH,
    )
    assert_problem(reply, 422, "invalid-input", "900 m")


def test_start_distances_per_route_reach_the_generator(client: TestClient) -> None:
    """One start distance per route, in order: the second car (on the ego's fork, 40 m
    before the line) would start behind the ego (30 m), which the generator refuses."""
    body = {"testcase": example_testcase(), "routes": [EXAMPLE_NEW_ROUTE, "E2C_1:C2W_1"],
            "start_distance": [None, 40]}  # fmt: skip
    reply = client.post("/extend", json=body, headers=AUTH)
    assert_problem(reply, 422, "invalid-input", "new car 2 (E2C_1:C2W_1)", "40 m", "behind the ego")


def test_a_budget_too_small_is_a_504(client: TestClient) -> None:
    """Two new cars on a seed no other test asks for: more than the 0.1 s a call gets at
    least, even from a warm worker whose caches hold the example's answers."""
    routes = [EXAMPLE_NEW_ROUTE, "W2C_1:C2E_1"]
    reply = client.post(
        "/extend",
        json={"testcase": example_testcase(), "routes": routes, "seed": 97, "budget": 0.01},
        headers=AUTH,
    )
    body = reply.json()
    assert reply.status_code == 504 and body["type"] in (
        "/problems/budget-exceeded",
        "/problems/none-found-within-budget",
    )
    assert "budget" in body["detail"]


def test_an_evaluation_budget_too_small_is_a_504_not_a_fail(client: TestClient) -> None:
    """The budget is the server's limit: running out of it is no verdict on the controller,
    and nothing is stored."""
    before = client.get("/evaluations").json()["total"]
    reply = client.post(
        "/evaluations",
        json={"testcase": example_testcase(), "controller": "sumo", "budget": 0.001},
        headers=AUTH,
    )  # a millisecond: a warm worker's replay of the example takes about 20 ms
    assert_problem(reply, 504, "budget-exceeded", "budget of 0.001 s", "no verdict on sumo")
    assert client.get("/evaluations").json()["total"] == before


def test_budget_over_the_limit_is_refused(client: TestClient) -> None:
    reply = client.post(
        "/extend",
        json={"testcase": example_testcase(), "routes": [EXAMPLE_NEW_ROUTE], "budget": 9999},
        headers=AUTH,
    )
    assert_problem(reply, 422, "invalid-request", "9999", "600")


def test_controllers_are_chosen_from_the_installed_ones(client: TestClient) -> None:
    names = [c["name"] for c in client.get("/controllers").json()]
    assert "sumo" in names and "certificate:solvability" in names
    for name in ("os:system", "nope"):
        reply = client.post(
            "/evaluations",
            json={"testcase": example_testcase(), "controller": name},
            headers=AUTH,
        )
        assert_problem(reply, 422, "invalid-input", repr(name), "sumo-cautious")


def test_picture_formats(client: TestClient) -> None:
    reply = client.get("/networks/4way-stop/junctions/C/plot", params={"format": "gif"})
    assert_problem(reply, 406, "not-acceptable", "png, svg")
    reply = client.get("/networks/4way-stop/junctions/C/plot", headers={"accept": "text/html"})
    assert_problem(reply, 406, "not-acceptable", "image/png")
    reply = client.get("/networks/4way-stop/junctions/C/plot", params={"route": "X:Y"})
    assert_problem(reply, 422, "unknown-lane", "'X'")
    assert_problem(client.get("/networks/4way-stop/junctions/Z"), 422, "unknown-junction", "'Z'")


def test_junction_geometry_names_a_bad_control_and_answers_the_same_twice(
    client: TestClient,
) -> None:
    reply = client.get("/networks/4way-stop/junctions/C/geometry", params={"control": "x"})
    assert_problem(reply, 422, "invalid-request", "allway_stop")
    first = client.get("/networks/4way-stop/junctions/C/geometry")
    assert first.status_code == 200, first.text
    shapes = first.json()
    stop_lines = shapes["stop_lines"]
    assert stop_lines and all(line["stop_sign"] for line in stop_lines)
    assert client.get("/networks/4way-stop/junctions/C/geometry").json() == shapes
    uncontrolled = client.get(
        "/networks/4way-stop/junctions/C/geometry", params={"control": "right_before_left"}
    ).json()
    assert not any(s["stop_sign"] for s in uncontrolled["stop_lines"])
    assert uncontrolled["roads"] == shapes["roads"]


BOMB = b"""<?xml version="1.0"?>
<!DOCTYPE net [<!ENTITY a "aaaaaaaaaa"><!ENTITY b "&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;">
<!ENTITY c "&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;">]><net>&c;</net>"""
EXTERNAL = b"""<?xml version="1.0"?>
<!DOCTYPE net [<!ENTITY x SYSTEM "file:///etc/passwd">]><net><junction/>&x;</net>"""


@pytest.mark.parametrize(
    ("content", "status", "slug", "words"),
    [
        (BOMB, 400, "malformed-request", ["refused", "DTD"]),
        (EXTERNAL, 400, "malformed-request", ["refused", "DTD"]),
        (b"<net><junction", 400, "malformed-request", ["not well-formed"]),
        (b"<routes/>", 422, "invalid-input", ["<routes>", "SUMO <net>"]),
        (b"<net/>", 422, "invalid-input", ["no junctions"]),
    ],
    ids=["entity-expansion", "external-entity", "truncated", "not-a-net", "empty-net"],
)
def test_unsafe_or_wrong_uploads_are_refused(
    client: TestClient, content: bytes, status: int, slug: str, words: list[str]
) -> None:
    reply = client.post("/networks", files={"file": ("x.net.xml", content)}, headers=AUTH)
    assert_problem(reply, status, slug, *words)


def test_uploads_over_the_cap_are_refused(client: TestClient) -> None:
    huge = b"<net>" + b" " * (2 * 1024 * 1024) + b"</net>"
    reply = client.post("/networks", files={"file": ("x.net.xml", huge)}, headers=AUTH)
    assert_problem(reply, 413, "payload-too-large", "1 MB")


@pytest.mark.parametrize(
    ("controls", "status", "slug", "words"),
    [
        ("{not json", 400, "malformed-request", ["controls"]),
        ('["C"]', 422, "invalid-input", ["JSON object"]),
        ('{"C": "roundabout"}', 422, "invalid-input", ["roundabout", "allway_stop"]),
        ('{"Q": "allway_stop"}', 422, "unknown-junction", ["'Q'"]),
    ],
)
def test_bad_control_overrides_are_named(
    client: TestClient, controls: str, status: int, slug: str, words: list[str]
) -> None:
    net = Path(__file__).parents[2] / "sumo_nets" / "t-stop.net.xml"
    reply = client.post(
        "/networks",
        files={"file": ("t.net.xml", net.read_bytes())},
        data={"controls": controls},
        headers=AUTH,
    )
    body = assert_problem(reply, status, slug, *words)
    assert "/tmp" not in body["detail"] and "cache" not in str(body.get("network", ""))


def test_deleting(client: TestClient) -> None:
    created = client.post(
        "/testcases", json={"network": "4way-stop", "ego_route": EXAMPLE_EGO}, headers=AUTH
    )
    assert created.status_code == 201
    ident = created.json()["id"]
    assert client.delete(f"/testcases/{ident}", headers=AUTH).status_code == 204
    assert_problem(client.get(f"/testcases/{ident}"), 404, "not-found")
    assert_problem(client.delete("/networks/4way-stop", headers=AUTH), 409, "conflict", "bundled")


def test_routes_cannot_reach_outside_the_cache(client: TestClient, tmp_path: Path) -> None:
    escape = "E2C_1:C2S/../../../../../../../../../../../../tmp/scengen-escape_1"
    reply = client.get("/networks/4way-stop/junctions/C/plot", params={"route": escape})
    assert_problem(reply, 422, "unknown-lane")
    assert not Path("/tmp/scengen-escape_1.png").exists()
    many = client.get(
        "/networks/4way-stop/junctions/C/plot", params={"route": ["E2C_1:C2S_1"] * 40}
    )
    assert many.status_code == 200 and many.headers["content-type"] == "image/png"


def test_unstorable_values_are_refused_not_500(client: TestClient) -> None:
    assert client.get("/testcases/%00").status_code == 404
    body = b'{"network": "4way-stop", "ego_route": "E2C_1:C2S_1", "name": "a\\ud800b"}'
    reply = client.post(
        "/testcases", content=body, headers={**AUTH, "content-type": "application/json"}
    )
    assert reply.status_code == 422, reply.text
    assert reply.headers["content-type"] == "application/problem+json"


def test_chunked_bodies_over_the_cap_are_413(client: TestClient) -> None:
    def chunks() -> Any:
        for _ in range(40):
            yield b" " * 65536

    reply = client.post(
        "/testcases", content=chunks(), headers={**AUTH, "content-type": "application/json"}
    )
    assert_problem(reply, 413, "payload-too-large")


def test_bad_parameters_and_seeds_are_422_not_worker_failures(client: TestClient) -> None:
    reply = client.post(
        "/testcases",
        json={"network": "4way-stop", "ego_route": EXAMPLE_EGO, "params": {"v_max": 1}},
        headers=AUTH,
    )
    assert_problem(reply, 422, "invalid-request", "v_stop < v_run < v_max")
    reply = client.post(
        "/extend",
        json={"testcase": example_testcase(), "routes": [EXAMPLE_NEW_ROUTE], "seed": 2**32},
        headers=AUTH,
    )
    assert_problem(reply, 422, "invalid-request", "seed")


def test_method_not_allowed_says_which_are(client: TestClient) -> None:
    reply = client.put("/networks")
    body = assert_problem(reply, 405, "method-not-allowed", "PUT")
    assert reply.headers["allow"] == "GET, HEAD, POST" and body["status"] == 405
    # every method of the path, not only the first route's (GET said Allow: GET alone)
    reply = client.put("/testcases/0123456789abcdef")
    assert_problem(reply, 405, "method-not-allowed", "it has DELETE, GET, HEAD")
    assert reply.headers["allow"] == "DELETE, GET, HEAD"


def test_a_browser_gets_evaluations_as_json() -> None:
    from service.api.media import wants_junit

    browser = "text/html,application/xhtml+xml,application/xml;q=0.9,*/*;q=0.8"
    assert not wants_junit(None, browser)
    assert wants_junit(None, "application/xml") and not wants_junit(None, None)


def test_without_the_token_no_body_is_read(client: TestClient) -> None:
    malformed = client.post(
        "/extend", content=b'{"routes": [', headers={"content-type": "application/json"}
    )
    assert_problem(malformed, 401, "unauthorized")
    huge = client.post("/networks", files={"file": ("x.net.xml", b" " * (2 * 1024 * 1024))})
    assert_problem(huge, 401, "unauthorized")


HUGE = "99999999999999999999"
ROOT = Path(__file__).parents[2]


@pytest.mark.parametrize("path", ["/testcases", "/evaluations", "/jobs"])
def test_a_huge_offset_is_refused(client: TestClient, path: str) -> None:
    assert_problem(client.get(f"{path}?offset={HUGE}"), 422, "invalid-request", "query.offset")


@pytest.mark.parametrize(
    ("body", "field"),
    [
        ('"timestep": 1e-6, "duration": 600', "timestep"),  # 600 million samples
        ('"timestep": 5e-324', "timestep"),
        ('"duration": 1e6', "duration"),
        ('"params": {"v_max": Infinity}', "params.v_max"),
        ('"params": {"v_max": 1e308}', "params.v_max"),  # were 201, then 502 on /extend
        ('"params": {"m": 1e308}', "params.m"),
        ('"params": {"a_min": -5e-324}', "params.a_min"),
        ('"start_speed": NaN', "start_speed"),
        ('"name": "a\\u0000b"', "name"),
    ],
)
def test_numbers_and_names_are_checked_at_the_edge(
    client: TestClient, body: str, field: str
) -> None:
    """Refused with 422 naming the field, before any worker runs (they used to reach SUMO
    or z3 and come back as 502 worker-failed, or pin a worker at gigabytes)."""
    reply = client.post(
        "/testcases",
        content='{"network": "4way-stop", "ego_route": "E2C_1:C2S_1", ' + body + "}",
        headers={"content-type": "application/json", **AUTH},
    )
    assert_problem(reply, 422, "invalid-request", field)


def test_an_ego_faster_than_its_lane_allows_is_refused(client: TestClient) -> None:
    """Within v_max (15) but above lane E2C_1's 13.89 m/s: SUMO would not insert the ego."""
    reply = client.post(
        "/testcases",
        json={"network": "4way-stop", "ego_route": "E2C_1:C2S_1", "start_speed": 14.5},
        headers=AUTH,
    )
    assert_problem(reply, 422, "invalid-testcase", "speed limit of lane 'E2C_1'")


def test_an_inline_testcase_has_the_caps_of_a_created_one(client: TestClient) -> None:
    document = new_testcase("4way-stop", "E2C_1:C2S_1").model_dump(mode="json", by_alias=True)
    for change, words in (({"duration": 1e6}, "duration"), ({"timestep": 1e-6}, "timestep"),
                          ({"name": "a\u0000b"}, "control characters")):  # fmt: skip
        reply = client.post(
            "/extend", json={"testcase": {**document, **change}, "routes": ["S2C_1:C2N_1"]},
            headers=AUTH,
        )  # fmt: skip
        assert_problem(reply, 422, "invalid-testcase", words)


@pytest.mark.parametrize("junction", ["a%00b", "x" * 10_000, "a%0Ab"])
@pytest.mark.parametrize("suffix", ["", "/plot", "/geometry"])
def test_a_junction_id_never_becomes_a_path(client: TestClient, junction: str, suffix: str) -> None:
    """A NUL or a 10,000-character id was a 500 (ValueError, ENAMETOOLONG): the id was the
    name of a folder of the artifact cache. Now a 422 naming the listing, at once."""
    reply = client.get(f"/networks/4way-stop/junctions/{junction}{suffix}")
    assert_problem(reply, 422, "unknown-junction", "is not a junction id", "/junctions")
    assert len(reply.json()["detail"]) < 300


def test_deeply_nested_controls_are_a_bad_request(client: TestClient) -> None:
    reply = client.post(
        "/networks",
        files={"file": ("4way.net.xml", (ROOT / "sumo_nets" / "4way-stop.net.xml").read_bytes())},
        data={"controls": "[" * 100_000 + "]" * 100_000},
        headers=AUTH,
    )
    assert_problem(reply, 400, "malformed-request", "nested too deeply")


def test_problems_hide_server_paths_but_echo_what_the_client_sent() -> None:
    from service.api.problems import _scrub

    here = str(Path(__file__).resolve())
    assert _scrub(f"cannot read {here}: bad") == "cannot read test_errors.py: bad"
    # '../../etc' came back as '..etc'; API paths lost their folders
    assert _scrub("route '../../etc' is unknown") == "route '../../etc' is unknown"
    assert _scrub("GET /networks/4way-stop/junctions") == "GET /networks/4way-stop/junctions"


def test_a_body_with_many_errors_gets_a_bounded_answer(client: TestClient) -> None:
    params = {f"k{i}": 1 for i in range(5000)}
    reply = client.post(
        "/testcases",
        json={"network": "4way-stop", "ego_route": "E2C_1:C2S_1", "params": params},
        headers=AUTH,
    )
    body = assert_problem(reply, 422, "invalid-request", "params.k0", "... and 4980 more errors")
    assert len(body["errors"]) == 21 and len(reply.content) < 5000


def test_uploads_staged_by_a_killed_server_are_removed_at_start(tmp_path: Path) -> None:
    import os

    from service.api.app import remove_stale_uploads

    uploads = tmp_path / "uploads"
    old, fresh = uploads / "1", uploads / "2"
    for folder in (old, fresh):
        folder.mkdir(parents=True)
        (folder / "x.net.xml").write_text("<net/>")
    os.utime(old, (1.0, 1.0))  # staged long ago, by a server that was killed
    assert remove_stale_uploads(uploads, budget=120.0) == [old]
    assert not old.exists() and fresh.exists()  # another server may be checking this one
