"""Stored documents answered without parsing them: the compact form equals the JSON module's,
the network is read from the first lines, and the public record is the model's JSON."""

from __future__ import annotations

import json
from datetime import UTC, datetime

import pytest

from service import store
from service.api import documents, public
from service.api.documents import compact_json, stored_network
from service.api.schemas import example_testcase
from service.core.testcase import dump_testcase, parse_testcase
from service.store import stored_form

TRICKY = [
    'a ": b',  # the key separator inside a string
    "ends with a backslash \\",
    'quote \\": and backslash',
    "line\nbreak\ttab \u2028 separator",
    "\u00e9t\u00e9 \u6771\u4eac \U0001f697",
    '{"nested": [1, 2]}',
]


def _document(name: str = "plain", cars: int = 1) -> str:
    """A stored document with samples (small numbers as Python spells them: 1e-05)."""
    testcase = example_testcase()
    testcase["name"] = name
    samples = [
        {"t": i * 0.1, "x": 1e-05 * i, "y": -2.5e-07, "heading": 90.0, "speed": 1.0,
         "distance": 0.1 * i}
        for i in range(3000)
    ]  # fmt: skip
    testcase["nonegos"] = [
        {"id": f"car{n}", "route": {"fork": "S2C_1", "exit": "C2N_1"}, "length": 5.0,
         "width": 1.8, "added_in": 1, "trajectory": samples, "events": []}
        for n in range(cars)
    ]  # fmt: skip
    return stored_form(parse_testcase(testcase)).document


@pytest.mark.parametrize("name", ["plain", *TRICKY])
def test_compact_json_equals_the_json_module(name: str) -> None:
    document = _document(name[:200].replace("\n", " ").replace("\t", " ").replace("\u2028", " "))
    compact = b"".join(compact_json(document)).decode()
    assert compact == json.dumps(json.loads(document), separators=(",", ":"))


@pytest.mark.parametrize("text", TRICKY)
def test_compact_json_keeps_every_string(text: str) -> None:
    """Strings and keys a client chooses, with quotes, colons and backslashes, in a
    document laid out as the store lays them out, over more than one piece."""
    value = {"a": [text] * 40_000, text: {text: text}, "b": {"c": [], "d": {}}}
    document = json.dumps(value, indent=2) + "\n"
    assert len(document.encode()) > 2 * 256 * 1024
    assert json.loads(b"".join(compact_json(document))) == value
    assert b"".join(compact_json(document)).decode() == json.dumps(value, separators=(",", ":"))


def test_compact_json_of_another_layout_is_parsed() -> None:
    assert compact_json('{"a": [1, 2],\n "b": "x: y"}') == [b'{"a":[1,2],"b":"x: y"}']


def test_stored_network_is_read_from_the_first_lines() -> None:
    document = _document(cars=3)
    assert stored_network(document) == parse_testcase(document).network
    assert stored_network(json.dumps(json.loads(document))) == parse_testcase(document).network


def test_testcase_body_is_the_public_record() -> None:
    stored = stored_form(parse_testcase(_document('a ": b')))
    record = store.TestCaseRecord(
        id=stored.id, network=stored.network.ref, junction=stored.junction, parent="p",
        name=stored.name, nonegos=stored.nonegos, document=stored.document,
        created_at=datetime(2026, 12, 4, tzinfo=UTC), level=stored.level,
        duration=stored.duration,
    )  # fmt: skip
    body = b"".join(documents.testcase_body(record))
    model = public.testcase_public(record)
    assert json.loads(body) == json.loads(model.model_dump_json())
    assert list(json.loads(body)) == list(model.model_dump())
    assert dump_testcase(parse_testcase(json.loads(body)["testcase"])) == stored.document
