"""A batch naming what the service does not have is refused when it is submitted: each
unknown test-case id, network and controller is named with the valid choices."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from service.core.errors import InvalidInput
from service.core.testcase import dump_testcase, new_testcase
from service.jobs.batch import parse_batch
from service.jobs.references import check_references, unknown_references
from service.store import Store


@pytest.fixture
def store(tmp_path: Path) -> Iterator[Store]:
    opened = Store(f"sqlite:///{tmp_path}/store.sqlite3", tmp_path / "cache")
    yield opened
    opened.close()


@pytest.fixture
def stored(store: Store) -> str:
    return store.add_testcase(new_testcase("4way-stop", "E2C_1:C2S_1")).id


def inline(network_ref: str | None = None) -> dict[str, Any]:
    document: dict[str, Any] = json.loads(dump_testcase(new_testcase("t-stop", "E2C_0:C2S_0")))
    if network_ref is not None:
        document["network"]["ref"] = network_ref
        document["network"]["sha256"] = "0" * 64
    return document


def test_a_batch_of_known_things_passes(store: Store, stored: str) -> None:
    batch = parse_batch({"items": [
        {"kind": "chain", "testcase_id": stored, "levels": 2},
        {"kind": "extend", "testcase": inline(), "routes": ["W2C_0:C2E_0"]},
        {"kind": "evaluate", "items": [0, 1], "controllers": ["sumo", "certificate:complexity"]},
        {"kind": "campaign", "network": "y-uncontrolled", "all_egos": True, "depth": 1,
         "chains": 1, "controllers": ["sumo-cautious"]},
    ]})  # fmt: skip
    assert unknown_references(batch, store) == []
    check_references(batch, store)


def test_guarded_controllers_are_known_and_guarded_certificates_are_not(
    store: Store, stored: str
) -> None:
    batch = parse_batch({"items": [
        {"kind": "evaluate", "testcase_id": stored, "controllers": ["sumo+rss"]},
        {"kind": "campaign", "network": "y-uncontrolled", "all_egos": True, "depth": 1,
         "chains": 1, "controllers": ["sumo-cautious+rss"]},
        {"kind": "evaluate", "testcase_id": stored, "controllers": ["certificate:complexity+rss"]},
    ]})  # fmt: skip
    (found,) = unknown_references(batch, store)
    assert found.startswith("items[2].controllers: 'certificate:complexity+rss' is not")


def test_each_unknown_thing_is_named_with_the_choices(store: Store, stored: str) -> None:
    batch = parse_batch({"items": [
        {"kind": "extend", "testcase_id": "0123456789abcdef", "routes": ["a:b"]},
        {"kind": "evaluate", "testcase_id": stored, "controllers": ["sumo", "my.module:Car"]},
        {"kind": "evaluate", "testcase": inline("mine.net.xml"), "controllers": ["sumo"]},
        {"kind": "campaign", "network": "Town05", "egos": ["a:b"], "depth": 1, "chains": 1,
         "controllers": ["autopilot"]},
    ]})  # fmt: skip
    with pytest.raises(InvalidInput) as refused:
        check_references(batch, store)
    found = refused.value.context["errors"]
    assert isinstance(found, list) and len(found) == 5
    assert found[0] == (
        "items[0].testcase_id: no stored test-case '0123456789abcdef' (POST /testcases makes "
        "one, GET /testcases lists them)"
    )
    # a module the client names is never imported by the server: only installed controllers
    assert found[1].startswith(
        "items[1].controllers: 'my.module:Car' is not a controller installed here (valid "
        "choices: certificate:complexity, "
    )
    assert found[2].startswith("items[2].testcase: network.ref: 'mine.net.xml' is neither "
                               "bundled nor uploaded here")  # fmt: skip
    assert found[3] == (
        "items[3].network: no network 'Town05' (known networks: 4way-signal, 4way-stop, "
        "crosswalk-signal, crosswalk-stop, t-signal, t-stop, y-uncontrolled)"
    )
    assert found[4].startswith("items[3].controllers: 'autopilot' is not a controller")
    assert str(refused.value).startswith("the batch names what this server does not have: ")
    assert "; ".join(found) in str(refused.value)


def test_an_inline_testcase_the_server_cannot_take_is_named(store: Store) -> None:
    broken = {**inline(), "duration": -1}
    batch = parse_batch({"items": [{"kind": "extend", "testcase": broken, "routes": ["a:b"]}]})
    assert unknown_references(batch, store) == [
        "items[0].testcase: invalid test-case: duration: Input should be greater than 0"
    ]
