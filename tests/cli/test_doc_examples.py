"""Every command example of README.md and of the docs pages runs as it stands, so the
documentation cannot drift from what the commands do (docs/development.md, "The examples
are tests").

Each file's ``console`` and ``sh`` blocks run in order in a folder of their own (a block may
use files an earlier block of the same file wrote), with the installed commands on the PATH,
as a new user would type them; the README's quick start runs in an empty folder. A
``console`` block's shown output must appear in what the command prints (whitespace aside,
``...`` for lines left out, solver timings aside), and the command must exit 2 where the
block shows a refusal (``scengen: error:``), 1 where it shows a FAIL, else 0. Blocks marked
on the line before them are not run here (tests.doc_examples says how they are marked).
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from tests.doc_examples import README, Block, blocks, set_up, sources, where

pytestmark = pytest.mark.slow  # a minute of work in all: `make test-fast` leaves it out

TIMINGS = [
    (re.compile(r"\[\s*\d+(\.\d+)? s\]"), "[T s]"),  # a progress line's clock
    (re.compile(r"\bin \d+(\.\d+)? s\b"), "in T s"),  # how long a solver or drive took
]
README_LINES = 400  # the README is a front door: the rest is in docs/
QUICK_START_LINES = 30  # heading included
QUICK_START_BY = 60  # the quick start starts within the README's first lines


def _with_examples() -> list[Path]:
    return [source for source in sources() if any(b.runs_here for b in blocks(source))]


def _normal(text: str) -> str:
    for pattern, replacement in TIMINGS:
        text = pattern.sub(replacement, text)
    return " ".join(text.split())


def _expected_parts(shown: str) -> list[re.Pattern[str]]:
    """The shown output as patterns to find in order: a line of ``...`` separates them, a
    ``...`` inside a line stands for any text."""
    parts, current = [], []
    for line in shown.splitlines():
        if line.strip() == "...":
            parts.append(current)
            current = []
        else:
            current.append(line)
    parts.append(current)
    patterns = []
    for part in parts:
        text = _normal("\n".join(part))
        if text:
            pieces = [re.escape(piece) for piece in text.split("...")]
            patterns.append(re.compile(".*?".join(pieces)))
    return patterns


def _script(block: Block, workdir: Path) -> str:
    rows = [f"cd {workdir}"]
    for k, command in enumerate(block.commands):
        rows.append(f"echo '@@start {k}'")
        rows += ["{", command.text, "} 2>&1"]  # on its own line: it may end in a comment
        rows.append(f'echo "@@end {k} $?"')
    return "\n".join(rows) + "\n"


def _quick_start() -> tuple[int, list[str]]:
    """The line number of the README's quick start heading, and the section's lines."""
    lines = README.read_text().splitlines()
    start = lines.index("## Quick start")
    end = next(k for k in range(start + 1, len(lines)) if lines[k].startswith("## "))
    section = lines[start:end]
    while section and not section[-1].strip():
        section.pop()
    return start + 1, section


def test_every_block_is_run_or_marked() -> None:
    every = [block for source in sources() for block in blocks(source)]
    run = [b for b in every if b.runs_here]
    assert len(run) >= 15 and all(b.commands for b in run)
    marked = [b for b in every if not b.runs_here]
    unexplained = [
        f"{where(b.source)}:{b.line}"
        for b in marked
        if "(" not in b.marker and "curl-example" not in b.marker
    ]
    assert not unexplained, f"a marked block says why it is not run here: {unexplained}"


def test_the_readme_is_a_front_door_with_a_quick_start() -> None:
    """Short; the quick start near the top, short, free of markers, and the README's only
    examples that run (so they run in an empty folder: the next test)."""
    assert len(README.read_text().splitlines()) <= README_LINES
    start, section = _quick_start()
    assert start <= QUICK_START_BY and len(section) <= QUICK_START_LINES, (start, len(section))
    assert "<!--" not in "\n".join(section)
    runs = [b for b in blocks(README) if b.runs_here]
    assert runs and all(start < b.line < start + len(section) for b in runs)
    commands = " ".join(c.text for b in runs for c in b.commands)
    for step in ("scengen new", "scengen extend", "--count", "scengen evaluate",
                 "--controller sumo ", "--controller sumo+rss", "scengen plot",
                 "--format openscenario", "scengen campaign"):  # fmt: skip
        assert step in commands, step
    assert "tests/" not in commands  # nothing of the repository: it runs from any folder
    links = re.findall(r"\]\(([^)#\s]+)", README.read_text())
    missing = [link for link in links if "://" not in link and not (README.parent / link).exists()]
    assert not missing, f"the README links to files that are not there: {missing}"


@pytest.mark.parametrize("source", _with_examples(), ids=where)
def test_the_examples_run_as_shown(source: Path, tmp_path: Path) -> None:
    workdir = tmp_path / "work"
    workdir.mkdir()
    set_up(source, workdir)
    if source == README:
        assert not any(workdir.iterdir())  # the quick start runs in an empty folder
    bin_dir = Path(sys.executable).parent
    env = {
        **os.environ,
        "PATH": f"{bin_dir}{os.pathsep}{os.environ.get('PATH', '')}",
        "PYTHONUNBUFFERED": "1",  # stdout and stderr interleave as they would on a terminal
        "XDG_CACHE_HOME": str(tmp_path / "cache"),
        "COLUMNS": "100",
    }
    problems = []
    ran = 0
    for block in blocks(source):
        if not block.runs_here:
            continue
        result = subprocess.run(
            ["bash", "-c", _script(block, workdir)],
            capture_output=True, text=True, timeout=600, env=env,
        )  # fmt: skip
        outputs = re.findall(r"@@start (\d+)\n(.*?)@@end \1 (\d+)\n", result.stdout, flags=re.S)
        assert len(outputs) == len(block.commands), (block.line, result.stdout, result.stderr)
        for command, (_, output, code) in zip(block.commands, outputs, strict=True):
            ran += 1
            expected_code = 1 if "FAIL" in command.shown else 0
            if "scengen: error:" in command.shown:
                expected_code = 2  # bad input, refused with its reason
            place = f"{where(source)}:{command.line}: $ {command.text}"
            if int(code) != expected_code:
                problems.append(f"{place}\n  exit {code}, expected {expected_code}\n{output}")
                continue
            actual = _normal(output)
            position = 0
            for pattern in _expected_parts(command.shown):
                found = pattern.search(actual, position)
                if found is None:
                    problems.append(f"{place}\n  shows {pattern.pattern!r}\n  printed:\n{output}")
                    break
                position = found.end()
    assert not problems, "\n\n".join(problems)
    assert ran >= 1
