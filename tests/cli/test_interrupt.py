"""Ctrl-C is a normal way to stop: ``scengen`` stopped with SIGINT (sent to its process
group, as a terminal does) says so in one line, exits 130, leaves no traceback, no process
and nothing half-written behind; ``evaluate`` reports the verdicts it already has."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from xml.etree import ElementTree as ET

import pytest

from tests.processes import alive, descendants

pytestmark = pytest.mark.slow


def interrupted(args: list[str], after: str, cwd: Path) -> tuple[int, str, str]:
    """``scengen ARGS`` stopped by Ctrl-C once a line of its stderr holds ``after``: its
    exit code, stdout and stderr. Every process it started is gone when it has exited."""
    child = subprocess.Popen(
        [sys.executable, "-m", "service", *args], cwd=cwd, text=True,
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, start_new_session=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )  # fmt: skip
    assert child.stderr is not None and child.stdout is not None
    seen = []
    for line in child.stderr:
        seen.append(line)
        if after in line:
            break
    else:
        raise AssertionError(f"{after!r} never came: {''.join(seen)}")
    started = descendants(child.pid)  # the command's child too, in a session of its own
    assert started, "the command's work runs in a child of its own"
    os.killpg(child.pid, signal.SIGINT)
    out, err = child.communicate(timeout=60)
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline:  # its children go with it
        try:
            os.killpg(child.pid, 0)
        except ProcessLookupError:
            if not any(alive(pid) for pid in started):
                break
        time.sleep(0.1)
    else:
        raise AssertionError("a process of the interrupted command is still running")
    return child.returncode, out, "".join(seen) + err


@pytest.fixture(scope="module")
def level1(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("interrupt")
    for args in (["new", "4way-stop", "--ego", "S2C_0:C2N_0", "-o", "root.json"],
                 ["extend", "root.json", "--add", "E2C_0:C2W_0", "-o", "level1.json"]):  # fmt: skip
        subprocess.run([sys.executable, "-m", "service", *args], cwd=folder, check=True,
                       capture_output=True)  # fmt: skip
    return folder


def test_ctrl_c_of_evaluate_keeps_the_verdicts_it_has(level1: Path) -> None:
    code, out, err = interrupted(
        ["evaluate", "level1.json", "root.json", "--controller", "sumo", "--controller",
         "sumo-cautious", "--controller", "sumo-aggressive", "--junit", "run.xml"],
        "1/6", level1,
    )  # fmt: skip
    assert code == 130 and "Traceback" not in err, err
    assert err.strip().endswith("run the same command again for all"), err
    assert "not run" in out and "pass" in out  # the table: what was judged, and the rest
    suite = ET.parse(level1 / "run.xml").getroot().find("testsuite")
    assert suite is not None and suite.get("tests") == "6"
    skipped = [case for case in suite.findall("testcase") if case.find("skipped") is not None]
    judged = 6 - len(skipped)
    assert 1 <= judged < 6
    assert all(
        "not run: the evaluation was interrupted" in str(c.find("skipped").get("message"))  # type: ignore[union-attr]
        for c in skipped
    )
    assert f"stopped (Ctrl-C) after {judged} of 6 evaluations" in err


def test_ctrl_c_of_extend_leaves_no_traceback_and_no_file(level1: Path) -> None:
    code, _, err = interrupted(
        ["extend", "level1.json", "--add", "W2C_0:C2E_0", "--count", "5", "-o", "more.json"],
        "step 1 poses", level1,
    )  # fmt: skip
    assert code == 130 and "Traceback" not in err, err
    assert err.strip().splitlines()[-1] == (
        "scengen: stopped (Ctrl-C); nothing half-written is left; run the same command to "
        "start again"
    )
    assert not list(level1.glob("more*.json"))


def test_ctrl_c_of_a_campaign_says_it_goes_on_when_run_again(tmp_path: Path) -> None:
    code, _, err = interrupted(
        [
            "campaign",
            "4way-stop",
            "--ego",
            "S2C_0:C2N_0",
            "--depth",
            "4",
            "--chains",
            "4",
            "--controller",
            "sumo",
            "--workers",
            "2",
            "--duration",
            "20",
            "-o",
            "c",
        ],
        "level 1",
        tmp_path,
    )  # fmt: skip (about 10 s of work: stopped at its first step past the root)
    assert code == 130 and "Traceback" not in err, err
    assert err.strip().splitlines()[-1] == (
        "scengen: stopped (Ctrl-C); run the same command to go on where it stopped"
    )
    assert not (tmp_path / "c" / "campaign.json").exists()
