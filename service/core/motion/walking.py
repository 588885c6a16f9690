"""Step 1 for people on foot: libsumo walks one pedestrian alone over its crossing.

The pedestrian walks at a constant pace (SUMO's striping model, its speed deviation off)
from its sidewalk, through the walking area at the curb, over the crossing and on along
the sidewalk after it, with the traffic light switched off: alone, it has no one to wait
for, as a car's drive in Step 1 ignores its signal. Poses are rectangle centres, as a
car's: SUMO reports a person's front and heading. Distances are metres walked along the
recorded path (its polyline), so that a pose is where the pedestrian has walked that far.

A walk starts ``start_distance`` metres of path before the pedestrian first steps onto
the crossing: the walk in SUMO begins further back on its sidewalk (up to WALK_LEAD
metres), and the poses before that point are dropped and the rest resampled at the pace,
as a car's drive that starts on internal lanes is. A walk that starts or ends on a traffic
island (no sidewalk leads there: SUMO walks no one out of a walking area against a
crossing, nor ends a walk on one) is walked straight along its crossing's line, from
WALK_LEAD metres before it: the one walk SUMO does not make.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from service.core.errors import InvalidInput, SimulationFailed
from service.core.motion.events import overlapping, rectangles
from service.core.motion.poses import DRIVE_BUDGET, DRIVER, PoseSample, PoseTrack
from service.core.network import Intersection, Walk, parsed_network
from service.core.sumo.run import front_to_centre

WALK_PACE = 1.3  # m/s: Step 1's constant walking pace (SUMO's default pedestrian walks 1.39)
WALK_LEAD = 25.0  # metres of sidewalk before the curb a walk in SUMO starts at most
PEDESTRIAN_START = 4.0  # metres of path before the crossing a new pedestrian starts, by default
WALKED_KEPT = 256


@dataclass(frozen=True)
class WalkPlan:
    """Everything the SUMO process needs to walk one pedestrian; plain data, picklable."""

    network_file: str
    edges: tuple[str, ...]  # the sidewalk before, the walking areas and the crossing, the
    # sidewalk after: given whole, so that SUMO's router cannot take another crossing
    depart_pos: float  # on the first edge
    arrival_pos: float  # on the second edge: where SUMO's walk ends
    crossing: str  # the crossing edge the walk must go over
    tls: str | None  # the junction's traffic light, switched off for the walk
    pace: float
    length: float
    width: float
    timestep: float
    steps: int  # SUMO steps at most
    reach: float  # metres of path the walk covers at least, where the sidewalk goes on
    line: tuple[tuple[float, float], ...] = ()  # a walk from an island: its straight line


def plan_walk(
    intersection: Intersection, walk: Walk, pace: float, duration: float, timestep: float,
    length: float, width: float, start_distance: float,
) -> WalkPlan:  # fmt: skip
    """The SUMO walk of ``walk``: from up to WALK_LEAD metres before the curb (at least
    ``start_distance``) on the sidewalk before it, to as far along the sidewalk after it as
    the duration allows."""
    if not walk.before or walk.after == intersection.crossings[walk.crossing].lane:
        return _from_island(intersection, walk, pace, duration, timestep, length, width)
    net = parsed_network(intersection.network_file)
    before, after = net.getLane(walk.before), net.getLane(walk.after)
    back = min(before.getLength(), max(WALK_LEAD, start_distance + 1.0))
    ahead = after.getLength()
    # A sidewalk is walked either way: towards the junction on a road into it (from the
    # lane's end) or out of it (from its start), and away from it likewise.
    into = before.getEdge().getToNode().getID() == intersection.junction
    depart = before.getLength() - back if into else back
    away = after.getEdge().getFromNode().getID() == intersection.junction
    arrival = ahead if away else 0.0
    reach = back + pace * duration + WALK_LEAD  # room for the walking area and the crossing
    steps = 3 * math.ceil(reach / (pace * timestep)) + 100  # room for SUMO's slower stretches
    edges = (before.getEdge().getID(), walk.start, walk.crossing, walk.end,
             after.getEdge().getID())  # fmt: skip
    return WalkPlan(
        network_file=str(intersection.network_file),
        edges=edges,
        depart_pos=round(depart, 6),
        arrival_pos=round(arrival, 6),
        crossing=walk.crossing,
        tls=intersection.tls,
        pace=pace,
        length=length,
        width=width,
        timestep=timestep,
        steps=steps,
        reach=reach,
    )


def _from_island(
    intersection: Intersection, walk: Walk, pace: float, duration: float, timestep: float,
    length: float, width: float,
) -> WalkPlan:  # fmt: skip
    """The straight walk of ``walk`` from a traffic island: its crossing's line, from
    WALK_LEAD metres before it to as far beyond it as the duration allows."""
    (x0, y0), (x1, y1) = walk.path.coords[0], walk.path.coords[-1]
    ux, uy = (x1 - x0) / walk.length, (y1 - y0) / walk.length
    reach = WALK_LEAD + pace * duration + 1.0
    line = ((x0 - ux * WALK_LEAD, y0 - uy * WALK_LEAD),
            (x0 + ux * (reach - WALK_LEAD), y0 + uy * (reach - WALK_LEAD)))  # fmt: skip
    steps = math.ceil(reach / (pace * timestep)) + 1
    return WalkPlan(
        str(intersection.network_file), (), 0.0, 0.0, walk.crossing, intersection.tls, pace,
        length, width, timestep, steps, reach, line,
    )  # fmt: skip


def _straight(plan: WalkPlan) -> list[PoseSample]:
    """The poses of a walk along its straight line, at the pace."""
    (x0, y0), (x1, y1) = plan.line
    span = math.hypot(x1 - x0, y1 - y0)
    heading = math.degrees(math.atan2(x1 - x0, y1 - y0)) % 360.0
    samples = []
    for k in range(plan.steps):
        walked = min(k * plan.timestep * plan.pace, span)
        share = walked / span
        samples.append(PoseSample(k * plan.timestep, x0 + share * (x1 - x0),
                                  y0 + share * (y1 - y0), heading, plan.pace, walked))  # fmt: skip
    return samples


def walk_persons(plans: Sequence[WalkPlan]) -> list[list[PoseSample]]:
    """Walk each plan in libsumo, one simulation after another, in this process."""
    import libsumo  # only here: libsumo is a per-process singleton

    return [_straight(plan) if plan.line else _walk_one(libsumo, plan) for plan in plans]


def _walk_one(traci: Any, plan: WalkPlan) -> list[PoseSample]:
    traci.start([
        "sumo", "-n", plan.network_file, "--step-length", repr(plan.timestep),
        "--no-step-log", "true", "--no-warnings", "true", "--pedestrian.model", "striping",
        "--default.speeddev", "0", "--collision.action", "none",
    ])  # fmt: skip
    try:
        if plan.tls is not None:
            traci.trafficlight.setProgram(plan.tls, "off")
        traci.vehicletype.copy("DEFAULT_PEDTYPE", "walker")
        traci.vehicletype.setLength("walker", plan.length)
        traci.vehicletype.setWidth("walker", plan.width)
        traci.vehicletype.setMaxSpeed("walker", plan.pace)
        traci.vehicletype.setSpeedDeviation("walker", 0.0)
        traci.person.add("walker", plan.edges[0], plan.depart_pos, depart=0.0, typeID="walker")
        traci.person.appendWalkingStage("walker", list(plan.edges), plan.arrival_pos,
                                        speed=plan.pace)  # fmt: skip
        return _record(traci, plan)
    except traci.TraCIException as exc:
        raise SimulationFailed(f"SUMO refused the walk: {exc}") from exc
    finally:
        traci.close()


def _record(traci: Any, plan: WalkPlan) -> list[PoseSample]:
    samples: list[PoseSample] = []
    visited: set[str] = set()
    walked = 0.0
    for step in range(plan.steps):
        traci.simulationStep()
        if "walker" not in traci.person.getIDList():
            break
        visited.add(traci.person.getRoadID("walker"))
        heading = traci.person.getAngle("walker") % 360.0
        fx, fy = traci.person.getPosition("walker")
        x, y = front_to_centre(fx, fy, heading, plan.length)
        if samples:
            walked += math.hypot(x - samples[-1].x, y - samples[-1].y)
        samples.append(PoseSample(step * plan.timestep, x, y, heading, plan.pace, walked))
        if walked >= plan.reach:
            break
    if plan.crossing not in visited:
        raise SimulationFailed(
            f"SUMO walked over {sorted(e for e in visited if e.startswith(':'))} instead of "
            f"the crossing {plan.crossing!r}"
        )
    return samples


def _onto_crossing(samples: Sequence[PoseSample], intersection: Intersection, walk: Walk,
                   length: float, width: float) -> float:  # fmt: skip
    """Metres of path walked when the rectangle first overlaps the walk's crossing."""
    crossing = intersection.crossings[walk.crossing].polygon
    rects = rectangles(np.array([s.x for s in samples]), np.array([s.y for s in samples]),
                       np.array([s.heading for s in samples]), length, width)  # fmt: skip
    inside = np.flatnonzero(overlapping(rects, crossing))
    if inside.size == 0:
        raise SimulationFailed(f"the walk {walk.id} never reached its crossing")
    return samples[int(inside[0])].distance


def _from_start(raw: Sequence[PoseSample], skip: float, pace: float, timestep: float,
                length: float, width: float) -> list[PoseSample]:  # fmt: skip
    """The walk from ``skip`` metres of path on, resampled at the pace from t = 0."""
    shifted = PoseTrack("", length, width, 0.0, tuple(raw))
    step = pace * timestep
    samples = []
    for k in range(math.floor((raw[-1].distance - skip) / step + 1e-9) + 1):
        distance = k * step
        x, y, heading = shifted.pose_at(distance + skip)
        samples.append(PoseSample(round(k * timestep, 9), x, y, heading, pace, distance))
    return samples


WALKED: dict[tuple[WalkPlan, int], tuple[PoseSample, ...]] = {}


def walk_tracks(
    intersection: Intersection,
    requests: Sequence[tuple[Walk, float]],
    pace: float,
    duration: float,
    timestep: float,
    length: float,
    width: float,
    budget: float = DRIVE_BUDGET,
) -> list[PoseTrack]:
    """Step 1 for (walk, start distance) pairs in the warm SUMO process: each pedestrian's
    poses from ``start_distance`` metres of path before it steps onto its crossing, at
    ``pace``, while its sidewalk goes on (the track's ``road``: there it leaves the map).
    A walk is a function of its plan, so one walked before in this process is not walked
    again."""
    plans = [
        plan_walk(intersection, walk, pace, duration, timestep, length, width, start)
        for walk, start in requests
    ]
    version = intersection.network_file.stat().st_mtime_ns
    missing = list(dict.fromkeys(plan for plan in plans if (plan, version) not in WALKED))
    if missing:
        walked = DRIVER.call(walk_persons, (missing,), budget, "the SUMO walk (Step 1)")
        for plan, samples in zip(missing, walked, strict=True):
            if len(WALKED) >= WALKED_KEPT:
                WALKED.pop(next(iter(WALKED)))
            WALKED[plan, version] = tuple(samples)
    tracks = []
    for (walk, start), plan in zip(requests, plans, strict=True):
        raw = WALKED[plan, version]
        onto = _onto_crossing(raw, intersection, walk, length, width)
        if start > onto + 1e-6:
            raise InvalidInput(
                f"walk {walk.id}: a start {start:g} m before the crossing is further back "
                f"than its sidewalk goes ({onto:.1f} m)"
            )
        samples = _from_start(raw, onto - start, pace, timestep, length, width)
        road = math.inf if raw[-1].distance >= plan.reach else samples[-1].distance
        tracks.append(PoseTrack(walk.id, length, width, start, tuple(samples), road))
    return tracks
