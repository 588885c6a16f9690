"""Cars from two forks that leave into one exit lane (service.core.generator.merging): the car
behind keeps its gap there, and cars gather speed after the junction instead of crawling
out of it. Checked on the generated samples, with the exit lane's own geometry.

The case: an old car ("slow") goes straight on from the south into C2N_0 and crawls along
it at 2 m/s; the ego turns right from the east into the same lane; the new car queues
behind "slow" on its fork. Without the gap on the exit lane, every answer set's
solvability certificate ran into "slow" behind the junction (none of 60 verified)."""

from __future__ import annotations

import functools
import itertools
from collections.abc import Callable, Sequence

import numpy as np
import pytest

from service.core.generator.extension import Extension, extend_testcase
from service.core.generator.timing_curves import CRUISE
from service.core.motion.poses import PoseSample, generate_poses
from service.core.network import Intersection, load_intersection
from service.core.testcase import new_testcase
from tests.helpers import drive_with_stops, retime, with_nonegos

NET = "4way-stop"
EGO = "E2C_0:C2N_0"  # a right turn into C2N_0
NEW = "S2C_0:C2N_0"  # straight on into C2N_0 too
EXIT = "C2N_0"


@functools.cache
def junction() -> Intersection:
    return load_intersection(NET)


@functools.cache
def extension() -> Extension:
    """The ego and one new car, both into C2N_0."""
    return extend_testcase(new_testcase(NET, EGO, duration=30.0), [NEW], seed=0, budget=120)


@functools.cache
def behind_a_slow_car() -> Extension:
    (track,) = generate_poses(junction(), [(junction().route(NEW), 10.0)], 8.0, 40.0, 0.1)
    crawl = drive_with_stops([(9.5, 2.0)], cruise=4.0, start_speed=0.0, crawl=2.0)
    slow = retime(track, crawl, 40.0, 0.1)
    old = with_nonegos(new_testcase(NET, EGO, duration=40.0), [("slow", NEW, slow)])
    return extend_testcase(old, [NEW], seed=0, budget=120)


def exit_places(samples: Sequence[PoseSample], length: float) -> tuple[np.ndarray, np.ndarray]:
    """Front and rear of a car along the exit lane's centreline (0: its first point), and
    NaN where the car is not lined up on it."""
    line = junction().exit(EXIT).departure
    (x0, y0), (x1, y1) = line.coords[0], line.coords[-1]
    direction = np.array([x1 - x0, y1 - y0]) / line.length
    centres = np.array([[s.x - x0, s.y - y0] for s in samples])
    along = centres @ direction
    across = np.abs(centres @ np.array([-direction[1], direction[0]]))
    on_lane = (across < 0.5) & (along - length / 2 >= 0)
    front = np.where(on_lane, along + length / 2, np.nan)
    rear = np.where(on_lane, along - length / 2, np.nan)
    return front, rear


@pytest.mark.parametrize("made", [extension, behind_a_slow_car])
def test_a_car_behind_another_on_its_exit_lane_keeps_its_gap(
    made: Callable[[], Extension],
) -> None:
    case = made().testcase
    assert case.certificates is not None
    params = case.params
    cars = {n.id: ([PoseSample(**s.model_dump()) for s in n.trajectory], n.length)
            for n in case.nonegos}  # fmt: skip
    for name, samples in (("solvability", case.certificates.solvability),
                          ("complexity", case.certificates.complexity)):  # fmt: skip
        cars[name] = ([PoseSample(**s.model_dump()) for s in samples], case.ego.length)
    new = set(case.provenance["new_nonegos"]) | {"solvability", "complexity"}
    checked = 0
    for (name_a, (a, length_a)), (name_b, (b, length_b)) in itertools.combinations(cars.items(), 2):
        if {name_a, name_b} == {"solvability", "complexity"} or not {name_a, name_b} & new:
            continue  # alternative egos never meet; two old cars are given
        front_a, rear_a = exit_places(a, length_a)
        front_b, rear_b = exit_places(b, length_b)
        both = ~np.isnan(front_a) & ~np.isnan(front_b)
        for k in np.flatnonzero(both):
            a_ahead = front_a[k] > front_b[k]
            gap = rear_a[k] - front_b[k] if a_ahead else rear_b[k] - front_a[k]
            speed = (b if a_ahead else a)[k].speed
            needed = params.gap + params.headway * speed
            assert gap >= needed - 0.01, (name_a, name_b, a[k].t, gap, needed)
            checked += 1
    assert checked > 20  # they do share the exit lane for a while


def test_cars_gather_speed_after_their_last_event() -> None:
    """The new car and the certificates end near CRUISE of v_max, not at the speed they
    left the junction with."""
    case = extension().testcase
    assert case.certificates is not None
    cruise = CRUISE * case.params.v_max
    new = next(n for n in case.nonegos if n.id in case.provenance["new_nonegos"])
    ends = [new.trajectory[-1].speed, case.certificates.solvability[-1].speed]
    assert ends == pytest.approx([cruise, cruise], abs=0.1)
