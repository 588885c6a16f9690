"""The server's pool of workers: its size is a true cap on the processes that compute."""

from __future__ import annotations

import asyncio
from pathlib import Path
from typing import Any

from service.core.network import resolve_network
from service.core.testcase import dump_testcase, new_testcase
from service.jobs import tasks
from service.jobs.executor import LocalExecutor
from tests.core.test_budget import spawning


def test_one_worker_is_one_process_with_a_controller_inside(tmp_path: Path) -> None:
    """With one worker, an evaluation, a picture with a controller and an extension (each of
    which replays or drives in SUMO inside) run one after another, each in one process that
    starts no other: at most one process computes at any time."""
    network = resolve_network("4way-stop")
    document = dump_testcase(new_testcase("4way-stop", "E2C_1:C2S_1", duration=20.0))
    calls: list[tuple[Any, tuple[Any, ...]]] = [
        (tasks.evaluate_controller, (document, network, tmp_path, "sumo", 60.0)),
        (tasks.plot_testcase, (document, network, tmp_path, "svg", "sumo", 60.0)),
        (tasks.extend, (document, network, tmp_path, ["S2C_1:C2N_1"], 0, 120.0, None)),
    ]
    executor = LocalExecutor(1)

    async def run_all() -> list[tuple[Any, int, list[str]]]:
        return await asyncio.gather(
            *(executor.run(spawning, call, 300.0, "a call") for call in calls)
        )

    answers = asyncio.run(run_all())
    verdict, picture, extension = (answer for answer, _, _ in answers)
    assert verdict["verdict"]["controller"] == "sumo" and len(verdict["drive"]) > 2
    assert picture.startswith(b"<?xml") and b"<svg" in picture
    assert '"nonegos"' in extension["document"]
    assert [started for _, _, started in answers] == [[], [], []]
    assert len({pid for _, pid, _ in answers}) == 3  # a fresh child per call
    assert executor.stats.finished == {"ok": 3}
