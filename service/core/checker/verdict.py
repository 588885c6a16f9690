"""The checker's verdict as data: JSON and a JUnit XML test case."""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from typing import Any
from xml.etree import ElementTree as ET

VERDICT_SCHEMA = "scengen/verdict/1"


@dataclass(frozen=True)
class EventRef:
    """An event a violation rests on: whose, which, where and when."""

    car: str
    kind: str
    lane: str
    t: float


@dataclass(frozen=True)
class Violation:
    """A rule the ego broke; ``other`` is the car whose right-of-way it violated, if any."""

    rule: str
    law: str  # California Vehicle Code section, e.g. "21800(a)"
    other: str | None
    events: tuple[EventRef, ...]

    def describe(self) -> str:
        times = ", ".join(f"{e.car} {e.kind} {e.lane} at {e.t:.2f} s" for e in self.events)
        against = f" of {self.other}" if self.other else ""
        return f"violated CVC {self.law} ({self.rule}){against}: {times}"


REAR_END = "rear-end"
CROSSING = "crossing"


@dataclass(frozen=True)
class CollisionRecord:
    other: str
    t: float
    x: float
    y: float
    kind: str = CROSSING  # REAR_END: two cars of one fork, one drove into the other

    def describe(self) -> str:
        what = "rear-end collision with" if self.kind == REAR_END else "collided with"
        return f"{what} {self.other} at {self.t:.2f} s at ({self.x:.1f}, {self.y:.1f})"


@dataclass(frozen=True)
class Verdict:
    """Pass or fail, and every reason: goal, collisions, violations."""

    testcase: str
    controller: str
    goal_reached: bool
    goal_time: float | None
    collisions: tuple[CollisionRecord, ...] = ()
    violations: tuple[Violation, ...] = ()
    ego_events: tuple[EventRef, ...] = field(default=(), repr=False)
    duration: float = 0.0
    errors: tuple[str, ...] = ()  # what stopped the ego's controller (an evaluation)

    @property
    def passed(self) -> bool:
        return self.goal_reached and not self.collisions and not self.violations and not self.errors

    @property
    def reasons(self) -> list[str]:
        found = list(self.errors)
        if not self.goal_reached:
            found.append(
                f"did not reach its exit lane, out of the junction, within {self.duration:g} s"
            )
        found += [c.describe() for c in self.collisions]
        found += [v.describe() for v in self.violations]
        return found

    def to_dict(self) -> dict[str, Any]:
        data = asdict(self)
        data = {"schema": VERDICT_SCHEMA, "passed": self.passed, **data}
        data["goal"] = {"reached": data.pop("goal_reached"), "time": data.pop("goal_time")}
        data["reasons"] = self.reasons
        return data

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), indent=2) + "\n"

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Verdict:
        """The verdict ``to_dict`` wrote (a stored evaluation read back)."""

        def events(items: Sequence[dict[str, Any]]) -> tuple[EventRef, ...]:
            return tuple(EventRef(**item) for item in items)

        return cls(
            testcase=data["testcase"],
            controller=data["controller"],
            goal_reached=data["goal"]["reached"],
            goal_time=data["goal"]["time"],
            collisions=tuple(CollisionRecord(**item) for item in data["collisions"]),
            violations=tuple(
                Violation(v["rule"], v["law"], v["other"], events(v["events"]))
                for v in data["violations"]
            ),
            ego_events=events(data["ego_events"]),
            duration=data["duration"],
            errors=tuple(data["errors"]),
        )

    def to_junit(self) -> str:
        """One JUnit test case: name = test-case / controller, failure = the reasons."""
        return junit_report([self])


def junit_report(
    verdicts: Sequence[Verdict],
    suite_name: str = "scengen",
    errors: Sequence[tuple[str, str]] = (),
    skipped: Sequence[str] = (),
) -> str:
    """One JUnit test suite with a test case per verdict (test-case / controller), one per
    evaluation that could not run (``errors``: name and why) and one per skipped cell."""
    failed = sum(1 for v in verdicts if not v.passed)
    suite = ET.Element(
        "testsuite",
        name=suite_name,
        tests=str(len(verdicts) + len(errors) + len(skipped)),
        failures=str(failed),
        errors=str(len(errors)),
        skipped=str(len(skipped)),
    )
    for verdict in verdicts:
        case = ET.SubElement(
            suite,
            "testcase",
            classname="scengen.check",
            name=f"{verdict.testcase} / {verdict.controller}",
        )
        if not verdict.passed:
            failure = ET.SubElement(case, "failure", message="; ".join(verdict.reasons))
            failure.text = "\n".join(verdict.reasons)
    for name, why in errors:
        case = ET.SubElement(suite, "testcase", classname="scengen.check", name=name)
        ET.SubElement(case, "error", message=why).text = why
    for name in skipped:
        case = ET.SubElement(suite, "testcase", classname="scengen.check", name=name)
        ET.SubElement(case, "skipped", message="the test-case has no certificate to replay")
    root = ET.Element("testsuites")
    root.append(suite)
    ET.indent(root)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, "unicode") + "\n"
