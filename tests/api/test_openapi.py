"""The committed OpenAPI document is the app's, and its examples are real."""

from __future__ import annotations

import json

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
