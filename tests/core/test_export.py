"""The exported SUMO bundle runs with the plain `sumo` binary and agrees with the
in-service evaluation (real SUMO, no mocks)."""

from __future__ import annotations

import math
import subprocess
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from service.core.check import check_testcase
from service.core.export import export_bundle
from service.core.generate import extend_testcase
from service.core.poses import centre_to_front
from service.core.replay import evaluate
from service.core.sumo_binaries import sumo_binary
from service.core.testcase import TestCase, new_testcase, read_testcase
from service.core.trajectory import read_trajectory


@pytest.fixture(scope="module")
def four_way() -> TestCase:
    start = new_testcase("4way-stop", "E2C_1:C2S_1", duration=25.0, name="left")
    return extend_testcase(start, ["S2C_1:C2N_1", "W2C_1:C2E_1"], seed=0, budget=120).testcase


@pytest.fixture(scope="module")
def bundle_run(four_way: TestCase, tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("bundle")
    export_bundle(four_way, folder)
    subprocess.run(
        [sumo_binary("sumo"), "-c", "testcase.sumocfg", "--fcd-output", "run.fcd.xml"],
        cwd=folder, check=True, capture_output=True, timeout=120,
    )  # fmt: skip
    return folder


def test_the_bundle_is_self_contained(bundle_run: Path, four_way: TestCase) -> None:
    names = {p.name for p in bundle_run.iterdir()}
    assert {"testcase.json", "testcase.rou.xml", "testcase.types.xml", "testcase.fcd.xml",
            "testcase.sumocfg", "README.md", "4way-stop.net.xml",
            "testcase.all.rou.xml"} <= names  # fmt: skip
    everyone = ET.parse(bundle_run / "testcase.all.rou.xml").getroot()
    assert [v.get("id") for v in everyone.iter("vehicle")] == ["ego", "car1", "car2"]
    assert read_testcase(bundle_run / "testcase.json") == four_way
    assert "sumo -c testcase.sumocfg" in (bundle_run / "README.md").read_text()


def test_sumo_replays_the_nonegos_within_centimetres(bundle_run: Path, four_way: TestCase) -> None:
    """SUMO's fcd-replay device puts each non-ego on its recorded front bumper; at a rare
    step (about one per car per run, near a lane boundary) it is off by up to a step's
    travel, about 10 cm at walking pace."""
    recorded = {n.id: n for n in four_way.nonegos}
    misses = []
    for step in ET.parse(bundle_run / "run.fcd.xml").getroot().iter("timestep"):
        t = float(step.get("time", "nan"))
        for car in step.iter("vehicle"):
            name = car.get("id", "")
            if name == "ego":
                continue
            nonego = recorded[name]
            sample = nonego.trajectory[round(t / four_way.timestep)]
            assert sample.t == pytest.approx(t)
            expected = centre_to_front(sample.x, sample.y, sample.heading, nonego.length)
            actual = (float(car.get("x", "nan")), float(car.get("y", "nan")))
            misses.append(math.dist(expected, actual))
    assert len(misses) >= len(recorded) * 200
    assert max(misses) < 0.15
    assert sum(1 for m in misses if m < 0.02) >= 0.99 * len(misses)


def test_the_bundle_run_gets_the_in_service_verdict(bundle_run: Path, four_way: TestCase) -> None:
    ego = read_trajectory(bundle_run / "run.fcd.xml", "ego", four_way.ego.length)
    from_bundle = check_testcase(four_way, ego, "sumo")
    in_service = evaluate(four_way, "sumo").verdict
    assert from_bundle.passed == in_service.passed
    assert {v.rule for v in from_bundle.violations} == {v.rule for v in in_service.violations}
    assert from_bundle.goal_reached == in_service.goal_reached
