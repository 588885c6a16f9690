"""Small things a new user meets first: --version, a lane id that starts with '-', a port
in use, a broken batch file, a trajectory no car can drive."""

from __future__ import annotations

import json
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from service.cli.commands import main
from service.core.testcase import dump_testcase, new_testcase, parse_testcase
from tests.conftest import TOWN05


def run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "service", *args], capture_output=True, text=True, check=False
    )


def test_version_names_the_package_and_sumo() -> None:
    result = run("--version")
    assert result.returncode == 0
    assert result.stdout.startswith("scengen 0.") and "(SUMO 1." in result.stdout


def test_a_lane_id_with_a_dash_gets_the_equals_hint() -> None:
    result = run("new", str(TOWN05), "--junction", "396", "--ego", "-44_1:-9_1")
    assert result.returncode == 2
    assert result.stderr.splitlines()[-1].endswith(
        "argument --ego: expected one argument; a value that starts with '-' goes after "
        "'=': --ego=-44_1:-9_1"
    )


def test_a_missing_value_gets_no_dash_hint(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(["new", "4way-stop", "--ego"])
    assert capsys.readouterr().err.splitlines()[-1].endswith("expected one argument")


def test_serve_on_a_port_in_use_says_so_before_it_starts() -> None:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        result = run("serve", "--port", str(port))
    assert result.returncode == 2
    assert result.stderr.strip() == (
        f"scengen: error: cannot serve on 127.0.0.1:{port}: Address already in use (another "
        "program listens there: choose another --port)"
    )


@pytest.mark.parametrize(
    ("name", "text", "message"),
    [
        ("b.yaml", "items:\n  - kind: chain\n    testcase: [a, b\n  x: 1\n",
         "is not valid YAML: while parsing a flow sequence: expected ',' or ']', but got ':' "
         "at line 4 column 4"),
        ("b.json", '{"items": [\n  {"kind": }\n]}', "is not valid JSON: Expecting value at "
         "line 2 column 12"),
    ],
)  # fmt: skip
def test_a_broken_batch_file_is_one_line(
    name: str, text: str, message: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    batch = tmp_path / name
    batch.write_text(text)
    assert main(["submit", str(batch), "--server", "http://127.0.0.1:9"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err, err


def test_a_trajectory_that_jumps_is_warned_about(tmp_path: Path) -> None:
    """A car that moves 30 m in one step of 0.1 s is still a valid document (the checker
    judges it as written), but every command that reads it says so."""
    document = json.loads(dump_testcase(new_testcase("4way-stop", "S2C_1:C2W_1")))
    samples = [
        {"t": k / 10, "x": 148.4, "y": 100.0 + k + (30 if k >= 5 else 0), "heading": 0.0,
         "speed": 10.0, "distance": k + (30.0 if k >= 5 else 0.0)}
        for k in range(10)
    ]  # fmt: skip
    document["nonegos"] = [
        {"id": "car1", "route": {"fork": "S2C_0", "exit": "C2N_0"}, "trajectory": samples,
         "added_in": 1}
    ]  # fmt: skip
    parse_testcase(document)  # valid
    path = tmp_path / "jumps.json"
    path.write_text(json.dumps(document))
    result = run("drive", str(path))
    assert result.returncode == 0
    assert (
        f"scengen: warning: {path}: car1's trajectory moves 31.0 m between 0.40 s and 0.50 s, "
        "where its speeds (10.0 and 10.0 m/s) allow at most 1.6 m: no car can"
    ) in result.stderr
