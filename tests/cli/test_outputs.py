"""Every path a command writes is checked before its work: a missing folder is made (and
said), a place that cannot take the file is refused with exit 2 and one line, never a
traceback; files are written whole or not at all."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from service.cli.commands import main, parser
from service.cli.output import EXIT_BAD_INPUT
from service.core.files import replacing, write_atomically
from service.core.testcase import dump_testcase, new_testcase

# every command that writes, with its written argument last (BAD stands for the place)
WRITERS = {
    "new -o": ["new", "4way-stop", "--ego", "S2C_1:C2W_1", "-o", "BAD/t.json"],
    "extend -o": ["extend", "TESTCASE", "--add", "W2C_0:C2E_0", "-o", "BAD/t.json"],
    "drive --plot": ["drive", "TESTCASE", "--plot", "BAD/d.png"],
    "intersection --plot": ["intersection", "4way-stop", "--plot", "BAD/i.png"],
    "check --junit": ["check", "TESTCASE", "--ego", "TESTCASE", "--junit", "BAD/j.xml"],
    "evaluate --junit": ["evaluate", "TESTCASE", "--junit", "BAD/j.xml"],
    "export -o": ["export", "TESTCASE", "-o", "BAD/bundle"],
    "plot -o": ["plot", "TESTCASE", "-o", "BAD/p.png"],
    "example -o": ["example", "four-way", "-o", "BAD/chain"],
    "campaign -o": ["campaign", "4way-stop", "--ego", "S2C_1:C2W_1", "--depth", "1",
                    "--chains", "1", "--controller", "sumo", "-o", "BAD/campaign"],
    "report -o": ["report", "somewhere", "-o", "BAD/r.html"],
    "submit --junit": ["submit", "BATCH", "--server", "http://127.0.0.1:9", "--junit", "BAD/j.xml"],
    "submit --out": ["submit", "BATCH", "--server", "http://127.0.0.1:9", "--out", "BAD/results"],
    "serve --data-dir": ["serve", "--port", "9", "--data-dir", "BAD/data"],
}  # fmt: skip


@pytest.fixture(scope="module")
def testcase_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("outputs") / "left.json"
    path.write_text(dump_testcase(new_testcase("4way-stop", "S2C_1:C2W_1")))
    return path


def _arguments(name: str, bad: Path, testcase: Path) -> list[str]:
    words = []
    for word in WRITERS[name]:
        head, _, tail = word.partition("/")
        words.append(str(bad / tail) if head == "BAD" else str(testcase) if head in (
            "TESTCASE", "BATCH") else word)  # fmt: skip
    return words


def test_every_written_argument_is_declared() -> None:
    """The table knows each written path (a new one cannot skip the check)."""
    declared = {}
    for action in parser()._subparsers._group_actions:  # type: ignore[union-attr]
        for name, sub in action.choices.items():
            declared[name] = {dest for dest, _ in sub.get_default("writes")}
    for name, words in WRITERS.items():
        flag = words[-2]
        dest = {"-o": "output"}.get(flag, flag.lstrip("-").replace("-", "_"))
        assert dest in declared[words[0]], name


@pytest.mark.parametrize("name", WRITERS)
@pytest.mark.parametrize("place", ["a file on the way", "a folder that takes no file"])
def test_an_unwritable_output_is_refused_before_the_work(
    name: str, place: str, testcase_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    if place == "a file on the way":
        (tmp_path / "plain").write_text("")
        bad = tmp_path / "plain" / "below"
    else:
        bad = Path("/proc/scengen-nope")
    assert main(_arguments(name, bad, testcase_file)) == EXIT_BAD_INPUT
    out, err = capsys.readouterr()
    assert out == ""
    assert err.count("\n") == 1 and err.startswith("scengen: error: cannot write"), err


def test_a_folder_as_a_file_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["new", "4way-stop", "--ego", "S2C_1:C2W_1", "-o", str(tmp_path)]) == 2
    assert "it is a folder; give a file name" in capsys.readouterr().err


def test_a_missing_folder_is_made_and_said(
    testcase_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    target = tmp_path / "a" / "b" / "t.json"
    assert main(["new", "4way-stop", "--ego", "S2C_1:C2W_1", "-o", str(target)]) == 0
    assert target.is_file()
    assert f"made the folder {target.parent}" in capsys.readouterr().err
    junit = tmp_path / "reports" / "j.xml"
    code = main(["check", str(target), "--ego", str(testcase_file), "--junit", str(junit)])
    assert code == 2  # a test-case is no trajectory: bad input, and no report
    assert not junit.exists()
    bundle = tmp_path / "x" / "bundle"
    assert main(["export", str(target), "-o", str(bundle)]) == 0
    assert (bundle / "testcase.json").is_file() and not list(bundle.glob(".*partial*"))


def test_an_interrupted_write_leaves_the_old_file(tmp_path: Path) -> None:
    target = tmp_path / "t.json"
    write_atomically(target, "old")
    with pytest.raises(KeyboardInterrupt), replacing(target) as partial:
        partial.write_text("half")
        raise KeyboardInterrupt
    assert target.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["t.json"]
    write_atomically(target, b"new")
    assert target.read_text() == "new"


def test_a_written_file_has_the_usual_mode(tmp_path: Path) -> None:
    os.umask(current := os.umask(0o022))
    target = tmp_path / "t.json"
    write_atomically(target, "x")
    assert target.stat().st_mode & 0o777 == 0o666 & ~current
