"""How a test-case finds its network: the workflow of docs/cli.md with the network in one folder
and the test-cases in another, no --network anywhere; moved folders; a changed network."""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from service.core.testcase import (
    document_sha256,
    find_network_file,
    new_testcase,
    read_testcase,
    with_network_path,
)
from tests.conftest import DATA

pytestmark = pytest.mark.slow  # 14 s of work or more: `make test-fast` leaves it out

SKEWED = DATA / "junctions" / "skewed-allway.net.xml"  # not bundled: found only by its path
EGO = "SSW2C_0:C2WSW_0"  # a left turn
NEW_CAR = "WSW2C_0:C2ENE_0"  # straight across it


def scengen(cwd: Path, *args: str, env: dict[str, str] | None = None) -> str:
    """Run a command as a user does; its stderr (checked: exit 0)."""
    result = subprocess.run(
        [sys.executable, "-m", "service", *args],
        cwd=cwd, capture_output=True, text=True, check=False, env=env,
    )  # fmt: skip
    assert result.returncode == 0, f"scengen {' '.join(args)}: {result.stderr}"
    assert "Traceback" not in result.stderr
    return result.stderr


@pytest.fixture(scope="module")
def project(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A project folder: nets/skewed.net.xml and suite/ with two levels made from it."""
    root = tmp_path_factory.mktemp("moved") / "project"
    (root / "nets").mkdir(parents=True)
    shutil.copyfile(SKEWED, root / "nets" / "skewed.net.xml")
    scengen(root, "new", "nets/skewed.net.xml", "--ego", EGO, "-o", "suite/t0.json")
    scengen(root, "extend", "suite/t0.json", "--add", NEW_CAR, "-o", "suite/t1.json")
    return root


def test_a_testcase_keeps_its_network_path_relative_to_its_folder(project: Path) -> None:
    for name in ("t0", "t1"):
        network = json.loads((project / "suite" / f"{name}.json").read_text())["network"]
        assert network["path"] == "../nets/skewed.net.xml"
        assert network["ref"] == "nets/skewed.net.xml"


def test_every_command_finds_the_network_without_being_told(project: Path) -> None:
    """check, evaluate, export and plot from another working directory (the ref, a path
    from the old working directory, leads nowhere there), then a campaign's test-cases."""
    elsewhere = project.parent
    suite = project / "suite"
    drive = subprocess.run(
        [sys.executable, "-m", "service", "drive", str(suite / "t1.json"), "--json"],
        cwd=elsewhere, capture_output=True, text=True, check=True,
    ).stdout  # fmt: skip
    (elsewhere / "cruise.json").write_text(drive)
    told = scengen(elsewhere, "evaluate", str(suite / "t1.json"), "--junit", "out/j.xml")
    assert "(its path from the test-case)" in told
    check = subprocess.run(
        [sys.executable, "-m", "service", "check", str(suite / "t1.json"), "--ego",
         "cruise.json"], cwd=elsewhere, capture_output=True, text=True, check=False,
    )  # fmt: skip
    assert check.returncode == 1 and "stopAtSign" in check.stdout, check.stderr  # it cruised
    scengen(elsewhere, "export", str(suite / "t1.json"), "-o", "bundle")
    bundled = json.loads((elsewhere / "bundle" / "testcase.json").read_text())
    assert bundled["network"]["path"] == "skewed.net.xml"  # the copy beside it
    scengen(elsewhere, "evaluate", "bundle/testcase.json")
    scengen(elsewhere, "plot", str(suite / "t0.json"), "-o", "pictures/t0.png")
    assert (elsewhere / "pictures" / "t0.png").stat().st_size > 10_000


def test_a_campaigns_testcases_find_the_copy_beside_them(project: Path) -> None:
    scengen(project, "campaign", "nets/skewed.net.xml", "--ego", EGO, "--depth", "1",
            "--chains", "1", "--controller", "sumo", "--duration", "20",
            "-o", "campaign")  # fmt: skip
    cases = project / "campaign" / "testcases"
    level1 = json.loads((cases / f"{EGO.replace(':', '-')}.chain1.level1.json").read_text())
    assert (cases / level1["network"]["path"]).is_file()
    shutil.move(cases, project.parent / "cases-alone")  # without the campaign around them
    told = scengen(project.parent, "evaluate", "cases-alone")
    assert "(its path from the test-case)" in told


def test_moving_both_folders_keeps_them_working(project: Path, tmp_path: Path) -> None:
    moved = tmp_path / "elsewhere" / "renamed"
    shutil.copytree(project, moved)
    told = scengen(tmp_path, "evaluate", str(moved / "suite" / "t1.json"))
    assert f"{moved / 'nets' / 'skewed.net.xml'} (its path from the test-case)" in told
    scengen(tmp_path, "extend", str(moved / "suite" / "t1.json"), "--add", "N2C_0:C2SSW_0",
            "-o", "level2/t2.json")  # fmt: skip
    level2 = json.loads((tmp_path / "level2" / "t2.json").read_text())
    assert level2["network"]["path"] == "../elsewhere/renamed/nets/skewed.net.xml"


def test_a_changed_network_is_refused_naming_the_file_and_both_hashes(
    project: Path, tmp_path: Path
) -> None:
    copy = tmp_path / "copy"
    shutil.copytree(project, copy)
    network = copy / "nets" / "skewed.net.xml"
    network.write_text(network.read_text().replace("</net>", "<!-- edited -->\n</net>"))
    result = subprocess.run(
        [sys.executable, "-m", "service", "evaluate", str(copy / "suite" / "t1.json")],
        cwd=tmp_path, capture_output=True, text=True, check=False,
    )  # fmt: skip
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    made_on = read_testcase(copy / "suite" / "t1.json").network.sha256
    now = hashlib.sha256(network.read_bytes()).hexdigest()
    assert made_on in lines[-1] and now in lines[-1] and str(network) in lines[-1]


def test_the_search_path_and_network_option_find_a_lonely_testcase(
    project: Path, tmp_path: Path
) -> None:
    lonely = tmp_path / "t1.json"
    shutil.copyfile(project / "suite" / "t1.json", lonely)
    missing = subprocess.run(
        [sys.executable, "-m", "service", "evaluate", str(lonely)],
        cwd=tmp_path, capture_output=True, text=True, check=False,
    )  # fmt: skip
    assert missing.returncode == 2 and "SCENGEN_NETWORK_PATH" in missing.stderr
    path = f"{tmp_path / 'nowhere'}:{project / 'nets'}"
    told = scengen(
        tmp_path, "evaluate", str(lonely), env={**os.environ, "SCENGEN_NETWORK_PATH": path}
    )
    assert "(on SCENGEN_NETWORK_PATH)" in told
    network = project / "nets" / "skewed.net.xml"
    told = scengen(tmp_path, "evaluate", str(lonely), "--network", str(network))
    assert "(given with --network)" in told


def test_the_path_does_not_change_what_the_testcase_is(tmp_path: Path) -> None:
    """A parent's hash and a server's id are taken without the path: the same test-case
    written in two folders is one test-case."""
    testcase = new_testcase(SKEWED, EGO)
    here = with_network_path(testcase, SKEWED, tmp_path)
    there = with_network_path(testcase, SKEWED, tmp_path / "a" / "b")
    assert here.network.path != there.network.path
    assert document_sha256(here) == document_sha256(there) == document_sha256(testcase)
    assert (
        with_network_path(new_testcase("4way-stop", "S2C_1:C2W_1"), SKEWED, tmp_path).network.path
        is None
    )


def test_the_first_file_with_the_right_hash_wins(tmp_path: Path) -> None:
    """A stale file at the path does not hide the right one next to the test-case."""
    testcase = with_network_path(new_testcase(SKEWED, EGO), tmp_path / "old.net.xml", tmp_path)
    (tmp_path / "old.net.xml").write_text("<net/>")
    shutil.copyfile(SKEWED, tmp_path / "skewed-allway.net.xml")
    found, how = find_network_file(testcase, near=tmp_path)
    assert (found, how) == ((tmp_path / "skewed-allway.net.xml").resolve(), "next to the test-case")
