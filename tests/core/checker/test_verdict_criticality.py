"""The criticality in a verdict: its JSON (and verdicts stored before it), its JUnit
properties and its line in the text output."""

from __future__ import annotations

import json
from xml.etree import ElementTree as ET

import pytest

from service.cli.output import print_verdict
from service.core.checker.verdict import Verdict
from service.core.motion.criticality_records import Criticality

MEASURES = {
    "others": {
        "car1": {
            "ttc": {"value": 1.23, "t": 4.5},
            "pet": [{"area": ":C_9_1|:C_13_0", "value": 0.8, "t": 6.1}],
            "drac": {"value": 2.1, "t": 4.4},
            "distance": {"value": 3.2, "t": 5.0},
        },
        "car2": {"ttc": None, "pet": [], "drac": None, "distance": {"value": 0.9, "t": 7.0}},
    },
    "overall": {
        "ttc": {"value": 1.23, "car": "car1", "t": 4.5},
        "pet": {"value": 0.8, "car": "car1", "t": 6.1, "area": ":C_9_1|:C_13_0"},
        "drac": {"value": 2.1, "car": "car1", "t": 4.4},
        "distance": {"value": 0.9, "car": "car2", "t": 7.0},
    },
}


def verdict() -> Verdict:
    return Verdict("four-way level 1", "sumo", True, 8.4, duration=20.0,
                   criticality=Criticality.from_dict(MEASURES))  # fmt: skip


def test_criticality_round_trips_through_json() -> None:
    document = json.loads(verdict().to_json())
    assert document["criticality"] == MEASURES
    assert Verdict.from_dict(document) == verdict()


def test_a_verdict_stored_without_criticality_reads_back_as_none() -> None:
    document = verdict().to_dict()
    del document["criticality"]
    assert Verdict.from_dict(document).criticality is None
    assert Verdict.from_dict({**document, "criticality": None}).criticality is None


def test_junit_lists_the_overall_measures_as_properties() -> None:
    case = ET.fromstring(verdict().to_junit()).find("testsuite/testcase")
    assert case is not None
    found = {p.get("name"): p.get("value") for p in case.iterfind("properties/property")}
    assert found == {
        "criticality.ttc": "1.23", "criticality.ttc.car": "car1", "criticality.ttc.t": "4.5",
        "criticality.pet": "0.8", "criticality.pet.car": "car1", "criticality.pet.t": "6.1",
        "criticality.pet.area": ":C_9_1|:C_13_0",
        "criticality.drac": "2.1", "criticality.drac.car": "car1", "criticality.drac.t": "4.4",
        "criticality.distance": "0.9", "criticality.distance.car": "car2",
        "criticality.distance.t": "7",
    }  # fmt: skip


def test_text_output_has_one_line_of_overall_measures(capsys: pytest.CaptureFixture[str]) -> None:
    print_verdict(verdict())
    last = capsys.readouterr().out.splitlines()[-1]
    assert last == (
        "  criticality: TTC 1.23 s (car1 at 4.50 s), PET 0.80 s (car1 at 6.10 s), "
        "DRAC 2.10 m/s^2 (car1 at 4.40 s), distance 0.90 m (car2 at 7.00 s)"
    )
    print_verdict(Verdict("t", "c", True, 1.0, criticality=Criticality(())))
    assert capsys.readouterr().out.splitlines()[-1] == (
        "  criticality: TTC -, PET -, DRAC -, distance -"
    )
