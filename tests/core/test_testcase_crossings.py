"""A test-case made with guessed crossings keeps them (crossings_guessed), and every later
load rebuilds the same network; a test-case without them keeps its bytes."""

from __future__ import annotations

import json
from pathlib import Path

from service.core.testcase import (
    dump_testcase,
    load_testcase_intersection,
    new_testcase,
    parse_testcase,
)


def test_a_testcase_without_guessed_crossings_has_no_such_key() -> None:
    testcase = new_testcase("crosswalk-stop", "S2C_2:C2W_2")
    text = dump_testcase(testcase)
    assert not testcase.crossings_guessed and "crossings_guessed" not in text
    assert dump_testcase(parse_testcase(json.loads(text))) == text
    stated = parse_testcase({**json.loads(text), "crossings_guessed": False})
    assert dump_testcase(stated) == text  # false is the default: left out
    # a bundled network with crosswalks of its own needs no guessing: walks as it is
    assert load_testcase_intersection(testcase).walks


def test_a_testcase_with_guessed_crossings_rebuilds_the_same_network(cache_dir: Path) -> None:
    testcase = new_testcase("4way-stop", "S2C_2:C2W_2", guess_crossings=True, cache_dir=cache_dir)
    document = json.loads(dump_testcase(testcase))
    assert document["crossings_guessed"] is True
    assert document["network"]["ref"] == "4way-stop"  # the network as named, not the copy
    again = parse_testcase(document)
    intersection = load_testcase_intersection(again, cache_dir)
    assert intersection.crossings_guessed and len(intersection.walks) == 8
    assert intersection.route("S2C_2:C2W_2").fork == "S2C_2"
