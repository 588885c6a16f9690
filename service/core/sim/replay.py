"""Replay a test-case in libsumo with an ego controller, and judge the ego with the checker.

The replay writes the runner's files (vehicle types, every car's route and departure, and
the plan ``testcase.run.json``) and runs the loop of service.core.sumo.run, the same files
and the same code that every exported bundle runs as ``python run.py``: non-egos (and a
replayed certificate) follow their trajectories exactly, the ego is driven by its controller
(service.core.sim.controllers): SUMO's own driver model and variants of it, or a user
controller whose acceleration is integrated here. The ego's poses are recorded every step
and judged by the checker.

Every evaluation runs in its own process (libsumo is a per-process singleton) under a time
budget. A user controller that raises gives a failed evaluation with the reason; a replay
that outlives its budget gives no verdict (BudgetExceeded: the budget is not the
controller's to meet).
"""

from __future__ import annotations

import json
import math
import os
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from service.core.budget import WarmPool, run_with_budget
from service.core.checker.check import check_testcase, testcase_label
from service.core.checker.verdict import Verdict
from service.core.errors import BudgetExceeded, InvalidInput
from service.core.files import write_atomically
from service.core.motion.poses import (
    CLEARANCE,
    PoseSample,
    centre_to_front,
    check_start_speed,
    front_to_centre,
    plan_drive,
    route_end,
    start_distance_of,
)
from service.core.names import REPLAY_BUDGET
from service.core.network import Intersection, SignalProgram, parsed_network
from service.core.sim.controllers import (
    BUILT_IN,
    CertificateDriver,
    Driver,
    GuardedDriver,
    SumoDriver,
    UserDriver,
    resolve_driver,
)
from service.core.sim.pedestrians import Walker, plan_section, walkers
from service.core.sim.replay_child import run_replay
from service.core.sim.rss_plan import rss_section
from service.core.sumo import run as sumo_run
from service.core.sumo.rss_guard import RSS_SUFFIX, GuardError, dynamics_from
from service.core.testcase import TestCase, load_testcase_intersection

TYPES_FILE = "testcase.types.xml"
ROUTES_FILE = "testcase.all.rou.xml"
SIGNALS_FILE = "testcase.signals.xml"  # the test-case's signal program, at a signalized junction


GOAL_PAST = 0.5  # metres past the runner's goal where the ego's route ends (more than
# SUMO's POSITION_EPS, by which a car arrives early)

SCRIPTED_MAX_SPEED = 100.0  # m/s: above every v_max a test-case may have
SCRIPTED_SPEED_FACTOR = 100.0  # times any lane's limit (at least 1 m/s): SCRIPTED_MAX_SPEED


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
    road: float = math.inf  # metres from its start to the end of its route (SUMO removes
    # the car when its front gets there; its trajectory may go on off the map)
    goal: float | None = None  # the ego's: metres from its start at which it has passed
    # its goal (its rear out of the junction): the runner removes it there (``goal_end``)
    arrival: float | None = None  # the ego's: where on its last edge its route ends, just
    # past its goal (SUMO's arrivalPos; ``goal_end``); None: at the end of the last edge


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
        testcase.params.v_max * testcase.duration,  # as far as any controller can drive
    )  # fmt: skip
    check_start_speed(intersection, plan, ego.start.speed)
    edges, arrival = goal_end(testcase, intersection, plan.edges)
    ego_departure = Departure(
        "ego", edges, plan.depart_lane, plan.depart_pos, ego.start.speed, ego.length,
        ego.width, plan.start_on, goal=plan.leave_distance - plan.skip, arrival=arrival,
    )  # fmt: skip
    others = []
    for nonego in testcase.nonegos:
        first = nonego.trajectory[0]
        route = intersection.route(nonego.route.id)
        front = centre_to_front(first.x, first.y, first.heading, nonego.length)
        start = start_distance_of(intersection, route, front)
        # a route long enough for the whole trajectory, where the road goes on
        speed = max(first.speed, 1.0, nonego.trajectory[-1].distance / testcase.duration)
        plan = plan_drive(
            intersection, route, start, speed,
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
                plan.road,
            )
        )
    return ego_departure, others


def goal_end(
    testcase: TestCase, intersection: Intersection, edges: tuple[str, ...]
) -> tuple[tuple[str, ...], float | None]:
    """The ego's route in SUMO: ``edges`` (as far as any controller can drive) cut where
    its test ends, and the position there on the last edge (SUMO's ``arrivalPos``; None
    where the road ends first). The test ends with the goal: the ego leaves the simulation
    there, as at the end of any route, rather than driving on to the next junction and
    standing at it, where a non-ego that follows its trajectory would run into it. The
    runner (service.core.sumo.run) removes it at the first step past its goal (its rear
    Step 1's CLEARANCE out of the junction: ``Departure.goal``); the route ends one step
    at ``v_max`` and GOAL_PAST later, so that where nothing moved the ego (plain ``sumo``
    on a bundle) SUMO's own route end leaves a last step past the goal too (SUMO reports a
    car last at the step before it arrives)."""
    beyond = (testcase.ego.length + CLEARANCE + GOAL_PAST
              + testcase.params.v_max * testcase.timestep)  # fmt: skip
    end = route_end(intersection, intersection.route(testcase.ego.route.id), edges, beyond)
    return (edges, None) if end is None else end


def vtype_lines(
    ego: Departure,
    nonegos: Sequence[Departure],
    testcase: TestCase,
    people: Sequence[Walker] = (),
) -> list[str]:
    """One SUMO vehicle type per car: its size; for the ego, SUMO's driver settings (the
    runner sets the stop-line wait of the chosen controller) and the test-case's bounds;
    and one per pedestrian: a person of its size."""
    p = testcase.params
    sumo = BUILT_IN["sumo"]
    assert isinstance(sumo, SumoDriver)
    lines = []
    for car in (ego, *nonegos):
        if car.id == "ego":
            extra = (
                f' sigma="0" jmStopSignWait="{sumo.stop_sign_wait:g}" minGap="1"'
                f' accel="{p.a_max:g}" decel="{-p.a_min:g}" emergencyDecel="{-p.a_min:g}"'
                f' maxSpeed="{p.v_max:g}" speedFactor="1" speedDev="0"'
            )
        else:
            # Scripted: they follow their trajectories, not the lanes' limits, so SUMO must
            # accept their departures at any speed up to maxSpeed (SUMO's limit at the start
            # is the lane's times speedFactor).
            extra = (
                f' sigma="0" minGap="0" speedFactor="{SCRIPTED_SPEED_FACTOR:g}" speedDev="0"'
                f' maxSpeed="{SCRIPTED_MAX_SPEED:g}"'
            )
        lines.append(
            f'    <vType id="type_{car.id}" length="{car.length:g}" width="{car.width:g}"{extra}/>'
        )
    for person in people:
        lines.append(
            f'    <vType id="type_{person.id}" vClass="pedestrian" length="{person.length:g}" '
            f'width="{person.width:g}"/>'
        )
    return lines


def vehicle_lines(cars: Sequence[Departure]) -> list[str]:
    """Each car departing at t = 0 with its own route, lane, position and speed (the ego
    arriving at the end of its route, just past its goal: ``goal_end``). SUMO's
    insertion checks are off: the test-case fixes every start (SUMO would otherwise delay a
    car that starts fast just after a junction it must yield at, "unpriorised junction too
    close", and the replay would no longer be the test-case)."""
    lines = []
    for car in cars:
        arrival = "" if car.arrival is None else f' arrivalPos="{car.arrival:.3f}"'
        lines.append(
            f'    <vehicle id="{car.id}" type="type_{car.id}" depart="0" '
            f'departLane="{car.lane}" departPos="{car.position:.3f}" '
            f'departSpeed="{car.speed:.3f}"{arrival} insertionChecks="none">'
        )
        lines.append(f'        <route edges="{" ".join(car.edges)}"/>')
        lines.append("    </vehicle>")
    return lines


def xml_file(root: str, lines: list[str]) -> str:
    return "\n".join(['<?xml version="1.0" encoding="UTF-8"?>', f"<{root}>", *lines, f"</{root}>"])


def controller_spec(driver: Driver) -> dict[str, Any]:
    """How the runner (service.core.sumo.run) drives the ego for ``driver``; a guarded
    driver's has ``"guard": "rss"``."""
    if isinstance(driver, GuardedDriver):
        return {**controller_spec(driver.inner), "guard": "rss"}
    if isinstance(driver, SumoDriver):
        return {
            "kind": "sumo", "speed_mode": driver.speed_mode,
            "stop_sign_wait": driver.stop_sign_wait, "rolling_speed": driver.rolling_speed,
        }  # fmt: skip
    if isinstance(driver, CertificateDriver):
        return {"kind": "certificate", "certificate": driver.certificate}
    return {"kind": "external"}


def sumo_signals(intersection: Intersection) -> SignalProgram | None:
    """The test-case's program as SUMO loads it on top of the network's (the program loaded
    last is the active one): the same phases and offset, under the test-case's program id
    unless the network already has a program of that id for the traffic light (SUMO refuses
    two), then under the first free ``<id>-scengen``, ``<id>-scengen2``, ...; None at a
    junction without traffic lights."""
    program = intersection.signals
    if program is None or intersection.tls is None:
        return None
    taken = set(parsed_network(intersection.network_file).getTLS(intersection.tls).getPrograms())
    name, k = program.program_id, 1
    while name in taken:
        name = f"{program.program_id}-scengen{k if k > 1 else ''}"
        k += 1
    return replace(program, tls=intersection.tls, program_id=name)


def signals_spec(testcase: TestCase, intersection: Intersection) -> dict[str, Any] | None:
    """The plan's ``signals``: the program's file, the traffic light, the ego's link."""
    if intersection.signals is None or intersection.tls is None:
        return None
    link = intersection.route(testcase.ego.route.id).link_index
    return {"file": SIGNALS_FILE, "tls": intersection.tls, "ego_link": link}


def run_plan(
    testcase: TestCase,
    ego: Departure,
    others: Sequence[Departure],
    network: str,
    signals: dict[str, Any] | None = None,
    rss: dict[str, Any] | None = None,
    people: Sequence[Walker] = (),
) -> dict[str, Any]:
    """The runner's plan: its files, the time step, every car's departure (``departures``)
    and distance per step, every pedestrian's route, start and pose per step
    (service.core.sim.pedestrians), the certificates, the signals (``signals_spec``: the program's
    file, the traffic light and the ego's link index, or None), what the RSS guard needs
    of the junction (``rss_section``), and the built-in controllers, SUMO's drivers also
    guarded (``NAME+rss``) (JSON, ``testcase.run.json``)."""
    certificates = None
    if testcase.certificates is not None:
        certificates = {
            kind: [s.distance for s in getattr(testcase.certificates, kind)]
            for kind in ("solvability", "complexity")
        }
    return {
        "schema": sumo_run.PLAN_SCHEMA,
        "network": network,
        "routes": ROUTES_FILE,
        "types": TYPES_FILE,
        "signals": signals,
        "timestep": testcase.timestep,
        "steps": round(testcase.duration / testcase.timestep),
        "ego": {
            "id": ego.id,
            "length": ego.length,
            "width": ego.width,
            "start_on": list(ego.start_on) if ego.start_on else None,
            "goal": ego.goal,
            "start_distance": testcase.ego.start.distance,
            "arrival_distance": testcase.params.arrival_distance,
        },
        "nonegos": [
            {
                "id": d.id,
                "length": d.length,
                "width": d.width,
                "start_on": list(d.start_on) if d.start_on else None,
                "distances": [s.distance for s in n.trajectory],
            }
            for d, n in zip(others, testcase.nonegos, strict=True)
        ],
        "pedestrians": plan_section(people),
        "certificates": certificates,
        "bounds": {
            "a_min": testcase.params.a_min,
            "a_max": testcase.params.a_max,
            "v_max": testcase.params.v_max,
        },
        "rss": rss,
        "controllers": {
            **{name: controller_spec(d) for name, d in BUILT_IN.items()},
            **{
                name + RSS_SUFFIX: controller_spec(GuardedDriver(name + RSS_SUFFIX, d))
                for name, d in BUILT_IN.items()
                if isinstance(d, SumoDriver)
            },
        },
    }


def write_run_files(
    testcase: TestCase,
    ego: Departure,
    others: Sequence[Departure],
    folder: Path,
    network: str,
    intersection: Intersection,
) -> dict[str, str]:
    """The runner's files in ``folder``: vehicle types, every car's route and departure,
    at a signalized junction the test-case's signal program (``sumo_signals``), and the
    plan (``network`` as the plan names it, relative to ``folder`` or absolute). The texts
    written, by file name."""
    people = walkers(testcase, intersection)
    plan = run_plan(
        testcase, ego, others, network, signals_spec(testcase, intersection),
        rss_section(testcase, intersection), people,
    )  # fmt: skip
    files = {
        TYPES_FILE: xml_file("additional", vtype_lines(ego, others, testcase, people)),
        ROUTES_FILE: xml_file("routes", vehicle_lines([ego, *others])),
        sumo_run.PLAN_FILE: json.dumps(plan, indent=1) + "\n",
    }
    program = sumo_signals(intersection)
    if program is not None:
        files[SIGNALS_FILE] = '<?xml version="1.0" encoding="UTF-8"?>\n' + program.to_sumo_xml()
    folder.mkdir(parents=True, exist_ok=True)
    for name, text in files.items():
        write_atomically(folder / name, text)
    return files


# Replays with the built-in drivers run in warm children (a replay's imports, about a
# second, paid once per child; SUMO starts afresh each time); as many idle ones are kept
# as the machine has cores.
REPLAYS = WarmPool(keep=os.cpu_count() or 2)


def evaluate(
    testcase: TestCase,
    controller: str,
    intersection: Intersection | None = None,
    budget: float = REPLAY_BUDGET,
    rss_params: dict[str, Any] | None = None,
) -> Evaluation:
    """Replay ``testcase`` with ``controller`` driving the ego, in a child process under
    ``budget``, and judge the ego. A controller that raises fails; a replay that does not
    finish within ``budget`` is BudgetExceeded (the budget is the caller's limit, so it
    gives no verdict: a controller that hangs is not told apart from a budget too small).
    A guarded controller (``NAME+rss``) uses ``rss_params`` (RSS dynamics overriding
    CARLA's defaults, service.core.sumo.rss_guard) and its verdict says how often the
    guard intervened (``guard``)."""
    driver = resolve_driver(controller)
    if rss_params is not None:
        try:
            dynamics_from(rss_params)
        except GuardError as exc:
            raise InvalidInput(str(exc)) from exc
    if isinstance(driver, CertificateDriver) and testcase.certificates is None:
        raise InvalidInput(
            f"controller {driver.name} replays a certificate, but this test-case has none "
            "(only generated test-cases carry certificates)"
        )
    junction = intersection or load_testcase_intersection(testcase)
    inner = driver.inner if isinstance(driver, GuardedDriver) else driver
    reference = inner.reference if isinstance(inner, UserDriver) else None
    with tempfile.TemporaryDirectory(prefix="scengen-replay-") as folder:
        plan_file = str(prepare_replay(testcase, junction, Path(folder)))
        arguments = (plan_file, controller_spec(driver), driver.name, reference, rss_params)
        try:
            # a user's controller runs in a fresh child: state it keeps between calls
            # (module globals, a changed module) must not carry from one replay to the next
            run = REPLAYS.call if reference is None else run_with_budget
            rows, error, guard = run(run_replay, arguments, budget, "the replay")
        except BudgetExceeded as exc:  # the server's limit: no verdict on the controller
            raise type(exc)(
                f"{exc.message}; no verdict on {controller} (raise the evaluation's budget)",
                **exc.context,
            ) from None
    return judge(testcase, rows, error, controller, junction, guard)


def prepare_replay(testcase: TestCase, intersection: Intersection, folder: Path) -> Path:
    """Write the runner's files for ``testcase`` into ``folder`` (every car's departure,
    the network by its absolute path); the plan's path."""
    ego, others = departures(testcase, intersection)
    network = str(intersection.network_file.resolve())
    write_run_files(testcase, ego, others, folder, network, intersection)
    return folder / sumo_run.PLAN_FILE


def judge(
    testcase: TestCase,
    rows: Sequence[sumo_run.Row],
    error: str | None,
    controller: str,
    intersection: Intersection,
    guard: dict[str, Any] | None = None,
) -> Evaluation:
    """The checker's verdict on the ego's rows of a replay, labelled ``controller``:
    failed with ``error`` when the ego never moved, and with ``error`` among its errors
    when something stopped its controller; ``guard``: the RSS guard's summary."""
    samples = [row_sample(row, testcase.ego.length) for row in rows]
    if len(samples) < 2:
        verdict = _failed(testcase, controller, error or "the ego never moved in SUMO")
        return Evaluation(replace(verdict, guard=guard), samples, error)
    verdict = check_testcase(testcase, samples, controller, intersection)
    if error is not None:
        verdict = replace(verdict, errors=(*verdict.errors, error))
    return Evaluation(replace(verdict, guard=guard), samples, error)


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


def row_sample(row: sumo_run.Row, length: float) -> PoseSample:
    """A runner's row (front bumper, odometer from the start) as a sample of the centre."""
    x, y = front_to_centre(row["x"], row["y"], row["angle"], length)
    return PoseSample(row["t"], x, y, row["angle"], row["speed"], row["odometer"])
