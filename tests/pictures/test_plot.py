"""What the pictures say, read from SVG text (matplotlib writes text as text when asked)."""

from __future__ import annotations

from pathlib import Path

import matplotlib
import pytest

from service.core.generator.extension import extend_testcase
from service.core.motion.poses import PoseSample, generate_poses
from service.core.network import load_intersection
from service.core.testcase import TestCase, load_testcase_intersection, new_testcase
from service.pictures.plot import (
    plot_intersection,
    plot_testcase,
    queue_leaders,
    start_label,
    time_labels,
)
from tests.conftest import TOWN05
from tests.helpers import car_ahead_of_ego, retime, with_nonegos


@pytest.fixture(autouse=True)
def text_as_text() -> object:
    with matplotlib.rc_context({"svg.fonttype": "none"}):
        yield


def test_every_lane_id_is_whole_and_exits_are_labelled(tmp_path: Path) -> None:
    intersection = load_intersection(TOWN05, "396", "allway_stop")
    picture = tmp_path / "junction.svg"
    plot_intersection(intersection, picture)
    text = picture.read_text()
    for fork in intersection.forks.values():  # "-8_0", not "8_0" under a stop marker
        assert f">{fork.lane} (stop)<" in text
    for exit_lane in intersection.exits.values():
        assert f">{exit_lane.lane} (exit)<" in text


def test_a_testcase_picture_marks_starts_times_and_stop_lines(tmp_path: Path) -> None:
    start = new_testcase("4way-stop", "E2C_1:C2S_1", duration=20.0)
    testcase = extend_testcase(start, ["S2C_1:C2N_1"], seed=0).testcase
    picture = tmp_path / "testcase.svg"
    plot_testcase(testcase, load_testcase_intersection(testcase), picture)
    text = picture.read_text()
    for words in ("start (t = 0)", "stop line (sign)", ">2s<", ">10s<", "car1 (level 1)",
                  "arrived (in the car's colour)"):  # fmt: skip
        assert words in text, words


def test_the_car_behind_another_on_its_fork_is_marked() -> None:
    """The README's queue: the ego starts behind car1 on their fork."""
    case = car_ahead_of_ego()
    queues = queue_leaders(case, load_testcase_intersection(case))
    assert queues == {"car1": None, "ego": "car1"}
    assert start_label("ego", queues) == "ego behind car1"
    assert start_label("car1", queues) == "car1"


def _three_on_one_fork() -> TestCase:
    """Three non-egos on the fork E2C_0 (10, 20 and 30 m out, two routes), standing; the ego
    comes from the south."""
    base = new_testcase("4way-stop", "S2C_1:C2N_1", duration=5.0)
    junction = load_testcase_intersection(base)
    starts = [("first", "E2C_0:C2W_0", 10.0), ("second", "E2C_0:C2N_0", 20.0),
              ("third", "E2C_0:C2W_0", 30.0)]  # fmt: skip
    requests = [(junction.route(route), start) for _, route, start in starts]
    tracks = generate_poses(junction, requests, 5.0, 5.0, 0.1)
    return with_nonegos(
        base,
        [(car, route, retime(track, lambda t: (0.0, 0.0), 5.0, 0.1))
         for (car, route, _), track in zip(starts, tracks, strict=True)],
    )  # fmt: skip


def test_each_car_in_a_queue_names_the_car_right_ahead_of_it() -> None:
    case = _three_on_one_fork()
    queues = queue_leaders(case, load_testcase_intersection(case))
    assert queues == {"first": None, "second": "first", "third": "second"}  # not the ego
    assert start_label("third", queues) == "third behind second"


def test_a_queue_picture_labels_the_car_behind(tmp_path: Path) -> None:
    case = car_ahead_of_ego()
    intersection = load_testcase_intersection(case)
    picture = tmp_path / "queue.svg"
    plot_testcase(case, intersection, picture)
    text = picture.read_text()
    for words in (">ego behind car1<", ">car1<", "start on a shared fork (label: the car ahead)"):
        assert words in text, words
    plot_testcase(case, intersection, tmp_path / "queue.png")
    assert (tmp_path / "queue.png").read_bytes()[:4] == b"\x89PNG"


def test_a_car_standing_gets_one_time_label_for_its_stay() -> None:
    at = [0.0, 0.0, 5.0, 5.1, 5.2, 12.0]  # x every 2 s: moves, stands from 4 s to 8 s, moves
    shown = [PoseSample(2.0 * k, x, 0.0, 90.0, 0.0, x) for k, x in enumerate(at)]
    assert [text for _, text in time_labels(shown)] == ["2s", "4-8s", "10s"]
