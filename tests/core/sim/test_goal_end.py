"""The replay ends with the goal: the ego leaves the simulation at the end of its route,
just past its goal, and does not stand on where a non-ego that drives on runs into it.

A chain on a network with a second junction after the first (tests.helpers: the all-way
stop C, and 80 m on the signalized D, always red); car1 of level 1 is generated and drives
on through D. Real SUMO, real checker, no mocks.
"""

from __future__ import annotations

import dataclasses
import tempfile
from pathlib import Path

import libsumo

from service.core.checker.check import check_testcase
from service.core.motion.poses import PoseSample, plan_drive
from service.core.network import Intersection, parsed_network
from service.core.sim.controllers import resolve_driver
from service.core.sim.replay import (
    controller_spec,
    departures,
    evaluate,
    row_sample,
    vehicle_lines,
    write_run_files,
)
from service.core.sumo import run as sumo_run
from service.core.testcase import TestCase, load_testcase_intersection


def test_the_ego_leaves_the_simulation_just_past_its_goal(next_junction: TestCase) -> None:
    evaluation = evaluate(next_junction, "sumo")
    verdict, trajectory = evaluation.verdict, evaluation.trajectory
    assert verdict.passed, verdict.reasons
    assert verdict.after_goal_collisions == ()  # nobody runs into an ego that left
    goal = verdict.goal_time
    assert goal is not None and goal < 10.0
    # the first step past its goal (its rear a metre out of C) is its last: it does not
    # drive on to D and stand at its red light until the end, 45 s
    passed = departures(next_junction, load_testcase_intersection(next_junction))[0].goal
    assert passed is not None
    assert trajectory[-2].distance < passed <= trajectory[-1].distance
    assert goal < trajectory[-1].t < goal + 0.5
    assert min(s.speed for s in trajectory if s.t >= goal) > 1.0


def test_the_route_ends_before_the_next_junction(next_junction: TestCase) -> None:
    """SUMO's route of the ego ends on its exit edge, a few metres past its goal (its
    arrivalPos), so SUMO's driver does not see the next junction at all."""
    junction = load_testcase_intersection(next_junction)
    ego, _ = departures(next_junction, junction)
    assert ego.edges == ("S2C", "C2D")
    assert ego.arrival is not None
    p = next_junction.params
    assert ego.arrival == 5.0 + 1.0 + 0.5 + p.v_max * next_junction.timestep  # length,
    # Step 1's clearance, GOAL_PAST, a step at v_max past the exit lane's start
    assert ego.arrival < parsed_network(junction.network_file).getEdge("C2D").getLength()
    assert f'arrivalPos="{ego.arrival:.3f}"' in vehicle_lines([ego])[0]


def _stay_on(testcase: TestCase, junction: Intersection) -> list[PoseSample]:
    """The ego's drive as the replay was before the judgement ended with the goal: its
    route as far as any controller can drive (through D), no end at its goal."""
    ego, others = departures(testcase, junction)
    e = testcase.ego
    plan = plan_drive(
        junction, junction.route(e.route.id), e.start.distance, max(e.start.speed, 1.0),
        testcase.duration, testcase.timestep, e.length, e.width,
        testcase.params.v_max * testcase.duration,
    )  # fmt: skip
    ego = dataclasses.replace(ego, edges=plan.edges, arrival=None, goal=None)
    with tempfile.TemporaryDirectory() as folder:
        write_run_files(testcase, ego, others, Path(folder), str(junction.network_file), junction)
        plan_file = Path(folder) / sumo_run.PLAN_FILE
        rows, _ = sumo_run.run(libsumo, plan_file, controller_spec(resolve_driver("sumo")))
    return [row_sample(row, e.length) for row in rows]


def test_a_collision_after_the_goal_is_information_not_failure(next_junction: TestCase) -> None:
    """Driven on through C to D, SUMO's driver stands at D's red light, and car1, following
    its trajectory through D, runs into it from behind 17 s after its goal: information."""
    junction = load_testcase_intersection(next_junction)
    stayed = _stay_on(next_junction, junction)
    assert stayed[-1].t == next_junction.duration and stayed[-1].speed == 0.0
    verdict = check_testcase(next_junction, stayed, "sumo", junction)
    assert verdict.passed, verdict.reasons
    [late] = verdict.after_goal_collisions
    assert verdict.goal_time is not None and late.other == "car1"
    assert late.t > verdict.goal_time + 15.0
    assert verdict.reasons == [] and verdict.information == [
        f"after its goal (not judged): {late.describe()}"
    ]
    # the judgement until the goal is the replay's: the same goal, the same criticality
    replayed = evaluate(next_junction, "sumo", junction).verdict
    assert replayed.goal_time == verdict.goal_time
    assert replayed.criticality == verdict.criticality
