"""The same request gives the same bytes on an idle and on a saturated machine.

The generator limits its search by counts (answer sets, clingo conflicts, z3's rlimit),
never by a clock. This test runs the four-way example (three levels, seed 1: the level
that needs several answer sets) as a user would, then again while it keeps both cores busy
with two spinning processes and under another hash seed, and compares every file.
"""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

SPIN = "while True: pass"


@contextmanager
def busy_cores(count: int) -> Iterator[None]:
    spinners = [subprocess.Popen([sys.executable, "-c", SPIN]) for _ in range(count)]
    try:
        yield
    finally:
        for spinner in spinners:
            spinner.kill()
            spinner.wait()


def run_example(folder: Path, hash_seed: str) -> dict[str, bytes]:
    command = [sys.executable, "-m", "service", "example", "four-way", "--seed", "1",
               "-o", str(folder), "--budget", "600"]  # fmt: skip
    environment = {**os.environ, "PYTHONHASHSEED": hash_seed}
    done = subprocess.run(command, capture_output=True, text=True, env=environment, check=False)
    assert done.returncode == 0, done.stderr
    return {path.name: path.read_bytes() for path in sorted(folder.glob("*.json"))}


def test_same_bytes_on_an_idle_and_a_saturated_machine(tmp_path: Path) -> None:
    idle = run_example(tmp_path / "idle", hash_seed="0")
    with busy_cores(2):
        loaded = run_example(tmp_path / "loaded", hash_seed="12345")
    assert sorted(idle) == [f"four-way-{level}.json" for level in range(4)]
    assert loaded == idle
