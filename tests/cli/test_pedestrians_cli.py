"""``scengen extend --add-pedestrian WALK`` as a user runs it: a verified level with a
pedestrian, a line that says what the certificate breaks, and clear errors for walks that
do not exist, junctions without crossings and a command that names nothing to add."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest


def run(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "service", *args], capture_output=True, text=True, cwd=cwd,
        check=False, timeout=300,
    )  # fmt: skip


@pytest.fixture(scope="module")
def folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    here = tmp_path_factory.mktemp("walk")
    made = run("new", "crosswalk-stop", "--ego", "E2C_1:C2N_1", "--duration", "30", "-o",
               "t0.json", cwd=here)  # fmt: skip
    assert made.returncode == 0, made.stderr
    return here


def test_extend_adds_a_pedestrian_and_says_whose_right_of_way_the_certificate_breaks(
    folder: Path,
) -> None:
    done = run("extend", "t0.json", "--add-pedestrian", "C_c0-", "-o", "t1.json", cwd=folder)
    assert done.returncode == 0, done.stderr
    assert "added ped1; the complexity certificate violates the right-of-way of ped1 " \
        "(yieldToPedestrian)" in done.stderr  # fmt: skip
    document = json.loads((folder / "t1.json").read_text())
    assert document["schema"] == "scengen/testcase/2"
    assert [p["walk"] for p in document["pedestrians"]] == ["C_c0-"]
    judged = run("evaluate", "t1.json", "--controller", "certificate:solvability", cwd=folder)
    assert judged.returncode == 0, judged.stdout


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (["--add-pedestrian", "C_c9+"], ["walk 'C_c9+' is not a walk", "valid walks: C_c0+"]),
        ([], ["--add FORK_LANE:EXIT_LANE", "--add-pedestrian WALK"]),
    ],
)
def test_bad_walks_are_refused_with_exit_2(folder: Path, args: list[str], words: list[str]) -> None:
    done = run("extend", "t0.json", *args, "-o", "x.json", cwd=folder)
    assert done.returncode == 2, done.stderr
    for word in words:
        assert word in done.stderr, done.stderr
    assert not (folder / "x.json").exists()


def test_a_junction_without_crossings_says_how_to_add_them(tmp_path: Path) -> None:
    made = run("new", "4way-stop", "--ego", "S2C_1:C2W_1", "-o", "t0.json", cwd=tmp_path)
    assert made.returncode == 0, made.stderr
    done = run("extend", "t0.json", "--add-pedestrian", "C_c0+", "-o", "x.json", cwd=tmp_path)
    assert done.returncode == 2
    assert "has no pedestrian crossings" in done.stderr and "--guess-crossings" in done.stderr
