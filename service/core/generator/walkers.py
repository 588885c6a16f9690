"""New pedestrians of an extension (docs/pedestrians.md): their walks checked, their ids and
starts, Step 1's walks, and what Steps 2 and 3 and the new document need of them.

A pedestrian is one more symbolic road user: Step 2 orders its events (at the curb, onto
and off its crossing, in and out of the cars' lanes) with everyone else's, Step 3 plans
its distance along its path within the walking bounds (it may wait anywhere, at the curb
first of all), and the checker verifies the result as for a car.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from service.core.checker.check import Judge
from service.core.errors import InvalidInput
from service.core.generator.ordering_facts import (
    CROSSING_PACE,
    CarKind,
    OrderingCar,
)
from service.core.generator.timing import CarPlan
from service.core.motion.events import LaneEvent, pedestrian_events
from service.core.motion.kinematics import Bounds
from service.core.motion.poses import PoseSample, PoseTrack
from service.core.motion.walking import PEDESTRIAN_START, WALK_PACE, walk_tracks
from service.core.network import Intersection, Walk
from service.core.testcase import PEDESTRIAN_LENGTH, PEDESTRIAN_WIDTH, TestCase


@dataclass(frozen=True)
class NewPedestrians:
    """The pedestrians an extension adds: their walks and ids, in the order asked."""

    walks: tuple[Walk, ...]
    ids: tuple[str, ...]

    def __bool__(self) -> bool:
        return bool(self.ids)


def validate_walks(junction: Intersection, walks: Sequence[str]) -> list[Walk]:
    """The walks asked for (UnknownWalk naming the valid ones, or how to add crossings);
    InvalidInput for a walk no car route crosses (a pedestrian there matters to no one)."""
    chosen = [junction.walk(w) for w in walks]
    for walk in chosen:
        if not walk.conflicts:
            raise InvalidInput(
                f"walk {walk.id} crosses no car route at junction {junction.junction}: a "
                "pedestrian on it can never matter to anyone"
            )
    return chosen


def new_pedestrian_ids(old: TestCase, count: int) -> list[str]:
    """``ped1``, ``ped2``, ... not yet used by a road user of ``old``."""
    used = {n.id for n in old.road_users}
    ids: list[str] = []
    k = 1
    while len(ids) < count:
        if f"ped{k}" not in used:
            ids.append(f"ped{k}")
        k += 1
    return ids


def walking_bounds(old: TestCase) -> Bounds:
    walk = old.params.walk
    return Bounds(walk.v_max, walk.a_max, walk.a_min)


def pedestrian_tracks(
    junction: Intersection, people: NewPedestrians, old: TestCase, budget: float
) -> dict[str, PoseTrack]:
    """Step 1 of every new pedestrian: its walk in SUMO from PEDESTRIAN_START metres before
    its crossing, as long as the test-case lasts."""
    if not people:
        return {}
    tracks = walk_tracks(
        junction, [(walk, PEDESTRIAN_START) for walk in people.walks], WALK_PACE,
        old.duration, old.timestep, PEDESTRIAN_LENGTH, PEDESTRIAN_WIDTH, budget,
    )  # fmt: skip
    return dict(zip(people.ids, tracks, strict=True))


def walk_events(
    samples: Sequence[PoseSample], length: float, width: float, junction: Intersection,
    walk: str, old: TestCase,
) -> list[LaneEvent]:  # fmt: skip
    """A pedestrian's events as the checker computes them."""
    walking = old.params.walk
    return pedestrian_events(samples, length, width, junction, walk, walking.arrival_distance,
                             old.params.v_stop)  # fmt: skip


def new_pedestrian_cars(
    junction: Intersection, people: NewPedestrians, tracks: dict[str, PoseTrack], old: TestCase
) -> list[OrderingCar]:
    """Step 2's road users of the new pedestrians: their crossing as a fork, its lane as
    their connecting lane, the events of their Step 1 walk."""
    cars = []
    for person, walk in zip(people.ids, people.walks, strict=True):
        track = tracks[person]
        crossing = junction.crossings[walk.crossing]
        events = walk_events(track.samples, track.length, track.width, junction, walk.id, old)
        cars.append(OrderingCar(person, CarKind.NEW, crossing.id, crossing.lane, tuple(events),
                                walker=True))  # fmt: skip
    return cars


def old_pedestrian_cars(judge: Judge, junction: Intersection) -> list[OrderingCar]:
    """Step 2's road users of the old test-case's pedestrians, with their events as the
    checker sees them."""
    found = []
    for person in judge.pedestrians:
        crossing = junction.crossings[junction.walk(person.walk).crossing]
        found.append(OrderingCar(person.id, CarKind.OLD, crossing.id, crossing.lane,
                                 tuple(person.events), walker=True))  # fmt: skip
    return found


def walker_plan(plan: CarPlan, old: TestCase) -> CarPlan:
    """A pedestrian's Step 3 plan: its knots as a car's, within the walking bounds, with no
    sign to run, crossing at CROSSING_PACE on average at least (it may wait at the curb as
    long as it likes, and it does not linger on the crosswalk)."""
    return CarPlan(plan.car, plan.knots, math.inf, None, None, plan.inside,
                   walking_bounds(old), CROSSING_PACE)  # fmt: skip


def event_rows(events: Sequence[LaneEvent]) -> list[dict[str, Any]]:
    """Lane events as a document's rows (a new car's or a new pedestrian's)."""
    return [
        {"kind": e.kind.value, "lane": e.lane, "t": round(e.time, 6),
         "distance": round(e.distance, 6)}
        for e in events
    ]  # fmt: skip


def pedestrian_rows(
    old: TestCase,
    junction: Intersection,
    people: NewPedestrians,
    samples: dict[str, list[PoseSample]],
    level: int,
    row: Any,
) -> list[dict[str, Any]]:
    """The new pedestrians as a document's rows (``row``: a sample as a document's row)."""
    rows = []
    for person, walk in zip(people.ids, people.walks, strict=True):
        trajectory = samples[person]
        events = walk_events(trajectory, PEDESTRIAN_LENGTH, PEDESTRIAN_WIDTH, junction, walk.id,
                             old)  # fmt: skip
        rows.append(
            {
                "id": person,
                "walk": walk.id,
                "length": PEDESTRIAN_LENGTH,
                "width": PEDESTRIAN_WIDTH,
                "trajectory": [row(s) for s in trajectory],
                "events": event_rows(events),
                "added_in": level,
            }
        )
    return rows
