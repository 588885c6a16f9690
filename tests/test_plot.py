"""What the pictures say, read from SVG text (matplotlib writes text as text when asked)."""

from __future__ import annotations

from pathlib import Path

import matplotlib
import pytest

from service.core.generate import extend_testcase
from service.core.network import load_intersection
from service.core.testcase import load_testcase_intersection, new_testcase
from service.plot import plot_intersection, plot_testcase
from tests.conftest import TOWN05


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
