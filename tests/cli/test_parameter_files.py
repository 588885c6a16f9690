"""Hostile parameter files on the command line (issue 50): a link to /dev/zero, JSON nested
100,000 deep, a boolean or an enormous RSS value, a signal program of sub-millisecond phases.
Each is one line and exit 2, quickly (a subprocess timeout, not a timed assertion, bounds it:
before the limits the first grew to 23 GB and the second printed a traceback)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from service import cli

EGO = ["--ego", "S2C_1:C2W_1"]
TIMEOUT = 30  # s: each command refuses its input before any replay or search


def scengen(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    """A command as a user runs it; TimeoutExpired (a failure) when it hangs."""
    return subprocess.run(
        [sys.executable, "-m", "service", *args],
        capture_output=True, text=True, check=False, cwd=cwd, timeout=TIMEOUT,
    )  # fmt: skip


def one_line(result: subprocess.CompletedProcess[str]) -> str:
    """The only line of a refusal (exit 2, nothing on stdout, no traceback)."""
    lines = result.stderr.strip().splitlines()
    assert result.returncode == 2, result.stderr
    assert len(lines) == 1 and lines[0].startswith("scengen: error: "), result.stderr
    assert result.stdout == ""
    return lines[0]


@pytest.fixture(scope="module")
def testcase(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("params") / "t0.json"
    assert cli.main(["new", "4way-stop", *EGO, "-o", str(path)]) == 0
    return path


def _zero(folder: Path) -> Path:
    link = folder / "zero.json"
    link.symlink_to("/dev/zero")
    return link


def _deep(folder: Path) -> Path:
    path = folder / "deep.json"
    path.write_text("[" * 100_000 + "]" * 100_000)
    return path


def _object_deep(folder: Path) -> Path:
    path = folder / "deep-object.json"
    path.write_text('{"ego": ' * 100_000 + "1" + "}" * 100_000)
    return path


def _written(name: str, document: object) -> object:
    def write(folder: Path) -> Path:
        path = folder / name
        path.write_text(json.dumps(document))
        return path

    return write


RSS = [  # (the file, what the one line says)
    (_zero, "is larger than 1,000,000 bytes, the limit"),
    (_deep, "is nested more than 32 levels deep, the limit"),
    (_object_deep, "is nested more than 32 levels deep, the limit"),
    (_written("bool.json", {"response_time": True}),
     "RSS parameter 'response_time' (ego) must be a number from 0.01 to 10 s, got true"),
    (_written("huge.json", {"accel_max": 1e308}),
     "RSS parameter 'accel_max' (ego) is 1e+308; valid: 0.01 to 20 m/s^2"),
    (_written("side.json", {"others": {"brake_max": -1e9}}),
     "RSS parameter 'brake_max' (others) is -1e+09; valid: -20 to -0.01 m/s^2"),
    (_written("list.json", [1, 2]), "expected a JSON object"),
]  # fmt: skip


@pytest.mark.parametrize(("make", "message"), RSS, ids=range(len(RSS)))
def test_a_hostile_rss_parameter_file_is_one_line_and_exit_2(
    make: object, message: str, testcase: Path, tmp_path: Path
) -> None:
    params = make(tmp_path)  # type: ignore[operator]
    result = scengen("evaluate", str(testcase), "--controller", "sumo+rss",
                     "--rss-params", str(params), cwd=tmp_path)  # fmt: skip
    line = one_line(result)
    assert message in line and str(params) in line, line


SIGNALS = [
    (_zero, "zero.json is neither JSON ({...}) nor SUMO XML (<...>)"),
    (_object_deep, "deep-object.json is nested more than 32 levels deep, the limit"),
    (_written("big.json", {"tls": "C", "phases": [], "note": "x" * 1_000_000}),
     "big.json is larger than 1,000,000 bytes, the limit of a JSON program"),
]  # fmt: skip


@pytest.mark.parametrize(("make", "message"), SIGNALS, ids=range(len(SIGNALS)))
def test_a_hostile_signals_file_is_one_line_and_exit_2(
    make: object, message: str, tmp_path: Path
) -> None:
    signals = make(tmp_path)  # type: ignore[operator]
    for command in (["intersection", "4way-signal"], ["new", "4way-signal", *EGO]):
        line = one_line(scengen(*command, "--signals", str(signals), cwd=tmp_path))
        assert message in line, line


def test_sub_millisecond_signals_make_intersection_refuse_at_once(tmp_path: Path) -> None:
    """It had not finished after 60 s."""
    tiny = tmp_path / "tiny.json"
    tiny.write_text(json.dumps({"tls": "C", "phases": [{"duration": 1e-6, "state": "G" * 16}]}))
    line = one_line(scengen("intersection", "4way-signal", "--signals", str(tiny),
                            "--duration", "20", cwd=tmp_path))  # fmt: skip
    assert "phases.0.duration is 1e-06 s; a phase lasts from 0.1 s (SUMO's step)" in line
