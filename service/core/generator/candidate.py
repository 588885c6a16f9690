"""An extension's candidate test-case from one order of events and its timing (Step 3).

For each order the search draws (service.core.generator.search): Step 3's timing problem
(the knots of every symbolic car, the times fixed by the old cars, who follows whom), and,
from its solution, the candidate: every curve sampled at each time step, rounded as stored
and held to the motion invariants, written into the new document with its certificates and
provenance, and verified (service.core.generator.verification). Its place in the method:
service.core.generator.extension.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from typing import Any

from service.core.checker.check import Judge
from service.core.errors import InvalidTestCase
from service.core.generator.additions import Added, Queue, car_events
from service.core.generator.following import CERTIFICATES
from service.core.generator.linear import GRID
from service.core.generator.merging import exit_followings
from service.core.generator.ordering import Ordering
from service.core.generator.ordering_facts import (
    CarKind,
    OrderingCar,
    event_groups,
    stand_distance,
    stop_symbol,
    timed_events,
)
from service.core.generator.timing import CarPlan, Following, Knot, TimingProblem, TimingSolution
from service.core.generator.verification import certificate_kind, verify_candidate
from service.core.generator.walkers import event_rows, pedestrian_rows, walker_plan
from service.core.motion.events import EventKind
from service.core.motion.invariants import ROUNDING, motion_fault
from service.core.motion.poses import PoseSample, PoseTrack
from service.core.network import Intersection
from service.core.testcase import (
    SCHEMA_WITH_PEDESTRIANS,
    TestCase,
    document_sha256,
    parse_testcase,
    testcase_level,
)


def safety_margin(old: TestCase) -> float:
    """The safety margin of every order relation: two time steps, at least 0.1 s."""
    return max(2 * old.timestep, 0.1)


def judged_candidate(
    old: TestCase,
    ordering: Ordering,
    timing: TimingSolution,
    tracks: dict[str, PoseTrack],
    junction: Intersection,
    added: Added,
    seed: int,
    tried: int,
    old_judge: Judge,
) -> tuple[str, TestCase | None]:
    """The candidate of one answer set, when its samples keep the motion invariants and the
    checker verifies it; else what is wrong with it."""
    samples = {
        car: [_rounded(s) for s in _sample(curve.at, tracks[car], old.duration, old.timestep)]
        for car, curve in timing.curves.items()
    }
    for car, rows in samples.items():
        start = old.ego.start.speed if car in ("ego", "illegal") else None
        limits = old.params.walk if car in added.people.ids else old.params
        fault = motion_fault(rows, limits, old.timestep, start)
        if fault is not None:
            return f"curves: {car} {fault}", None
    try:
        candidate = _candidate(old, junction, ordering, samples, added, seed, timing.method, tried)
    except InvalidTestCase as error:  # our own fault, never the caller's input
        return f"internal: the candidate is not a valid test-case ({error})", None
    problem, verdict = verify_candidate(old, candidate, junction, added.everyone, old_judge)
    if problem is not None:
        return f"verification: {problem}", None
    assert candidate.provenance is not None and verdict is not None
    candidate.provenance["complexity_certificate"] = certificate_kind(verdict)
    return "verified", candidate


def _plan(car: OrderingCar, ordering: Ordering, track: PoseTrack, stop_sign: bool) -> CarPlan:
    """The knots of one symbolic car: the points (time symbols) the order speaks of, where
    it arrives, enters and leaves its own lane, and a stand just before the point where it
    enters when it stops at its sign."""
    knots: list[Knot] = []
    arrival = entry = leaves = None
    used = {s for _, a, b in ordering.named for s in (a, b)}
    stops = car.car in ordering.stops
    for group in event_groups(car):
        symbol, kinds = str(group[0].symbol), {t.event.kind for t in group}
        if EventKind.ENTERED in kinds:
            stand = stand_distance(car)
            if stops and stand is not None:
                knots.append(Knot(str(stop_symbol(car.car)), _on_grid(stand), stop=True))
                knots.append(Knot(None, _on_grid(stand), stop=True))
            entry = len(knots)
        if EventKind.ARRIVED in kinds:
            arrival = len(knots)
        own_exit = any(
            t.event.kind is EventKind.LEFT_LANE and t.event.lane == car.lane for t in group
        )
        if own_exit:
            leaves = len(knots)
        if group[0].event.distance <= ROUNDING:  # an event at the start: at t = 0
            arrival = None if EventKind.ARRIVED in kinds else arrival
            continue
        if symbol in used or kinds & {EventKind.ARRIVED, EventKind.ENTERED} or own_exit:
            knots.append(Knot(symbol, _on_grid(group[0].event.distance)))
    runs = None
    if stop_sign and not stops and arrival is not None and entry is not None:
        runs = (arrival, entry)
    inside = (entry, leaves) if entry is not None and leaves is not None else None
    # No end of the road here: a car's trajectory ends where it leaves the map (_sample).
    return CarPlan(car.car, tuple(knots), math.inf, car.start_speed, runs, inside, arrival=arrival)


def _on_grid(distance: float) -> float:
    """A knot distance on Step 3's micrometre grid, rounded up: the curve passes the event
    (at most a micrometre earlier) when the knot says."""
    return math.ceil(distance * GRID - 1e-6) / GRID


def timing_problem(
    old: TestCase,
    junction: Intersection,
    cars: Sequence[OrderingCar],
    ordering: Ordering,
    tracks: dict[str, PoseTrack],
    queue: Queue,
) -> TimingProblem:
    plans = []
    fixed = []
    for car in cars:
        if car.kind is CarKind.OLD:
            fixed += [(str(t.symbol), t.event.time) for t in timed_events(car)]
            continue
        if car.walker:
            plans.append(walker_plan(_plan(car, ordering, tracks[car.car], False), old))
        else:
            sign = junction.forks[car.fork].stop_sign
            plans.append(_plan(car, ordering, tracks[car.car], sign))
        fixed += [  # events where the car starts happen at t = 0
            (str(group[0].symbol), 0.0)
            for group in event_groups(car)
            if group[0].event.distance <= ROUNDING
        ]
    rows = {n.id: tuple((s.t, s.distance, s.speed) for s in n.trajectory) for n in old.nonegos}
    lines = {name: (member.line, member.length) for name, member in queue.members.items()}
    params = old.params
    follows = _followings(old, queue, rows) + exit_followings(
        junction, cars, ordering, lines, rows, params.gap, params.headway + safety_margin(old)
    )
    plans = _leaders_first(plans, follows)
    knotted = {k.symbol for p in plans for k in p.knots}
    bounds = queue.bounds
    return TimingProblem(
        cars=tuple(plans),
        fixed=tuple(fixed),
        relations=ordering.named,
        gaps=tuple(
            (str(a), str(b), gap)
            for a, b, gap in bounds.headways
            if str(a) in knotted and str(b) in knotted
        ),
        earliest=tuple((str(s), t) for s, t in bounds.earliest if str(s) in knotted)
        + tuple((s, start + safety_margin(old)) for s, start, _ in ordering.spans if s in knotted),
        latest=tuple((str(s), t) for s, t in bounds.latest if str(s) in knotted)
        + tuple(
            (s, end - 0.001 - safety_margin(old)) for s, _, end in ordering.spans if s in knotted
        ),
        follows=follows,
        timestep=old.timestep,
        duration=old.duration,
        m=old.params.m,
        margin=safety_margin(old),
        a_min=old.params.a_min,
        a_max=old.params.a_max,
        v_stop=old.params.v_stop,
        v_run=old.params.v_run,
        crossing=old.params.v_run,
        v_max=old.params.v_max,
    )


def _leaders_first(plans: Sequence[CarPlan], follows: Sequence[Following]) -> list[CarPlan]:
    """The plans in an order that puts every symbolic leader before its followers (Step 3
    fits a follower's curve behind its leader's), else in the order given."""
    names = [plan.car for plan in plans]
    ahead = {name: {f.leader for f in follows if f.follower == name and f.leader in names}
             for name in names}  # fmt: skip
    placed: list[str] = []
    while len(placed) < len(names):
        ready = [n for n in names if n not in placed and ahead[n] <= set(placed)]
        if not ready:  # leaders in a circle: no curves can keep them all; any order
            ready = [n for n in names if n not in placed]
        placed.append(ready[0])
    by_name = {plan.car: plan for plan in plans}
    return [by_name[name] for name in placed]


def _followings(
    old: TestCase, queue: Queue, rows: dict[str, tuple[tuple[float, float, float], ...]]
) -> tuple[Following, ...]:
    """Step 3's pairs: every follow with a symbolic car (the ego's stands for both
    certificates), except the complexity certificate behind a new car (it may hit it)."""
    found = []
    for follow in queue.follows:
        for leader in CERTIFICATES if follow.leader == "ego" else (follow.leader,):
            for follower in CERTIFICATES if follow.follower == "ego" else (follow.follower,):
                a, b = queue.members[leader], queue.members[follower]
                if a.places is not None and b.places is not None:
                    continue
                if follower == "illegal" and a.car.kind is CarKind.NEW:
                    continue
                found.append(
                    Following(
                        leader,
                        follower,
                        a.line,
                        b.line,
                        a.length,
                        follow.parting,
                        old.params.gap,
                        old.params.headway + safety_margin(old),
                        rows.get(leader) or rows.get(follower) or (),
                    )
                )
    return tuple(found)


def _sample(
    at: Callable[[float], tuple[float, float]], track: PoseTrack, duration: float, timestep: float
) -> list[PoseSample]:
    """The curve at every time step while the car is on the map: a car whose front reaches
    the end of its road leaves there (as SUMO removes it), and its trajectory ends."""
    samples: list[PoseSample] = []
    for k in range(round(duration / timestep) + 1):
        t = round(k * timestep, 9)
        distance, speed = at(t)
        if distance > track.road and len(samples) >= 2:
            break
        if -ROUNDING < speed < 0:
            speed = 0.0  # float noise of a standing car
        if samples and samples[-1].distance - ROUNDING < distance < samples[-1].distance:
            distance = samples[-1].distance  # float noise, not a car backing up
        x, y, heading = track.pose_at(distance)
        samples.append(PoseSample(t, x, y, heading, speed, distance))
    return samples


def _candidate(
    old: TestCase,
    junction: Intersection,
    ordering: Ordering,
    samples: dict[str, list[PoseSample]],
    added: Added,
    seed: int,
    method: str,
    tried: int,
) -> TestCase:
    document: dict[str, Any] = old.model_dump(mode="json", by_alias=True, exclude_none=True)
    level = 1 + testcase_level(old)
    ids = added.everyone
    for car_id, route in zip(added.ids, added.routes, strict=True):
        trajectory = samples[car_id]
        events = car_events(trajectory, old.ego.length, old.ego.width, junction, route.fork, old)
        document["nonegos"].append(
            {
                "id": car_id,
                "route": {"fork": route.fork, "exit": route.exit},
                "length": old.ego.length,
                "width": old.ego.width,
                "trajectory": [_row(s) for s in trajectory],
                "events": event_rows(events),
                "added_in": level,
            }
        )
    if added.people:
        document["schema"] = SCHEMA_WITH_PEDESTRIANS
        document.setdefault("pedestrians", []).extend(
            pedestrian_rows(old, junction, added.people, samples, level, _row)
        )
    document["certificates"] = {
        "complexity": [_row(s) for s in samples["illegal"]],
        "solvability": [_row(s) for s in samples["ego"]],
    }
    document["provenance"] = {
        "parent": document_sha256(old),
        "level": level,
        "new_nonegos": list(ids),
        "seed": seed,
        "answer_sets_tried": tried,
        "timing": method,
        "complexity_certificate_violates": [
            {"car": car, "rule": rule} for car, rule in ordering.violated if car in ids
        ],
        "order": ordering.describe(),
        "stops": sorted(ordering.stops),
    }
    return parse_testcase(document)


def _rounded(sample: PoseSample) -> PoseSample:
    """The sample as it is stored: six decimals (a micrometre), heading in [0, 360)."""
    t, x, y, heading, speed, distance = (round(v, 6) + 0.0 for v in _fields_of(sample))  # no -0.0
    return PoseSample(t, x, y, heading % 360.0, speed, distance)


def _fields_of(sample: PoseSample) -> tuple[float, float, float, float, float, float]:
    """The sample's fields in their order (dataclasses.astuple deep-copies: slow here)."""
    return sample.t, sample.x, sample.y, sample.heading, sample.speed, sample.distance


def _row(sample: PoseSample) -> dict[str, float]:
    """The sample as a document's row (dataclasses.asdict, without its deep copies)."""
    return dict(zip(_SAMPLE_FIELDS, _fields_of(sample), strict=True))


_SAMPLE_FIELDS = tuple(f.name for f in dataclasses.fields(PoseSample))
