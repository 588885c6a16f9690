"""The checker's verdict as data: JSON, and JUnit XML test cases and reports.

A test-case's judgement ends when the ego has reached its goal (on its exit lane, its whole
rectangle out of the junction), or at the duration when it never does: ``judged_until``.
Collisions and rule violations after that moment are kept apart (``after_goal_*``, in the
JSON ``after_goal``), as information: they are not reasons, never fail the ego, and JUnit
reports them nowhere as failures. So are the rules a pedestrian breaks (21950 (b), 21456:
``pedestrians_broke``, in the JSON only when there are some): they are not the ego's.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from typing import Any
from xml.etree import ElementTree as ET

from service.core.motion.criticality_records import Criticality

VERDICT_SCHEMA = "scengen/verdict/1"
NOT_REACHED = "did not reach its exit lane"  # a verdict's reason when the goal was not reached


@dataclass(frozen=True)
class EventRef:
    """An event a violation rests on: whose, which, where and when."""

    car: str
    kind: str
    lane: str
    t: float


# The rules that give a pedestrian the right-of-way (asp/laws: cvc21950.lp, cvc21951.lp,
# and the signal laws cvc21451.lp, cvc21453.lp): their ``other`` is a person on foot.
RIGHTS_OF_PEDESTRIANS = frozenset(
    {
        "yieldToPedestrian",
        "passesCarStoppedForPedestrian",
        "yieldToPedestrianOnGreen",
        "yieldToPedestrianOnArrow",
        "yieldToPedestrianOnRightOnRed",
    }
)


@dataclass(frozen=True)
class Violation:
    """A rule the ego broke; ``other`` is the car, or the pedestrian (a rule of
    RIGHTS_OF_PEDESTRIANS), whose right-of-way it violated, if any."""

    rule: str
    law: str  # California Vehicle Code section, e.g. "21800(a)"
    other: str | None
    events: tuple[EventRef, ...]

    def describe(self) -> str:
        times = ", ".join(f"{e.car} {e.kind} {e.lane} at {e.t:.2f} s" for e in self.events)
        whose = "pedestrian " if self.rule in RIGHTS_OF_PEDESTRIANS else ""
        against = f" of {whose}{self.other}" if self.other else ""
        return f"violated CVC {self.law} ({self.rule}){against}: {times}"


@dataclass(frozen=True)
class RoadUserViolation:
    """A rule a pedestrian broke (a rule of the pedestrian: ``violation.other`` is None):
    information in the ego's verdict, never its failure."""

    by: str
    violation: Violation

    def describe(self) -> str:
        return f"pedestrian {self.by} (not the ego's failure) {self.violation.describe()}"


REAR_END = "rear-end"
CROSSING = "crossing"
PEDESTRIAN = "pedestrian"  # the ego and a person on foot


@dataclass(frozen=True)
class CollisionRecord:
    other: str
    t: float
    x: float
    y: float
    kind: str = CROSSING  # REAR_END: two cars of one fork, one drove into the other;
    # PEDESTRIAN: the ego and a person on foot

    def describe(self) -> str:
        what = {REAR_END: "rear-end collision with", PEDESTRIAN: "collided with pedestrian"}.get(
            self.kind, "collided with"
        )
        return f"{what} {self.other} at {self.t:.2f} s at ({self.x:.1f}, {self.y:.1f})"


@dataclass(frozen=True)
class Verdict:
    """Pass or fail, and every reason: goal, collisions, violations until the judgement
    ends (``judged_until``); and, apart, the collisions and violations after the goal."""

    testcase: str
    controller: str
    goal_reached: bool
    goal_time: float | None
    collisions: tuple[CollisionRecord, ...] = ()
    violations: tuple[Violation, ...] = ()
    ego_events: tuple[EventRef, ...] = field(default=(), repr=False)
    duration: float = 0.0
    errors: tuple[str, ...] = ()  # what stopped the ego's controller (an evaluation)
    criticality: Criticality | None = None  # how close it came (None: not measured)
    # a guarded controller's record (service.core.sumo.rss_guard: kind, steps,
    # interventions, braking, by_car, fallback, first, spans); None: no guard (not hashed)
    guard: dict[str, Any] | None = field(default=None, hash=False)

    # after the judgement ended (the goal): information, not failures (module docstring)
    after_goal_collisions: tuple[CollisionRecord, ...] = ()
    after_goal_violations: tuple[Violation, ...] = ()
    # the rules the test-case's pedestrians broke: information, not the ego's failure
    pedestrians_broke: tuple[RoadUserViolation, ...] = ()

    @property
    def passed(self) -> bool:
        """Whether the ego passed: only what happened until ``judged_until`` counts."""
        return self.goal_reached and not self.collisions and not self.violations and not self.errors

    @property
    def judged_until(self) -> float:
        """When the judgement ends: the goal's time, or the duration when it was missed."""
        return self.goal_time if self.goal_time is not None else self.duration

    @property
    def information(self) -> list[str]:
        """What happened after the judgement ended, in words: not judged, shown for
        information."""
        records = [c.describe() for c in self.after_goal_collisions]
        records += [v.describe() for v in self.after_goal_violations]
        when = "after its goal" if self.goal_reached else "after the duration"
        found = [f"{when} (not judged): {record}" for record in records]
        return found + [broken.describe() for broken in self.pedestrians_broke]

    @property
    def reasons(self) -> list[str]:
        found = list(self.errors)
        if not self.goal_reached:
            found.append(f"{NOT_REACHED}, out of the junction, within {self.duration:g} s")
        found += [c.describe() for c in self.collisions]
        found += [v.describe() for v in self.violations]
        return found

    def to_dict(self) -> dict[str, Any]:
        data = asdict(self)
        data = {"schema": VERDICT_SCHEMA, "passed": self.passed, **data}
        data["goal"] = {"reached": data.pop("goal_reached"), "time": data.pop("goal_time")}
        data["judged_until"] = self.judged_until
        data["after_goal"] = {
            "collisions": data.pop("after_goal_collisions"),
            "violations": data.pop("after_goal_violations"),
        }
        if not self.pedestrians_broke:
            del data["pedestrians_broke"]  # as before pedestrians: no key
        data["reasons"] = self.reasons
        data["information"] = self.information
        data["criticality"] = None if self.criticality is None else self.criticality.to_dict()
        return data

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), indent=2) + "\n"

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Verdict:
        """The verdict ``to_dict`` wrote (a stored evaluation read back)."""

        def events(items: Sequence[dict[str, Any]]) -> tuple[EventRef, ...]:
            return tuple(EventRef(**item) for item in items)

        def violations(items: Sequence[dict[str, Any]]) -> tuple[Violation, ...]:
            return tuple(
                Violation(v["rule"], v["law"], v["other"], events(v["events"])) for v in items
            )

        after = data.get("after_goal") or {}  # none in verdicts stored before it was kept
        return cls(
            testcase=data["testcase"],
            controller=data["controller"],
            goal_reached=data["goal"]["reached"],
            goal_time=data["goal"]["time"],
            collisions=tuple(CollisionRecord(**item) for item in data["collisions"]),
            violations=violations(data["violations"]),
            ego_events=events(data["ego_events"]),
            duration=data["duration"],
            errors=tuple(data["errors"]),
            criticality=(
                Criticality.from_dict(data["criticality"]) if data.get("criticality") else None
            ),
            guard=data.get("guard"),
            after_goal_collisions=tuple(
                CollisionRecord(**item) for item in after.get("collisions", ())
            ),
            after_goal_violations=violations(after.get("violations", ())),
            pedestrians_broke=tuple(
                RoadUserViolation(item["by"], violations([item["violation"]])[0])
                for item in data.get("pedestrians_broke", ())
            ),
        )

    def to_junit(self) -> str:
        """One JUnit test case: name = test-case / controller, failure = the reasons."""
        return junit_report([self])


OUTCOMES = ("failure", "error", "skipped")  # of a JUnit test case that did not pass


@dataclass(frozen=True)
class JUnitCase:
    """One JUnit test case: ``outcome`` passed, failure (the ego failed), error (it could not
    be judged) or skipped, with ``message`` saying why in plain words."""

    classname: str
    name: str
    outcome: str = "passed"
    message: str = ""
    details: str = ""  # the element's text (default: the message)
    properties: tuple[tuple[str, str], ...] = ()  # <properties> of the test case


def criticality_properties(verdict: Verdict) -> tuple[tuple[str, str], ...]:
    """The overall criticality as JUnit properties: ``criticality.ttc`` (its value) with
    ``criticality.ttc.car`` and ``.t``, the same for pet (and ``.area``), drac, distance."""
    if verdict.criticality is None:
        return ()
    return overall_properties(verdict.criticality.to_dict()["overall"])


def overall_properties(overall: dict[str, Any]) -> tuple[tuple[str, str], ...]:
    """JUnit properties of a criticality's ``overall`` (as in the verdict's JSON)."""
    found = []
    for name, extreme in overall.items():
        if extreme is not None:
            found.append((f"criticality.{name}", f"{extreme['value']:g}"))
            found.append((f"criticality.{name}.car", extreme["car"]))
            found.append((f"criticality.{name}.t", f"{extreme['t']:g}"))
            if "area" in extreme:
                found.append((f"criticality.{name}.area", extreme["area"]))
    return tuple(found)


def verdict_case(
    verdict: Verdict, name: str | None = None, classname: str = "scengen.check"
) -> JUnitCase:
    """The test case of a verdict: named ``name``, by default ``test-case / controller``;
    a failure lists the reasons (never what happened after the goal: information)."""
    label = name or f"{verdict.testcase} / {verdict.controller}"
    properties = criticality_properties(verdict)
    if verdict.passed:
        return JUnitCase(classname, label, properties=properties)
    reasons = verdict.reasons
    return JUnitCase(
        classname, label, "failure", "; ".join(reasons), "\n".join(reasons), properties
    )


def junit_report(
    verdicts: Sequence[Verdict],
    suite_name: str = "scengen",
    errors: Sequence[tuple[str, str]] = (),
    skipped: Sequence[str] = (),
    not_run: Sequence[str] = (),
) -> str:
    """One JUnit test suite with a test case per verdict (test-case / controller), one per
    evaluation that could not run (``errors``: name and why), one per skipped cell and one
    per evaluation never started (``not_run``: the run was interrupted)."""
    cases = [verdict_case(verdict) for verdict in verdicts]
    cases += [JUnitCase("scengen.check", name, "error", why) for name, why in errors]
    cases += [
        JUnitCase("scengen.check", name, "skipped", "the test-case has no certificate to replay")
        for name in skipped
    ]
    cases += [
        JUnitCase("scengen.check", name, "skipped", "not run: the evaluation was interrupted")
        for name in not_run
    ]
    return junit_document(cases, suite_name)


def junit_document(cases: Sequence[JUnitCase], suite_name: str) -> str:
    """JUnit XML: one test suite of ``cases``, counted by outcome."""
    counts = {kind: sum(1 for c in cases if c.outcome == kind) for kind in OUTCOMES}
    suite = ET.Element(
        "testsuite",
        name=suite_name,
        tests=str(len(cases)),
        failures=str(counts["failure"]),
        errors=str(counts["error"]),
        skipped=str(counts["skipped"]),
    )
    for case in cases:
        element = ET.SubElement(suite, "testcase", classname=case.classname, name=case.name)
        if case.properties:
            listed = ET.SubElement(element, "properties")
            for name, value in case.properties:
                ET.SubElement(listed, "property", name=name, value=value)
        if case.outcome != "passed":
            detail = ET.SubElement(element, case.outcome, message=case.message)
            if case.outcome != "skipped":
                detail.text = case.details or case.message
    root = ET.Element("testsuites")
    root.append(suite)
    ET.indent(root)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, "unicode") + "\n"
