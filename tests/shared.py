"""Work made once per test run and shared by every pytest-xdist worker.

A session fixture is made once per worker: with ``-n 2`` an expensive chain would be grown
twice, once in each worker that has a test needing it. ``made_once`` makes it in whichever
worker asks first, under a file lock in the run's own temporary folder, and the other
workers read its pickle. Outside xdist it is a plain call. The folder belongs to this run
(pytest's base temporary folder), so nothing is carried from one run to the next.
"""

from __future__ import annotations

import fcntl
import pickle
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

import pytest

T = TypeVar("T")


def run_folder(tmp_path_factory: pytest.TempPathFactory, worker_id: str) -> Path | None:
    """The temporary folder every worker of this run shares; None without xdist."""
    if worker_id == "master":
        return None
    return tmp_path_factory.getbasetemp().parent  # .../pytest-N, above each popen-gwK


def made_once(
    name: str, make: Callable[[], T], tmp_path_factory: pytest.TempPathFactory, worker_id: str
) -> T:
    """``make()`` once per test run, whichever worker asks first."""
    shared = run_folder(tmp_path_factory, worker_id)
    if shared is None:
        return make()
    folder = shared / "made-once"
    folder.mkdir(exist_ok=True)
    result = folder / f"{name}.pickle"
    with (folder / f"{name}.lock").open("w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes
        if result.exists():
            loaded: T = pickle.loads(result.read_bytes())
            return loaded
        made = make()
        partial = result.with_suffix(".partial")
        partial.write_bytes(pickle.dumps(made))
        partial.rename(result)  # whole or absent, should this worker die writing it
        return made
