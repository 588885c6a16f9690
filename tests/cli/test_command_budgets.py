"""Every command's work runs inside its budget (issue 50): a command that works on the
user's input runs in a child process that is stopped when the command's budget runs out,
whatever the work is doing (service.cli.budgeted): reading an input that never ends, a
grounding that never looks at the clock, thousands of frames. It ends within its budget
and ``KILL_GRACE``, exit 3, saying which budget ran out; no process and no partial file is
left behind."""

from __future__ import annotations

import json
import os
import socket
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from service import cli
from service.cli.budgeted import COMMANDS, KILL_GRACE
from service.cli.judging import JUDGING

SLACK = 5.0  # s beyond the kill for starting and reaping the child on a loaded machine
FLICKER = [  # a program at its bounds (64 phases of SUMO's step), all green then all red
    {"duration": 0.1, "state": "GGGgrrrrGGGgrrrr" if i % 2 == 0 else "rrrrGGGgrrrrGGGg"}
    for i in range(64)
]


@pytest.fixture
def silent_server() -> Iterator[str]:
    """The address of a server that takes connections and never answers."""
    with socket.create_server(("127.0.0.1", 0)) as server:
        yield f"http://127.0.0.1:{server.getsockname()[1]}"


def stopped(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[float, str]:
    """``scengen ARGV`` run until its budget stopped it: the seconds it took, its last line
    on stderr."""
    started = time.monotonic()
    code = cli.main(argv)
    took = time.monotonic() - started
    err = capsys.readouterr().err
    assert code == 3, err
    return took, err.strip().splitlines()[-1]


# every command with a budget, on an input that never ends: a named pipe nobody writes to
# (a test-case, a signal program), or a server that never answers
NEVER = {
    "intersection": ["intersection", "4way-signal", "--signals", "{fifo}"],
    "new": ["new", "4way-signal", "--ego", "S2C_0:C2N_0", "--signals", "{fifo}"],
    "drive": ["drive", "{fifo}"],
    "check": ["check", "{fifo}", "--ego", "{fifo}"],
    "extend": ["extend", "{fifo}", "--add", "E2C_0:C2W_0"],
    "evaluate": ["evaluate", "{fifo}"],
    "cosim": ["cosim", "{fifo}", "--port", "0", "--wait", "0.1"],
    "export": ["export", "{fifo}", "-o", "{tmp}/out"],
    "plot": ["plot", "{fifo}", "-o", "{tmp}/p.png"],
    "report": ["report", "1", "--server", "{server}", "-o", "{tmp}/r.html"],
}


@pytest.mark.parametrize("name", sorted(NEVER))
def test_a_command_on_an_input_that_never_ends_stops_at_its_budget(
    name: str, tmp_path: Path, silent_server: str, capsys: pytest.CaptureFixture[str]
) -> None:
    fifo = tmp_path / "never.json"
    os.mkfifo(fifo)
    values = {"fifo": str(fifo), "tmp": str(tmp_path), "server": silent_server}
    argv = [word.format(**values) for word in NEVER[name]] + ["--budget", "0.1"]
    limit = {"evaluate": 0.1 + JUDGING, "cosim": 0.2 + JUDGING}.get(name, 0.1)
    took, said = stopped(argv, capsys)
    assert said.startswith(f"scengen: failed: scengen {name} did not finish within its budget "
                           f"of {limit:g} s"), said  # fmt: skip
    assert said.endswith("and was stopped; a larger --budget gives it more time")
    assert limit <= took < limit + KILL_GRACE + SLACK
    assert sorted(p.name for p in tmp_path.iterdir()) == ["never.json"]  # nothing written


def test_every_command_with_work_has_a_budget() -> None:
    """The table says which commands run in a budgeted child; the rest do no work on the
    user's input (networks), serve (serve, worker), send a job to a server that runs it
    under its own budgets (submit), or run each step in a budgeted child and stop on
    Ctrl-C where they can go on (campaign)."""
    budgeted = {entry.name for entry in cli.commands.COMMANDS if entry.limit is not None}
    assert budgeted == {*NEVER, "example"}


def test_example_stops_within_its_extensions_budgets(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    took, said = stopped(
        ["example", "four-way", "--no-evaluate", "--budget", "0.01", "-o", str(tmp_path)],
        capsys,
    )
    assert "budget" in said and took < 3 * 0.01 + KILL_GRACE + SLACK


@pytest.fixture(scope="module")
def flicker(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 600 s test-case at a light whose program changes every 0.1 s."""
    folder = tmp_path_factory.mktemp("flicker")
    program = folder / "flicker.json"
    program.write_text(json.dumps({"tls": "C", "program": "flicker", "phases": FLICKER}))
    testcase = folder / "t0.json"
    assert cli.main(["new", "4way-signal", "--ego", "S2C_0:C2N_0", "--signals", str(program),
                     "--duration", "600", "-o", str(testcase)]) == 0  # fmt: skip
    return testcase


def test_extend_whose_search_does_not_look_at_the_clock_stops_at_its_budget(
    flicker: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Step 2's grounding of this program takes seconds and never looks at the clock:
    before issue 50, ``--budget 2`` ran for 7.5 s in the command's own process."""
    out = tmp_path / "t1.json"
    took, said = stopped(
        ["extend", str(flicker), "--add", "W2C_0:C2E_0", "--budget", "2", "-o", str(out)], capsys
    )
    # stopped by the search's own look at the clock, or by the kill when the grounding
    # did not come back in time: the budget either way
    assert "budget of 2 s" in said and ("Step 2" in said or "extend did not finish" in said)
    assert took < 2 + KILL_GRACE + 1.5 and not out.exists()  # the kill comes on time


def test_an_animation_stopped_at_its_budget_leaves_no_partial_file(
    flicker: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """1,201 frames, about 13 s of drawing."""
    gif = tmp_path / "a.gif"
    took, said = stopped(["plot", str(flicker), "-o", str(gif), "--animate", "--budget", "1"],
                         capsys)  # fmt: skip
    assert "scengen plot did not finish within its budget of 1 s" in said
    assert took < 1 + KILL_GRACE + SLACK
    assert list(tmp_path.iterdir()) == []  # neither the GIF nor its partial file


def test_the_child_serves_the_next_command_after_one_was_stopped(
    flicker: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert cli.main(["intersection", "4way-signal", "--json", "--budget", "60"]) == 0
    assert json.loads(capsys.readouterr().out)["junction"] == "C"
    COMMANDS.close()  # as a kill leaves it
    assert cli.main(["drive", str(flicker), "--budget", "60"]) == 0
    assert "route S2C_0:C2N_0 (straight)" in capsys.readouterr().out


def test_a_command_past_its_memory_cap_says_so_and_leaves_no_partial_file(
    flicker: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:  # fmt: skip
    """The command's child is capped as a worker is: 520 MB hold about half of the
    animation's frames."""
    gif = tmp_path / "a.gif"
    monkeypatch.setenv("SCENGEN_WORKER_MEMORY_MB", "520")
    COMMANDS.close()  # the cap is the child's from its start: a fresh one
    try:
        assert cli.main(["plot", str(flicker), "-o", str(gif), "--animate"]) == 3
    finally:
        COMMANDS.close()
    said = capsys.readouterr().err.strip().splitlines()[-1]
    assert said == ("scengen: failed: scengen plot needed more memory than a worker may use "
                    "(520 MB, SCENGEN_WORKER_MEMORY_MB)")  # fmt: skip
    assert list(tmp_path.iterdir()) == []
