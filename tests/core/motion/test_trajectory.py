"""Reading ego trajectories: JSON forms and SUMO FCD."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from service.core.errors import InvalidTrajectory
from service.core.motion.trajectory import parse_samples, read_trajectory

FCD = """<?xml version="1.0" encoding="UTF-8"?>
<fcd-export>
    <timestep time="0.00">
        <vehicle id="ego" x="10.00" y="20.00" angle="90.00" type="car" speed="5.00" pos="1"
                 lane="a_0" slope="0.00"/>
        <vehicle id="other" x="0.00" y="0.00" angle="0.00" type="car" speed="1.00" pos="1"
                 lane="b_0" slope="0.00"/>
    </timestep>
    <timestep time="0.10">
        <vehicle id="ego" x="10.50" y="20.00" angle="90.00" type="car" speed="5.00" pos="1.5"
                 lane="a_0" slope="0.00"/>
    </timestep>
</fcd-export>
"""


def test_fcd_front_bumper_becomes_the_centre(tmp_path: Path) -> None:
    path = tmp_path / "run.fcd.xml"
    path.write_text(FCD)
    samples = read_trajectory(path, "ego", length=4.0)
    assert [(s.t, s.x, s.y, s.heading) for s in samples] == [
        (0.0, 8.0, 20.0, 90.0),
        (0.1, 8.5, 20.0, 90.0),
    ]
    assert [s.distance for s in samples] == pytest.approx([0.0, 0.5])
    assert [s.speed for s in samples] == [5.0, 5.0]


def test_fcd_other_vehicle_by_id(tmp_path: Path) -> None:
    path = tmp_path / "run.xml"
    path.write_text(FCD)
    with pytest.raises(InvalidTrajectory, match="'other' has fewer than 2 samples"):
        read_trajectory(path, "other")


@pytest.mark.parametrize(
    "wrap", [lambda s: s, lambda s: {"samples": s}, lambda s: {"trajectory": s}]
)
def test_json_forms(tmp_path: Path, wrap: object) -> None:
    samples = [{"t": 0.0, "x": 0.0, "y": 0.0, "heading": 0.0},
               {"t": 0.5, "x": 0.0, "y": 2.0, "heading": 0.0}]  # fmt: skip
    path = tmp_path / "ego.json"
    path.write_text(json.dumps(wrap(samples)))  # type: ignore[operator]
    read = read_trajectory(path)
    assert [s.distance for s in read] == [0.0, 2.0]
    assert [s.speed for s in read] == [4.0, 4.0]


@pytest.mark.parametrize(
    ("document", "message"),
    [
        ({"nothing": []}, "expected a list of at least 2 samples"),
        ([{"t": 0, "x": 0, "y": 0}], "expected a list of at least 2 samples"),
        ([{"t": 0, "x": 0, "y": 0}, {"t": 1, "x": 0, "y": 0}], "sample 0 needs numbers"),
        ([{"t": 1, "x": 0, "y": 0, "heading": 0}, {"t": 0, "x": 0, "y": 0, "heading": 0}],
         "sample 1: times must increase"),
        ([{"t": 0, "x": "a", "y": 0, "heading": 0}, {"t": 1, "x": 0, "y": 0, "heading": 0}],
         "sample 0 needs numbers"),
    ],
)  # fmt: skip
def test_bad_json_names_the_problem(document: object, message: str) -> None:
    with pytest.raises(InvalidTrajectory, match=message):
        parse_samples(document)


def test_unreadable_and_garbage_files(tmp_path: Path) -> None:
    with pytest.raises(InvalidTrajectory, match="cannot read trajectory"):
        read_trajectory(tmp_path / "missing.json")
    garbage = tmp_path / "garbage.txt"
    garbage.write_text("hello")
    with pytest.raises(InvalidTrajectory, match="neither JSON nor SUMO FCD"):
        read_trajectory(garbage)
    broken = tmp_path / "broken.xml"
    broken.write_text("<fcd-export><timestep>")
    with pytest.raises(InvalidTrajectory, match="not well-formed XML"):
        read_trajectory(broken)
