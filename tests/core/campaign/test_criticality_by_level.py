"""Criticality by level from hand-made verdicts: a level's distributions (quartiles), a
verdict without criticality counted as not measured, and whether criticality grows from
level to level, with the step where it does not."""

from __future__ import annotations

from typing import Any

from service.core.campaign.criticality_by_level import (
    criticality_trend,
    distribution,
    level_criticality,
    overall_value,
)


def measured(ttc: float | None, pet: float | None, drac: float, distance: float) -> dict[str, Any]:
    """A verdict whose overall criticality is these values (None: it never arose)."""

    def at(value: float | None) -> dict[str, Any] | None:
        return None if value is None else {"value": value, "car": "car1", "t": 4.0}

    overall = {"ttc": at(ttc), "pet": at(pet), "drac": at(drac), "distance": at(distance)}
    return {"passed": True, "criticality": {"others": {}, "overall": overall}}


def test_a_distribution_has_its_quartiles_and_values() -> None:
    assert distribution([4.0, 1.0, 3.0, 2.0, 5.0]) == {
        "count": 5, "min": 1.0, "q1": 2.0, "median": 3.0, "q3": 4.0, "max": 5.0,
        "values": [1.0, 2.0, 3.0, 4.0, 5.0],
    }  # fmt: skip
    assert distribution([1.0, 2.0])["q1"] == 1.25  # type: ignore[index]
    one = distribution([2.5])
    assert one is not None and one["min"] == one["median"] == one["max"] == 2.5
    assert distribution([]) is None


def test_a_level_counts_what_was_measured_and_skips_the_rest() -> None:
    verdicts = [
        measured(1.5, None, 2.0, 3.0),
        measured(None, 0.8, 1.0, 6.0),
        {"passed": True, "criticality": None},  # measured nothing
        {"passed": False},  # stored before verdicts had criticality
    ]
    assert overall_value(verdicts[3], "ttc") is None
    level = level_criticality(verdicts)
    assert level["measured"] == 2
    assert level["ttc"]["values"] == [1.5] and level["pet"]["values"] == [0.8]
    assert level["drac"]["median"] == 1.5 and level["distance"]["max"] == 6.0
    assert level_criticality(verdicts[2:]) == {
        "measured": 0, "ttc": None, "pet": None, "drac": None, "distance": None
    }  # fmt: skip


def test_criticality_grows_when_every_median_gets_more_critical() -> None:
    levels = [
        (0, level_criticality([{"passed": True, "criticality": None}])),  # ego alone
        (1, level_criticality([measured(3.0, 2.0, 1.0, 8.0), measured(2.0, 2.0, 1.0, 6.0)])),
        (2, level_criticality([measured(1.5, 1.0, 2.0, 4.0)])),
        (3, level_criticality([measured(1.0, 0.5, 3.5, 2.0)])),
    ]
    trend = criticality_trend(levels)
    assert trend["grows"] is True
    assert trend["measures"]["ttc"] == {
        "medians": [[1, 2.5], [2, 1.5], [3, 1.0]], "grows": True, "breaks": [], "flat": []
    }  # fmt: skip
    assert trend["summary"].startswith("grows: median TTC 2.5 → 1.5 → 1 s (levels 1–3);")
    # DRAC grows by rising; PET falling back up at level 3 is where it breaks
    levels[3] = (3, level_criticality([measured(1.0, 1.2, 3.5, 2.0)]))
    trend = criticality_trend(levels)
    assert trend["grows"] is False and trend["measures"]["drac"]["grows"] is True
    assert trend["measures"]["pet"]["breaks"] == [[2, 3]]
    pet = "median PET 2 → 1 → 1.2 s (levels 1–3), less critical from level 2 → 3"
    assert pet in trend["summary"]
    assert trend["summary"].startswith("does not grow: ")
    alone = criticality_trend(levels[:2])  # one level measured: nothing to compare
    assert alone["grows"] is None and alone["summary"] == "not measured on two levels or more"
