"""`scengen campaign` and `scengen report` as a user runs them: a campaign killed with
kill -9 halfway resumes when the same command runs again (with two workers) and ends
with the outcome an uninterrupted run with one worker gives; the report opens without a
server; a different campaign in the same folder is refused; bad input is a one-line
error."""

from __future__ import annotations

import copy
import itertools
import json
import os
import re
import signal
import subprocess
import sys
from pathlib import Path
from typing import Any
from xml.etree import ElementTree as ET

import pytest

pytestmark = pytest.mark.slow

COMMAND = ["campaign", "4way-stop", "--ego", "S2C_0:C2N_0", "--depth", "1", "--chains", "2",
           "--duration", "20", "--controller", "sumo", "--controller",
           "sumo-rolling-stop"]  # fmt: skip
LONGER = [*COMMAND[:4], "--depth", "3", *COMMAND[6:]]  # 20 steps: time to kill it halfway


def scengen(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "service", *args], capture_output=True, text=True, check=False
    )


def without_evaluation_ids(folder: Path) -> dict[str, Any]:
    outcome: dict[str, Any] = json.loads((folder / "campaign.json").read_text())
    for chain in outcome["chains"]:
        for level in chain["levels"]:
            for verdict in level["verdicts"].values():
                verdict.pop("evaluation")
    return outcome


def test_a_killed_campaign_resumes_and_ends_as_an_uninterrupted_one(tmp_path: Path) -> None:
    resumed = tmp_path / "resumed"
    child = subprocess.Popen(
        [sys.executable, "-m", "service", *LONGER, "--workers", "1", "-o", str(resumed)],
        stderr=subprocess.PIPE, text=True, start_new_session=True,
    )  # fmt: skip
    assert child.stderr is not None
    # kill -9 mid-campaign, once it reports a step past the root (the progress shows the
    # last step when it looks): levels 2 and 3 of both chains are still to come (seconds
    # of work, one at a time), so a parent that reads the line late on a loaded machine
    # still kills a campaign that has not ended
    for line in child.stderr:
        if "level 1" in line:
            break
    os.killpg(child.pid, signal.SIGKILL)
    child.wait()
    assert not (resumed / "campaign.json").exists()
    again = scengen(*LONGER, "--workers", "2", "-o", str(resumed))
    assert again.returncode == 1, again.stderr  # rolling through the stop sign fails
    assert "resuming the campaign" in again.stderr
    # what was made before the kill is remembered, not made again: the root and its two
    # evaluations (at least; more if the kill came late)
    made = re.search(r"resuming after (\d+) test-case\(s\) and (\d+) evaluation", again.stderr)
    assert made and int(made[1]) >= 1 and int(made[2]) >= 2, again.stderr
    assert not re.search(r"(?<!\d)[12]/20:", again.stderr)
    uninterrupted = tmp_path / "uninterrupted"
    assert scengen(*LONGER, "--workers", "1", "-o", str(uninterrupted)).returncode == 1
    assert not (uninterrupted / ".campaign.lock").exists()
    assert not (resumed / ".campaign.lock").exists()
    assert without_evaluation_ids(resumed) == without_evaluation_ids(uninterrupted)
    assert re.search(r"^level +test-cases +sumo +sumo-rolling-stop$", again.stdout, re.M)


def test_a_campaigns_files_are_test_cases_a_user_replays(tmp_path: Path) -> None:
    fresh = tmp_path / "fresh"
    finished = scengen(*COMMAND, "--workers", "1", "-o", str(fresh))
    assert finished.returncode == 1, finished.stderr  # rolling through the stop sign fails
    assert "FAIL sumo-rolling-stop: failed 3 of 3 test-cases; first at level 0" in finished.stdout

    outcome = without_evaluation_ids(fresh)
    assert [lv["controllers"]["sumo-rolling-stop"]["share"] for lv in outcome["levels"]] == [1, 1]
    cases = sorted(p.name for p in (fresh / "testcases").glob("*.json"))
    assert cases == [f"S2C_0-C2N_0.chain{c}.level{lv}.json" for c in (1, 2) for lv in (0, 1)]
    check = scengen("evaluate", str(fresh / "testcases"), "--controller", "sumo", "--json")
    assert check.returncode == 0, check.stderr  # the files are test-cases a user can replay
    stem = "4way-stop C S2C_0:C2N_0"  # each level is named by its chain and level
    assert {v["testcase"] for v in json.loads(check.stdout)} == {
        f"{stem} level 0", f"{stem} chain 1 level 1", f"{stem} chain 2 level 1"
    }  # fmt: skip
    assert outcome["chains"][1]["levels"][1]["name"] == f"{stem} chain 2 level 1"
    suite = ET.parse(fresh / "junit.xml").getroot().find("testsuite")
    assert suite is not None and suite.get("tests") == str(2 * 2 * 2)
    names = [case.get("name", "") for case in suite.findall("testcase")]
    assert len(set(names)) == len(names)
    assert all(
        re.fullmatch(rf"{stem} chain [12] level [01] \([0-9a-f]{{16}}\) / sumo(-rolling-stop)?", n)
        for n in names
    ), names

    report = tmp_path / "report.html"
    written = scengen("report", str(fresh), "-o", str(report))
    assert written.returncode == 0, written.stderr
    page = report.read_text()
    assert "window.SCENGEN_REPORT" in page
    assert not re.search(r'(src|href)="(https?:|/)', page)  # nothing loaded from elsewhere

    other = scengen(*COMMAND[:-2], "-o", str(fresh))  # another campaign, same folder
    assert other.returncode == 2
    assert "holds another campaign" in other.stderr


def test_bad_campaign_input_is_a_one_line_error(tmp_path: Path) -> None:
    wrong_route = scengen(*COMMAND[:3], "S2C_0:C2S_0", *COMMAND[4:], "-o", str(tmp_path / "a"))
    assert wrong_route.returncode == 2
    assert "valid routes" in wrong_route.stderr and "Traceback" not in wrong_route.stderr
    wrong_driver = scengen(*COMMAND[:-1], "no-such-driver", "-o", str(tmp_path / "b"))
    assert wrong_driver.returncode == 2 and "Traceback" not in wrong_driver.stderr
    guarded_replay = scengen(*COMMAND[:-1], "certificate:complexity+rss", "-o", str(tmp_path / "g"))
    assert guarded_replay.returncode == 2 and "cannot be guarded" in guarded_replay.stderr
    assert "sumo-rolling-stop+rss" in guarded_replay.stderr  # the guarded ones it could use
    no_workers = scengen(*COMMAND, "--workers", "0", "-o", str(tmp_path / "w"))
    assert no_workers.returncode == 2 and "--workers: give 1 to 64" in no_workers.stderr
    assert not (tmp_path / "w").exists()
    not_a_folder = scengen("report", str(tmp_path), "-o", str(tmp_path / "r.html"))
    assert not_a_folder.returncode == 2 and "not a campaign folder" in not_a_folder.stderr


def test_the_summary_prints_the_papers_table_and_criticality_by_level(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """The command's printing over a campaign of hand-made verdicts (the loop and the
    measures are tested in the core)."""
    from service.cli import campaign_folder
    from service.cli.commands import main
    from service.core.campaign.growing import run_campaign
    from service.core.sim import controllers
    from tests.core.campaign.test_campaign import RULES, FakeSteps, plan

    outcome = run_campaign(plan(), FakeSteps(measured=True), RULES)
    monkeypatch.setattr(campaign_folder, "run_folder_campaign", lambda *_: outcome)
    monkeypatch.setattr(controllers, "resolve_driver", lambda name: None)  # strong and weak
    command = ["campaign", "4way-stop", "--ego", "S2C_0:C2N_0", "--depth", "3", "--chains", "2",
               "--controller", "strong", "--controller", "weak", "--duration", "20", "-o",
               str(tmp_path)]  # fmt: skip
    assert main([*command, "--table", "paper"]) == 1
    out = capsys.readouterr().out
    assert "weak        pass     pass 2/2  2/2 FAIL 21800(a)  2/2 FAIL 21800(a)\n" in out
    assert "criticality of weak by level (median (min–max) n=test-cases that have it):" in out
    assert re.search(r"^2 +2/2 +2\.25 \(2–2\.5\) n=2 +— +— +4\.5 \(4–5\) n=2$", out, re.M), out
    assert "criticality of weak grows: median TTC 3.25 → 2.25 → 1.25 s (levels 1–3)" in out
    assert "criticality of strong does not grow: median distance 5 → 5 → 5 m" in out
    assert main([*command, "--markdown"]) == 1
    row = "| weak | pass | pass 2/2 | 2/2 FAIL 21800(a) | 2/2 FAIL 21800(a) |"
    assert row in capsys.readouterr().out


# (failed, test-cases): the Wilson score interval at 95 %, the roots of
# (1 + z²/n) p² - (2 k/n + z²/n) p + (k/n)² = 0 with z = 1.959964, worked out by hand
WILSON_95 = {(0, 1): (0.0, 0.7935), (1, 1): (0.2065, 1.0), (0, 4): (0.0, 0.4899),
             (1, 4): (0.0456, 0.6994), (2, 4): (0.15, 0.85), (3, 4): (0.3006, 0.9544),
             (4, 4): (0.5101, 1.0)}  # fmt: skip


def test_a_campaign_holds_no_repeated_test_case_at_any_level(tmp_path: Path) -> None:
    """Four chains of two levels on the bundled four-way stop: at each level the stored
    test-cases differ pairwise (variety's signature, read from the files the campaign
    wrote, and the documents themselves), the campaign counts them all as distinct, the
    shares carry the Wilson interval, and the diversity is that of the files."""
    from service.cli.campaign_folder import open_store, testcase_file_name
    from service.core.campaign.outcome import resummarized
    from service.core.generator.variety import Signature, distinct_count, signature
    from service.core.testcase import dump_testcase, read_testcase

    folder = tmp_path / "four"
    done = scengen("campaign", "4way-stop", "--ego", "S2C_0:C2N_0", "--depth", "2", "--chains",
                   "4", "--controller", "sumo", "--duration", "20", "-o", str(folder))  # fmt: skip
    assert done.returncode in (0, 1), done.stderr
    outcome = json.loads((folder / "campaign.json").read_text())
    assert outcome["schema"] == "scengen/campaign/2"
    assert [c["reached"] for c in outcome["chains"]] == [2, 2, 2, 2], outcome["chains"]
    for number in (1, 2):
        paths = [folder / "testcases" / testcase_file_name("S2C_0:C2N_0", chain, number)
                 for chain in (1, 2, 3, 4)]  # fmt: skip
        stored = [read_testcase(path) for path in paths]
        marks = [signature(testcase) for testcase in stored]
        assert not any(a.same_as(b) for a, b in itertools.combinations(marks, 2)), marks
        assert distinct_count(stored) == 4
        unnamed = {dump_testcase(t.model_copy(update={"name": ""})) for t in stored}
        assert len(unnamed) == 4  # the documents differ beyond their names
        kept = [Signature.from_dict(c["levels"][number]["signature"]) for c in outcome["chains"]]
        assert kept == marks  # the campaign's signatures are the files'
        level = outcome["levels"][number]
        assert level["testcases"] == level["grown"] == 4
        arrivals = sorted(car.arrival for mark in marks for car in mark.cars)
        assert level["diversity"]["arrival"]["values"] == arrivals
        broken = {rule for c in outcome["chains"] for rule in c["levels"][number]["breaks"]}
        assert level["diversity"]["rules"] == sorted(broken)
        assert 1 <= level["diversity"]["orders"] <= 4
    assert outcome["levels"][0]["testcases"] == 1  # the root, shared by every chain
    for level in outcome["levels"]:
        share = level["controllers"]["sumo"]
        lower, upper = WILSON_95[(share["failed"], share["evaluated"])]
        assert share["interval"] == {"lower": lower, "upper": upper}
        row = (rf"^{level['level']} +{level['testcases']} +{share['failed']}/"
               rf"{share['evaluated']} {round(100 * share['share'])}% "
               rf"\({round(100 * lower)}–{round(100 * upper)}%\)$")  # fmt: skip
        assert re.search(row, done.stdout, re.M), done.stdout
    assert "diversity per level" in done.stdout
    # the outcome as a campaign stored before schema 2 kept it is counted anew, from the
    # stored test-cases, to the same outcome
    old = copy.deepcopy(outcome)
    old["schema"] = "scengen/campaign/1"
    for chain in old["chains"]:
        for level in chain["levels"]:
            del level["signature"]
    store, _ = open_store(folder)
    try:
        records = {
            ident: store.testcase(ident)
            for ident in {level["testcase"] for chain in old["chains"] for level in chain["levels"]}
        }
        assert all(records.values())
        again = resummarized(old, lambda ident: records[ident].testcase)  # type: ignore[union-attr]
        assert again == outcome
    finally:
        store.close()


# the bundled T's program with shorter greens and an offset: the campaign's starts carry it
T_PROGRAM = {"tls": "C", "program": "campaign", "offset": 4.0, "phases": [
    {"duration": 16.0, "state": "GgsrGG"}, {"duration": 3.0, "state": "yysrGy"},
    {"duration": 1.0, "state": "rrsrGr"}, {"duration": 14.0, "state": "rrGGGr"},
    {"duration": 3.0, "state": "rryyGr"}, {"duration": 1.0, "state": "rrsrGr"}]}  # fmt: skip


def test_a_campaign_on_a_signalized_junction_carries_its_program(tmp_path: Path) -> None:
    """Two chains of two levels on the signalized T under a program of the user's: every
    level's test-case carries the program, keeps its parent's cars, and is verified here
    by the checker (its solvability certificate passes it, its complexity certificate
    passes the parent and fails it by a new car), each new car within the motion bounds."""
    from service.core.checker.check import check_testcase
    from service.core.motion.invariants import motion_fault
    from service.core.motion.poses import PoseSample
    from service.core.testcase import Signals, TestCase, read_testcase

    (tmp_path / "t.json").write_text(json.dumps(T_PROGRAM))
    folder = tmp_path / "campaign"
    done = scengen("campaign", "t-signal", "--signals", str(tmp_path / "t.json"), "--ego",
                   "E2C_0:C2S_0", "--depth", "2", "--chains", "2", "--duration", "45",
                   "--controller", "sumo", "--controller", "sumo-rolling-stop",
                   "-o", str(folder))  # fmt: skip
    assert done.returncode in (0, 1), done.stderr
    outcome = json.loads((folder / "campaign.json").read_text())
    assert [c["reached"] for c in outcome["chains"]] == [2, 2], outcome["chains"]
    assert outcome["plan"]["control"] == "traffic_light_right_on_red"
    coverable = {c["rule"] for c in outcome["coverage"] if c["coverable"]}
    assert "stopAtRed" not in coverable and "turnOnGreenYieldsToOncoming" in coverable

    def samples(rows: Any) -> list[PoseSample]:
        return [PoseSample(**row.model_dump()) for row in rows]

    program = Signals.model_validate(T_PROGRAM)
    for chain in (1, 2):
        levels: list[TestCase] = [
            read_testcase(folder / "testcases" / f"E2C_0-C2S_0.chain{chain}.level{level}.json")
            for level in range(3)
        ]
        for parent, child in itertools.pairwise(levels):
            assert child.signals == parent.signals == program
            assert child.nonegos[: len(parent.nonegos)] == parent.nonegos  # kept as they were
            assert child.certificates is not None
            assert check_testcase(child, samples(child.certificates.solvability)).passed
            complexity = samples(child.certificates.complexity)
            assert check_testcase(parent, complexity).passed
            failed = check_testcase(child, complexity)
            new = {car.id for car in child.nonegos[len(parent.nonegos) :]}
            assert not failed.passed
            assert {v.other for v in failed.violations} & new or {
                c.other for c in failed.collisions
            } & new
            for car in child.nonegos[len(parent.nonegos) :]:
                assert motion_fault(car.trajectory, child.params, child.timestep) is None
    verdicts = [lv["verdicts"]["sumo"] for c in outcome["chains"] for lv in c["levels"]]
    assert len(verdicts) == 2 * 3 and all(not v["errors"] for v in verdicts)


def test_a_folder_holds_one_run_at_a_time_and_its_lock_goes_with_it(tmp_path: Path) -> None:
    from service.cli.campaign_folder import LOCK_FILE, hold_lock
    from service.core.errors import InvalidInput

    path = tmp_path / LOCK_FILE
    held = hold_lock(path)
    with pytest.raises(InvalidInput, match=f"another scengen campaign is running in {tmp_path}"):
        hold_lock(path)
    stale = path.open("w")  # a run that opened the file just before the holder ended
    path.unlink()  # the holder ends: it removes the file, then lets go
    held.close()
    taken = hold_lock(path)  # a new file, not the removed one the late opener holds
    assert path.stat().st_ino == os.fstat(taken.fileno()).st_ino
    stale.close()
    taken.close()
