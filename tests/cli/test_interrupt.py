"""Ctrl-C is a normal way to stop a command: one line on stderr, exit code 130, no
traceback, no worker process left behind, and what was written before is kept."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path


def _as_a_shell_starts_it() -> None:
    """SIGINT at its default, as a shell starts a foreground command (a test runner's
    worker may ignore it, and a child inherits that)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def test_ctrl_c_stops_a_command_with_one_line_and_keeps_what_it_wrote(tmp_path: Path) -> None:
    folder = tmp_path / "ex"
    command = [sys.executable, "-m", "service", "example", "crosswalk", "-o", str(folder)]
    process = subprocess.Popen(
        command,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,  # its own process group, as a terminal's foreground job
        preexec_fn=_as_a_shell_starts_it,
    )
    assert process.stderr is not None
    told = []
    for line in process.stderr:  # the first level written: the work is under way
        told.append(line)
        if "level 1 written" in line:
            break
    os.killpg(process.pid, signal.SIGINT)  # what Ctrl-C sends: the whole group
    rest = process.stderr.read()
    assert process.wait(timeout=60) == 130, "".join(told) + rest
    assert "Traceback" not in rest, rest
    assert rest.strip().splitlines()[-1].startswith("scengen: stopped (Ctrl-C)"), rest
    level1 = json.loads((folder / "crosswalk-1.json").read_text())  # kept, whole
    assert [p["id"] for p in level1["pedestrians"]] == ["ped1"]
    survivors = subprocess.run(
        ["pgrep", "-g", str(process.pid)], capture_output=True, text=True, check=False
    )
    assert survivors.stdout == "", "a worker of the stopped command still runs"
