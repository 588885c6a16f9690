"""The child-process side of a replay: run the plan in libsumo with the runner's loop.

Kept apart from service.core.replay so that the child imports only what it runs (the
runner, the controllers, libsumo), not the checker and the network model: every evaluation
starts a fresh process.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from service.core import sumo_run
from service.core.controllers import Controller, Observation, Vehicle, load_user_controller
from service.core.errors import ScengenError, SimulationFailed


def run_replay(
    plan_file: str, controller: dict[str, Any], name: str, reference: str | None
) -> tuple[list[sumo_run.Row], str | None]:
    """Run the plan in libsumo; the ego's rows (front bumper) and what stopped it early.
    ``reference``: a user controller's ``module:attribute``, driving the ego."""
    import libsumo

    on_step = None
    if reference is not None:
        try:
            user = load_user_controller(reference)
        except ScengenError as exc:
            return [], str(exc)
        on_step = _user_step(user, name, sumo_run.load_plan(Path(plan_file)))
    try:
        return sumo_run.run(libsumo, Path(plan_file), controller, on_step)
    except sumo_run.RunFailed as exc:
        raise SimulationFailed(str(exc)) from exc
    except libsumo.TraCIException as exc:
        raise SimulationFailed(f"SUMO refused the replay: {exc}") from exc


def _user_step(user: Controller, name: str, plan: dict[str, Any]) -> sumo_run.OnStep:
    """The runner's hook for a user controller: observe, ask, clip, set the ego's speed."""
    timestep = float(plan["timestep"])
    bounds = plan["bounds"]
    ego = plan["ego"]
    sizes = {car["id"]: (float(car["length"]), float(car["width"])) for car in plan["nonegos"]}

    def step(traci: Any, row: sumo_run.Row, present: set[str]) -> str | None:
        x, y = sumo_run.front_to_centre(row["x"], row["y"], row["angle"], float(ego["length"]))
        speed = row["speed"]
        others = []
        for car in sorted(present - {sumo_run.EGO}):
            length, width = sizes[car]
            heading = traci.vehicle.getAngle(car) % 360.0
            fx, fy = traci.vehicle.getPosition(car)
            cx, cy = sumo_run.front_to_centre(fx, fy, heading, length)
            others.append(Vehicle(car, cx, cy, heading, traci.vehicle.getSpeed(car), length, width))
        observation = Observation(
            t=row["t"],
            timestep=timestep,
            ego=Vehicle(sumo_run.EGO, x, y, row["angle"], speed, ego["length"], ego["width"]),
            distance=row["odometer"],
            to_stop_line=float(ego["start_distance"]) - row["odometer"],
            lane=traci.vehicle.getLaneID(sumo_run.EGO),
            others=tuple(others),
            a_min=bounds["a_min"],
            a_max=bounds["a_max"],
            v_max=bounds["v_max"],
        )
        try:
            command = float(user.step(observation))
            if not math.isfinite(command):
                raise ValueError(f"acceleration {command!r} is not a finite number")
        except Exception as exc:  # the user's code: any failure fails the evaluation
            return f"controller {name} raised {type(exc).__name__}: {exc}"
        accel = min(max(command, bounds["a_min"]), bounds["a_max"])
        new_speed = min(max(speed + accel * timestep, 0.0), bounds["v_max"])
        traci.vehicle.setSpeed(sumo_run.EGO, new_speed)
        return None

    return step
