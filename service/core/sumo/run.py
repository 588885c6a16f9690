"""Replay a test-case in SUMO: the one loop that `scengen evaluate` runs and that every
exported bundle ships as ``run.py``.

The non-egos (and a replayed certificate) follow their trajectories exactly: speed mode 0
and, every step, ``setSpeed`` with the distance they cover in that step (SUMO moves a car by
its speed times the step, Euler steps). The ego is driven by SUMO's own driver with a
controller's settings, or replays a certificate, or is left to a caller's ``on_step`` (a
user controller). Cars that start inside an upstream junction depart just before it and are
moved onto their start (``vehicle.moveTo``) right after the first step.

Pedestrians (the plan's ``pedestrians``) are persons walking their walk's edges in three
walking stages (up to the curb, the crossing alone, from the far curb: SUMO keeps a
person's direction on a crossing only on a stage of the crossing alone), added before the
first step on the edge nearest their first pose, and placed at their recorded pose every
step after it with ``person.moveToXY(..., keepRoute=1)``: mapped onto the nearest edge of
their stage, so that SUMO has them on the crossing's lane while they are on it and its
drivers yield to them; the runner moves a person on to her next stage when her pose comes
near it (``removeStage``). At t = 0 SUMO has a person at its departure place (a lane's
centreline, up to half a sidewalk's width from the pose, or the end of the sidewalk before
a walking area); from the first step on at its pose (service.core.sim.pedestrians says how
near, where). A person leaves when its trajectory ends (the test-case's, or where it left
its route's lanes: the map). Collisions with persons are SUMO's to report, not to act on:
``--intermodal-collision.action none`` (the checker judges them). The test ends with
the ego's goal: the ego leaves the simulation at the end of its route, the first step past
its goal (``plan["ego"]["goal"]``, metres from its start), rather than driving on and
standing where a non-ego that follows its trajectory runs into it. (The route file ends its
route a little further on, where SUMO removes it by itself; a ``moveTo`` onto another edge
makes SUMO forget a route's ``arrivalPos``, so the runner does not rely on it.)

This file is standalone on purpose: the standard library and SUMO's own Python modules
(libsumo, or traci with the ``sumo`` binary) only, so that a bundle runs where only
``eclipse-sumo`` is installed. ``service.core.export`` copies it into every bundle; keep it
free of scengen imports.

In a bundle::

    python run.py [--controller NAME] [--fcd-output FILE] [--rss-params FILE] [--traci] [--gui]

``NAME+rss`` (e.g. ``sumo+rss``) drives with the RSS guard of ``rss_guard.py``, the file
next to this one (it needs ``pip install ad-rss``; without it the guard says so and uses
its time-gap rule).
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import json
import math
import os
import shutil
import sys
import tempfile
import xml.etree.ElementTree as ET
from collections.abc import Callable
from pathlib import Path
from typing import Any

PLAN_SCHEMA = "scengen/run/1"
PLAN_FILE = "testcase.run.json"
EGO = "ego"

Row = dict[str, float]  # the ego at one step: t, x, y (front bumper), angle, speed, odometer
OnStep = Callable[[Any, Row, set[str]], "str | None"]  # a caller's controller; text stops it


def front_to_centre(x: float, y: float, heading: float, length: float) -> tuple[float, float]:
    """The rectangle centre from SUMO's front-bumper position and heading (degrees
    clockwise from north)."""
    rad = math.radians(heading)
    return x - math.sin(rad) * length / 2.0, y - math.cos(rad) * length / 2.0


def centre_to_front(x: float, y: float, heading: float, length: float) -> tuple[float, float]:
    """The front-bumper centre from the rectangle centre and heading."""
    rad = math.radians(heading)
    return x + math.sin(rad) * length / 2.0, y + math.cos(rad) * length / 2.0


class RunFailed(Exception):
    """SUMO could not run the plan (the ego could not be inserted, a file is wrong)."""


def load_plan(path: Path) -> dict[str, Any]:
    """The run plan (``testcase.run.json``): files, time step, cars, controllers."""
    plan = json.loads(path.read_text())
    if plan.get("schema") != PLAN_SCHEMA:
        raise RunFailed(f"{path} is not a scengen run plan (schema {PLAN_SCHEMA})")
    return dict(plan)


def sumo_arguments(plan: dict[str, Any], folder: Path, types_file: Path) -> list[str]:
    """SUMO's options for the plan (files relative to ``folder``), without the program. At
    a signalized junction the test-case's signal program is loaded after the network's,
    so it is the active one (SUMO runs the program it loads last)."""
    step = repr(float(plan["timestep"]))
    additional = [str(types_file)]
    if plan.get("signals"):
        additional.append(str(folder / plan["signals"]["file"]))
    return [
        "-n", str(folder / plan["network"]), "-r", str(folder / plan["routes"]),
        "--additional-files", ",".join(additional), "--step-length", step,
        "--default.action-step-length", step, "--step-method.ballistic", "false",
        "--time-to-teleport", "-1", "--collision.action", "none",
        "--intermodal-collision.action", "none", "--collision.check-junctions", "true",
        "--ignore-route-errors", "false", "--no-step-log", "true", "--no-warnings", "true",
    ]  # fmt: skip


def write_types(
    plan: dict[str, Any], folder: Path, controller: dict[str, Any], target: Path
) -> Path:
    """The plan's vehicle types with the ego's stop-line wait set by ``controller``."""
    tree = ET.parse(folder / plan["types"])
    for vtype in tree.getroot().iter("vType"):
        if vtype.get("id") == f"type_{EGO}" and controller["kind"] == "sumo":
            vtype.set("jmStopSignWait", repr(float(controller["stop_sign_wait"])))
    tree.write(target, encoding="UTF-8", xml_declaration=True)
    return target


def ego_signal(traci: Any, plan: dict[str, Any]) -> str | None:
    """The SUMO colour of the ego's link now (``G g y Y r u s O o``, see SUMO's
    ``trafficlight.getRedYellowGreenState``); None when the ego's route has no signal."""
    signals = plan.get("signals")
    if not signals or int(signals["ego_link"]) < 0:
        return None
    return str(traci.trafficlight.getRedYellowGreenState(signals["tls"])[int(signals["ego_link"])])


def drive(
    traci: Any,
    plan: dict[str, Any],
    controller: dict[str, Any],
    on_step: OnStep | None = None,
    guard: Any = None,
) -> tuple[list[Row], str | None]:
    """Run the started simulation step by step; the ego's rows and what stopped it early.
    The ego leaves the simulation at the end of its route: the first step at which it is
    ``plan["ego"]["goal"]`` metres from its start or more, past its goal, where its test
    ends (or where SUMO removes it, at the end of its route's last lane).

    ``controller``: ``{"kind": "sumo", "speed_mode", "stop_sign_wait", "rolling_speed"}``,
    ``{"kind": "certificate", "certificate": "solvability"|"complexity"}``, or
    ``{"kind": "external"}`` (speed mode 0; ``on_step`` sets the ego's speed every step).
    ``guard``: an RSS guard (rss_guard.RssGuard) told every car's state each step; SUMO's
    driver is then capped to its ceiling (``setSpeed`` with SUMO's own checks on, -1 hands
    the ego back), an ``on_step`` asks ``guard.limit`` for its command."""
    timestep = float(plan["timestep"])
    steps = int(plan["steps"])
    ego = plan["ego"]
    replayed = [(car["id"], car["distances"]) for car in plan["nonegos"]]
    if controller["kind"] == "certificate":
        certificates = plan.get("certificates") or {}
        if controller["certificate"] not in certificates:
            raise RunFailed("this test-case has no certificates to replay")
        replayed.append((EGO, certificates[controller["certificate"]]))
    sumo_driven = controller["kind"] == "sumo"
    goal = None if ego.get("goal") is None else float(ego["goal"])
    moved = {car["id"]: car["start_on"] for car in (ego, *plan["nonegos"]) if car["start_on"]}
    people = plan.get("pedestrians") or []
    add_people(traci, people)
    rows: list[Row] = []
    rolling = capped = False
    odometer = 0.0  # the ego's SUMO odometer at its start
    for step in range(steps + 1):
        traci.simulationStep()
        present = set(traci.vehicle.getIDList())
        if step == 0:
            for car, (lane, position) in moved.items():  # onto its start in the junction
                if car in present:
                    traci.vehicle.moveTo(car, lane, position)
            missing = [car["id"] for car in (ego, *plan["nonegos"]) if car["id"] not in present]
            if missing:
                raise RunFailed(f"SUMO could not insert {', '.join(missing)} at the start")
            odometer = traci.vehicle.getDistance(EGO)
            for car in present:
                traci.vehicle.setLaneChangeMode(car, 0)
                if car != EGO or not sumo_driven:
                    traci.vehicle.setSpeedMode(car, 0)
            if sumo_driven:
                traci.vehicle.setSpeedMode(EGO, int(controller["speed_mode"]))
        if EGO not in present:
            break  # the ego reached the end of its route
        x, y = traci.vehicle.getPosition(EGO)
        row = {
            "t": round(step * timestep, 9), "x": x, "y": y,
            "angle": traci.vehicle.getAngle(EGO) % 360.0, "speed": traci.vehicle.getSpeed(EGO),
            "odometer": traci.vehicle.getDistance(EGO) - odometer,
        }  # fmt: skip
        rows.append(row)
        if goal is not None and row["odometer"] >= goal:
            traci.vehicle.remove(EGO)  # past its goal: its test is over, it leaves
            break
        if step == steps:
            break
        for car, distances in replayed:
            if car not in present:
                continue
            if step + 1 < len(distances):
                gap = distances[step + 1] - distances[step]
                traci.vehicle.setSpeed(car, max(gap, 0.0) / timestep)
            elif car != EGO:  # its trajectory ended: it left the map there
                traci.vehicle.remove(car)
                present.discard(car)  # gone for the controller too: SUMO no longer knows it
        walk_people(traci, people, step)
        if sumo_driven and controller.get("rolling_speed") is not None:
            rolling = _roll(traci, plan, controller, row, rolling)
        if guard is not None:
            _observe(traci, plan, guard, step, row, present)
            if sumo_driven:
                resume = float(controller["rolling_speed"]) if rolling else -1.0
                capped = _cap(traci, guard, row, timestep, capped, resume)
        if on_step is not None:
            stopped = on_step(traci, row, present)
            if stopped is not None:
                return rows, stopped
    return rows, None


def add_people(traci: Any, people: list[dict[str, Any]]) -> None:
    """Add every pedestrian before the first step: a person of its own type (its size)
    departing at t = 0 on its first stage's first edge, with its walking stages (up to the
    curb, the crossing alone, from the far curb: SUMO keeps a person's direction on a
    crossing only on a stage of the crossing alone)."""
    for person in people:
        name = person["id"]
        stages = person["stages"]
        traci.person.add(name, stages[0]["edges"][0], float(person["depart_pos"]), depart=0.0,
                         typeID=f"type_{name}")  # fmt: skip
        for stage in stages:
            traci.person.appendWalkingStage(name, list(stage["edges"]), float(stage["arrival"]))


def walk_people(traci: Any, people: list[dict[str, Any]], step: int) -> None:
    """Put every pedestrian still in SUMO where its trajectory has it at the next step
    (``moveToXY`` before a step is where the person is after it), in the walking stage of
    that pose (the stages before it ended: ``removeStage(id, 0)``); or remove it when its
    trajectory ends at this step."""
    if not people:
        return  # no call to SUMO: over TraCI (run.py --traci, a co-simulation) each costs
    walking = set(traci.person.getIDList())
    for person in people:
        name, poses = person["id"], person["poses"]
        if name not in walking:
            continue
        if step + 1 >= len(poses):
            traci.person.remove(name)
            continue
        x, y, angle, _, stage, edge = poses[step + 1]
        stages = person["stages"]
        for _ in range(int(stage) - (len(stages) - traci.person.getRemainingStages(name))):
            traci.person.removeStage(name, 0)  # on to the next stage
        edges = stages[min(int(stage), len(stages) - 1)]["edges"]
        traci.person.moveToXY(name, edges[int(edge)], x, y, angle, 1)


def people_at(traci: Any, people: list[dict[str, Any]], step: int) -> dict[str, list[float]]:
    """Every pedestrian in SUMO at this step and its recorded pose (front x, y, heading,
    speed)."""
    walking = set(traci.person.getIDList())
    return {
        person["id"]: [float(v) for v in person["poses"][step][:4]]
        for person in people
        if person["id"] in walking and step < len(person["poses"])
    }


def _observe(
    traci: Any, plan: dict[str, Any], guard: Any, step: int, row: Row, present: set[str]
) -> None:
    """Tell the guard where every car is: its front's metres from its own stop line (the
    ego's from its odometer, a non-ego's from its trajectory) and its speed; where every
    pedestrian in the ego's path is (her front's metres along her walk, her speed, her
    centre and heading); and where the ego is in the plane (its centre and heading)."""
    rss = plan.get("rss") or {}
    cars = rss.get("cars", {})
    others = {}
    for car in plan["nonegos"]:
        name = car["id"]
        if name in present and name in cars and step < len(car["distances"]):
            front = car["distances"][step] - cars[name]["stop_line"]
            others[name] = (front, traci.vehicle.getSpeed(name))
    walkers = rss.get("pedestrians", {})
    sizes = {person["id"]: float(person["length"]) for person in plan.get("pedestrians") or []}
    people = {}
    for name, (x, y, heading, speed) in people_at(
        traci, plan.get("pedestrians") or [], step
    ).items():
        if name in walkers:
            cx, cy = front_to_centre(x, y, heading, sizes[name])
            people[name] = (walkers[name]["places"][step], speed, cx, cy, heading)
    ego = (row["odometer"] - float(plan["ego"]["start_distance"]), row["speed"])
    pose = (*front_to_centre(row["x"], row["y"], row["angle"], float(plan["ego"]["length"])),
            row["angle"])  # fmt: skip
    signals = plan.get("signals")
    colours = traci.trafficlight.getRedYellowGreenState(signals["tls"]) if signals else None
    if rss.get("pedestrians"):
        guard.step(row["t"], ego, others, colours, people, pose)
    else:  # as before pedestrians: a guard of one's own with the old step keeps working
        guard.step(row["t"], ego, others, colours)


def _cap(traci: Any, guard: Any, row: Row, timestep: float, capped: bool, resume: float) -> bool:
    """Cap SUMO's driver at the guard's ceiling (its own safety checks stay on: the speed
    set is an upper bound it may still undercut); when the guard lets go, hand the ego
    back (``resume``: -1, or the rolling stop's speed while it rolls). Whether the ego is
    capped now."""
    accel = guard.limit(row["t"], math.inf)
    if accel < math.inf:
        traci.vehicle.setSpeed(EGO, max(0.0, row["speed"] + accel * timestep))
        return True
    if capped:
        traci.vehicle.setSpeed(EGO, resume)
    return False


def _roll(
    traci: Any, plan: dict[str, Any], controller: dict[str, Any], row: Row, rolling: bool
) -> bool:
    """Keep the ego at the rolling speed or faster from arriving at the fork to passing
    the stop line; then hand it back to SUMO's driver. It rolls through a stop, not
    through a light that tells it to stop: while its signal is red, red-yellow or yellow
    SUMO's driver has it (and stops at the line)."""
    speed = float(controller["rolling_speed"])
    to_line = float(plan["ego"]["start_distance"]) - row["odometer"]
    inside_zone = -1.0 < to_line <= float(plan["ego"]["arrival_distance"])
    if inside_zone and to_line > 0.0 and ego_signal(traci, plan) in ("r", "u", "y", "Y"):
        inside_zone = False
    if inside_zone and traci.vehicle.getSpeed(EGO) <= speed:
        if not rolling:
            traci.vehicle.setSpeedMode(EGO, 0)
        traci.vehicle.setSpeed(EGO, speed)
        return True
    if rolling and not inside_zone:
        traci.vehicle.setSpeed(EGO, -1)
        traci.vehicle.setSpeedMode(EGO, int(controller["speed_mode"]))
        return False
    return rolling


def run(
    traci: Any,
    plan_file: Path,
    controller: dict[str, Any],
    on_step: OnStep | None = None,
    program: str = "sumo",
    extra: tuple[str, ...] = (),
    guard: Any = None,
) -> tuple[list[Row], str | None]:
    """Start SUMO (``traci`` is the libsumo or traci module) on the plan, drive, close."""
    plan = load_plan(plan_file)
    folder = plan_file.parent
    with tempfile.TemporaryDirectory(prefix="scengen-run-") as scratch:
        types = write_types(plan, folder, controller, Path(scratch) / "types.xml")
        traci.start([program, *sumo_arguments(plan, folder, types), *extra])
        try:
            return drive(traci, plan, controller, on_step, guard)
        finally:
            traci.close()


def fcd_text(rows: list[Row]) -> str:
    """The ego's rows as SUMO FCD (front bumper, angle, speed, odometer from its start)."""
    lines = ['<?xml version="1.0" encoding="UTF-8"?>', "<fcd-export>"]
    for row in rows:
        lines.append(f'    <timestep time="{row["t"]!r}">')
        lines.append(
            f'        <vehicle id="{EGO}" x="{row["x"]!r}" y="{row["y"]!r}" '
            f'angle="{row["angle"]!r}" speed="{row["speed"]!r}" odometer="{row["odometer"]!r}"/>'
        )
        lines.append("    </timestep>")
    lines.append("</fcd-export>")
    return "\n".join(lines) + "\n"


def find_program(name: str) -> str:
    """A SUMO program: the eclipse-sumo wheel's, $SUMO_HOME/bin's, or the PATH's."""
    homes = [os.environ.get("SUMO_HOME", "")]
    try:
        import sumo  # the eclipse-sumo wheel

        homes.insert(0, str(sumo.SUMO_HOME))
    except ImportError:
        pass
    for home in filter(None, homes):
        candidate = Path(home) / "bin" / name
        if candidate.exists():
            return str(candidate)
    found = shutil.which(name)
    if found is None:
        raise RunFailed(f"{name} not found: pip install eclipse-sumo, or set SUMO_HOME")
    return found


def _sumo(use_traci: bool, name: str) -> tuple[Any, str]:
    """libsumo (in this process) unless told otherwise or missing; else traci and ``name``."""
    if not use_traci:
        try:
            return importlib.import_module("libsumo"), name
        except ImportError:
            pass
    return importlib.import_module("traci"), find_program(name)


def load_guard(here: Path, plan: dict[str, Any], params_file: Path | None) -> Any:
    """The RSS guard of ``rss_guard.py`` next to this file, for this plan."""
    module = _module(here, "rss_guard.py")
    params = module.load_params(params_file) if params_file is not None else None
    return module.RssGuard(plan.get("rss") or {}, params)


def _module(here: Path, name: str) -> Any:
    """The Python file ``name`` next to this one, loaded (RunFailed when it is missing)."""
    source = here / name
    if not source.exists():
        raise RunFailed(f"{source} is missing: the bundle needs it beside run.py")
    spec = importlib.util.spec_from_file_location(source.stem, source)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[source.stem] = module  # dataclasses look their module up by name
    spec.loader.exec_module(module)
    return module


def guard_text(summary: dict[str, Any]) -> str:
    """One line on what the guard did."""
    text = (
        f"the RSS guard intervened at {summary['interventions']} of {summary['steps']} steps "
        f"({summary['braking']} braking)"
    )
    if summary.get("first"):
        first = summary["first"]
        text += f", first at {first['t']:.2f} s: {first['why']}"
    if summary.get("fallback"):
        text += f"; fell back on the time-gap rule: {summary['fallback']}"
    return text


def main(argv: list[str] | None = None) -> int:
    here = Path(__file__).resolve().parent
    parser = argparse.ArgumentParser(
        description="Replay this test-case in SUMO as `scengen evaluate` does: the non-egos "
        "follow their trajectories exactly, the ego is driven by the chosen controller; the "
        "ego's trajectory is written as SUMO FCD for `scengen check`."
    )
    parser.add_argument("--plan", type=Path, default=here / PLAN_FILE, help="the run plan")
    parser.add_argument("--controller", default="sumo", help="who drives the ego (default sumo)")
    parser.add_argument("--fcd-output", type=Path, default=Path("run.fcd.xml"), metavar="FILE")
    parser.add_argument("--rss-params", type=Path, metavar="FILE", help="RSS dynamics (JSON) "
                        "overriding CARLA's defaults, for a NAME+rss controller")  # fmt: skip
    parser.add_argument("--traci", action="store_true", help="use traci and the sumo binary, "
                        "not libsumo")  # fmt: skip
    parser.add_argument("--gui", action="store_true", help="watch it in sumo-gui (implies --traci)")
    parser.add_argument("--cosim", type=int, metavar="PORT", help="co-simulation: wait for "
                        "your driving stack as TraCI client 2 on PORT (README.md)")  # fmt: skip
    parser.add_argument("--host", default="127.0.0.1", help="--cosim's address (default "
                        "127.0.0.1: this machine only)")  # fmt: skip
    parser.add_argument(
        "--wait",
        type=float,
        default=60.0,
        metavar="SECONDS",
        help="--cosim: how long to wait for the client (default 60 s)",
    )
    parser.add_argument(
        "--budget",
        type=float,
        default=600.0,
        metavar="SECONDS",
        help="--cosim: how long the run may take (default 600 s)",
    )
    args = parser.parse_args(argv)
    try:
        plan = load_plan(args.plan)
    except (OSError, ValueError, RunFailed) as exc:
        print(f"run.py: cannot read the run plan: {exc}", file=sys.stderr)
        return 2
    if args.cosim is not None:
        cosim = _module(here, "cosim.py")
        return int(cosim.bundle_main(sys.modules[__name__], importlib.import_module("traci"),
                                     find_program("sumo"), args))  # fmt: skip
    controllers = plan["controllers"]
    if args.controller not in controllers:
        print(f"run.py: unknown controller {args.controller!r}; valid: "
              f"{', '.join(controllers)}", file=sys.stderr)  # fmt: skip
        return 2
    controller = controllers[args.controller]
    if controller["kind"] == "certificate" and not plan.get("certificates"):
        print(f"run.py: {args.controller} replays a certificate, but this test-case has none",
              file=sys.stderr)  # fmt: skip
        return 2
    guard = None
    if controller.get("guard") == "rss":
        try:
            guard = load_guard(here, plan, args.rss_params)
        except (RunFailed, ValueError) as exc:
            print(f"run.py: cannot start the RSS guard: {exc}", file=sys.stderr)
            return 2
    try:
        module, program = _sumo(args.gui or args.traci, "sumo-gui" if args.gui else "sumo")
        extra = ("--start", "--quit-on-end") if args.gui else ()
        rows, _ = run(module, args.plan, controller, program=program, extra=extra, guard=guard)
    except Exception as exc:  # SUMO's own errors: TraCIException, FatalTraCIError, ...
        print(f"run.py: SUMO failed: {exc}", file=sys.stderr)
        return 3
    args.fcd_output.write_text(fcd_text(rows))
    duration = int(plan["steps"]) * float(plan["timestep"])
    last = rows[-1]["t"] if rows else 0.0
    until = (
        f"for the whole {duration:g} s"
        if last >= duration - 1e-9
        else f"until it left at the end of its route, past its goal, at {last:.2f} s"
    )
    print(f"run.py: {args.controller} drove the ego {until}; wrote {args.fcd_output}")
    if guard is not None:
        print(f"run.py: {guard_text(guard.summary())}")
    testcase = os.path.relpath(here / "testcase.json")
    print(f"judge it: scengen check {testcase} --ego {args.fcd_output} "
          f"--controller {args.controller}")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
