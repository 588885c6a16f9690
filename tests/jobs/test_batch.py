"""Batch validation: every mistake is named before anything runs."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

import pytest

from service.cli.submit import read_batch
from service.core.errors import InvalidInput
from service.jobs.batch import CampaignItem, ChainItem, ExtendItem, dependencies, parse_batch

ROOT = {"testcase_id": "c2de5a280aab66bd"}
CAMPAIGN = {"kind": "campaign", "network": "4way-stop", "egos": ["S2C_0:C2N_0"], "depth": 2,
            "chains": 1, "controllers": ["sumo"]}  # fmt: skip


def test_a_batch_with_every_kind_of_item() -> None:
    batch = parse_batch(
        {
            "name": "nightly",
            "items": [
                {"kind": "extend", **ROOT, "routes": ["S2C_1:C2N_1"]},
                {"kind": "chain", "after": 0, "levels": 2, "seed": 3},
                {"kind": "chain", **ROOT, "steps": [["S2C_1:C2N_1"], ["W2C_1:C2E_1"]]},
                {"kind": "evaluate", "items": [0, 1, 2], "controllers": ["sumo"]},
            ],
        }
    )
    assert [dependencies(item) for item in batch.items] == [[], [0], [], [0, 1, 2]]
    chain = batch.items[2]
    assert isinstance(chain, ChainItem) and chain.count == 2


@pytest.mark.parametrize("start", [None, 12, 12.5, [12, None], [None, None]])
def test_extend_items_take_one_start_distance_or_one_per_route(start: object) -> None:
    item = {"kind": "extend", **ROOT, "routes": ["E2C_1:C2W_1", "S2C_1:C2N_1"]}
    batch = parse_batch({"items": [{**item, "start_distance": start}]})
    extend = batch.items[0]
    assert isinstance(extend, ExtendItem) and extend.start_distance == start
    assert ExtendItem.model_validate(extend.model_dump(mode="json")) == extend  # as stored


def test_the_fingerprint_ignores_formatting_not_content() -> None:
    one = parse_batch({"items": [{"kind": "extend", **ROOT, "routes": ["a:b"]}]})
    same = parse_batch({"items": [{"routes": ["a:b"], **ROOT, "kind": "extend", "seed": 0}]})
    other = parse_batch({"items": [{"kind": "extend", **ROOT, "routes": ["a:b"], "seed": 1}]})
    assert one.fingerprint() == same.fingerprint() != other.fingerprint()
    # count 1 is the single extension batches meant before count existed
    counted = parse_batch({"items": [{"kind": "extend", **ROOT, "routes": ["a:b"], "count": 1}]})
    more = parse_batch({"items": [{"kind": "extend", **ROOT, "routes": ["a:b"], "count": 2}]})
    assert counted.fingerprint() == one.fingerprint() != more.fingerprint()


def test_a_campaign_item_reads_its_defaults() -> None:
    item = parse_batch({"items": [CAMPAIGN]}).items[0]
    assert isinstance(item, CampaignItem)
    assert (item.seed, item.duration, item.junction, item.all_egos) == (0, 45.0, None, False)
    assert dependencies(item) == []


def test_a_campaign_item_takes_a_signal_control_and_program() -> None:
    program = {"tls": "C", "offset": 5, "phases": [{"duration": 20, "state": "G" * 16}]}
    signalized = {**CAMPAIGN, "network": "4way-signal", "control": "traffic_light"}
    given = parse_batch({"items": [{**signalized, "signals": program}]})
    item = given.items[0]
    assert isinstance(item, CampaignItem) and item.control == "traffic_light"
    assert item.signals is not None and item.signals.to_program().cycle == 20.0
    # without a program, the fingerprint is the one it had before the field existed (a
    # campaign folder made then resumes); with one, it is another campaign
    plain = parse_batch({"items": [signalized]})
    document = plain.model_dump(mode="json")
    del document["items"][0]["signals"]
    before = hashlib.sha256(json.dumps(document, sort_keys=True).encode()).hexdigest()
    assert plain.fingerprint() == before != given.fingerprint()


@pytest.mark.parametrize(
    ("items", "message"),
    [
        ([], "items: List should have at least 1 item"),
        ([{"kind": "grow", **ROOT}], "does not match any of the expected tags"),
        ([{"kind": "extend", "routes": ["a:b"]}], "exactly one of testcase_id"),
        ([{"kind": "chain", **ROOT}], "exactly one of steps"),
        ([{"kind": "chain", **ROOT, "levels": 11}], "less than or equal to 10"),
        ([{"kind": "evaluate", "items": [0], "controllers": ["sumo"]}], "not an earlier one"),
        (
            [{"kind": "evaluate", **ROOT, "controllers": ["sumo"]},
             {"kind": "chain", "after": 0, "levels": 1}],
            "an evaluation, which makes no test-case",
        ),
        ([{"kind": "evaluate", **ROOT, "controllers": []}], "controllers"),
        ([{"kind": "extend", **ROOT, "routes": ["a:b"], "colour": 1}], "colour"),
        (
            [{"kind": "extend", **ROOT, "routes": ["a:b"], "start_distance": [12, None]}],
            "items.0.extend: start_distance: give one number for every new car "
            "or one entry per route: 1 route, 2 start distances",
        ),
        (
            [{"kind": "extend", **ROOT, "routes": ["a:b", "c:d"], "start_distance": [12, -1]}],
            "items.0.extend.start_distance: entry 1 (for routes[1]) is -1",
        ),
        (
            [{"kind": "extend", **ROOT, "routes": ["a:b"], "start_distance": -3}],
            "items.0.extend.start_distance: a start distance must be a finite number >= 0 m",
        ),
        ([{"kind": "extend", **ROOT, "routes": ["a:b"], "start_distance": [True]}], "True"),
        ([{"kind": "extend", **ROOT, "routes": ["a:b"], "count": 0}],
         "items.0.extend.count: Input should be greater than or equal to 1"),
        ([{"kind": "extend", **ROOT, "routes": ["a:b"], "count": 51}],
         "items.0.extend.count: Input should be less than or equal to 50"),
        ([{**CAMPAIGN, "all_egos": True}], "exactly one of egos (routes) and all_egos"),
        ([{**CAMPAIGN, "egos": ["a:b", "a:b"]}], "egos names a route twice"),
        ([{**CAMPAIGN, "controllers": ["sumo", "certificate:complexity"]}],
         "certificate:complexity replay a certificate"),
        ([{**CAMPAIGN, "depth": 0}], "depth"),
    ],
)  # fmt: skip
def test_bad_batches_are_named(items: list[dict[str, Any]], message: str) -> None:
    with pytest.raises(InvalidInput, match="invalid batch") as caught:
        parse_batch({"items": items})
    assert message in str(caught.value)


@pytest.mark.parametrize(
    ("item", "field"),
    [
        ({"kind": "chain", **ROOT, "levels": 2, "seed": True}, "seed"),
        ({"kind": "chain", **ROOT, "levels": "2"}, "levels"),
        ({"kind": "chain", "after": False, "levels": 2}, "after"),
    ],
)
def test_numbers_are_strict(item: dict[str, Any], field: str) -> None:
    """true is not 1 and "2" is not 2 (as in every other body of the API)."""
    with pytest.raises(InvalidInput, match=field):
        parse_batch({"items": [{"kind": "extend", **ROOT, "routes": ["a:b"]}, item]})


def test_a_yaml_batch_reads_floats_as_json_writes_them(tmp_path: Path) -> None:
    """PyYAML alone reads 1e-06 as a string (YAML 1.1); json.dumps writes it for 0.000001."""
    path = tmp_path / "batch.yaml"
    item = "  - {kind: extend, testcase_id: x, routes: ['a:b'], budget: %s}\n"
    path.write_text("items:\n" + item % "1e-06" + item % "1e+01")
    budgets = [item.budget for item in read_batch(path).items]  # type: ignore[union-attr]
    assert budgets == [1e-06, 10.0]


@pytest.mark.parametrize("name", ["regression.yaml", "campaign.yaml", "signals.yaml"])
def test_the_example_batches_are_valid(name: str) -> None:
    batch = read_batch(Path(__file__).parents[2] / "examples" / name)
    assert batch.items
    for item in batch.items:
        if isinstance(item, CampaignItem) and item.signals is not None:
            assert item.signals.to_program().cycle > 0
