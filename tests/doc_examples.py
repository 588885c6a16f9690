"""The examples of README.md and of the pages in docs/, read as the tests run them.

A ``console`` block holds commands after ``$ `` with the output they show below them; a
``sh`` block holds commands alone (a line ending in ``\\`` goes on on the next). The
non-blank line before a block may mark it: ``<!-- example: not run (why) -->`` (never run:
it needs what a test machine lacks, or minutes), ``<!-- example: server (...) -->`` and
``<!-- curl-example ... -->`` (run against a real server by tests/api/test_http_examples.py).
A file whose examples need files of the repository names them in a comment,
``<!-- example set-up: copy PATH PATH ... -->``, and they are copied into the folder its
examples run in (development.md, "The examples are tests").
"""

from __future__ import annotations

import re
import shutil
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).parents[1]
README = ROOT / "README.md"
DOCS = ROOT / "docs"
NOT_RUN = "<!-- example: not run"
SERVER_MARKERS = ("<!-- example: server", "<!-- curl-example")
MARKERS = (NOT_RUN, *SERVER_MARKERS)
SET_UP = re.compile(r"<!-- example set-up: copy ([^>]*?) -->")


@dataclass(frozen=True)
class Command:
    line: int  # in its file
    text: str
    shown: str  # the output shown under it ("" in a sh block)


@dataclass(frozen=True)
class Block:
    source: Path
    line: int
    language: str
    marker: str  # the non-blank line before the block
    body: str
    commands: tuple[Command, ...]

    @property
    def runs_here(self) -> bool:
        """Run by the examples' test, as opposed to marked."""
        return not self.marker.startswith(MARKERS)

    @property
    def runs_on_a_server(self) -> bool:
        return self.marker.startswith(SERVER_MARKERS)


def sources() -> list[Path]:
    """README.md and every page of docs/ (not the hooks')."""
    return [README, *sorted(DOCS.glob("**/*.md"))]


def blocks(source: Path) -> list[Block]:
    """The file's console and sh blocks, in order, with the marker before each."""
    lines = source.read_text().splitlines()
    found = []
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
        commands = tuple(parse(body, start + 2))
        found.append(
            Block(source, start + 1, language.group(1), before, "\n".join(body) + "\n", commands)
        )
        k = end + 1
    return found


def set_up_files(source: Path) -> list[Path]:
    """The repository's files that the source's examples need in their folder."""
    return [ROOT / name for names in SET_UP.findall(source.read_text()) for name in names.split()]


def set_up(source: Path, folder: Path) -> None:
    """Copy the files the source's examples need into the folder they run in."""
    for file in set_up_files(source):
        shutil.copy(file, folder / file.name)


def where(source: Path) -> str:
    return str(source.relative_to(ROOT))


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
