"""The child-process side of a replay: run the plan in libsumo with the runner's loop.

Kept apart from service.core.sim.replay so that the child imports only what it runs (the
runner, the controllers, libsumo), not the checker and the network model: every evaluation
starts a fresh process. A Gymnasium environment's child (service.core.sim.gym_env) runs
this module (``serve_episodes``): the same observation and the same clipping of the
command as a user controller's (``observer``, ``apply_command``), the action from the
parent.
"""

from __future__ import annotations

import contextlib
import math
import pickle
import signal
import sys
import tempfile
import traceback
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from service.core.errors import ScengenError, SimulationFailed
from service.core.sim.controllers import (
    LEADER_LOOKAHEAD,
    Controller,
    Leader,
    Observation,
    Vehicle,
    load_user_controller,
)
from service.core.sumo import run as sumo_run
from service.core.sumo.rss_guard import RssGuard

Lanes = dict[str, float]  # a car's lanes in driving order, each with where it starts (m)


def run_replay(
    plan_file: str,
    controller: dict[str, Any],
    name: str,
    reference: str | None,
    rss_params: dict[str, Any] | None = None,
) -> tuple[list[sumo_run.Row], str | None, dict[str, Any] | None]:
    """Run the plan in libsumo; the ego's rows (front bumper), what stopped it early, and
    the RSS guard's summary (None: unguarded). ``reference``: a user controller's
    ``module:attribute``, driving the ego; ``rss_params``: the guard's dynamics."""
    import libsumo

    plan = sumo_run.load_plan(Path(plan_file))
    guard = None
    if controller.get("guard") == "rss":
        guard = RssGuard(plan.get("rss") or {}, rss_params)
    summary = guard.summary if guard is not None else (lambda: None)
    on_step = None
    if reference is not None:
        try:
            user = load_user_controller(reference)
        except ScengenError as exc:
            return [], str(exc), summary()
        on_step = _user_step(user, name, plan, guard)
    with _sumo_errors(libsumo):
        rows, error = sumo_run.run(libsumo, Path(plan_file), controller, on_step, guard=guard)
        return rows, error, summary()


@contextlib.contextmanager
def _sumo_errors(libsumo: Any) -> Iterator[None]:
    """The runner's and SUMO's errors as SimulationFailed."""
    try:
        yield
    except sumo_run.RunFailed as exc:
        raise SimulationFailed(str(exc)) from exc
    except libsumo.TraCIException as exc:
        raise SimulationFailed(f"SUMO refused the replay: {exc}") from exc


EXTERNAL = {"kind": "external"}  # the runner leaves the ego's speed to ``on_step``
Send = Callable[[tuple[Any, ...]], None]
Receive = Callable[[], "tuple[Any, ...] | None"]


def run_episode(
    libsumo: Any, plan_file: str, send: Send, receive: Receive
) -> tuple[list[sumo_run.Row], str | None, Observation | None]:
    """One episode of a Gymnasium environment (service.core.sim.gym_env) in libsumo: at
    every step where a user controller would be asked, send ``("observation",
    Observation)`` and apply the acceleration of the ``("action", float)`` received,
    exactly as a user controller's (``apply_command``); ``("stop",)`` ends the episode
    early. The ego's rows, what stopped it early, and the observation after the last step
    (None: no row)."""
    plan = sumo_run.load_plan(Path(plan_file))
    observe = observer(plan)

    def on_step(traci: Any, row: sumo_run.Row, present: set[str]) -> str | None:
        send(("observation", observe(traci, row, present)))
        message = receive()
        if message is None:  # the parent is gone
            raise SystemExit(0)
        if message[0] == "stop":
            return "stopped by the environment's caller"
        apply_command(traci, plan, row, float(message[1]))
        return None

    folder = Path(plan_file).parent
    # in the parent's folder: the parent removes it when it kills this child mid-episode
    with (
        _sumo_errors(libsumo),
        tempfile.TemporaryDirectory(prefix="scratch-", dir=folder) as scratch,
    ):
        types = sumo_run.write_types(plan, folder, EXTERNAL, Path(scratch) / "types.xml")
        libsumo.start(["sumo", *sumo_run.sumo_arguments(plan, folder, types)])
        try:
            rows, error = sumo_run.drive(libsumo, plan, EXTERNAL, on_step)
            present = set(libsumo.vehicle.getIDList())
            last = observe(libsumo, rows[-1], present) if rows else None
        finally:
            libsumo.close()
    return rows, error, last


def serve_episodes() -> None:
    """The child process of a Gymnasium environment (``python -m
    service.core.sim.replay_child``): framed pickles on stdin and stdout
    (service.core.budget's FRAME). It reads ``("episode", plan_file)``, runs it
    (``run_episode``) and answers ``("done", rows, error, last observation)``, or
    ``("error", ScengenError)`` / ``("crash", text)``; until stdin closes. It dies with its
    parent and leaves Ctrl-C to it (the parent kills it)."""
    from service.core.budget import FRAME, answer_pipe, enter_child

    enter_child()
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    source = sys.stdin.buffer
    out = answer_pipe()  # whatever SUMO prints must not corrupt the answers

    def send(message: tuple[Any, ...]) -> None:
        data = pickle.dumps(message)
        out.write(FRAME.pack(len(data)) + data)
        out.flush()

    def receive() -> tuple[Any, ...] | None:
        header = source.read(FRAME.size)
        if len(header) < FRAME.size:
            return None
        (size,) = FRAME.unpack(header)
        return tuple(pickle.loads(source.read(size)))

    import libsumo

    while (request := receive()) is not None:
        try:
            send(("done", *run_episode(libsumo, str(request[1]), send, receive)))
        except SystemExit:
            return
        except ScengenError as exc:
            send(("error", exc))
        except Exception as exc:  # reported, the parent decides
            send(("crash", f"{type(exc).__name__}: {exc}\n{traceback.format_exc()}"))


def _user_step(
    user: Controller, name: str, plan: dict[str, Any], guard: RssGuard | None = None
) -> sumo_run.OnStep:
    """The runner's hook for a user controller: observe, ask, clip (to the RSS guard's
    ceiling too, when guarded), set the ego's speed."""
    observe = observer(plan)

    def step(traci: Any, row: sumo_run.Row, present: set[str]) -> str | None:
        observation = observe(traci, row, present)
        try:
            command = float(user.step(observation))
            if not math.isfinite(command):
                raise ValueError(f"acceleration {command!r} is not a finite number")
        except Exception as exc:  # the user's code: any failure fails the evaluation
            return f"controller {name} raised {type(exc).__name__}: {exc}"
        apply_command(traci, plan, row, command, guard)
        return None

    return step


Observer = Callable[[Any, sumo_run.Row, set[str]], Observation]


def observer(plan: dict[str, Any]) -> Observer:
    """What the ego observes at a step (``observe(traci, row, present)``): the plug-in
    controller's Observation. It remembers every car's lanes from where the car is the
    first time it is seen. After the ego has left (at its goal) the ego's part comes from
    its last row, on no lane and with no leader."""
    timestep = float(plan["timestep"])
    bounds = plan["bounds"]
    ego = plan["ego"]
    sizes = {car["id"]: (float(car["length"]), float(car["width"])) for car in plan["nonegos"]}
    ego_size = ego["length"], ego["width"]
    people = plan.get("pedestrians") or []
    lanes: dict[str, Lanes] = {}  # every car's, from where it is at the first step

    def observe(traci: Any, row: sumo_run.Row, present: set[str]) -> Observation:
        for car in present - lanes.keys():
            lanes[car] = route_lanes(traci, car)
        x, y = sumo_run.front_to_centre(row["x"], row["y"], row["angle"], float(ego["length"]))
        nonegos = sorted(present - {sumo_run.EGO})
        there = sumo_run.EGO in present
        vehicle = Vehicle(sumo_run.EGO, x, y, row["angle"], row["speed"], *ego_size)
        lengths = {car: sizes[car][0] for car in nonegos}
        return Observation(
            t=row["t"],
            timestep=timestep,
            ego=vehicle,
            distance=row["odometer"],
            to_stop_line=float(ego["start_distance"]) - row["odometer"],
            lane=traci.vehicle.getLaneID(sumo_run.EGO) if there else "",
            others=tuple(_vehicle(traci, car, *sizes[car]) for car in nonegos),
            a_min=bounds["a_min"],
            a_max=bounds["a_max"],
            v_max=bounds["v_max"],
            leader=find_leader(traci, lanes, lengths) if there else None,
            signal=sumo_run.ego_signal(traci, plan),
            pedestrians=pedestrians_seen(traci, people, round(row["t"] / timestep)),
        )

    return observe


def apply_command(
    traci: Any,
    plan: dict[str, Any],
    row: sumo_run.Row,
    command: float,
    guard: RssGuard | None = None,
) -> None:
    """Clip an acceleration command to the plan's bounds (and the RSS guard's ceiling,
    when guarded), integrate it over one step, and set the ego's speed (within [0, v_max])."""
    bounds = plan["bounds"]
    accel = min(command, bounds["a_max"])
    if guard is not None:
        accel = guard.limit(row["t"], accel)
    accel = max(accel, bounds["a_min"])
    new_speed = min(max(row["speed"] + accel * float(plan["timestep"]), 0.0), bounds["v_max"])
    traci.vehicle.setSpeed(sumo_run.EGO, new_speed)


def pedestrians_seen(traci: Any, people: list[dict[str, Any]], step: int) -> tuple[Vehicle, ...]:
    """Every pedestrian in SUMO at ``step``, at her recorded pose (the centre of her
    rectangle; SUMO has her there from the first step on, and at t = 0 at her departure
    place nearby)."""
    sizes = {person["id"]: (float(person["length"]), float(person["width"])) for person in people}
    found = []
    for name, (x, y, heading, speed) in sumo_run.people_at(traci, people, step).items():
        length, width = sizes[name]
        cx, cy = sumo_run.front_to_centre(x, y, heading, length)
        found.append(Vehicle(name, cx, cy, heading, speed, length, width))
    return tuple(found)


def _vehicle(traci: Any, car: str, length: float, width: float) -> Vehicle:
    """A non-ego as the ego sees it: its rectangle's centre from SUMO's front bumper."""
    heading = traci.vehicle.getAngle(car) % 360.0
    fx, fy = traci.vehicle.getPosition(car)
    cx, cy = sumo_run.front_to_centre(fx, fy, heading, length)
    return Vehicle(car, cx, cy, heading, traci.vehicle.getSpeed(car), length, width)


def route_lanes(traci: Any, car: str) -> Lanes:
    """The lanes ``car`` drives on from the one it is on to the end of its route, internal
    lanes included, each with the metres from the start of the first to its own start."""
    edges = list(traci.vehicle.getRoute(car))
    index = traci.vehicle.getRouteIndex(car)  # on an internal lane: the edge before it
    lane = traci.vehicle.getLaneID(car)
    found: Lanes = {}
    at = 0.0
    while lane and lane not in found:
        found[lane] = at
        at += traci.lane.getLength(lane)
        if not lane.startswith(":"):
            index = edges.index(traci.lane.getEdgeID(lane), index)
        if index + 1 >= len(edges):
            break
        onward = [link for link in traci.lane.getLinks(lane)
                  if traci.lane.getEdgeID(link[0]) == edges[index + 1]]  # fmt: skip
        if not onward:
            break
        lane = onward[0][4] or onward[0][0]  # its internal lane, else the next edge's
    return found


def find_leader(traci: Any, lanes: dict[str, Lanes], lengths: dict[str, float]) -> Leader | None:
    """The nearest car (of ``lengths``, by id) whose front is ahead of the ego's front and
    whose rear or front is on one of the ego's lanes, within LEADER_LOOKAHEAD metres.
    The gap, along the ego's lanes, is what SUMO's ``vehicle.getLeader`` gives plus the
    ego's minGap (SUMO's excludes it). Computed here rather than asked of getLeader, which
    can also name a car crossing the ego's path in the junction (a "link leader")."""
    ego_lanes = lanes[sumo_run.EGO]
    lane = traci.vehicle.getLaneID(sumo_run.EGO)
    if lane not in ego_lanes:
        return None
    front = ego_lanes[lane] + traci.vehicle.getLanePosition(sumo_run.EGO)
    nearest: Leader | None = None
    for car, length in sorted(lengths.items()):
        place = traci.vehicle.getLaneID(car), traci.vehicle.getLanePosition(car)
        rear = _rear_along(ego_lanes, lanes[car], *place, length)
        if rear is None or rear + length <= front or rear - front > LEADER_LOOKAHEAD:
            continue
        if nearest is None or rear - front < nearest.gap:
            nearest = Leader(car, rear - front, traci.vehicle.getSpeed(car))
    return nearest


def _rear_along(
    ego_lanes: Lanes, car_lanes: Lanes, lane: str, position: float, length: float
) -> float | None:
    """Where a car's rear is along the ego's lanes (None: neither its rear nor its front is
    on one of them). A car partly on a lane of another turn counts while its rear is still
    on the ego's lane, as in SUMO."""
    if lane not in car_lanes:
        return None
    rear = car_lanes[lane] + position - length  # along its own lanes
    behind = [name for name, start in car_lanes.items() if start <= rear]
    rear_lane = behind[-1] if behind else next(iter(car_lanes))  # lanes in driving order
    if rear_lane in ego_lanes:
        return ego_lanes[rear_lane] + rear - car_lanes[rear_lane]
    if lane in ego_lanes:  # merging into the ego's lane from another
        return ego_lanes[lane] + position - length
    return None


if __name__ == "__main__":
    serve_episodes()
