"""Replay a test-case in libsumo with an ego controller, and judge the ego with the checker.

Non-egos (and a replayed certificate) follow their trajectories exactly: speed mode 0 and,
every step, ``setSpeed`` with the distance they cover in that step (SUMO moves a car by its
speed times the step). The ego is driven by its controller (service.core.controllers):
SUMO's own driver model and variants of it, or a user controller whose acceleration is
integrated here. The ego's poses are recorded every step and judged by the checker.

Every evaluation runs in its own process (libsumo is a per-process singleton) under a time
budget. A user controller that raises or hangs gives a failed evaluation with the reason.
"""

from __future__ import annotations

import math
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from service.core.budget import run_with_budget
from service.core.check import check_testcase, testcase_label
from service.core.controllers import (
    CertificateDriver,
    Driver,
    Observation,
    SumoDriver,
    UserDriver,
    Vehicle,
    load_user_controller,
    resolve_driver,
)
from service.core.errors import BudgetExceeded, InvalidInput, ScengenError, SimulationFailed
from service.core.network import Intersection
from service.core.poses import (
    PoseSample,
    centre_to_front,
    front_to_centre,
    plan_drive,
    start_distance_of,
)
from service.core.testcase import TestCase, load_testcase_intersection
from service.core.verdict import Verdict

REPLAY_BUDGET = 60.0  # seconds for one evaluation


@dataclass(frozen=True)
class Departure:
    """Where and how a car enters SUMO: route edges, lane index, position, speed."""

    id: str
    edges: tuple[str, ...]
    lane: int
    position: float
    speed: float
    length: float
    width: float
    start_on: tuple[str, float] | None = None  # a start inside an upstream junction: moved
    # there (internal lane, position) right after it departs just before that junction


@dataclass(frozen=True)
class ReplayPlan:
    """Everything the SUMO process needs; plain data, picklable."""

    route_file: str
    network_file: str
    timestep: float
    steps: int
    ego: Departure
    ego_start: float  # the ego's front bumper before its stop line at t = 0
    arrival_distance: float
    nonegos: tuple[tuple[Departure, tuple[float, ...]], ...]  # and distance per step
    driver: Driver
    certificate: tuple[float, ...] = ()  # distance per step when replaying a certificate
    a_min: float = -4.0
    a_max: float = 3.0
    v_max: float = 15.0


@dataclass(frozen=True)
class Evaluation:
    """The verdict of one controller on one test-case, with the ego's trajectory."""

    verdict: Verdict
    trajectory: list[PoseSample]
    error: str | None = None  # what stopped the controller, when something did


def departures(testcase: TestCase, intersection: Intersection) -> tuple[Departure, list[Departure]]:
    """The ego's and every non-ego's departure (same order as ``testcase.nonegos``)."""
    ego = testcase.ego
    plan = plan_drive(
        intersection, intersection.route(ego.route.id), ego.start.distance,
        max(ego.start.speed, 1.0), testcase.duration, testcase.timestep, ego.length, ego.width,
    )  # fmt: skip
    ego_departure = Departure(
        "ego", plan.edges, plan.depart_lane, plan.depart_pos, ego.start.speed,
        ego.length, ego.width, plan.start_on,
    )  # fmt: skip
    others = []
    for nonego in testcase.nonegos:
        first = nonego.trajectory[0]
        route = intersection.route(nonego.route.id)
        front = centre_to_front(first.x, first.y, first.heading, nonego.length)
        start = start_distance_of(intersection, route, front)
        plan = plan_drive(
            intersection, route, start, max(first.speed, 1.0),
            testcase.duration, testcase.timestep, nonego.length, nonego.width,
        )  # fmt: skip
        others.append(
            Departure(
                nonego.id,
                plan.edges,
                plan.depart_lane,
                plan.depart_pos,
                first.speed,
                nonego.length,
                nonego.width,
                plan.start_on,
            )
        )
    return ego_departure, others


def vtype_lines(
    ego: Departure, nonegos: Sequence[Departure], driver: Driver, testcase: TestCase
) -> list[str]:
    """One SUMO vehicle type per car: its size; for the ego, the driver's settings and
    the test-case's bounds."""
    p = testcase.params
    sumo = driver if isinstance(driver, SumoDriver) else SumoDriver("replayed", "")
    lines = []
    for car in (ego, *nonegos):
        if car.id == "ego":
            extra = (
                f' sigma="0" jmStopSignWait="{sumo.stop_sign_wait:g}" minGap="1"'
                f' accel="{p.a_max:g}" decel="{-p.a_min:g}" emergencyDecel="{-p.a_min:g}"'
                f' maxSpeed="{p.v_max:g}" speedFactor="1" speedDev="0"'
            )
        else:
            extra = ' sigma="0" minGap="0" speedFactor="1" speedDev="0" maxSpeed="100"'
        lines.append(
            f'    <vType id="type_{car.id}" length="{car.length:g}" width="{car.width:g}"{extra}/>'
        )
    return lines


def vehicle_lines(cars: Sequence[Departure]) -> list[str]:
    """Each car departing at t = 0 with its own route, lane, position and speed."""
    lines = []
    for car in cars:
        # a car moved into an upstream junction right away: its speed is not SUMO's to check
        checks = ' insertionChecks="none"' if car.start_on else ""
        lines.append(
            f'    <vehicle id="{car.id}" type="type_{car.id}" depart="0" '
            f'departLane="{car.lane}" departPos="{car.position:.3f}" '
            f'departSpeed="{car.speed:.3f}"{checks}>'
        )
        lines.append(f'        <route edges="{" ".join(car.edges)}"/>')
        lines.append("    </vehicle>")
    return lines


def route_file_text(
    ego: Departure, nonegos: Sequence[Departure], driver: Driver, testcase: TestCase
) -> str:
    """A SUMO route file with every car's type and every car departing at t = 0."""
    body = [*vtype_lines(ego, nonegos, driver, testcase), *vehicle_lines([ego, *nonegos])]
    return "\n".join(['<?xml version="1.0" encoding="UTF-8"?>', "<routes>", *body, "</routes>"])


def replay_plan(
    testcase: TestCase, driver: Driver, intersection: Intersection, route_file: Path
) -> ReplayPlan:
    ego, others = departures(testcase, intersection)
    certificate: tuple[float, ...] = ()
    if isinstance(driver, CertificateDriver):
        if testcase.certificates is None:
            raise InvalidInput(
                f"controller {driver.name} replays a certificate, but this test-case has none "
                "(only generated test-cases carry certificates)"
            )
        samples = getattr(testcase.certificates, driver.certificate)
        certificate = tuple(s.distance for s in samples)
    route_file.write_text(route_file_text(ego, others, driver, testcase))
    return ReplayPlan(
        route_file=str(route_file),
        network_file=str(intersection.network_file),
        timestep=testcase.timestep,
        steps=round(testcase.duration / testcase.timestep),
        ego=ego,
        ego_start=testcase.ego.start.distance,
        arrival_distance=testcase.params.arrival_distance,
        nonegos=tuple(
            (d, tuple(s.distance for s in n.trajectory))
            for d, n in zip(others, testcase.nonegos, strict=True)
        ),
        driver=driver,
        certificate=certificate,
        a_min=testcase.params.a_min,
        a_max=testcase.params.a_max,
        v_max=testcase.params.v_max,
    )


def evaluate(
    testcase: TestCase,
    controller: str,
    intersection: Intersection | None = None,
    budget: float = REPLAY_BUDGET,
) -> Evaluation:
    """Replay ``testcase`` with ``controller`` driving the ego, in a child process under
    ``budget``, and judge the ego. A controller that fails or runs out of time fails."""
    driver = resolve_driver(controller)
    junction = intersection or load_testcase_intersection(testcase)
    with tempfile.TemporaryDirectory(prefix="scengen-replay-") as folder:
        plan = replay_plan(testcase, driver, junction, Path(folder) / "replay.rou.xml")
        try:
            samples, error = run_with_budget(run_replay, (plan,), budget, "the replay")
        except BudgetExceeded as exc:
            samples, error = [], str(exc)
    if len(samples) < 2:
        verdict = _failed(testcase, controller, error or "the ego never moved in SUMO")
        return Evaluation(verdict, samples, error)
    verdict = check_testcase(testcase, samples, controller, junction)
    if error is not None:
        verdict = replace(verdict, errors=(*verdict.errors, error))
    return Evaluation(verdict, samples, error)


def _failed(testcase: TestCase, controller: str, error: str) -> Verdict:
    return Verdict(
        testcase=testcase_label(testcase),
        controller=controller,
        goal_reached=False,
        goal_time=None,
        collisions=(),
        violations=(),
        ego_events=(),
        duration=testcase.duration,
        errors=(error,),
    )


def run_replay(plan: ReplayPlan) -> tuple[list[PoseSample], str | None]:
    """Child side: run the replay in libsumo; the ego's samples and what stopped it."""
    import libsumo

    libsumo.start([
        "sumo", "-n", plan.network_file, "-r", plan.route_file,
        "--step-length", repr(plan.timestep), "--no-step-log", "true", "--no-warnings", "true",
        "--time-to-teleport", "-1", "--collision.action", "none",
        "--collision.check-junctions", "true", "--default.action-step-length",
        repr(plan.timestep), "--ignore-route-errors", "false",
        "--step-method.ballistic", "false",
    ])  # fmt: skip
    try:
        return _drive(libsumo, plan)
    except libsumo.TraCIException as exc:
        raise SimulationFailed(f"SUMO refused the replay: {exc}") from exc
    finally:
        libsumo.close()


def _drive(traci: Any, plan: ReplayPlan) -> tuple[list[PoseSample], str | None]:
    user = None
    error: str | None = None
    if isinstance(plan.driver, UserDriver):
        try:
            user = load_user_controller(plan.driver.reference)
        except ScengenError as exc:
            return [], str(exc)
    samples: list[PoseSample] = []
    replayed = [(d.id, distances) for d, distances in plan.nonegos]
    if isinstance(plan.driver, CertificateDriver):
        replayed.append(("ego", plan.certificate))
    rolling = False
    moved = {d.id: d.start_on for d in (plan.ego, *(d for d, _ in plan.nonegos)) if d.start_on}
    odometer = 0.0  # the ego's SUMO odometer at its start
    for step in range(plan.steps + 1):
        traci.simulationStep()
        present = set(traci.vehicle.getIDList())
        if step == 0:
            for car, (lane, position) in moved.items():  # onto its start in the junction
                if car in present:
                    traci.vehicle.moveTo(car, lane, position)
            if "ego" in present:
                odometer = traci.vehicle.getDistance("ego")
            for car in present:
                traci.vehicle.setLaneChangeMode(car, 0)
                if car != "ego" or not isinstance(plan.driver, SumoDriver):
                    traci.vehicle.setSpeedMode(car, 0)
            if isinstance(plan.driver, SumoDriver):
                traci.vehicle.setSpeedMode("ego", plan.driver.speed_mode)
            if "ego" not in present:
                raise SimulationFailed("SUMO could not insert the ego at its start")
        if "ego" not in present:
            break  # the ego reached the end of its route
        sample = _sample(traci, "ego", step * plan.timestep, plan.ego.length)
        samples.append(replace(sample, distance=sample.distance - odometer))
        if step == plan.steps:
            break
        for car, distances in replayed:
            if car in present and step + 1 < len(distances):
                gap = distances[step + 1] - distances[step]
                traci.vehicle.setSpeed(car, max(gap, 0.0) / plan.timestep)
        if isinstance(plan.driver, SumoDriver) and plan.driver.rolling_speed is not None:
            rolling = _roll(traci, plan, plan.driver.rolling_speed, samples[-1], rolling)
        if user is not None:
            try:
                command = float(user.step(_observe(traci, plan, samples[-1], present)))
                if not math.isfinite(command):
                    raise ValueError(f"acceleration {command!r} is not a finite number")
            except Exception as exc:  # the user's code: any failure fails the evaluation
                error = f"controller {plan.driver.name} raised {type(exc).__name__}: {exc}"
                break
            accel = min(max(command, plan.a_min), plan.a_max)
            speed = min(max(samples[-1].speed + accel * plan.timestep, 0.0), plan.v_max)
            traci.vehicle.setSpeed("ego", speed)
    return samples, error


def _roll(traci: Any, plan: ReplayPlan, speed: float, now: PoseSample, rolling: bool) -> bool:
    """Keep the ego at ``speed`` or faster from arriving at the fork to passing the stop
    line; then hand it back to SUMO's driver."""
    to_line = plan.ego_start - now.distance
    inside_zone = -1.0 < to_line <= plan.arrival_distance
    if inside_zone and traci.vehicle.getSpeed("ego") <= speed:
        if not rolling:
            traci.vehicle.setSpeedMode("ego", 0)
        traci.vehicle.setSpeed("ego", speed)
        return True
    if rolling and not inside_zone:
        traci.vehicle.setSpeed("ego", -1)
        traci.vehicle.setSpeedMode("ego", plan.driver.speed_mode)  # type: ignore[union-attr]
        return False
    return rolling


def _sample(traci: Any, car: str, t: float, length: float) -> PoseSample:
    heading = traci.vehicle.getAngle(car) % 360.0
    fx, fy = traci.vehicle.getPosition(car)
    x, y = front_to_centre(fx, fy, heading, length)
    return PoseSample(
        round(t, 9), x, y, heading, traci.vehicle.getSpeed(car), traci.vehicle.getDistance(car)
    )


def _observe(traci: Any, plan: ReplayPlan, ego: PoseSample, present: set[str]) -> Observation:
    sizes = {d.id: (d.length, d.width) for d, _ in plan.nonegos}
    others = []
    for car in sorted(present - {"ego"}):
        s = _sample(traci, car, ego.t, sizes[car][0])
        others.append(Vehicle(car, s.x, s.y, s.heading, s.speed, *sizes[car]))
    return Observation(
        t=ego.t,
        timestep=plan.timestep,
        ego=Vehicle("ego", ego.x, ego.y, ego.heading, ego.speed, plan.ego.length, plan.ego.width),
        distance=ego.distance,
        to_stop_line=plan.ego_start - ego.distance,
        lane=traci.vehicle.getLaneID("ego"),
        others=tuple(others),
        a_min=plan.a_min,
        a_max=plan.a_max,
        v_max=plan.v_max,
    )
