"""``scengen extend --count N``: N distinct extensions in one call, each a file of its own
and each verified here by the checker itself; seeds that give different test-cases."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from service import cli
from service.core.checker.check import check_testcase
from service.core.generator.variety import distinct_count, signature
from service.core.motion.poses import PoseSample
from service.core.testcase import TestCase, load_testcase_intersection, read_testcase

pytestmark = pytest.mark.slow  # 14 s of work or more: `make test-fast` leaves it out

# A case where the generator finds distinct extensions in about a second: the ego straight
# on from the south of the all-way stop, a new car straight on from the west.
EGO, NEW = "S2C_1:C2N_1", "W2C_0:C2E_0"


def run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "service", *args], capture_output=True, text=True, check=False
    )


@pytest.fixture(scope="module")
def root(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("count") / "s0.json"
    made = run("new", "4way-stop", "--ego", EGO, "--duration", "30", "-o", str(path))
    assert made.returncode == 0, made.stderr
    return path


def _samples(rows: object) -> list[PoseSample]:
    return [PoseSample(**row.model_dump()) for row in rows]  # type: ignore[attr-defined]


def assert_verified(old: TestCase, new: TestCase) -> None:
    """The solvability certificate passes ``new``; the complexity certificate passes ``old``
    and fails ``new`` by a rule."""
    junction = load_testcase_intersection(new)
    assert new.certificates is not None
    solvable = check_testcase(new, _samples(new.certificates.solvability), "s", junction)
    assert solvable.passed, solvable.reasons
    complexity = _samples(new.certificates.complexity)
    assert check_testcase(old, complexity, "c", junction).passed
    failed = check_testcase(new, complexity, "c", junction)
    assert not failed.passed and failed.violations


def test_count_3_writes_3_distinct_verified_testcases(root: Path, tmp_path: Path) -> None:
    out = tmp_path / "s1.json"
    result = run("extend", str(root), "--add", NEW, "--count", "3", "-o", str(out))
    assert result.returncode == 0, result.stderr
    paths = [tmp_path / f"s1-{k}.json" for k in (1, 2, 3)]
    assert sorted(tmp_path.iterdir()) == paths  # no s1.json: only the variants
    made = [read_testcase(p) for p in paths]
    assert distinct_count(made) == 3
    assert [t.name for t in made] == [f"4way-stop C {EGO} variant {k} level 1" for k in (1, 2, 3)]
    old = read_testcase(root)
    for new in made:
        assert_verified(old, new)
    # a line per extension saying what tells it apart, before the file is written
    said = [line for line in result.stderr.splitlines() if line.startswith("s1-")]
    assert [line.split(":")[0] for line in said] == [p.name for p in paths]
    for line, new in zip(said, made, strict=True):
        car = signature(new).cars[0]
        assert f"car1 ({NEW}) {'stops' if car.stops else 'does not stop'}" in line
        assert f"enters at {car.entry:.2f} s" in line and "yieldToInside of car1" in line
    assert "3 distinct extensions of 3 asked for" in result.stderr


def test_seeds_give_different_testcases_and_the_same_seed_the_same_bytes(
    root: Path, tmp_path: Path
) -> None:
    written = {}
    for name, extra in (("a", ["--seed", "0"]), ("b", ["--seed", "1"]),
                        ("c", ["--seed", "1", "--count", "1"])):  # fmt: skip
        path = tmp_path / f"{name}.json"
        result = run("extend", str(root), "--add", NEW, *extra, "-o", str(path))
        assert result.returncode == 0, result.stderr
        written[name] = path.read_bytes()
    assert written["b"] == written["c"]  # --count 1 is the extension of today, byte for byte
    made = [read_testcase(tmp_path / f"{name}.json") for name in ("a", "b")]
    assert distinct_count(made) == 2


def test_fewer_than_asked_say_why(root: Path, tmp_path: Path) -> None:
    """Far fewer than 50 distinct extensions exist here: those found are written, and the
    last line says how far the search went."""
    result = run("extend", str(root), "--add", NEW, "--count", "50", "-o", str(tmp_path / "s.json"))
    assert result.returncode == 0, result.stderr
    written = sorted(tmp_path.iterdir(), key=lambda path: int(path.stem.split("-")[1]))
    have = len(written)
    assert 3 < have < 50 and [p.name for p in written] == [
        f"s-{k}.json" for k in range(1, have + 1)
    ]
    assert distinct_count([read_testcase(p) for p in written]) == have
    assert f"{have} distinct extensions of 50 asked for" in result.stderr
    last = result.stderr.splitlines()[-1]
    assert last.startswith(f"{have} distinct extensions ") and "answer sets" in last, last


@pytest.mark.parametrize(
    ("given", "words"),
    [
        (["--count", "0", "-o", "x.json"], "from 1 to 50"),
        (["--count", "51", "-o", "x.json"], "from 1 to 50"),
        (["--count", "two", "-o", "x.json"], "from 1 to 50"),
        (["--count", "3"], "give -o FILE.json"),
    ],
)
def test_bad_counts_are_usage_errors(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, given: list[str], words: str
) -> None:
    """Checked before the old test-case is read (it does not exist here)."""
    with pytest.raises(SystemExit) as caught:
        cli.main(["extend", str(tmp_path / "missing.json"), "--add", NEW, *given])
    error = capsys.readouterr().err
    assert caught.value.code == 2 and words in error, error
