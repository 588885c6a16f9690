"""Verification of an extension's candidate by the checker: the method's last step.

A candidate that Step 3's curves make (service.core.generator.candidate) is returned only
when the checker verifies it: the solvability certificate passes the new test-case; the
complexity certificate passes the old one and fails the new one only by a new road user's
right-of-way (or by driving into a new car ahead of it); the new road users keep the rules
Step 2 holds them to and collide with nothing; every follower in a queue with a new car or
the solvability certificate keeps its gap. Also the check of the old test-case that an
extension starts from (``checked_judge``), and which kind of complexity certificate a
verdict shows. Its place in the method: service.core.generator.extension.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from service.core.checker.check import Car, Judge
from service.core.checker.rules import people_laws
from service.core.checker.verdict import REAR_END, Verdict, Violation
from service.core.errors import InvalidTestCase
from service.core.motion.collisions import Motion, first_collision
from service.core.motion.poses import PoseSample, check_start_speed, plan_drive
from service.core.motion.queues import Places, follows, gap_fault
from service.core.network import Intersection
from service.core.testcase import TestCase


def checked_judge(old: TestCase, junction: Intersection) -> Judge:
    """The checker of ``old``, once its own solvability certificate passed it and its ego
    starts within its lane's speed limit, where SUMO can insert it (InvalidTestCase if
    not)."""
    ego = old.ego
    plan = plan_drive(
        junction, junction.route(ego.route.id), ego.start.distance, max(ego.start.speed, 1.0),
        old.duration, old.timestep, ego.length, ego.width,
    )  # fmt: skip
    check_start_speed(junction, plan, ego.start.speed)
    judge = Judge(old, junction)
    _check_old(old, judge)
    return judge


def _check_old(old: TestCase, judge: Judge) -> None:
    if old.certificates is None:
        return
    samples = [PoseSample(**s.model_dump()) for s in old.certificates.solvability]
    verdict = judge.verdict(samples, "solvability certificate")
    if not verdict.passed:
        raise InvalidTestCase(
            "the old test-case fails its own checks: its solvability certificate "
            + "; ".join(verdict.reasons)
        )


def _binds_new(violation: Violation, junction: Intersection) -> bool:
    """Whether Step 2 holds a new road user to the rule it broke: at a signal every rule
    (a new car obeys its light), elsewhere those of people on foot (theirs, and 21951 of
    the cars): at a sign a new car stops or does not, Step 2's choice, as without them."""
    return junction.signals is not None or violation.rule in people_laws(junction.control)


def verify_extension(
    old: TestCase,
    new: TestCase,
    junction: Intersection,
    ids: Sequence[str],
    old_judge: Judge | None = None,
) -> str | None:
    """None when the candidate is verified, else what is wrong (``old_judge``: the
    checker of ``old``, when the caller has it)."""
    return verify_candidate(old, new, junction, ids, old_judge)[0]


def verify_candidate(
    old: TestCase,
    new: TestCase,
    junction: Intersection,
    ids: Sequence[str],
    old_judge: Judge | None,
) -> tuple[str | None, Verdict | None]:
    """What is wrong with the candidate (None: verified), and the verdict of its
    complexity certificate in it once that was judged."""
    assert new.certificates is not None
    old_judge = old_judge or Judge(old, junction)
    new_judge = Judge(new, junction, known=old_judge)
    solvability = new_judge.ego_car(
        [PoseSample(**s.model_dump()) for s in new.certificates.solvability]
    )
    verdict = new_judge.verdict(solvability, "solvability")
    if not verdict.passed:
        reasons = "; ".join(verdict.reasons)
        return f"solvability certificate fails the new test-case: {reasons}", None
    if late := _after_goal(verdict):
        return f"solvability certificate {late} in the new test-case", None
    complexity = old_judge.ego_car(
        [PoseSample(**s.model_dump()) for s in new.certificates.complexity]
    )
    verdict = old_judge.verdict(complexity, "complexity")
    if not verdict.passed:
        reasons = "; ".join(verdict.reasons)
        return f"complexity certificate fails the old test-case: {reasons}", None
    if late := _after_goal(verdict):
        return f"complexity certificate {late} in the old test-case", None
    verdict = new_judge.verdict(complexity, "complexity")
    if verdict.passed:
        return "complexity certificate passes the new test-case", verdict
    if not verdict.goal_reached:
        reasons = "; ".join(verdict.reasons)
        return f"complexity certificate fails the new test-case otherwise: {reasons}", verdict
    if any(c.other not in ids or c.kind != REAR_END for c in verdict.collisions):
        problem = "complexity certificate collides with a car other than a new car ahead of it"
        return problem, verdict
    if late := _after_goal(verdict):
        return f"complexity certificate {late} in the new test-case", verdict
    if any(v.other not in ids for v in verdict.violations):
        return "complexity certificate breaks a rule besides a new car's right-of-way", verdict
    people = {p.id for p in new.pedestrians}
    for car_id in ids:  # new road users obey the rules Step 2 holds them to
        broken = [v for v in new_judge.rules_broken_by(car_id) if _binds_new(v, junction)]
        if broken:
            laws = ", ".join(f"{v.rule} ({v.law})" for v in broken)
            return f"{car_id} breaks {laws}", verdict
    motions = {
        n.id: Motion([PoseSample(**s.model_dump()) for s in n.trajectory], n.length, n.width)
        for n in new.road_users
    }
    for car_id in ids:
        for other, motion in motions.items():
            if other == car_id or (other in ids and other < car_id):
                continue
            if car_id in people and other in people:  # people on foot step round each other
                continue
            hit = first_collision(motions[car_id], motion)
            if hit is not None:
                return f"{car_id} collides with {other} at {hit.time:.2f} s", verdict
    return _gaps_kept(new, new_judge, solvability, junction, ids), verdict


def _after_goal(verdict: Verdict) -> str | None:
    """What a certificate does after its goal that a certificate must not, in words (None:
    nothing). The pass-fail criteria end with the goal, so the verdict only keeps it as
    information; a certificate still collides with no car and breaks no rule over its
    whole trajectory (design, section 2), and the complexity certificate's one binding
    rear-end collision is judged: before its goal."""
    if verdict.after_goal_collisions:
        first = verdict.after_goal_collisions[0]
        return f"collides with {first.other} at {first.t:.2f} s, after its goal"
    if verdict.after_goal_violations:
        return f"breaks {verdict.after_goal_violations[0].rule} after its goal"
    return None


def _gaps_kept(
    new: TestCase, judge: Judge, solvability: Car, junction: Intersection, ids: Sequence[str]
) -> str | None:
    """What is wrong with the gaps in the queues that a new car or the solvability
    certificate is in (None: every follower keeps its gap)."""
    cars = {car.id: car for car in (solvability, *judge.nonegos)}
    checked = {*ids, solvability.id}
    for follow in follows([car.in_queue for car in cars.values()], junction):
        if not checked & {follow.leader, follow.follower}:
            continue
        leader, follower = cars[follow.leader], cars[follow.follower]
        fault = gap_fault(
            follow,
            Places.of(leader.samples, leader.in_queue),
            Places.of(follower.samples, follower.in_queue),
            new.params.gap,
            new.params.headway,
        )
        if fault is not None:
            name = "the solvability certificate" if follower.id == solvability.id else None
            return f"{name or follower.id} does not keep its gap: {fault}"
    return None


def certificate_kind(verdict: Verdict) -> dict[str, Any]:
    """The kind of complexity certificate its verdict in the new test-case shows."""
    hit = sorted({c.other for c in verdict.collisions})
    return {
        "kind": "rear-end" if hit else "right-of-way",
        "right_of_way": sorted({v.other for v in verdict.violations if v.other}),
        "rear_end": hit,
    }
