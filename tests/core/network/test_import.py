"""Maps that are not SUMO networks: an OpenDRIVE file (written from a bundled network by
the export) and a small OpenStreetMap extract written for the tests, converted by the real
netconvert, described, and extended; the extension re-checked by the checker here."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from service.core.checker.check import check_testcase
from service.core.errors import InvalidInput
from service.core.export.openscenario import opendrive_text
from service.core.generator.extension import extend_testcase
from service.core.motion.poses import PoseSample
from service.core.network import bundled_networks, load_intersection
from service.core.network.convert import convert_network, source_format
from service.core.testcase import (
    TestCase,
    dump_testcase,
    load_testcase_intersection,
    new_testcase,
    parse_testcase,
)

OSM = Path(__file__).parents[2] / "data" / "maps" / "crossing.osm"


@pytest.fixture(scope="module")
def xodr(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("maps") / "4way.xodr"
    four_way = load_intersection(bundled_networks()["4way-stop"], "C")
    path.write_text(opendrive_text(four_way))
    return path


def _extended(old: TestCase, route: str) -> TestCase:
    new = extend_testcase(old, [route], seed=0, budget=120).testcase
    new = parse_testcase(dump_testcase(new))
    assert new.certificates is not None
    junction = load_testcase_intersection(new)
    solvable = [PoseSample(**s.model_dump()) for s in new.certificates.solvability]
    harder = [PoseSample(**s.model_dump()) for s in new.certificates.complexity]
    assert check_testcase(new, solvable, intersection=junction).passed
    assert not check_testcase(new, harder, intersection=junction).passed
    return new


def test_formats_are_told_by_the_file_name() -> None:
    assert source_format("a/b.xodr") == "opendrive" and source_format("x.OSM") == "openstreetmap"
    assert source_format("x.net.xml") is None


def test_an_opendrive_map_is_converted_keeping_its_road_ids(xodr: Path, tmp_path: Path) -> None:
    net = convert_network(xodr, tmp_path)
    again = convert_network(xodr, tmp_path / "other")
    assert net.read_bytes() == again.read_bytes()  # no time or path in it: the same hash
    junction = load_intersection(xodr, "1", "allway_stop", tmp_path)
    assert len(junction.forks) == 8 and len(junction.routes) == 16
    # every SUMO lane is an OpenDRIVE road's lane: -54_1 is road 54's second right lane
    assert all(lane.split("_")[0].lstrip("-").isdigit() for lane in junction.forks)
    assert "origId" in net.read_text()


def test_an_extension_on_an_opendrive_map(xodr: Path) -> None:
    old = new_testcase(xodr, "-54_1:-52_1", junction="1", control="allway_stop", duration=25.0)
    assert old.network.ref == "4way.xodr"  # found again by its name, converted again
    new = _extended(old, "-55_1:-50_1")
    assert [car.id for car in new.nonegos] == ["car1"]


def test_an_extension_on_an_openstreetmap_extract() -> None:
    junction = load_intersection(OSM, "1", "priority_stop")
    # the extract's stop signs are on the minor street (ways 11 and 12)
    assert {f.lane for f in junction.forks.values() if f.stop_sign} == {"11_0", "-12_0"}
    old = new_testcase(OSM, "11_0:10#1_0", junction="1", control="priority_stop", duration=25.0)
    new = _extended(old, "-10#1_0:-10#0_0")
    assert new.provenance is not None


def test_a_broken_map_is_the_users_error_with_netconvert_s_words(tmp_path: Path) -> None:
    broken = tmp_path / "broken.xodr"
    broken.write_text("<OpenDRIVE><header revMajor='1' revMinor='4'/><road/></OpenDRIVE>")
    with pytest.raises(
        InvalidInput, match=r"broken\.xodr is not an OpenDRIVE map netconvert can read: Error"
    ):
        convert_network(broken, tmp_path)


def test_the_command_line_takes_both_maps(xodr: Path, tmp_path: Path) -> None:
    """As a user types it, in a folder with the maps: new, extend, and a judge of the
    extension run later, which finds the map next to the test-case and converts it again."""
    shutil.copyfile(xodr, tmp_path / "town.xodr")
    shutil.copyfile(OSM, tmp_path / "crossing.osm")
    steps = [
        ("town.xodr", "allway_stop", "-54_1:-52_1", "-55_1:-50_1"),
        ("crossing.osm", "priority_stop", "11_0:10#1_0", "-10#1_0:-10#0_0"),
    ]
    for network, control, ego, route in steps:
        name = Path(network).stem
        commands = [
            ["new", network, "--junction", "1", "--control", control, f"--ego={ego}",
             "-o", f"{name}-0.json", "--duration", "25"],
            ["extend", f"{name}-0.json", f"--add={route}", "-o", f"{name}-1.json"],
            ["evaluate", f"{name}-1.json", "--controller", "certificate:solvability"],
        ]  # fmt: skip
        for command in commands:
            done = subprocess.run([sys.executable, "-m", "service", *command], cwd=tmp_path,
                                  capture_output=True, text=True, timeout=300)  # fmt: skip
            assert done.returncode == 0, (command, done.stderr)
        assert "PASS" in done.stdout and f"network {network}:" in done.stderr


def test_an_imported_map_s_only_junction_is_taken_with_a_control(
    xodr: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The map's one junction of three or more approaches (CARLA's plain priority) is
    taken when --control says what it is; without one, under its own type: yield signs on
    its minor road."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    junction = load_intersection(xodr, control="right_before_left", cache_dir=tmp_path)
    assert junction.junction == "1" and junction.control.value == "right_before_left"
    command = [sys.executable, "-m", "service", "intersection", str(xodr), "--control",
               "right_before_left"]  # fmt: skip
    environment = {**os.environ, "XDG_CACHE_HOME": str(tmp_path)}
    done = subprocess.run(command, capture_output=True, text=True, timeout=120, env=environment)
    assert done.returncode == 0 and "junction 1  control right_before_left" in done.stdout
    own = load_intersection(xodr, cache_dir=tmp_path)
    assert own.junction == "1" and own.control.value == "priority"
    assert any(fork.yield_sign for fork in own.forks.values())
