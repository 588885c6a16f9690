"""The test-case document: creation, validation messages, JSON round trip."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from service.core.errors import InvalidInput, InvalidTestCase, UnknownRoute
from service.core.network import load_intersection
from service.core.testcase import (
    DEFAULT_START_DISTANCE,
    SCHEMA,
    SCHEMA_WITH_PEDESTRIANS,
    TestCase,
    dump_testcase,
    load_testcase_intersection,
    new_testcase,
    parse_testcase,
    read_testcase,
)
from tests.conftest import TOWN05, TOWN07


@pytest.fixture(scope="module")
def ego_only() -> TestCase:
    return new_testcase("4way-stop", "S2C_1:C2W_1", name="left turn")


def _document(testcase: TestCase) -> dict[str, Any]:
    return json.loads(dump_testcase(testcase))  # type: ignore[no-any-return]


def _nonego(samples: int = 3, **changes: Any) -> dict[str, Any]:
    car = {
        "id": "car1",
        "route": {"fork": "W2C_0", "exit": "C2E_0"},
        "trajectory": [
            {
                "t": k * 0.1,
                "x": 100.0 + k,
                "y": 148.4,
                "heading": 90.0,
                "speed": 10.0,
                "distance": float(k),
            }
            for k in range(samples)
        ],
        "added_in": 1,
    }
    car.update(changes)
    return car


def test_new_testcase_fields(ego_only: TestCase) -> None:
    document = _document(ego_only)
    assert document["schema"] == SCHEMA
    assert document["network"]["ref"] == "4way-stop"
    assert len(document["network"]["sha256"]) == 64
    assert (document["junction"], document["control"], document["rules"]) == (
        "C",
        "allway_stop",
        "allway_stop",
    )
    assert document["ego"]["route"] == {"fork": "S2C_1", "exit": "C2W_1"}
    assert document["ego"]["start"] == {"distance": 30.0, "speed": 8.0}
    assert document["nonegos"] == []
    assert set(document["params"]) == {
        "m",
        "a_min",
        "a_max",
        "v_stop",
        "v_run",
        "v_max",
        "arrival_distance",
        "gap",
        "headway",
    }


def test_round_trip_is_byte_identical(ego_only: TestCase) -> None:
    text = dump_testcase(ego_only)
    assert dump_testcase(parse_testcase(text)) == text


def test_new_testcase_on_real_map_with_override(cache_dir: Path) -> None:
    testcase = new_testcase(TOWN05, "-44_1:-9_1", "396", "allway_stop", cache_dir=cache_dir)
    assert testcase.network.ref == "Town05.net.xml"  # no path of this machine
    assert testcase.control == "allway_stop"
    intersection = load_testcase_intersection(testcase, cache_dir)
    assert intersection.overridden
    assert intersection.route(testcase.ego.route.id).turn.value == "left"


def test_new_testcase_rejects_unknown_route() -> None:
    with pytest.raises(UnknownRoute, match="valid routes"):
        new_testcase("4way-stop", "S2C_1:C2E_1")


def test_new_testcase_rejects_start_off_the_map() -> None:
    with pytest.raises(InvalidInput, match="longer than the road"):
        new_testcase("4way-stop", "S2C_1:C2W_1", start_distance=400.0)


def test_new_testcase_rejects_start_faster_than_the_limit() -> None:
    with pytest.raises(InvalidTestCase, match="exceeds v_max"):
        new_testcase("4way-stop", "S2C_1:C2W_1", start_speed=30.0)


def test_new_testcase_rejects_start_faster_than_its_lane_allows() -> None:
    # SUMO refuses to insert a car faster than its lane's limit (13.89 m/s here)
    with pytest.raises(InvalidTestCase, match=r"above the speed limit of lane 'S2C_1'.* 13\.89"):
        new_testcase("4way-stop", "S2C_1:C2W_1", start_speed=14.5)


def test_new_testcase_refuses_a_duration_no_ego_can_reach_its_exit_in() -> None:
    """From 30 m before the stop line at 8 m/s, the ego drives 55.4 m until its back has
    left the four-way stop: braking to a stand at its stop sign (2 s at 4 m/s²) and on from
    there at up to 3 m/s² take 6.05 s at the least (service.core.motion.kinematics.fastest).
    On the uncontrolled Y no sign stops it: 46.3 m take 3.63 s at the least."""
    message = (r"duration 2 s is too short for the ego to reach its exit: .* drives 55\.4 m to "
               r"leave the junction, which takes at least 6\.05 s .* stopping only at the stop "
               r"sign.* give a duration of 6\.1 s or more")  # fmt: skip
    with pytest.raises(InvalidInput, match=message):
        new_testcase("4way-stop", "E2C_1:C2S_1", duration=2)
    with pytest.raises(InvalidInput, match=r"duration 6 s is too short"):
        new_testcase("4way-stop", "E2C_1:C2S_1", duration=6)
    assert new_testcase("4way-stop", "E2C_1:C2S_1", duration=6.1).duration == 6.1
    first = sorted(load_intersection("y-uncontrolled").offered_routes)[0]
    with pytest.raises(InvalidInput, match=r"at least 3\.63 s .* never stopping"):
        new_testcase("y-uncontrolled", first, duration=3.6)
    assert new_testcase("y-uncontrolled", first, duration=3.7)


def test_new_testcase_refuses_an_ego_whose_light_stays_red() -> None:
    """Town05 1126's program (42 s green, 3 s yellow each way): the ego from -46 waits for
    red until 45 s, so in a 45 s test-case no ego can pass; at 50 s it can."""
    with pytest.raises(InvalidInput, match=r"link 13 of traffic light '1126'\) is red for the "
                       r"whole test-case \(45 s\) and first lets it go at 45 s"):  # fmt: skip
        new_testcase(TOWN05, "-46_0:-47_0", junction="1126", duration=45)
    assert new_testcase(TOWN05, "-46_0:-47_0", junction="1126", duration=50).signals


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (
            lambda d: d["ego"]["start"].update(speed=-1),
            r"ego\.start\.speed: .*greater than or equal to 0",
        ),
        (lambda d: d.update(control="zipper"), r"control: Input should be 'allway_stop'"),
        (
            lambda d: d.update(control="traffic_light", rules="traffic_light"),
            r"a traffic_light junction needs its signal program",
        ),
        (lambda d: d.update(rules="right_before_left"), r"rules 'right_before_left' do not match"),
        (
            lambda d: d.update(schema="other/1"),
            r"schema: Input should be 'scengen/testcase/1' or 'scengen/testcase/2'",
        ),
        (lambda d: d["params"].update(v_run=0.05), r"params: .*v_stop < v_run < v_max"),
        (lambda d: d.update(colour="red"), r"colour: Extra inputs are not permitted"),
        (lambda d: d.pop("ego"), r"ego: Field required"),
        (lambda d: d["nonegos"].append(_nonego(id="ego")), r"nonegos\.0\.id: .*reserved"),
        (lambda d: d["nonegos"].extend([_nonego(), _nonego()]), r"repeated: car1"),
        (
            lambda d: d["nonegos"].append(_nonego(samples=1)),
            r"nonegos\.0\.trajectory: .*at least 2",
        ),
        # bounds on the work a test-case asks for, and numbers that are numbers
        (lambda d: d.update(timestep=1e-6), r"timestep: .*greater than or equal to 0\.001"),
        (lambda d: d.update(timestep=5e-324), r"timestep: .*greater than or equal to 0\.001"),
        (lambda d: d.update(duration=1e6), r"duration: .*less than or equal to 600"),
        (lambda d: d.update(timestep=0.001, duration=600), r"600000 samples per car; at most"),
        (lambda d: d.update(duration=float("inf")), r"duration: Input should be a finite number"),
        (lambda d: d.update(duration=float("nan")), r"duration: Input should be a finite number"),
        (lambda d: d["params"].update(v_max=float("inf")), r"params\.v_max: .*finite number"),
        (lambda d: d["ego"]["start"].update(distance=float("nan")), r"ego\.start\.distance"),
        # physical bounds: nothing accepted can overflow a solver or a worker
        (lambda d: d["params"].update(v_max=1e308), r"params\.v_max: .*less than or equal to 70"),
        (lambda d: d["params"].update(m=1e308), r"params\.m: .*less than or equal to 10"),
        (lambda d: d["params"].update(m=5e-324), r"params\.m: .*greater than or equal to 0\.01"),
        (
            lambda d: d["params"].update(a_min=-5e-324),
            r"params\.a_min: .*less than or equal to -0\.1",
        ),
        (
            lambda d: d["params"].update(a_min=-1e308),
            r"params\.a_min: .*greater than or equal to -15",
        ),
        (
            lambda d: d["params"].update(a_max=1e-300),
            r"params\.a_max: .*greater than or equal to 0\.1",
        ),
        (lambda d: d["params"].update(gap=1e308), r"params\.gap: .*less than or equal to 50"),
        (lambda d: d["params"].update(headway=1e9), r"params\.headway: .*less than or equal to 10"),
        (lambda d: d["params"].update(arrival_distance=1e-9), r"params\.arrival_distance: "),
        (lambda d: d["ego"].update(length=1e308), r"ego\.length: .*less than or equal to 30"),
        (lambda d: d["ego"].update(width=1e-9), r"ego\.width: .*greater than or equal to 0\.5"),
        (
            lambda d: d["ego"]["start"].update(speed=1e308),
            r"ego\.start\.speed: .*less than or equal to 100",
        ),
        (lambda d: d["ego"]["start"].update(distance=1e308), r"ego\.start\.distance: "),
        (lambda d: d.update(name="a\u0000b"), r"name: must not contain control .*U\+0000"),
        (lambda d: d.update(name="x" * 201), r"name: .*at most 200 characters"),
    ],
)
def test_validation_names_the_bad_field(ego_only: TestCase, change: Any, message: str) -> None:
    document = _document(ego_only)
    change(document)
    with pytest.raises(InvalidTestCase, match=message):
        parse_testcase(document)


def test_trajectory_must_not_back_up(ego_only: TestCase) -> None:
    document = _document(ego_only)
    car = _nonego()
    car["trajectory"][2]["distance"] = 0.5
    document["nonegos"].append(car)
    with pytest.raises(InvalidTestCase, match=r"nonegos\.0\.trajectory: .*sample 2.*back up"):
        parse_testcase(document)


def test_trajectory_must_sample_every_step(ego_only: TestCase) -> None:
    document = _document(ego_only)
    car = _nonego()
    car["trajectory"][2]["t"] = 0.25
    document["nonegos"].append(car)
    with pytest.raises(InvalidTestCase, match=r"nonegos\.0\.trajectory\.2\.t is 0\.25"):
        parse_testcase(document)


def test_valid_nonego_is_accepted(ego_only: TestCase) -> None:
    document = _document(ego_only)
    document["nonegos"].append(_nonego())
    assert parse_testcase(document).nonegos[0].id == "car1"


def test_read_testcase_reports_unreadable_and_non_json(tmp_path: Path) -> None:
    with pytest.raises(InvalidTestCase, match="cannot read test-case"):
        read_testcase(tmp_path / "missing.json")
    broken = tmp_path / "broken.json"
    broken.write_text("{not json")
    with pytest.raises(InvalidTestCase, match="is not JSON"):
        read_testcase(broken)


def test_changed_network_is_detected(ego_only: TestCase, tmp_path: Path) -> None:
    document = _document(ego_only)
    document["network"]["sha256"] = "0" * 64
    with pytest.raises(InvalidTestCase, match="the network has changed since"):
        load_testcase_intersection(parse_testcase(document))


def test_the_major_road_is_kept_only_when_named(cache_dir: Path) -> None:
    chosen = new_testcase(TOWN05, "4_1:-46_0", "1882", "priority_stop", cache_dir=cache_dir)
    assert chosen.major_road is None and "major_road" not in _document(chosen)
    named = new_testcase(TOWN05, "4_1:-46_0", "1882", "priority_stop", cache_dir=cache_dir,
                         major_road=["46", "4"])  # fmt: skip
    document = _document(named)
    assert document["major_road"] == ["46", "4"]
    assert list(document).index("major_road") == list(document).index("control") + 1
    assert dump_testcase(parse_testcase(dump_testcase(named))) == dump_testcase(named)
    # every later command rebuilds the network the test-case was made on
    again = load_testcase_intersection(parse_testcase(document), cache_dir)
    made = load_intersection(TOWN05, "1882", "priority_stop", cache_dir, major_road=["46", "4"])
    assert again.network_file == made.network_file
    assert {f.edge for f in again.forks.values() if f.stop_sign} == {"-45"}


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"major_road": ["46"]}, r"major_road: List should have at least 2 items"),
        ({"major_road": ["46", "4", "-45"]}, r"major_road: List should have at most 2 items"),
        ({"major_road": ["46", "46"]}, r"major_road must name two different roads"),
        ({"major_road": ["46", ""]}, r"major_road\.1: String should have at least 1 character"),
        ({"major_road": "46,4"}, r"major_road: Input should be a valid list"),
        ({"major_road": ["46", "4"], "control": "allway_stop", "rules": "allway_stop"},
         r"major_road applies to a priority_stop or priority junction, not to allway_stop"),
    ],
)  # fmt: skip
def test_a_bad_major_road_is_refused(
    ego_only: TestCase, change: dict[str, Any], message: str
) -> None:
    document = {**_document(ego_only), "control": "priority_stop", "rules": "priority_stop"}
    with pytest.raises(InvalidTestCase, match=message):
        parse_testcase({**document, **change})


def test_the_automatic_start_fits_the_road(cache_dir: Path) -> None:
    """Town07 725: the road before fork -26#1_0 is 17.91 m long. The automatic start (no
    start distance) is the whole road; a start the user gives must fit."""
    fitted = new_testcase(TOWN07, "-26#1_0:14_0", "725", "allway_stop", cache_dir=cache_dir)
    assert fitted.ego.start.distance == 17.91
    full = new_testcase(TOWN07, "15_0:14_0", "725", "allway_stop", cache_dir=cache_dir)
    assert full.ego.start.distance == DEFAULT_START_DISTANCE == 30.0
    with pytest.raises(InvalidInput, match=r"start distance 30 m is longer than the road"):
        new_testcase(TOWN07, "-26#1_0:14_0", "725", "allway_stop", 30.0, cache_dir=cache_dir)


def _pedestrian(**changes: Any) -> dict[str, Any]:
    person = {
        "id": "ped1",
        "walk": "C_c0+",
        "trajectory": [
            {
                "t": round(k * 0.1, 9),
                "x": 1.0,
                "y": 0.1 * k,
                "heading": 0.0,
                "speed": 1.0,
                "distance": round(0.1 * k, 9),
            }
            for k in range(3)
        ],
        "added_in": 1,
    }
    return {**person, **changes}


def test_a_document_with_pedestrians_is_version_2_and_one_without_stays_version_1(
    ego_only: TestCase,
) -> None:
    plain = _document(ego_only)
    assert plain["schema"] == SCHEMA and "pedestrians" not in plain
    walking = parse_testcase({**plain, "schema": SCHEMA_WITH_PEDESTRIANS,
                              "pedestrians": [_pedestrian()]})  # fmt: skip
    written = _document(walking)
    assert written["schema"] == SCHEMA_WITH_PEDESTRIANS
    assert written["pedestrians"][0]["length"] == 0.215  # SUMO's default pedestrian
    assert parse_testcase(dump_testcase(walking)) == walking
    # a version 2 document without pedestrians is written as version 1, unchanged
    assert dump_testcase(parse_testcase({**plain, "schema": SCHEMA_WITH_PEDESTRIANS})) == (
        dump_testcase(ego_only)
    )


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"schema": SCHEMA}, "pedestrians need schema scengen/testcase/2"),
        ({"pedestrians": [_pedestrian(id="ego")]}, "'ego' is reserved"),
        ({"nonegos": [_nonego(id="ped1")]}, "unique among cars and pedestrians; repeated: ped1"),
        ({"pedestrians": [_pedestrian(width=3.0)]}, r"pedestrians\.0\.width"),
        ({"params": {"walking": {"v_max": 4.0}}}, r"params\.walking\.v_max"),
        ({"params": {"walking": {"a_min": 0.5}}}, r"params\.walking\.a_min"),
    ],
)
def test_pedestrians_and_their_bounds_are_checked_at_the_edge(
    ego_only: TestCase, change: dict[str, Any], message: str
) -> None:
    document = {**_document(ego_only), "schema": SCHEMA_WITH_PEDESTRIANS,
                "pedestrians": [_pedestrian()], **change}  # fmt: skip
    with pytest.raises(InvalidTestCase, match=message):
        parse_testcase(document)
