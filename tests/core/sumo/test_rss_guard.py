"""The RSS guard on its own: real ad-rss, situations set by hand (no SUMO)."""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import pytest

from service.core.inputs import MAX_PARAMETER_FILE_BYTES
from service.core.sumo.rss_guard import (
    CARLA_DYNAMICS,
    CARLA_PEDESTRIAN_DYNAMICS,
    DYNAMICS_RANGES,
    MAX_PARAMS_BYTES,
    CarState,
    GuardError,
    RssGuard,
    WalkerState,
    dynamics_from,
    load_params,
    pedestrian_dynamics_from,
)


def _section(priority: str = "other", **car: Any) -> dict[str, Any]:
    """The ego and one car whose route crosses the ego's 5-10 m past both stop lines."""
    spec = {"relation": "crossing", "priority": priority, "length": 5.0, "stop_line": 0.0,
            "ego_area": [5.0, 10.0], "other_area": [5.0, 10.0], "link": 1, **car}  # fmt: skip
    return {"ego_length": 5.0, "lane_width": 3.2, "ego_link": 0, "cars": {"car1": spec}}


def test_a_car_crossing_ahead_with_priority_forces_braking() -> None:
    guard = RssGuard(_section("other"))
    restriction = guard.step(0.0, CarState(-10.0, 10.0), {"car1": CarState(-10.0, 10.0)}, None)
    assert guard.fallback is None
    assert restriction is not None and restriction.kind == "brake"
    assert restriction.ceiling == CARLA_DYNAMICS["brake_min"]
    assert (restriction.car, restriction.scene) == ("car1", "IntersectionObjectHasPriority")
    assert guard.limit(0.0, 2.0) == CARLA_DYNAMICS["brake_min"]
    assert guard.limit(0.0, -6.0) == -6.0  # braking harder than RSS asks is the driver's
    summary = guard.summary()
    assert (summary["interventions"], summary["braking"], summary["by_car"]) == (1, 1, {"car1": 1})
    assert summary["first"]["why"].startswith("IntersectionObjectHasPriority with car1: brake")
    guard.step(0.1, CarState(-9.0, 10.0), {"car1": CarState(-9.0, 10.0)}, None)
    guard.limit(0.1, 2.0)
    assert guard.summary()["spans"] == [  # every intervention, consecutive steps joined
        {"from": 0.0, "to": 0.1, "car": "car1", "scene": "IntersectionObjectHasPriority",
         "kind": "brake"}
    ]  # fmt: skip


def test_a_car_far_away_or_gone_changes_nothing() -> None:
    guard = RssGuard(_section("other"))
    assert guard.step(0.0, CarState(-10.0, 10.0), {"car1": CarState(-200.0, 5.0)}, None) is None
    # car1 has cleared the conflict area (its rear past 10 m): it no longer matters
    assert guard.step(0.1, CarState(-10.0, 10.0), {"car1": CarState(16.0, 10.0)}, None) is None
    assert guard.step(0.2, CarState(-10.0, 10.0), {}, None) is None
    assert guard.limit(0.2, 3.0) == 3.0
    assert guard.summary()["interventions"] == 0


def test_the_ego_with_priority_is_not_braked_for_the_yielding_car() -> None:
    guard = RssGuard(_section("ego"))
    assert guard.step(0.0, CarState(-30.0, 10.0), {"car1": CarState(-30.0, 10.0)}, None) is None


def test_the_signal_colours_decide_priority() -> None:
    guard = RssGuard(_section("signal", tie="same"))
    assert guard.priority("car1", "Gr") == "ego"
    assert guard.priority("car1", "rG") == "other"
    assert guard.priority("car1", "gg") == "same"
    assert guard.priority("car1", None) == "same"


def test_with_the_same_priority_the_car_already_in_the_area_goes_first() -> None:
    guard = RssGuard(_section("same"))
    guard.step(0.0, CarState(-10.0, 5.0), {"car1": CarState(-10.0, 5.0)}, None)
    assert guard.priority("car1", None) == "same"  # neither has entered
    guard.step(0.1, CarState(6.0, 5.0), {"car1": CarState(-9.0, 5.0)}, None)
    assert guard.priority("car1", None) == "ego"  # the ego is past 5 m: in the area
    guard.step(0.2, CarState(7.0, 5.0), {"car1": CarState(6.0, 5.0)}, None)
    assert guard.priority("car1", None) == "ego"  # and stays first


def test_a_car_close_ahead_in_the_ego_lane_forces_braking() -> None:
    section = _section()
    section["cars"]["car1"] = {"relation": "same_route", "priority": "same", "length": 5.0}
    guard = RssGuard(section)
    restriction = guard.step(0.0, CarState(-30.0, 10.0), {"car1": CarState(-20.0, 10.0)}, None)
    assert restriction is not None and restriction.scene == "SameDirection"


def test_a_situation_ad_rss_refuses_is_reported_and_the_time_gap_rule_takes_over() -> None:
    guard = RssGuard(_section("other"))
    far = 5e9  # beyond ad-rss's input range (1e9 m)
    guard.step(0.0, CarState(-10.0, 10.0), {"car1": CarState(-10.0 - far, 10.0)}, None)
    assert guard.fallback is not None and "could not model" in guard.fallback
    restriction = guard.step(0.1, CarState(-10.0, 10.0), {"car1": CarState(-10.0, 10.0)}, None)
    assert restriction is not None and restriction.scene == "time gap (intersection)"
    assert guard.summary()["fallback"] == guard.fallback


def test_without_ad_rss_the_time_gap_rule_brakes_and_says_so() -> None:
    guard = RssGuard(_section("other"), use_ad_rss=False)
    assert guard.fallback is not None
    restriction = guard.step(0.0, CarState(-10.0, 10.0), {"car1": CarState(-10.0, 10.0)}, None)
    assert restriction is not None and restriction.kind == "brake"
    # far from its area the ego may keep its speed but not accelerate
    restriction = guard.step(0.1, CarState(-60.0, 10.0), {"car1": CarState(-50.0, 10.0)}, None)
    assert restriction is not None and restriction.kind == "no-accel"


def test_rss_parameters_override_carla_defaults_and_bad_ones_are_named(tmp_path: Path) -> None:
    ego, others = dynamics_from({"response_time": 0.5, "others": {"accel_max": 2.0}})
    assert (ego["response_time"], ego["accel_max"]) == (0.5, 3.5)
    assert (others["response_time"], others["accel_max"]) == (0.5, 2.0)
    with pytest.raises(GuardError, match=r"unknown RSS parameter 'reaction'.*response_time"):
        dynamics_from({"reaction": 1.0})
    with pytest.raises(GuardError, match="brake_max <= brake_min"):
        dynamics_from({"brake_min": -9.0})
    path = tmp_path / "rss.json"
    path.write_text(json.dumps({"brake_min": "hard"}))
    with pytest.raises(GuardError, match="must be a number"):
        load_params(path)


@pytest.mark.parametrize("key", list(DYNAMICS_RANGES))
def test_every_rss_parameter_has_a_type_and_a_range(key: str) -> None:
    """Booleans are not numbers; a value out of its range is named with the range; both
    ends are valid, and CARLA's defaults lie within."""
    low, high, unit = DYNAMICS_RANGES[key]
    assert low <= CARLA_DYNAMICS[key] <= high and low <= CARLA_PEDESTRIAN_DYNAMICS[key] <= high
    for value in (True, False, None, "1", [1.0]):
        with pytest.raises(GuardError, match=rf"'{key}' \(ego\) must be a number from"):
            dynamics_from({"ego": {key: value}})
    span = high - low
    for value in (low - span, high + span, 1e308, -1e308):
        out = rf"'{key}' \(others\) is .*; valid: .* {re.escape(unit)}"
        with pytest.raises(GuardError, match=out):
            dynamics_from({"others": {key: value}})
    for value in (low, high):
        if not key.startswith("brake"):  # the brakes are ordered: checked below
            assert dynamics_from({key: value})[0][key] == value
    assert set(DYNAMICS_RANGES) == set(CARLA_DYNAMICS)


def test_a_parameter_file_is_read_within_its_limits(tmp_path: Path) -> None:
    """The bundle's run.py reads --rss-params with this standalone module: /dev/zero and
    JSON nested 100,000 deep are GuardErrors, not a machine out of memory or a traceback."""
    assert MAX_PARAMS_BYTES == MAX_PARAMETER_FILE_BYTES
    zero = tmp_path / "zero.json"
    zero.symlink_to("/dev/zero")
    with pytest.raises(GuardError, match="larger than 1,000,000 bytes"):
        load_params(zero)
    deep = tmp_path / "deep.json"
    deep.write_text("[" * 100_000 + "]" * 100_000)
    with pytest.raises(GuardError, match="nested too deeply"):
        load_params(deep)
    deep.write_text('{"ego": {"accel_max": {"x": 1}}}')
    with pytest.raises(GuardError, match="'accel_max' \\(ego\\) must be a number"):
        load_params(deep)
    deep.write_bytes(b"\xff{}")
    with pytest.raises(GuardError, match="are not JSON"):
        load_params(deep)


def _walker_section(**walker: Any) -> dict[str, Any]:
    """The ego (5 m long, 1.8 m wide) heading north, and ped1 on a crosswalk 5-9 m past its
    stop line: the ego's lane spans 4-7 m of her walk from the curb."""
    spec = {"walk": "C_c2+", "length": 0.215, "width": 0.478, "ego_area": [5.0, 9.0],
            "other_area": [4.0, 7.0], "places": [], **walker}  # fmt: skip
    return {"ego_length": 5.0, "ego_width": 1.8, "lane_width": 3.2, "ego_link": -1,
            "cars": {}, "pedestrians": {"ped1": spec}}  # fmt: skip


def _her(front: float, speed: float = 1.3) -> WalkerState:
    """ped1 walking east over the ego's lane (the ego's centre line at x = 0, its stop line
    at y = 0; her curb at x = -5.5, y = 7)."""
    return WalkerState(front, speed, -5.5 + front - 0.1075, 7.0, 90.0)


def _ego(front: float) -> tuple[float, float, float]:
    return (0.0, front - 2.5, 0.0)  # the ego's centre and heading (north)


def test_a_pedestrian_in_the_ego_path_is_an_ad_rss_pedestrian() -> None:
    """ad-rss's unstructured scene with ObjectType.Pedestrian: the ego closing in on her
    brakes; far away, or once she has walked past its lane, it may go on."""
    guard = RssGuard(_walker_section())
    restriction = guard.step(0.0, CarState(-5.0, 8.0), {}, None, {"ped1": _her(2.0)}, _ego(-5.0))
    assert guard.fallback is None
    assert restriction is not None and restriction.kind == "brake"
    assert (restriction.car, restriction.scene) == ("ped1", "Unstructured")
    assert guard.limit(0.0, 1.0) == restriction.ceiling
    far = guard.step(0.1, CarState(-80.0, 8.0), {}, None, {"ped1": _her(2.0)}, _ego(-80.0))
    assert far is None
    # her rear past the far side of the ego's lane (7 m): she is out of its path
    gone = guard.step(0.2, CarState(-5.0, 8.0), {}, None, {"ped1": _her(7.3)}, _ego(-5.0))
    assert gone is None
    assert guard.summary()["by_car"] == {"ped1": 1}


def test_without_ad_rss_the_time_gap_rule_stops_for_a_pedestrian_in_the_path() -> None:
    """The fallback: she has priority in her conflict area; the ego brakes when it is
    within its stopping distance of its own and she is in hers about when it would get
    there, and may not accelerate before that."""
    guard = RssGuard(_walker_section(), use_ad_rss=False)
    near = guard.step(0.0, CarState(-5.0, 8.0), {}, None, {"ped1": _her(4.5)}, _ego(-5.0))
    assert near is not None and near.kind == "brake"
    assert (near.car, near.scene) == ("ped1", "time gap (pedestrian)")
    early = guard.step(0.1, CarState(-30.0, 8.0), {}, None, {"ped1": _her(0.0)}, _ego(-30.0))
    assert early is not None and early.kind == "no-accel"
    # standing at the curb, far from the ego's arrival: not in its way yet
    standing = guard.step(0.2, CarState(-30.0, 8.0), {}, None, {"ped1": _her(-1.0, 0.0)})
    assert standing is None


def test_pedestrian_dynamics_are_carlas_and_can_be_set() -> None:
    assert pedestrian_dynamics_from(None) == CARLA_PEDESTRIAN_DYNAMICS
    changed = pedestrian_dynamics_from({"pedestrians": {"accel_max": 1.0}, "accel_max": 5.0})
    assert (changed["accel_max"], changed["response_time"]) == (1.0, 0.5)
    assert dynamics_from({"pedestrians": {"accel_max": 1.0}})[0]["accel_max"] == 3.5
    with pytest.raises(GuardError, match=r"unknown RSS parameter 'pace'"):
        dynamics_from({"pedestrians": {"pace": 1.0}})
