"""run.py, the replay loop every bundle ships: the ego leaves the simulation at the end of
its route, the first step past its goal, whoever drives it (real libsumo, no mocks)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import libsumo
import pytest

from service.core.sim.controllers import resolve_driver
from service.core.sim.replay import controller_spec, departures, write_run_files
from service.core.sumo import run as sumo_run
from service.core.testcase import TestCase, load_testcase_intersection


@pytest.fixture(scope="module")
def plan_file(next_junction: TestCase, tmp_path_factory: pytest.TempPathFactory) -> Path:
    junction = load_testcase_intersection(next_junction)
    ego, others = departures(next_junction, junction)
    folder = tmp_path_factory.mktemp("plan")
    write_run_files(next_junction, ego, others, folder, str(junction.network_file), junction)
    return folder / sumo_run.PLAN_FILE


@pytest.mark.parametrize("controller", ["sumo", "certificate:solvability", "external"])
def test_the_ego_leaves_at_the_first_step_past_its_goal(plan_file: Path, controller: str) -> None:
    goal = json.loads(plan_file.read_text())["ego"]["goal"]
    assert goal is not None
    spec = {"kind": "external"} if controller == "external" else (
        controller_spec(resolve_driver(controller))
    )  # fmt: skip
    asked: list[float] = []

    def cruise(traci: Any, row: sumo_run.Row, present: set[str]) -> str | None:
        asked.append(row["t"])
        traci.vehicle.setSpeed(sumo_run.EGO, 8.0)  # no stop, no yield: straight through
        return None

    on_step = cruise if controller == "external" else None
    rows, stopped = sumo_run.run(libsumo, plan_file, spec, on_step)
    assert stopped is None
    assert rows[-2]["odometer"] < goal <= rows[-1]["odometer"]
    assert rows[-1]["t"] < 20.0  # of 45 s: it does not drive on to the next junction
    if on_step is not None:  # asked every step but the last: then the ego had left
        assert asked == [row["t"] for row in rows[:-1]]
