"""The committed OpenAPI document is the app's, and its examples are real."""

from __future__ import annotations

import json
import re
from typing import Any

import pytest
from pydantic import ValidationError

from service.api.openapi import COMMITTED, openapi_document
from service.api.schemas import EXAMPLE_NETWORK, EXAMPLE_NEW_ROUTE
from service.core.network import bundled_networks, file_sha256


def test_committed_openapi_is_up_to_date() -> None:
    assert COMMITTED.read_text() == openapi_document(), (
        "openapi/openapi.json is out of date: run `make openapi` and commit it"
    )


def test_operation_ids_are_unique_and_every_operation_has_a_summary() -> None:
    schema = json.loads(openapi_document())
    operations = [op for ops in schema["paths"].values() for op in ops.values()]
    ids = [op["operationId"] for op in operations]
    assert len(ids) == len(set(ids))
    assert all(op["summary"] and not op["summary"].endswith(".") for op in operations)


def test_descriptions_are_markdown_not_restructured_text() -> None:
    """Swagger renders descriptions as Markdown: reST's double backticks show literally."""
    assert "``" not in openapi_document()


def test_extend_example_names_a_real_network_and_routes() -> None:
    schema = json.loads(openapi_document())
    body = schema["paths"]["/extend"]["post"]["requestBody"]["content"]["application/json"]
    example = body["examples"]["four-way"]["value"]
    assert example["routes"] == [EXAMPLE_NEW_ROUTE]
    network = example["testcase"]["network"]
    assert network["ref"] == EXAMPLE_NETWORK
    assert network["sha256"] == file_sha256(bundled_networks()[EXAMPLE_NETWORK])


def test_errors_are_documented_as_problems() -> None:
    schema = json.loads(openapi_document())
    extend = schema["paths"]["/extend"]["post"]["responses"]
    for code in ("422", "504"):
        assert "application/problem+json" in extend[code]["content"]
    assert "HTTPValidationError" not in schema["components"]["schemas"]


def _operations(schema: dict[str, Any]) -> list[tuple[str, str, dict[str, Any]]]:
    return [
        (path, method, operation)
        for path, operations in schema["paths"].items()
        for method, operation in operations.items()
    ]


def test_files_are_binary_strings_and_every_body_has_a_schema() -> None:
    schema = json.loads(openapi_document())
    upload = schema["components"]["schemas"]["Body_upload_network"]["properties"]["file"]
    assert upload["type"] == "string" and upload["format"] == "binary"
    assert "contentMediaType" not in openapi_document()
    binary = 0
    for path, method, operation in _operations(schema):
        for code, response in operation["responses"].items():
            for media, entry in response.get("content", {}).items():
                assert entry.get("schema"), (method, path, code, media)
                if not (media.endswith("json") or media.startswith("text/")):
                    assert entry["schema"] == {"type": "string", "format": "binary"}, (path, media)
                    binary += 1
    assert binary >= 12  # zips, XML, PNG and SVG pictures, JUnit


def test_the_token_is_required_where_listed_never_optional() -> None:
    schema = json.loads(openapi_document())
    secured = [(p, m) for p, m, op in _operations(schema) if "security" in op]
    writes = [(p, m) for p, m, _ in _operations(schema) if m in ("post", "delete")]
    assert sorted(secured) == sorted(writes)
    for _, _, operation in _operations(schema):
        assert operation.get("security", [{"HTTPBearer": []}]) == [{"HTTPBearer": []}]


def test_enums_and_patterns_are_the_servers() -> None:
    from service.api.routes.jobs import STATES
    from service.core.sim.controllers import controller_names
    from service.jobs.store import FINISHED

    schema = json.loads(openapi_document())
    components = schema["components"]["schemas"]

    def query(path: str, method: str, name: str) -> dict[str, Any]:
        parameters = schema["paths"][path][method]["parameters"]
        found: dict[str, Any] = next(p for p in parameters if p["name"] == name)["schema"]
        return found

    assert ("queued", "running", *FINISHED) == STATES
    assert query("/jobs", "get", "state")["anyOf"][0]["enum"] == list(STATES)
    for path in ("/testcases/{testcase}/plot", "/networks/{network}/junctions/{junction}/plot"):
        assert query(path, "get", "format")["enum"] == ["png", "svg"]
    assert query("/evaluations/{evaluation}", "get", "format")["enum"] == ["json", "junit"]
    assert query("/testcases/{testcase}/plot", "get", "controller")["enum"] == controller_names()
    route = components["ExtendRequestById"]["properties"]["routes"]["items"]
    assert re.fullmatch(route["pattern"], "S2C_1:C2N_1")
    for wrong in ("", ":", "S2C_1", ":C2N_1", "S2C_1:", "S2C_1::x"):
        assert not re.fullmatch(route["pattern"], wrong), wrong
    assert components["TestCaseCreate"]["properties"]["ego_route"]["pattern"] == route["pattern"]


@pytest.mark.parametrize("body", ["ExtendRequest", "EvaluationCreate"])
def test_a_body_takes_a_testcase_inline_or_by_id_never_both_or_neither(body: str) -> None:
    from service.api import schemas

    components = json.loads(openapi_document())["components"]["schemas"]
    refs = [v["$ref"].rsplit("/", 1)[1] for v in components[body]["oneOf"]]
    assert refs == [f"{body}Inline", f"{body}ById"]
    inline, by_id = (components[name] for name in refs)
    assert "testcase" in inline["required"] and "testcase_id" not in inline["properties"]
    assert "testcase_id" in by_id["required"] and "testcase" not in by_id["properties"]
    assert inline["additionalProperties"] is False and by_id["additionalProperties"] is False
    model = getattr(schemas, body)
    extra = {"routes": [EXAMPLE_NEW_ROUTE]} if body == "ExtendRequest" else {}
    for refused in (
        {},
        {"testcase": {}, "testcase_id": "x"},
        {"testcase": None, "testcase_id": "x"},
    ):
        with pytest.raises(ValidationError):
            model.model_validate({**refused, **extra})
    model.model_validate({"testcase_id": "x", **extra})


def test_budgets_and_the_extend_example_stay_within_the_servers_limit() -> None:
    from service.api import create_app
    from service.settings import Settings

    for limit in (600.0, 5.0):
        schema = create_app(Settings(max_budget=limit)).openapi()
        components = schema["components"]["schemas"]
        for name in ("ExtendRequestById", "EvaluationCreateInline", "ChainItem", "CampaignItem"):
            budget = components[name]["properties"]["budget"]["anyOf"][0]
            assert budget["maximum"] == limit, name
        body = schema["paths"]["/extend"]["post"]["requestBody"]["content"]["application/json"]
        assert 0 < body["examples"]["four-way"]["value"]["budget"] <= limit
