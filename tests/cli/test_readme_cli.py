"""Every command block of the README runs as it stands, so the README cannot drift.

Each ``console`` and ``sh`` block runs, in README order, in one working folder (a block may
use files an earlier block wrote), with the installed commands on the PATH, as a new user
would type them. A ``console`` block's shown output must appear in what the command prints
(whitespace aside, ``...`` for lines left out, solver timings aside), and the command must
exit 2 where the README shows a refusal (``scengen: error:``), 1 where it shows a FAIL,
else 0. A block that cannot run offline is marked on
the line before it, with the reason (``<!-- readme: not run (...) -->``) or with the test
that runs it against a server (``<!-- readme: server ... -->``, ``<!-- curl-example ... -->``).
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow  # 14 s of work or more: `make test-fast` leaves it out

ROOT = Path(__file__).parents[2]
README = ROOT / "README.md"
MARKERS = ("<!-- readme: not run", "<!-- readme: server", "<!-- curl-example")
TIMINGS = [
    (re.compile(r"\[\s*\d+(\.\d+)? s\]"), "[T s]"),  # a progress line's clock
    (re.compile(r"\bin \d+(\.\d+)? s\b"), "in T s"),  # how long a solver or drive took
]


@dataclass(frozen=True)
class Command:
    line: int  # in the README
    text: str
    shown: str  # the output the README shows under it ("" for an sh block)


@dataclass(frozen=True)
class Block:
    line: int
    marker: str
    commands: tuple[Command, ...]


def readme_blocks() -> list[Block]:
    """The README's console and sh blocks with the marker on the line before each."""
    lines = README.read_text().splitlines()
    blocks = []
    k = 0
    while k < len(lines):
        language = re.fullmatch(r"```(console|sh)", lines[k])
        if not language:
            k += 1
            continue
        start = k
        end = lines.index("```", k + 1)
        body = lines[start + 1 : end]
        before = next((line for line in reversed(lines[:start]) if line.strip()), "")
        parse = _console if language.group(1) == "console" else _shell
        blocks.append(Block(start + 1, before, tuple(parse(body, start + 2))))
        k = end + 1
    return blocks


def _console(body: list[str], first: int) -> list[Command]:
    commands: list[Command] = []
    text, shown, line = "", [], 0
    for k, row in enumerate(body):
        if row.startswith("$ "):
            if text:
                commands.append(Command(line, text, "\n".join(shown)))
            text, shown, line = row[2:], [], first + k
        else:
            shown.append(row)
    if text:
        commands.append(Command(line, text, "\n".join(shown)))
    return commands


def _shell(body: list[str], first: int) -> list[Command]:
    commands: list[Command] = []
    text, line = "", 0
    for k, row in enumerate(body):
        if not text and (not row.strip() or row.lstrip().startswith("#")):
            continue
        line = line if text else first + k
        text += row.removesuffix("\\") + (" " if row.endswith("\\") else "")
        if not row.endswith("\\"):
            commands.append(Command(line, text.strip(), ""))
            text = ""
    return commands


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


def test_every_block_is_run_or_marked() -> None:
    blocks = readme_blocks()
    run = [b for b in blocks if not b.marker.startswith(MARKERS)]
    assert len(run) >= 8 and all(b.commands for b in run)
    marked = [b for b in blocks if b.marker.startswith(MARKERS)]
    assert all("(" in b.marker or "curl-example" in b.marker for b in marked), [
        b.line for b in marked
    ]


@pytest.fixture(scope="module")
def workdir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("readme")
    (folder / "tests").symlink_to(ROOT / "tests")  # the README's tests/data/carla/... paths
    return folder


def test_the_readme_commands_run_as_shown(workdir: Path) -> None:
    bin_dir = Path(sys.executable).parent
    env = {
        **os.environ,
        "PATH": f"{bin_dir}{os.pathsep}{os.environ.get('PATH', '')}",
        "PYTHONUNBUFFERED": "1",  # stdout and stderr interleave as they would on a terminal
        "XDG_CACHE_HOME": str(workdir / ".cache"),
        "COLUMNS": "100",
    }
    problems = []
    ran = 0
    for block in readme_blocks():
        if block.marker.startswith(MARKERS):
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
            where = f"README.md:{command.line}: $ {command.text}"
            if int(code) != expected_code:
                problems.append(f"{where}\n  exit {code}, expected {expected_code}\n{output}")
                continue
            actual = _normal(output)
            position = 0
            for pattern in _expected_parts(command.shown):
                found = pattern.search(actual, position)
                if found is None:
                    problems.append(f"{where}\n  shows {pattern.pattern!r}\n  printed:\n{output}")
                    break
                position = found.end()
    assert not problems, "\n\n".join(problems)
    assert ran >= 20
