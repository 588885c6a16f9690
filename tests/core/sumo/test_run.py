"""run.py, the replay loop every bundle ships: the ego leaves the simulation at the end of
its route, the first step past its goal, whoever drives it (real libsumo, no mocks)."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import libsumo
import pytest
from shapely.geometry import Point

from service.core.sim.controllers import resolve_driver
from service.core.sim.replay import controller_spec, departures, write_run_files
from service.core.sumo import run as sumo_run
from service.core.testcase import TestCase, load_testcase_intersection, new_testcase
from tests.walkers import rectangle, straight_walk, with_pedestrians


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
    assert rows[-1]["t"] < 25.0  # of 45 s: it does not drive on to the next junction
    if on_step is not None:  # asked every step but the last: then the ego had left
        assert asked == [row["t"] for row in rows[:-1]]


def _walker_plan(folder: Path, walk: str, lead: float, wait: float = 0.0) -> tuple[Path, TestCase]:
    """The run files of the ego on crosswalk-stop (S2C_1:C2N_1) with ``ped1`` on ``walk``."""
    alone = new_testcase("crosswalk-stop", "S2C_1:C2N_1", duration=25.0)
    junction = load_testcase_intersection(alone)
    samples = straight_walk(junction, walk, 25.0, lead=lead, wait=wait)
    testcase = with_pedestrians(alone, {"ped1": (walk, samples)})
    ego, others = departures(testcase, junction)
    write_run_files(testcase, ego, others, folder, str(junction.network_file), junction)
    return folder / sumo_run.PLAN_FILE, testcase


@pytest.mark.parametrize("walk", ["C_c1+", "C_c1-"])
def test_a_pedestrian_is_where_her_trajectory_says_until_she_leaves(
    tmp_path: Path, walk: str
) -> None:
    """SUMO has her at her recorded front from the first step on (at t = 0 at her
    departure nearby): exactly on the crosswalk, and on its lane, whichever way she walks
    it; within 2 m on the corners' walking areas (SUMO keeps her near its own path across
    one, which her straight walk leaves; near the curb SUMO has her at the
    curb already); it never moves her on to another walking stage by itself (the runner
    does, before SUMO could put her where that stage begins, metres away). She leaves at
    her last pose on the map: straight on past the far corner (the east arm is skewed) she
    walks off her walk's sidewalk, and SUMO no longer knows her."""
    plan_file, testcase = _walker_plan(tmp_path, walk, lead=2.0)
    (person,) = json.loads(plan_file.read_text())["pedestrians"]
    poses = person["poses"]
    assert 100 < len(poses) < len(testcase.pedestrians[0].trajectory)  # she leaves the map
    junction = load_testcase_intersection(testcase)
    crossing = walk[:-1]
    strip = junction.crossings[f":{crossing}"].polygon
    libsumo.start(["sumo", *sumo_run.sumo_arguments(
        json.loads(plan_file.read_text()), tmp_path, tmp_path / "testcase.types.xml")])  # fmt: skip
    try:
        sumo_run.add_people(libsumo, [person])
        for k in range(len(testcase.pedestrians[0].trajectory)):
            libsumo.simulationStep()
            if k >= len(poses):
                assert "ped1" not in libsumo.person.getIDList()  # gone since her last pose
                continue
            x, y, _, _, stage, _ = poses[k]
            done = len(person["stages"]) - libsumo.person.getRemainingStages("ped1")
            assert done == stage  # the runner moved her on, not SUMO
            lane = libsumo.person.getLaneID("ped1")
            miss = math.dist(libsumo.person.getPosition("ped1"), (x, y))
            if strip.contains(Point(x, y)):
                assert lane == f":{crossing}_0" and (k == 0 or miss < 1e-6), k
            elif k > 0:
                assert miss < 2.0, k
            sumo_run.walk_people(libsumo, [person], k)
    finally:
        libsumo.close()


def test_collisions_with_a_pedestrian_remove_nobody(tmp_path: Path) -> None:
    """An ego that drives on at 8 m/s runs into her on the crosswalk: SUMO reports it but
    acts on nothing (the checker judges it): both stay, the ego to its goal, she on her
    trajectory."""
    plan_file, testcase = _walker_plan(tmp_path, "C_c2+", lead=-5.7)
    person = testcase.pedestrians[0]
    overlaps, present = [], []

    def cruise(traci: Any, row: sumo_run.Row, now: set[str]) -> str | None:
        x, y = sumo_run.front_to_centre(row["x"], row["y"], row["angle"], testcase.ego.length)
        her = person.trajectory[round(row["t"] / testcase.timestep)]
        ego = rectangle(x, y, row["angle"], testcase.ego.length, testcase.ego.width)
        overlaps.append(ego.intersects(rectangle(her.x, her.y, her.heading, person.length,
                                                 person.width)))  # fmt: skip
        present.append("ped1" in traci.person.getIDList())
        traci.vehicle.setSpeed(sumo_run.EGO, 8.0)
        return None

    rows, _ = sumo_run.run(libsumo, plan_file, {"kind": "external"}, cruise)
    assert any(overlaps)  # it drove into her
    goal = json.loads(plan_file.read_text())["ego"]["goal"]
    assert rows[-1]["odometer"] >= goal  # the ego went on to its goal
    assert all(present)  # and she stayed while it drove
