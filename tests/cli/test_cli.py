"""The command line contract: output shapes, exit codes, one-line errors."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path
from xml.etree import ElementTree as ET

import pytest

from service import cli
from service.cli import submit as _submit  # noqa: F401 (its errors join the tree: collected always)
from service.cli.commands import parser
from service.cli.examples import EXAMPLES
from service.cli.output import exit_code
from service.cli.testcases import start_distances
from service.core import errors
from service.core.checker.check import Judge
from service.core.network import load_intersection
from service.core.testcase import read_testcase
from tests.conftest import TOWN05, TOWN07

pytestmark = pytest.mark.slow  # 14 s of work or more: `make test-fast` leaves it out

UNREGULATED = Path(__file__).parents[1] / "data" / "junctions" / "skewed-unregulated.net.xml"


def run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "service", *args], capture_output=True, text=True, check=False
    )


def test_intersection_json_contract() -> None:
    result = run("intersection", "t-stop", "--json")
    assert result.returncode == 0, result.stderr
    data = json.loads(result.stdout)
    assert data["junction"] == "C"
    assert data["control"] == "priority_stop"
    fork = next(f for f in data["forks"] if f["lane"] == "S2C_0")
    assert fork == fork | {"stop_sign": True, "to_its_right": ["E2C_0"], "opposite": []}
    assert isinstance(fork["heading"], float)
    route = next(r for r in data["routes"] if r["id"] == "E2C_0:C2S_0")
    assert route["fork"] == "E2C_0" and route["exit"] == "C2S_0" and route["turn"] == "left"
    assert route["conflicts"] == ["S2C_0:C2W_0", "W2C_0:C2E_0", "W2C_0:C2S_0"]


def test_intersection_table_is_readable(capsys: pytest.CaptureFixture[str]) -> None:
    assert cli.main(["intersection", "y-uncontrolled"]) == 0
    out = capsys.readouterr().out
    assert "junction C  control right_before_left" in out
    assert re.search(r"^N2C_0:C2SE_0 +left +SE2C_0:C2SW_0", out, re.MULTILINE)


def test_intersection_on_carla_with_override(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    code = cli.main(
        [
            "intersection",
            str(TOWN07),
            "--junction",
            "358",
            "--control",
            "right_before_left",
            "--json",
            "--plot",
            str(tmp_path / "y.png"),
        ]
    )
    assert code == 0
    data = json.loads(capsys.readouterr().out)
    assert data["control"] == "right_before_left" and data["control_overridden"]
    assert (tmp_path / "y.png").read_bytes()[:4] == b"\x89PNG"


def test_new_writes_an_ego_only_testcase(tmp_path: Path) -> None:
    target = tmp_path / "tc.json"
    result = run("new", "4way-stop", "--junction", "C", "--ego", "S2C_1:C2W_1", "-o", str(target))
    assert result.returncode == 0, result.stderr
    data = json.loads(target.read_text())
    assert data["ego"]["route"] == {"fork": "S2C_1", "exit": "C2W_1"}
    assert data["nonegos"] == []


def test_new_prints_to_stdout_without_output(capsys: pytest.CaptureFixture[str]) -> None:
    assert cli.main(["new", "y-uncontrolled", "--ego", "N2C_0:C2SE_0"]) == 0
    assert json.loads(capsys.readouterr().out)["control"] == "right_before_left"


def test_drive_lists_events(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    target = tmp_path / "tc.json"
    assert cli.main(["new", "4way-stop", "--ego", "S2C_1:C2W_1", "-o", str(target)]) == 0
    assert cli.main(["drive", str(target), "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    kinds = [e["kind"] for e in data["events"]]
    assert kinds[0] == "arrived" and "entered" in kinds and "exited" in kinds
    assert len(data["samples"]) == 201
    assert cli.main(["drive", str(target), "--route", "E2C_1:C2S_1"]) == 0
    assert "route E2C_1:C2S_1 (left)" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["intersection", "nowhere"], "is neither a bundled network"),
        (["intersection", str(UNREGULATED)], "has control type 'unregulated'"),
        (["intersection", str(TOWN07)], "name one with --junction"),
        (["new", "4way-stop", "--ego", "S2C_1:C2E_1"], "no connection from fork 'S2C_1'"),
        (["new", "4way-stop", "--ego", "Q_0:C2E_1"], "valid forks"),
        (["drive", "missing.json"], "cannot read test-case"),
    ],
)
def test_bad_input_exits_2_with_one_line(args: list[str], message: str) -> None:
    result = run(*args)
    assert result.returncode == 2
    assert result.stdout == ""
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], result.stderr


def test_example_refuses_unknown_or_repeated_controllers_before_any_work(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = tmp_path / "chain"
    code = cli.main(["example", "four-way", "-o", str(folder), "--controllers", "sumo,nope"])
    assert code == 2
    error = capsys.readouterr().err
    assert "unknown controller 'nope'; valid: " in error and "sumo-cautious" in error, error
    assert list(folder.glob("*.json")) == []
    with pytest.raises(SystemExit):
        cli.main(["example", "four-way", "-o", str(folder), "--controllers", "sumo,,sumo"])
    assert "controllers separated by commas, each once" in capsys.readouterr().err


def test_unknown_control_choice_exits_2() -> None:
    result = run("intersection", "4way-stop", "--control", "traffic_light_unregulated")
    assert result.returncode == 2
    assert "invalid choice: 'traffic_light_unregulated'" in result.stderr
    assert (
        "'allway_stop', 'priority', 'priority_stop', 'right_before_left', 'traffic_light'"
        in result.stderr
    )


def _subclasses(root: type[errors.ScengenError]) -> list[type[errors.ScengenError]]:
    found = []
    for sub in root.__subclasses__():
        found += [sub, *_subclasses(sub)]
    return found


@pytest.mark.parametrize("error", _subclasses(errors.ScengenError), ids=lambda e: e.__name__)
def test_every_domain_error_has_an_exit_code(error: type[errors.ScengenError]) -> None:
    expected = 2 if issubclass(error, errors.InvalidInput | errors.UnsupportedIntersection) else 3
    expected = 4 if issubclass(error, errors.ClientFault) else expected
    assert exit_code(error("x")) == expected
    if error.__module__ == errors.__name__:  # the core's tree in its docstring is complete
        assert error.__name__ in (errors.__doc__ or "")


@pytest.fixture(scope="module")
def left_turn_files(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """An ego-only test-case and the constant-speed Step 1 drive of its ego (no stop)."""
    folder = tmp_path_factory.mktemp("check")
    testcase = folder / "tc.json"
    assert cli.main(["new", "4way-stop", "--ego", "S2C_1:C2W_1", "-o", str(testcase)]) == 0
    drive = run("drive", str(testcase), "--json")
    trajectory = folder / "drive.json"
    trajectory.write_text(drive.stdout)
    return testcase, trajectory


def test_check_fails_a_drive_through_the_stop_sign(
    left_turn_files: tuple[Path, Path], tmp_path: Path
) -> None:
    testcase, trajectory = left_turn_files
    junit = tmp_path / "verdict.xml"
    result = run("check", str(testcase), "--ego", str(trajectory), "--junit", str(junit))
    assert result.returncode == 1, result.stderr
    assert result.stdout.startswith("FAIL  4way-stop C S2C_1:C2W_1 level 0 / drive")
    assert "violated CVC 22450(a) (stopAtSign)" in result.stdout
    xml = junit.read_text()
    assert 'failures="1"' in xml and "22450(a)" in xml
    assert 'name="4way-stop C S2C_1:C2W_1 level 0 / drive"' in xml


def test_check_json_verdict(left_turn_files: tuple[Path, Path]) -> None:
    testcase, trajectory = left_turn_files
    result = run(
        "check", str(testcase), "--ego", str(trajectory), "--json", "--controller", "cruise"
    )
    assert result.returncode == 1
    verdict = json.loads(result.stdout)
    assert verdict["schema"] == "scengen/verdict/1"
    assert verdict["passed"] is False
    assert verdict["controller"] == "cruise"
    assert verdict["goal"]["reached"] is True
    assert [v["law"] for v in verdict["violations"]] == ["22450(a)"]
    assert verdict["violations"][0]["events"][0]["kind"] == "arrived"


def test_check_bad_trajectory_exits_2(left_turn_files: tuple[Path, Path], tmp_path: Path) -> None:
    testcase, _ = left_turn_files
    bad = tmp_path / "bad.json"
    bad.write_text("[]")
    result = run("check", str(testcase), "--ego", str(bad))
    assert result.returncode == 2
    assert "expected a list of at least 2 samples" in result.stderr


def test_extend_writes_a_more_complex_testcase(tmp_path: Path) -> None:
    old = tmp_path / "old.json"
    assert cli.main(["new", "y-uncontrolled", "--ego", "N2C_0:C2SE_0", "-o", str(old)]) == 0
    new = tmp_path / "new.json"
    result = run("extend", str(old), "--add", "SW2C_0:C2N_0", "--add", "SE2C_0:C2N_0",
                 "--seed", "0", "--budget", "120", "-o", str(new))  # fmt: skip
    assert result.returncode == 0, result.stderr
    assert "step 1 poses" in result.stderr and "verified" in result.stderr
    assert "the complexity certificate violates the right-of-way of car1" in result.stderr
    document = json.loads(new.read_text())
    assert [n["id"] for n in document["nonegos"]] == ["car1", "car2"]
    assert set(document["certificates"]) == {"complexity", "solvability"}


def test_extend_without_a_conflict_exits_3(tmp_path: Path) -> None:
    old = tmp_path / "old.json"
    assert cli.main(["new", "4way-stop", "--ego", "S2C_1:C2W_1", "-o", str(old)]) == 0
    result = run("extend", str(old), "--add", "E2C_0:C2N_0")
    assert result.returncode == 3
    assert "no more complex test-case exists" in result.stderr


def test_extend_unknown_route_exits_2(tmp_path: Path) -> None:
    old = tmp_path / "old.json"
    assert cli.main(["new", "4way-stop", "--ego", "S2C_1:C2W_1", "-o", str(old)]) == 0
    result = run("extend", str(old), "--add", "S2C_1:C2E_1")
    assert result.returncode == 2
    assert "valid routes" in result.stderr


@pytest.mark.parametrize(
    ("given", "expected"),
    [
        ([], None),
        (["12"], 12.0),
        (["auto"], None),
        (["12", "auto"], [12.0, None]),
    ],
)
def test_extend_start_distances_none_one_or_one_per_car(given: list[str], expected: object) -> None:
    starts = [arg for value in given for arg in ("--start-distance", value)]
    adds = ["--add", "E2C_0:C2W_0", "--add", "S2C_1:C2N_1"]
    args = parser().parse_args(["extend", "old.json", *adds, *starts])
    assert start_distances(args) == expected


@pytest.mark.parametrize(
    ("starts", "words"),
    [
        (["12", "auto", "3"], "2 --add, 3 --start-distance"),
        (["-4"], "argument --start-distance: a distance >= 0 (m) or 'auto', not '-4'"),
        (["far"], "not 'far'"),
        (["nan"], "not 'nan'"),
    ],
)
def test_extend_start_distance_usage_errors_exit_2(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, starts: list[str], words: str
) -> None:
    """Checked before the old test-case is read (it does not exist here)."""
    adds = ["--add", "E2C_0:C2W_0", "--add", "S2C_1:C2N_1"]
    given = [arg for value in starts for arg in ("--start-distance", value)]
    with pytest.raises(SystemExit) as caught:
        cli.main(["extend", str(tmp_path / "missing.json"), *adds, *given])
    assert caught.value.code == 2
    error = capsys.readouterr().err
    assert error.startswith("usage: scengen extend") and words in error


def test_extend_starts_each_new_car_at_its_own_distance(tmp_path: Path) -> None:
    """One --start-distance per --add, in order: a car 12 m before the line ahead of the
    ego on the ego's fork, and one on a free fork that starts automatically, where the ego
    starts (30 m)."""
    old, new = tmp_path / "old.json", tmp_path / "new.json"
    assert cli.main(["new", "4way-stop", "--ego", "E2C_0:C2N_0", "--duration", "45",
                     "-o", str(old)]) == 0  # fmt: skip
    result = run("extend", str(old), "--add", "E2C_0:C2W_0", "--start-distance", "12",
                 "--add", "S2C_1:C2N_1", "--start-distance", "auto", "-o", str(new))  # fmt: skip
    assert result.returncode == 0, result.stderr
    assert "the complexity certificate drives into car1 (rear-end)" in result.stderr
    testcase = read_testcase(new)
    judge = Judge(testcase, load_intersection("4way-stop"))
    starts = {car.id: (car.fork, car.in_queue.start) for car in judge.nonegos}
    assert starts == {
        "car1": ("E2C_0", pytest.approx(12.0, abs=0.01)),
        "car2": ("S2C_1", pytest.approx(testcase.ego.start.distance, abs=0.01)),
    }
    assert testcase.ego.start.distance == 30.0


@pytest.mark.parametrize("name", sorted(EXAMPLES))
def test_examples_produce_verified_chains(name: str, tmp_path: Path) -> None:
    """Each level's certificates, judged by `scengen check` as a separate process: the
    solvability certificate passes the level, the complexity certificate passes the level
    before and fails this one. So the complexity strictly increases along the chain. The
    t-junction's levels are evaluated into the paper's table (the others' are not: the
    checks below judge them)."""
    table = name == "t-junction"
    evaluation = ["--controllers", "sumo,certificate:complexity"] if table else ["--no-evaluate"]
    result = run("example", name, "-o", str(tmp_path), *evaluation)
    assert result.returncode == 0, result.stderr
    if table:  # a certificate replays nothing on the ego-only level
        assert result.stdout.endswith(
            "t-junction, the paper's table (seed 0):\n"
            "controller              level 0  level 1\n"
            "sumo                    pass     pass (TTC 3.4 s)\n"
            "certificate:complexity  —        FAIL 21801(a) car1 (TTC 1.2 s)\n"
        ), result.stdout
    else:
        assert "the paper's table" not in result.stdout
    levels = len(EXAMPLES[name].steps)
    files = [tmp_path / f"{name}-{level}.json" for level in range(levels + 1)]
    assert sorted(tmp_path.glob("*.json")) == sorted(files)
    for level in range(1, levels + 1):
        document = json.loads(files[level].read_text())
        assert document["name"] == f"{name} level {level}"
        assert document["provenance"]["level"] == level
        users = [*document["nonegos"], *document.get("pedestrians", [])]
        added = [n for n in users if n["added_in"] == level]
        assert len(added) == len(EXAMPLES[name].steps[level - 1])
        for kind in ("solvability", "complexity"):
            trajectory = tmp_path / f"{level}-{kind}.json"
            trajectory.write_text(json.dumps(document["certificates"][kind]))
        solvable = run(
            "check", str(files[level]), "--ego", str(tmp_path / f"{level}-solvability.json")
        )
        assert solvable.returncode == 0, solvable.stdout
        complexity = str(tmp_path / f"{level}-complexity.json")
        assert run("check", str(files[level - 1]), "--ego", complexity).returncode == 0
        harder = run("check", str(files[level]), "--ego", complexity)
        assert harder.returncode == 1
        assert any(n["id"] in harder.stdout for n in added), harder.stdout
    # The certificate controllers, replayed in SUMO, do what their definition says.
    certificates = ["--controller", "certificate:solvability", "--controller"]
    result = run(
        "evaluate", *map(str, files[1:]), *certificates, "certificate:complexity", "--json"
    )
    assert result.returncode == 1, result.stderr
    verdicts = json.loads(result.stdout)
    assert len(verdicts) == 2 * levels
    for verdict in verdicts:
        if verdict["controller"] == "certificate:solvability":
            assert verdict["passed"], verdict["reasons"]
        else:
            level = int(verdict["testcase"].removeprefix(f"{name} level "))
            assert verdict["file"] == str(files[level])
            document = json.loads(files[level].read_text())
            users = [*document["nonegos"], *document.get("pedestrians", [])]
            new_ids = {n["id"] for n in users if n["added_in"] == level}
            assert not verdict["passed"] and verdict["goal"]["reached"]
            assert not verdict["collisions"]
            assert {v["other"] for v in verdict["violations"]} <= new_ids


def test_evaluate_prints_a_table_and_writes_junit(tmp_path: Path) -> None:
    """Rows and JUnit cases are named by the test-case's name (which says the level), the
    file beside it, as `check` names them."""
    first = tmp_path / "a.json"
    assert cli.main(["new", "4way-stop", "--ego", "S2C_1:C2W_1", "-o", str(first)]) == 0
    (tmp_path / "b.json").write_text(first.read_text())
    junit = tmp_path / "report.xml"
    result = run(
        "evaluate", str(tmp_path), "--controller", "sumo", "--controller", "sumo-aggressive",
        "--junit", str(junit),
    )  # fmt: skip
    assert result.returncode == 1, result.stderr
    lines = result.stdout.splitlines()
    name = "4way-stop C S2C_1:C2W_1 level 0"
    assert lines[0].split() == ["test-case", "file", "sumo", "sumo-aggressive"]
    assert lines[1].split() == [*name.split(), str(first), "pass", "FAIL:", "stopAtSign"]
    assert lines[2].split() == [*name.split(), str(tmp_path / "b.json"), "pass", "FAIL:",
                                "stopAtSign"]  # fmt: skip
    suite = ET.parse(junit).getroot().find("testsuite")
    assert suite is not None and suite.get("tests") == "4" and suite.get("failures") == "2"
    assert [case.get("name") for case in suite.findall("testcase")] == [
        f"{name} ({tmp_path / file}) / {controller}"
        for file in ("a.json", "b.json")
        for controller in ("sumo", "sumo-aggressive")
    ]


def test_an_evaluation_table_finishes_whatever_its_cells(tmp_path: Path) -> None:
    """A certificate the test-case lacks reads (none) and counts as neither pass nor fail;
    a file that cannot be evaluated is named in its row and below the table, and the rest
    of the table goes on; the exit code says what happened overall; progress on stderr."""
    y0, y1 = tmp_path / "y0.json", tmp_path / "y1.json"
    assert cli.main(["new", "y-uncontrolled", "--ego", "N2C_0:C2SE_0", "--duration", "25",
                     "-o", str(y0)]) == 0  # fmt: skip
    assert cli.main(["extend", str(y0), "--add", "SW2C_0:C2N_0", "-o", str(y1)]) == 0
    certificates = ["--controller", "sumo", "--controller", "certificate:solvability"]
    result = run("evaluate", str(y0), str(y1), *certificates)
    assert result.returncode == 0, result.stdout + result.stderr
    named = ["y-uncontrolled", "C", "N2C_0:C2SE_0", "level"]
    assert [line.split() for line in result.stdout.splitlines()] == [
        ["test-case", "file", "sumo", "certificate:solvability"],
        [*named, "0", str(y0), "pass", "(none)"],
        [*named, "1", str(y1), "pass", "pass"],
    ]
    last = f"4/4 y-uncontrolled C N2C_0:C2SE_0 level 1 ({y1}) / certificate:solvability: pass"
    assert "[" in result.stderr and last in result.stderr
    assert "3 passed, 0 failed, 1 without a certificate to replay" in result.stderr

    broken = tmp_path / "broken.json"
    broken.write_text('{"network": "4way-stop"}')
    upstream = tmp_path / "town07.json"  # the default start lies in an upstream junction
    assert cli.main(["new", str(TOWN07), "--junction", "358", "--control", "right_before_left",
                     "--ego=-40_0:35_0", "-o", str(upstream)]) == 0  # fmt: skip
    (tmp_path / TOWN07.name).write_bytes(TOWN07.read_bytes())  # found next to the test-case
    junit = tmp_path / "report.xml"
    result = run("evaluate", str(y0), str(broken), str(upstream), str(y1), *certificates,
                 "--junit", str(junit))  # fmt: skip
    assert result.returncode == 2, result.stdout + result.stderr
    rows = [line.split() for line in result.stdout.splitlines()]
    assert rows[1:5] == [
        [*named, "0", str(y0), "pass", "(none)"],
        ["-", str(broken), "ERROR", "(below)", "ERROR", "(below)"],
        ["Town07", "358", "-40_0:35_0", "level", "0", str(upstream), "pass", "(none)"],
        [*named, "1", str(y1), "pass", "pass"],
    ]
    below = result.stdout.splitlines()[5:]
    assert below[0].startswith(f"ERROR {broken}: invalid test-case")
    assert len(below) == 1
    report = junit.read_text()
    assert 'tests="7"' in report and 'errors="1"' in report and 'skipped="2"' in report


def test_a_testcase_finds_its_network_next_to_it_or_with_network(tmp_path: Path) -> None:
    """No absolute path is stored: a test-case made from a file names it by file name and
    hash (and its path relative to its own folder, which this test takes away, as from a
    test-case written before paths were kept); the CLI looks next to the test-case and takes
    --network, and says which it used."""
    folder = tmp_path / "suite"
    folder.mkdir()
    testcase = folder / "t7.json"
    made = subprocess.run(
        [sys.executable, "-m", "service", "new", str(TOWN07), "--junction", "358", "--control",
         "right_before_left", "--ego=-40_0:35_0", "-o", str(testcase)],
        cwd=tmp_path, capture_output=True, text=True, check=False,
    )  # fmt: skip
    assert made.returncode == 0, made.stderr
    document = json.loads(testcase.read_text())
    assert document["network"]["ref"] == "Town07.net.xml"
    assert not Path(document["network"].pop("path")).is_absolute()
    testcase.write_text(json.dumps(document))
    text = testcase.read_text()
    assert str(tmp_path) not in text and str(TOWN07.parent) not in text

    def evaluate(*extra: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run(
            [sys.executable, "-m", "service", "evaluate", str(testcase), *extra],
            cwd=tmp_path, capture_output=True, text=True, check=False,
        )  # fmt: skip

    missing = evaluate()
    assert missing.returncode == 2
    assert "'Town07.net.xml'" in missing.stderr and "--network FILE" in missing.stderr
    given = evaluate("--network", str(TOWN07))
    assert given.returncode == 0, given.stderr
    assert "(given with --network)" in given.stderr
    (folder / "Town07.net.xml").write_bytes(TOWN07.read_bytes())
    beside = evaluate()
    assert beside.returncode == 0, beside.stderr
    assert f"network Town07.net.xml: {folder / 'Town07.net.xml'} (next to the test-case)" in (
        beside.stderr
    )


def test_evaluate_one_passing_controller_exits_0(tmp_path: Path) -> None:
    testcase = tmp_path / "left.json"
    assert cli.main(["new", "4way-stop", "--ego", "S2C_1:C2W_1", "-o", str(testcase)]) == 0
    result = run("evaluate", str(testcase), "--controller", "sumo-cautious")
    assert result.returncode == 0, result.stdout + result.stderr
    assert result.stdout.startswith("PASS  4way-stop C S2C_1:C2W_1 level 0 / sumo-cautious")


def test_evaluate_a_guarded_controller_with_rss_parameters(tmp_path: Path) -> None:
    testcase = tmp_path / "left.json"
    assert cli.main(["new", "4way-stop", "--ego", "S2C_1:C2W_1", "-o", str(testcase)]) == 0
    params = tmp_path / "rss.json"
    params.write_text('{"response_time": 0.5, "others": {"accel_max": 2.0}}')
    result = run("evaluate", str(testcase), "--controller", "sumo+rss", "--rss-params", str(params))
    assert result.returncode == 0, result.stdout + result.stderr
    assert result.stdout.startswith("PASS  4way-stop C S2C_1:C2W_1 level 0 / sumo+rss")
    assert "the RSS guard intervened at 0 of" in result.stdout  # nobody else: nothing to do
    params.write_text('{"reaction_time": 0.5}')
    refused = run(
        "evaluate", str(testcase), "--controller", "sumo+rss", "--rss-params", str(params)
    )
    assert refused.returncode == 2 and "unknown RSS parameter 'reaction_time'" in refused.stderr


def test_evaluate_with_a_budget_too_small_exits_3_without_a_verdict(tmp_path: Path) -> None:
    """The budget is the command's limit, not the controller's: an error, never a FAIL."""
    testcase = tmp_path / "left.json"
    assert cli.main(["new", "4way-stop", "--ego", "S2C_1:C2W_1", "-o", str(testcase)]) == 0
    result = run("evaluate", str(testcase), "--budget", "0.01")
    assert result.returncode == 3, result.stdout + result.stderr
    assert "budget of 0.01 s" in result.stderr and "no verdict on sumo" in result.stderr
    assert "FAIL" not in result.stdout + result.stderr


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--controller", "autopilot"], "unknown controller 'autopilot'; valid: certificate"),
        (["--controller", "certificate:complexity"], "has none"),
        (["--controller", "certificate:complexity+rss"], "cannot be guarded"),
        (["--controller", "sumo+rss", "--rss-params", "missing.json"], "cannot read RSS"),
    ],
)
def test_evaluate_bad_input_exits_2(args: list[str], message: str, tmp_path: Path) -> None:
    testcase = tmp_path / "left.json"
    assert cli.main(["new", "4way-stop", "--ego", "S2C_1:C2W_1", "-o", str(testcase)]) == 0
    result = run("evaluate", str(testcase), *args)
    assert result.returncode == 2
    assert message in result.stderr


def test_export_writes_a_bundle(tmp_path: Path) -> None:
    testcase = tmp_path / "left.json"
    assert cli.main(["new", "4way-stop", "--ego", "S2C_1:C2W_1", "-o", str(testcase)]) == 0
    result = run("export", str(testcase), "-o", str(tmp_path / "bundle"))
    assert result.returncode == 0, result.stderr
    written = {Path(line).name for line in result.stdout.splitlines()}
    assert {"testcase.sumocfg", "testcase.fcd.xml", "run.py", "testcase.run.json"} <= written
    assert "python run.py --controller sumo" in result.stderr


def test_export_writes_openscenario(tmp_path: Path) -> None:
    testcase = tmp_path / "left.json"
    assert cli.main(["new", "4way-stop", "--ego", "S2C_1:C2W_1", "-o", str(testcase)]) == 0
    result = run("export", str(testcase), "--format", "openscenario", "-o", str(tmp_path / "o"))
    assert result.returncode == 0, result.stderr
    # an ego-only test-case has no certificates: no certificate scenarios
    written = {Path(line).name for line in result.stdout.splitlines()}
    assert written == {"testcase.xodr", "testcase.xosc", "verdict-rules.md"}
    assert "esmini" in result.stderr
    carla = run("export", str(testcase), "--format", "openscenario", "--flavour", "carla",
                "-o", str(tmp_path / "c"))  # fmt: skip
    assert carla.returncode == 0, carla.stderr
    assert 'revMinor="0"' in (tmp_path / "c" / "testcase.xosc").read_text()
    bad = run("export", str(testcase), "--format", "openscenario", "--flavour", "vtd",
              "-o", str(tmp_path / "v"))  # fmt: skip
    assert bad.returncode == 2 and "'asam', 'carla'" in bad.stderr


def test_plot_draws_a_testcase_and_an_evaluation(tmp_path: Path) -> None:
    testcase = tmp_path / "left.json"
    assert cli.main(["new", "4way-stop", "--ego", "S2C_1:C2W_1", "-o", str(testcase)]) == 0
    png, svg = tmp_path / "left.png", tmp_path / "left.svg"
    assert run("plot", str(testcase), "-o", str(png)).returncode == 0
    assert png.read_bytes().startswith(b"\x89PNG")
    result = run("plot", str(testcase), "-o", str(svg), "--controller", "sumo-aggressive")
    assert result.returncode == 0, result.stderr
    for stage in ("evaluating sumo-aggressive", "placing", f"writing {svg}"):  # progress
        assert stage in result.stderr, result.stderr
    text = svg.read_text()
    assert text.lstrip().startswith("<?xml") and "<svg" in text
    bad = run("plot", str(testcase), "-o", str(tmp_path / "left.gif"))
    assert bad.returncode == 2 and ".png or .svg" in bad.stderr


def test_plot_animates_a_replay(tmp_path: Path) -> None:
    testcase = tmp_path / "left.json"
    assert cli.main(["new", "4way-stop", "--ego", "S2C_1:C2W_1", "--duration", "7", "-o",
                     str(testcase)]) == 0  # fmt: skip
    gif = tmp_path / "left.gif"
    result = run("plot", str(testcase), "-o", str(gif), "--animate", "--controller", "sumo")
    assert result.returncode == 0, result.stderr
    from PIL import Image

    with Image.open(gif) as image:
        assert image.n_frames == 15  # one frame every 0.5 s of 7 s
    wrong = run("plot", str(testcase), "-o", str(tmp_path / "x.png"), "--animate")
    assert wrong.returncode == 2 and "--animate writes a GIF" in wrong.stderr
    gif_alone = run("plot", str(testcase), "-o", str(tmp_path / "x.gif"))
    assert gif_alone.returncode == 2 and "an animated GIF needs --animate" in gif_alone.stderr


def test_cli_testcases_get_readable_default_names(tmp_path: Path) -> None:
    """Network, junction, ego route and level; an extension renames the level; a name
    given with --name is kept and the next level continues it."""
    root, level1, level2 = tmp_path / "root.json", tmp_path / "l1.json", tmp_path / "l2.json"
    args = ["new", str(TOWN05), "--junction", "396", "--control", "allway_stop"]
    assert cli.main([*args, "--ego=-44_1:-9_1", "-o", str(root)]) == 0
    assert read_testcase(root).name == "Town05 396 -44_1:-9_1 level 0"
    assert cli.main(["extend", str(root), "--add=-8_1:-9_1", "-o", str(level1)]) == 0
    assert read_testcase(level1).name == "Town05 396 -44_1:-9_1 level 1"
    assert cli.main(["extend", str(level1), "--add", "45_1:44_1", "--name", "left",
                     "-o", str(level2)]) == 0  # fmt: skip
    assert read_testcase(level2).name == "left"
    named = tmp_path / "named.json"
    assert cli.main(["new", "t-stop", "--ego", "E2C_0:C2S_0", "--name", "t left",
                     "-o", str(named)]) == 0  # fmt: skip
    assert cli.main(["extend", str(named), "--add", "W2C_0:C2E_0", "-o", str(level1)]) == 0
    assert read_testcase(level1).name == "t left level 1"


def test_an_unstorable_name_fails_before_the_search(tmp_path: Path) -> None:
    root = tmp_path / "root.json"
    assert cli.main(["new", "t-stop", "--ego", "E2C_0:C2S_0", "-o", str(root)]) == 0
    result = run("extend", str(root), "--add", "W2C_0:C2E_0", "--name", "a\x01b")
    assert result.returncode == 2
    assert "name: must not contain control characters" in result.stderr
    assert "step 1" not in result.stderr  # no search was started
    long = tmp_path / "long.json"
    assert cli.main(["new", "t-stop", "--ego", "E2C_0:C2S_0", "--name", "x" * 199,
                     "-o", str(long)]) == 0  # fmt: skip
    assert cli.main(["extend", str(long), "--add", "W2C_0:C2E_0", "-o", str(root)]) == 0
    assert read_testcase(root).name == "x" * 192 + " level 1"  # cut to fit, not lost
