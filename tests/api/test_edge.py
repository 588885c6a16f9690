"""What every request passes through: HEAD as GET without a body, the security headers
(the pages' scripts allowed by their hashes), the read policy (SCENGEN_PROTECT_READS) both
ways, and a junction id that cannot be a URL segment refused at upload."""

from __future__ import annotations

import base64
import hashlib
import re
from collections.abc import Iterator
from typing import Any

import pytest
from fastapi.testclient import TestClient

from service.api import create_app
from service.api.edge import page_policy
from service.settings import Settings
from tests.api.test_errors import assert_problem

TOKEN = "edge-token"
AUTH = {"authorization": f"Bearer {TOKEN}"}


def _client(tmp_path_factory: pytest.TempPathFactory, **settings: Any) -> Iterator[TestClient]:
    chosen = Settings(data_dir=tmp_path_factory.mktemp("edge"), workers=1, **settings)
    with TestClient(create_app(chosen), raise_server_exceptions=False) as test_client:
        yield test_client


@pytest.fixture(scope="module")
def public_reads(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    yield from _client(tmp_path_factory, api_token=TOKEN)


@pytest.fixture(scope="module")
def protected(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    yield from _client(tmp_path_factory, api_token=TOKEN, protect_reads=True)


def _get_paths(client: TestClient) -> list[str]:
    """Every GET operation of the API, its path parameters filled with ids that exist."""
    filled = {"network": "4way-stop", "junction": "C", "slug": "not-found"}
    paths = client.get("/openapi.json").json()["paths"]
    return [
        re.sub(r"\{(\w+)\}", lambda m: filled.get(m.group(1), "nope"), path)
        for path, operations in paths.items()
        if "get" in operations
    ]


def test_head_answers_every_get_route_as_get_without_a_body(public_reads: TestClient) -> None:
    paths = [*_get_paths(public_reads), "/ui/", "/ui/ui.js", "/docs"]
    assert len(paths) > 30
    for path in paths:
        if path.endswith(("/plot", "/metrics")):
            continue  # a picture is made by a worker; /metrics counts this very request
        got, head = public_reads.get(path), public_reads.head(path)
        assert head.status_code == got.status_code != 405, (path, head.status_code)
        assert head.content == b"", path
        assert head.headers["content-type"] == got.headers["content-type"], path
        if got.status_code == 200:
            assert head.headers["content-length"] == str(len(got.content)), path
    picture = public_reads.head("/networks/4way-stop/junctions/C/plot?format=svg")
    assert picture.status_code == 200 and picture.content == b""
    assert picture.headers["content-type"] == "image/svg+xml"


def test_every_response_says_nosniff_and_no_framing(public_reads: TestClient) -> None:
    for reply in (
        public_reads.get("/healthz"),
        public_reads.get("/ui/"),
        public_reads.get("/testcases/nope"),
        public_reads.post("/testcases", json={}),  # 401 from the token check
        public_reads.put("/networks"),  # 405
    ):
        assert reply.headers["x-content-type-options"] == "nosniff", reply.url
        assert reply.headers["x-frame-options"] == "DENY", reply.url
        assert "frame-ancestors 'none'" in reply.headers["content-security-policy"]
    assert "default-src 'none'" in public_reads.get("/healthz").headers["content-security-policy"]


@pytest.mark.parametrize("path", ["/ui/", "/docs", "/redoc"])
def test_a_page_may_run_its_own_scripts_only(public_reads: TestClient, path: str) -> None:
    reply = public_reads.get(path)
    policy = reply.headers["content-security-policy"]
    scripts = next(d for d in policy.split(";") if d.strip().startswith("script-src"))
    assert "unsafe" not in scripts and "*" not in scripts
    for inline in re.findall(r"<script(?![^>]*\bsrc=)[^>]*>(.*?)</script>", reply.text, re.S):
        digest = base64.b64encode(hashlib.sha256(inline.encode()).digest()).decode()
        assert f"'sha256-{digest}'" in scripts  # allowed by its hash: the page works
    assert "connect-src 'self'" in policy and "object-src 'none'" in policy


def test_a_page_revalidated_keeps_its_policy(public_reads: TestClient) -> None:
    """A browser revalidates a cached page and lays the 304's headers over the cached ones:
    a 304 that carried the policy of a non-page (no script, no stylesheet) would break the
    page it keeps (the browser UI lost its ui.js so, on a fresh clone)."""
    page = public_reads.get("/ui/")
    again = public_reads.get("/ui/", headers={"If-None-Match": page.headers["etag"]})
    assert again.status_code == 304
    assert "content-security-policy" not in again.headers
    assert again.headers["x-content-type-options"] == "nosniff"


def test_page_policy_hashes_inline_scripts_not_those_it_loads() -> None:
    page = b'<script src="/ui/ui.js"></script><script>window.X = 1;</script><style>p{}</style>'
    digest = base64.b64encode(hashlib.sha256(b"window.X = 1;").digest()).decode()
    policy = page_policy(page)
    assert f"script-src 'self' 'sha256-{digest}';" in policy
    assert policy.count("sha256-") == 1


def test_reads_are_public_by_default_writes_need_the_token(public_reads: TestClient) -> None:
    for path in ("/networks", "/testcases", "/ui/", "/metrics", "/networks/4way-stop/file"):
        assert public_reads.get(path).status_code == 200, path
    assert_problem(public_reads.post("/testcases", json={}), 401, "unauthorized")
    schema = public_reads.get("/openapi.json").json()
    assert "security" not in schema["paths"]["/testcases"]["get"]
    assert schema["paths"]["/testcases"]["post"]["security"] == [{"HTTPBearer": []}]


def test_protected_reads_need_the_token_too(protected: TestClient) -> None:
    for path in ("/networks", "/testcases", "/ui/", "/ui/ui.js", "/metrics", "/problems"):
        reply = protected.get(path)
        assert_problem(reply, 401, "unauthorized", "SCENGEN_PROTECT_READS")
        assert reply.headers["www-authenticate"] == "Bearer"
        assert protected.head(path).status_code == 401
        assert protected.get(path, headers=AUTH).status_code == 200, path
    wrong = {"authorization": "Bearer not-it"}
    assert protected.get("/networks", headers=wrong).status_code == 401
    for path in ("/healthz", "/docs", "/redoc", "/openapi.json", "/docs-assets/swagger-ui.css"):
        assert protected.get(path).status_code == 200, path  # health checks and the docs
    assert_problem(protected.post("/testcases", json={}), 401, "unauthorized")


def test_the_document_of_a_protected_server_lists_the_token_everywhere(
    protected: TestClient,
) -> None:
    schema = protected.get("/openapi.json").json()
    for path, operations in schema["paths"].items():
        for method, operation in operations.items():
            if path == "/healthz":
                assert "security" not in operation
                continue
            assert operation["security"] == [{"HTTPBearer": []}], (method, path)
            assert "401" in operation["responses"], (method, path)


def test_a_server_without_a_token_lists_none(tmp_path_factory: pytest.TempPathFactory) -> None:
    for client in _client(tmp_path_factory):
        schema = client.get("/openapi.json").json()
        for operations in schema["paths"].values():
            for operation in operations.values():
                assert "security" not in operation and "401" not in operation["responses"]


def test_protecting_reads_without_a_token_is_refused() -> None:
    with pytest.raises(ValueError, match="SCENGEN_API_TOKEN"):
        Settings(protect_reads=True)


def test_a_junction_id_with_a_slash_is_refused_at_upload(public_reads: TestClient) -> None:
    network = (
        b'<net><edge id="a2b" from="a/1" to="b"/><junction id="a/1" type="priority"/>'
        b'<junction id="b" type="dead_end"/><junction id=":a/1_0" type="internal"/></net>'
    )
    reply = public_reads.post(
        "/networks", files={"file": ("slashed.net.xml", network)}, headers=AUTH
    )
    body = assert_problem(reply, 422, "invalid-input", "'a/1'", "'/'")
    assert "':a/1_0'" not in body["detail"]  # internal junctions have no URL


def test_a_junctions_own_link_answers(public_reads: TestClient) -> None:
    listed = public_reads.get("/networks/4way-stop/junctions").json()
    for junction in listed:
        assert public_reads.get(junction["links"]["self"]).status_code == 200
