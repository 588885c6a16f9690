"""Pedestrians in the replay (real SUMO, no mocks): SUMO's drivers see a replayed
pedestrian on a crosswalk and wait for her, with and without the RSS guard, and user
controllers observe her."""

from __future__ import annotations

import json
import math
from functools import cache
from pathlib import Path

import pytest

from service.core.network import Intersection
from service.core.sim.pedestrians import walkers
from service.core.sim.replay import evaluate
from service.core.testcase import TestCase
from tests.walkers import crosswalk_scene, in_path_times, on_crossing_times

# crosswalk-stop: an all-way stop whose east arm leaves 25 degrees off, a crosswalk over
# every arm that drivers yield on. (ego route, walk, metres before the curb, seconds she
# waits there): she is on the crosswalk in the ego's path when it comes
SCENES = {
    # over the skewed east arm, along the crossing's lane, as the ego arrives at its line
    "skewed arm, along its lane": ("E2C_1:C2W_1", "C_c1+", 2.0, 0.0),
    # the same crosswalk the other way (against its lane), stepping off as the ego stops
    "skewed arm, against its lane": ("E2C_1:C2W_1", "C_c1-", 2.0, 3.0),
    # the crosswalk where the ego leaves: she comes from its left as it drives through
    "at the exit, against its lane": ("S2C_1:C2N_1", "C_c0-", 0.0, 0.0),
}
DURATION = 25.0


@cache
def _scene(name: str) -> tuple[TestCase, TestCase, Intersection]:
    """The ego alone, the ego with the pedestrian ``ped1``, and the junction."""
    route, walk, lead, wait = SCENES[name]
    return crosswalk_scene(route, walk, lead, wait, DURATION, name)


@pytest.mark.parametrize("controller", ["sumo", "sumo+rss"])
@pytest.mark.parametrize("scene", list(SCENES))
def test_the_ego_waits_for_a_pedestrian_on_the_crosswalk(scene: str, controller: str) -> None:
    """The heart of it: SUMO's driver (alone or under the RSS guard) does not enter the
    crosswalk while she is in its path; it waits before it and goes once she has passed,
    and reaches its goal. Without her it would have been on the crosswalk then. Under the
    guard, ad-rss's pedestrian scenes are what slowed it."""
    alone, testcase, junction = _scene(scene)
    in_path = in_path_times(testcase, junction)
    assert len(in_path) > 20  # she is in its path for seconds
    without = on_crossing_times(
        testcase, junction, evaluate(alone, controller, junction).trajectory
    )
    assert any(in_path[0] <= t <= in_path[-1] for t in without)  # the scene is a real one
    evaluation = evaluate(testcase, controller, junction)
    assert evaluation.verdict.goal_reached and evaluation.error is None
    # and the checker, judging her right-of-way (CVC 21950 (a)), passes it
    assert evaluation.verdict.passed, evaluation.verdict.reasons
    entered = on_crossing_times(testcase, junction, evaluation.trajectory)
    assert entered and not set(entered) & set(in_path)
    assert entered[0] > in_path[-1] and entered[0] > without[0] + 1.0
    guard = evaluation.verdict.guard
    if controller == "sumo":  # SUMO's driver stood (at its line or before the crosswalk)
        assert [s for s in evaluation.trajectory if s.speed <= 0.05 and s.t in set(in_path)]
    if controller.endswith("+rss"):  # the guard slowed it earlier: it may creep instead
        assert guard is not None and guard["fallback"] is None
        assert set(guard["by_car"]) == {"ped1"} and guard["first"]["car"] == "ped1"
        assert {span["scene"] for span in guard["spans"]} == {"Unstructured"}
    else:
        assert guard is None


def test_the_pedestrian_in_the_plan_walks_in_three_stages() -> None:
    """Up to the curb, the crossing alone (arriving at its far curb: its lane's length
    along it, 0 against it), from the far curb on; her poses run until she leaves the map
    (straight on past the far corner, off her walk's sidewalk)."""
    for scene, arrival in (("skewed arm, along its lane", 12.8),
                           ("skewed arm, against its lane", 0.0)):  # fmt: skip
        _, testcase, junction = _scene(scene)
        (walker,) = walkers(testcase, junction)
        walk = junction.walk(testcase.pedestrians[0].walk)
        assert [edges for edges, _ in walker.stages] == [
            (walk.before.rsplit("_", 1)[0], walk.start),
            (walk.crossing,),
            (walk.end, walk.after.rsplit("_", 1)[0]),
        ]
        assert walker.stages[1][1] == pytest.approx(arrival, abs=0.05)
        assert walker.edge_at(0) == walk.start  # 2 m before the curb: the corner
        assert 100 < len(walker.poses) < len(testcase.pedestrians[0].trajectory)


CONTROLLER = """
import json


class Watcher:
    \"\"\"Creeps on at 1.5 m/s whatever happens and notes the pedestrians it sees.\"\"\"

    def step(self, obs):
        people = [[p.id, p.x, p.y, p.heading, p.speed, p.length, p.width]
                  for p in obs.pedestrians]
        with open("seen.txt", "a") as out:
            out.write(json.dumps([obs.t, people]) + "\\n")
        return min(obs.a_max, 1.5 - obs.ego.speed)
"""


def test_a_user_controller_sees_the_pedestrians(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``Observation.pedestrians``: every pedestrian on the map at her recorded pose (the
    centre of her rectangle), and nobody once she has left the map (her walk's sidewalk
    goes off at an angle at the far corner; she walks straight on)."""
    _, testcase, junction = _scene("skewed arm, along its lane")
    (tmp_path / "watcher.py").write_text(CONTROLLER)
    monkeypatch.chdir(tmp_path)
    evaluation = evaluate(testcase, "watcher:Watcher", junction)
    assert evaluation.error is None
    seen = [json.loads(line) for line in (tmp_path / "seen.txt").read_text().splitlines()]
    assert len(seen) == len(evaluation.trajectory) - 1  # every step but the ego's last
    person = testcase.pedestrians[0]
    (walker,) = walkers(testcase, junction)
    for t, people in seen:
        k = round(t / testcase.timestep)
        if k >= len(walker.poses) - 1:  # at her last pose she leaves (as a car at its last)
            assert people == []
            continue
        ((name, x, y, heading, speed, length, width),) = people
        sample = person.trajectory[k]
        assert name == "ped1" and (length, width) == (person.length, person.width)
        assert math.dist((x, y), (sample.x, sample.y)) < 1e-6
        assert (heading, speed) == (pytest.approx(sample.heading), sample.speed)
