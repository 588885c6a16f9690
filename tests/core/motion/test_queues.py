"""Queues: cars that share a fork, in the checker (the queue reading of the law, rear-end
collisions, the gap) and in the generator (a new car ahead of the ego)."""

from __future__ import annotations

import functools
import gzip
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import pytest

from service.core.checker.check import Judge, check_testcase
from service.core.checker.verdict import REAR_END
from service.core.errors import InvalidInput
from service.core.generator.extension import extend_testcase
from service.core.generator.timing_solve import BEHIND
from service.core.motion.collisions import Motion, first_collision
from service.core.motion.events import EventKind
from service.core.motion.poses import PoseSample, PoseTrack, generate_poses
from service.core.motion.queues import Follow, Places, QueueCar, follows, gap_fault
from service.core.network import Intersection, load_intersection
from service.core.testcase import TestCase, new_testcase, parse_testcase
from tests.helpers import drive_with_stops, retime, with_nonegos

NET = "4way-stop"
EGO = "E2C_0:C2N_0"  # all-way stop: every fork has a stop sign
LEAD_START = 12.0  # the car ahead starts this far before the line; the ego at 30 m


@functools.cache
def junction() -> Intersection:
    return load_intersection(NET)


@functools.cache
def tracks() -> tuple[PoseTrack, PoseTrack]:
    """Step 1 poses of the ego (30 m) and of a car ahead of it (12 m) on one route."""
    route = junction().route(EGO)
    ego, lead = generate_poses(junction(), [(route, 30.0), (route, LEAD_START)], 8.0, 30.0, 0.1)
    return ego, lead


def queue_case() -> TestCase:
    """The ego behind "lead", which stops at the line for 2 s and drives on."""
    base = new_testcase(NET, EGO, duration=30.0)
    lead = retime(
        tracks()[1],
        drive_with_stops([(LEAD_START - 0.5, 2.0)], cruise=5.0, start_speed=0.0),
        30.0,
        0.1,
    )
    return with_nonegos(base, [("lead", EGO, lead)])


def ego_drive(stops: list[tuple[float, float]], crawl: float | None = None) -> list[PoseSample]:
    return retime(tracks()[0], drive_with_stops(stops, crawl=crawl), 30.0, 0.1)


def test_a_car_behind_another_arrives_when_the_one_ahead_has_entered() -> None:
    case = queue_case()
    judge = Judge(case, junction())
    ego = judge.ego_car(ego_drive([(22.0, 8.0), (29.5, 1.5)]))  # front 8 m back, then the line
    verdict = judge.verdict(ego)
    lead = next(car for car in judge.nonegos if car.id == "lead")
    entered = next(e.time for e in lead.events if e.kind is EventKind.ENTERED)
    arrived = next(e.t for e in verdict.ego_events if e.kind == "arrived")
    assert arrived == pytest.approx(entered, abs=1e-6)  # it stood 8 m back well before
    assert verdict.passed, verdict.reasons


def _first_moving_after_stand(profile: list[PoseSample], at: float) -> float:
    stood = [s.t for s in profile if abs(s.distance - at) < 1e-6 and s.speed == 0.0]
    return max(stood)


def test_a_stop_behind_the_car_ahead_is_no_stop_at_the_line() -> None:
    """22450(a) for a queue: the ego stands 8 m back (within the arrival distance) while
    the car ahead stands at the line, and drives on when it does, following it through:
    it stopped, but never at the line (it had not arrived while a car was ahead)."""
    case = queue_case()
    lead = [PoseSample(**s.model_dump()) for s in case.nonegos[0].trajectory]
    leaves = _first_moving_after_stand(lead, LEAD_START - 0.5)
    reaches = min(s.t for s in ego_drive([(22.0, 30.0)]) if s.distance >= 22.0 - 1e-6)
    ego = ego_drive([(22.0, leaves - reaches)], crawl=3.0)  # slower than the car ahead
    verdict = check_testcase(case, ego, "ego", junction())
    assert [v.rule for v in verdict.violations] == ["stopAtSign"]
    assert not verdict.collisions
    standing = [s for s in ego if s.speed == 0.0]
    assert standing and all(s.distance == pytest.approx(22.0) for s in standing)


def test_driving_into_the_car_ahead_is_a_rear_end_collision() -> None:
    verdict = check_testcase(queue_case(), ego_drive([]), "ego", junction())
    assert [(c.other, c.kind) for c in verdict.collisions] == [("lead", REAR_END)]
    assert any("rear-end collision with lead" in reason for reason in verdict.reasons)


def test_who_is_ahead_and_where_paths_part() -> None:
    lanes = {r.id: r.connecting_lane for r in junction().routes.values()}
    left = "E2C_0:C2W_0"
    cars = [
        QueueCar("b", "E2C_0", lanes[EGO], 5.0, 1.8, 30.0, 0.0),
        QueueCar("a", "E2C_0", lanes[left], 5.0, 1.8, 12.0, 0.0),
        QueueCar("c", "E2C_0", lanes[EGO], 5.0, 1.8, 40.0, 0.0),
        QueueCar("x", "N2C_0", lanes["N2C_0:C2S_0"], 5.0, 1.8, 30.0, 0.0),
    ]
    found = {(f.leader, f.follower): f.parting for f in follows(cars, junction())}
    assert set(found) == {("a", "b"), ("a", "c"), ("b", "c")}
    assert found[("b", "c")] == float("inf")  # one route: they never part
    assert 0.0 < found[("a", "b")] < junction().connecting_lanes[lanes[EGO]].centreline.length


def test_the_gap_is_checked_at_every_sample() -> None:
    def places(distances: list[float], speed: float) -> Places:
        return Places.of(
            [PoseSample(0.1 * k, 0.0, 0.0, 0.0, speed, d) for k, d in enumerate(distances)],
            QueueCar("c", "f", "l", 5.0, 1.8, 0.0, 0.0),
        )

    follow = Follow("lead", "back", "f", float("inf"))
    lead = places([10.0, 10.0, 10.0], 0.0)
    assert gap_fault(follow, lead, places([2.9, 2.9, 2.9], 0.0), 2.0, 1.0) is None
    fault = gap_fault(follow, lead, places([2.9, 3.5, 3.5], 0.0), 2.0, 1.0)
    assert fault is not None and "0.10 s" in fault
    moving = gap_fault(follow, lead, places([1.0, 1.0, 1.0], 2.5), 2.0, 1.0)
    assert moving is not None and "4.50 m" in moving  # 2 m + 1 s x 2.5 m/s


def test_a_new_car_ahead_of_the_ego() -> None:
    """The complexity certificate fails the new test-case only by driving into the new car;
    the solvability certificate follows it at the gap, and arrives once it has entered."""
    old = new_testcase(NET, EGO, duration=45.0)
    extension = extend_testcase(old, ["E2C_0:C2W_0"], seed=0, budget=120)
    new = extension.testcase
    assert new.certificates is not None and new.provenance is not None
    assert new.provenance["complexity_certificate"]["kind"] == "rear-end"
    car = new.nonegos[0]
    car_samples = [PoseSample(**s.model_dump()) for s in car.trajectory]
    complexity = [PoseSample(**s.model_dump()) for s in new.certificates.complexity]
    solvability = [PoseSample(**s.model_dump()) for s in new.certificates.solvability]

    assert check_testcase(old, complexity, "c", junction()).passed
    failed = check_testcase(new, complexity, "c", junction())
    assert [(c.other, c.kind) for c in failed.collisions] == [(car.id, REAR_END)]
    assert not failed.violations and failed.goal_reached

    judge = Judge(new, junction())
    ego = judge.ego_car(solvability)
    verdict = judge.verdict(ego)
    assert verdict.passed, verdict.reasons
    lead = judge.nonegos[0]
    assert first_collision(Motion(solvability, 5.0, 1.8), Motion(car_samples, 5.0, 1.8)) is None
    pairs = follows([lead.in_queue, ego.in_queue], junction())
    assert [(f.leader, f.follower) for f in pairs] == [(car.id, "ego")]
    places = Places.of(car_samples, lead.in_queue), Places.of(solvability, ego.in_queue)
    assert gap_fault(pairs[0], *places, new.params.gap, new.params.headway) is None
    entered = next(e.time for e in lead.events if e.kind is EventKind.ENTERED)
    arrived = next(e.t for e in verdict.ego_events if e.kind == "arrived")
    assert arrived >= entered


def test_a_new_car_behind_the_ego_is_refused() -> None:
    old = new_testcase(NET, EGO, duration=45.0)
    with pytest.raises(InvalidInput, match="behind the ego"):
        extend_testcase(old, ["E2C_0:C2W_0"], start_distance=40.0)
    with pytest.raises(InvalidInput, match="gap"):
        extend_testcase(old, ["E2C_0:C2W_0"], start_distance=27.0)
    with pytest.raises(InvalidInput, match="one start distance per new route"):
        extend_testcase(old, ["E2C_0:C2W_0"], start_distance=[10.0, 20.0])


def _samples(rows: Sequence[Any]) -> list[PoseSample]:
    return [PoseSample(**s.model_dump()) for s in rows]


def _check_queue(
    old: TestCase, new: TestCase, fork: str, where: Intersection | None = None
) -> None:
    """Independently of the generator: the complexity certificate passes the old case and
    fails the new one, the solvability certificate passes, and on ``fork`` every car keeps
    behind every car ahead of it: no overlap at any moment, the gap at every sample, and
    it arrives only once the car ahead has entered."""
    where = where or junction()
    assert new.certificates is not None
    complexity, solvability = (
        _samples(new.certificates.complexity),
        _samples(new.certificates.solvability),
    )
    assert check_testcase(old, complexity, "c", where).passed
    assert not check_testcase(new, complexity, "c", where).passed
    assert check_testcase(new, solvability, "s", where).passed
    judge = Judge(new, where)
    queue = [car for car in judge.nonegos if car.fork == fork]
    cars = {n.id: n for n in new.nonegos}
    pairs = follows([car.in_queue for car in queue], where)
    assert len(pairs) == len(queue) * (len(queue) - 1) // 2
    by_id = {car.id: car for car in queue}
    for pair in pairs:
        first, second = by_id[pair.leader], by_id[pair.follower]
        lead, behind = _samples(cars[first.id].trajectory), _samples(cars[second.id].trajectory)
        motions = [Motion(rows, cars[c.id].length, cars[c.id].width)
                   for rows, c in ((lead, first), (behind, second))]  # fmt: skip
        assert first_collision(*motions) is None, pair
        places = Places.of(lead, first.in_queue), Places.of(behind, second.in_queue)
        assert gap_fault(pair, *places, new.params.gap, new.params.headway) is None
        entered = next(e.time for e in first.events if e.kind is EventKind.ENTERED)
        arrived = next(e.time for e in second.events if e.kind is EventKind.ARRIVED)
        assert arrived >= entered, pair


@pytest.mark.parametrize(
    ("ego", "route", "count", "duration"),
    [("E2C_1:C2S_1", "S2C_1:C2N_1", 2, 20.0), ("E2C_0:C2N_0", "S2C_0:C2N_0", 3, 30.0)],
)
def test_new_cars_queue_on_one_fork(ego: str, route: str, count: int, duration: float) -> None:
    """Two or three new cars on one free fork of the all-way stop, in one extension, each
    starting behind the one before (automatic spacing). The three leave into the ego's
    exit lane too."""
    old = new_testcase(NET, ego, duration=duration)
    new = extend_testcase(old, [route] * count, seed=0, budget=240).testcase
    assert len(new.nonegos) == count
    _check_queue(old, new, route.split(":")[0])


def test_a_new_car_joins_a_queue_of_old_cars() -> None:
    """A third car behind two old cars in line (a chain's next level on a fork in use)."""
    start = new_testcase(NET, EGO, duration=45.0)
    old = extend_testcase(start, ["S2C_0:C2N_0"] * 2, seed=0, budget=240).testcase
    new = extend_testcase(old, ["S2C_0:C2N_0"], seed=0, budget=240).testcase
    assert [n.added_in for n in new.nonegos] == [1, 1, 2]
    _check_queue(old, new, "S2C_0")


QUEUE_DATA = Path(__file__).resolve().parents[2] / "data" / "queues"


def test_a_follower_behind_a_car_that_stands_is_planned_behind_it() -> None:
    """Level 4 of a chain on the T-junction (tests/data/queues): car3 crawls to the stop
    sign of the stem and stands there. A new car behind it on the stem cannot reach its
    knots as a plan that sees car3 only at those knots has it; planned again behind car3's
    frontier, it is found (before that re-plan, none of 60 answer sets gave curves)."""
    with gzip.open(QUEUE_DATA / "t-stop-level4.json.gz") as file:
        old = parse_testcase(file.read().decode())
    t_stop = load_intersection("t-stop")
    new = extend_testcase(old, ["S2C_0:C2W_0"], seed=0, budget=240, intersection=t_stop).testcase
    assert new.provenance is not None
    assert new.provenance["timing"].endswith(BEHIND)
    _check_queue(old, new, "S2C_0", t_stop)
