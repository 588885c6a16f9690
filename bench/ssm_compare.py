"""Our criticality measures against SUMO's SSM device, on the same replay.

Each case replays a test-case in SUMO with the ego equipped with SUMO's SSM device
(``--device.ssm``: TTC, DRAC and PET, every value logged), judges the ego's replayed
trajectory with the checker, and prints, per other car, SUMO's extreme next to ours. Here
the ego does not leave the simulation at its goal, as it does in ``scengen evaluate``: it
drives on to the end of its route's last lane, so that SUMO's device, which the ego carries, can
log a PET whose second car enters the conflict area after the ego's goal (ours measures
it from the other car's trajectory; every other measure of ours ends at the goal).
Run with ``python -m bench.ssm_compare`` (part of ``make bench``); tests/bench/
test_ssm_compare.py checks the agreement within the tolerances of docs/criticality.md.
"""

from __future__ import annotations

import functools
import math
import tempfile
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from xml.etree import ElementTree as ET

import numpy as np

from bench.ssm_child import replay_with_ssm
from service.core.budget import run_with_budget
from service.core.checker.check import check_testcase
from service.core.checker.verdict import Verdict
from service.core.generator.extension import extend_testcase, extend_testcases
from service.core.motion.criticality import Mover, measure_series
from service.core.motion.poses import PoseSample
from service.core.sim.controllers import resolve_driver
from service.core.sim.replay import controller_spec, departures, row_sample, write_run_files
from service.core.sumo import run as sumo_run
from service.core.testcase import TestCase, load_testcase_intersection, new_testcase

SSM_FILE = "ssm.xml"


FOLLOWING = (2, 3)  # SUMO's encounter types: the ego follows, the ego leads
MERGING = (6, 7)  # SUMO's encounter types before the merge point: the ego leads, follows
NA = math.nan


@dataclass(frozen=True)
class SsmConflicts:
    """SUMO's extremes against one car, (value, time) or None, and every logged step:
    (time, encounter type, TTC, DRAC), NaN where SUMO gives none."""

    ttc: tuple[float, float] | None
    drac: tuple[float, float] | None
    pet: tuple[float, float] | None
    steps: tuple[tuple[float, int, float, float], ...] = ()


def parse_ssm(text: str) -> dict[str, SsmConflicts]:
    """SUMO's SSM output: the extremes of every conflict with each car, by car."""
    found: dict[str, list[ET.Element]] = {}
    for conflict in ET.fromstring(text).iter("conflict"):
        found.setdefault(conflict.get("foe", ""), []).append(conflict)

    def extreme(elements: list[ET.Element], tag: str, smallest: bool) -> tuple[float, float] | None:
        values = []
        for element in elements:
            item = element.find(tag)
            if item is not None and item.get("value") not in (None, "NA"):
                values.append((float(item.get("value", "nan")), float(item.get("time", "nan"))))
        if not values:
            return None
        return min(values) if smallest else max(values)

    return {
        car: SsmConflicts(
            extreme(items, "minTTC", True),
            extreme(items, "maxDRAC", False),
            extreme(items, "PET", True),
            tuple(step for item in items for step in _steps(item)),
        )
        for car, items in found.items()
    }


def _steps(conflict: ET.Element) -> list[tuple[float, int, float, float]]:
    def values(tag: str) -> list[str]:
        item = conflict.find(tag)
        return [] if item is None else item.get("values", "").split()

    def number(text: str) -> float:
        return NA if text == "NA" else float(text)

    return [
        (float(t), int(kind), number(ttc), number(drac))
        for t, kind, ttc, drac in zip(
            values("timeSpan"),
            values("typeSpan"),
            values("TTCSpan"),
            values("DRACSpan"),
            strict=True,
        )
    ]


@dataclass(frozen=True)
class Replay:
    """A replay with SSM: the ego's trajectory, our verdict on it, SUMO's conflicts."""

    testcase: TestCase
    samples: list[PoseSample]
    verdict: Verdict
    conflicts: dict[str, SsmConflicts]

    def series(self, car: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Our (times, TTC, DRAC) against ``car`` (service.core.motion.criticality)."""
        junction = load_testcase_intersection(self.testcase)
        ego = self.testcase.ego
        other = next(n for n in self.testcase.nonegos if n.id == car)
        return measure_series(
            junction,
            Mover("ego", junction.route(ego.route.id), ego.length, ego.width, self.samples),
            Mover(car, junction.route(other.route.id), other.length, other.width,
                  [PoseSample(**s.model_dump()) for s in other.trajectory]),
        )  # fmt: skip


def ssm_replay(testcase: TestCase, controller: str) -> Replay:
    """Replay ``testcase`` with ``controller`` and SSM; our verdict on the ego's replayed
    trajectory (with its criticality) and SUMO's conflicts."""
    junction = load_testcase_intersection(testcase)
    with tempfile.TemporaryDirectory(prefix="scengen-ssm-") as scratch:
        folder = Path(scratch)
        ego, others = departures(testcase, junction)
        ego = replace(ego, goal=None, arrival=None)  # on to the end of its last lane
        write_run_files(testcase, ego, others, folder, str(junction.network_file.resolve()),
                        junction)  # fmt: skip
        arguments = (str(folder / sumo_run.PLAN_FILE), controller_spec(resolve_driver(controller)),
                     str(folder / SSM_FILE))  # fmt: skip
        rows = run_with_budget(replay_with_ssm, arguments, 60.0, "the replay with SSM")
        conflicts = parse_ssm((folder / SSM_FILE).read_text())
    samples = [row_sample(row, testcase.ego.length) for row in rows]
    verdict = check_testcase(testcase, samples, controller, junction)
    return Replay(testcase, samples, verdict, conflicts)


def crossing_case() -> TestCase:
    """At the all-way stop the ego turns left and a new car comes straight from the
    opposite side (generated, seed 0)."""
    old = new_testcase("4way-stop", "S2C_1:C2W_1", duration=25.0, name="crossing")
    return extend_testcase(old, ["N2C_0:C2S_0"], seed=0, budget=60).testcase


def following_case() -> TestCase:
    """At the all-way stop a new car starts ahead of the ego on its fork (generated)."""
    old = new_testcase("4way-stop", "E2C_0:C2N_0", duration=30.0, name="following")
    return extend_testcase(old, ["E2C_0:C2W_0"], seed=0, budget=60).testcase


@functools.cache
def _merges() -> tuple[TestCase, ...]:
    """At the T's stop sign the ego turns left into C2W_0 and a new car on the major road
    goes straight into it (E2C_0:C2W_0): the first four extensions (generated, seed 0)."""
    old = new_testcase("t-stop", "S2C_0:C2W_0", duration=30.0, name="merge")
    found = extend_testcases(old, ["E2C_0:C2W_0"], count=4, seed=0, budget=120).found
    return tuple(extension.testcase for extension in found)


def merge_conflict_case() -> TestCase:
    """The ego, braking for its stop line, and the new car approach the merge point at
    once: the first extension (the new car at the line at 4.3 s)."""
    return _merges()[0]


def merge_following_case() -> TestCase:
    """The new car crawls through the junction first (at its line at 13.4 s) and the ego,
    after its stop, follows it through the merge and closes in on it: the fourth."""
    return _merges()[3]


CASES: dict[str, tuple[Callable[[], TestCase], str]] = {
    "crossing, complexity certificate": (crossing_case, "certificate:complexity"),
    "crossing, sumo": (crossing_case, "sumo"),
    "following, sumo": (following_case, "sumo"),
    "following, complexity certificate": (following_case, "certificate:complexity"),
    "merge conflict, sumo": (merge_conflict_case, "sumo"),
    "merge, following after it, sumo": (merge_following_case, "sumo"),
}


def rows_of(verdict: Verdict, conflicts: dict[str, SsmConflicts]) -> list[list[str]]:
    """Per car and measure: SUMO's value (time), ours (time)."""
    assert verdict.criticality is not None
    rows = []
    for pair in verdict.criticality.others:
        sumo = conflicts.get(pair.car, SsmConflicts(None, None, None))
        ours_pet = min(((p.value, p.t) for p in pair.pet), default=None)
        for name, theirs, mine in (
            ("TTC", sumo.ttc, None if pair.ttc is None else (pair.ttc.value, pair.ttc.t)),
            ("DRAC", sumo.drac, None if pair.drac is None else (pair.drac.value, pair.drac.t)),
            ("PET", sumo.pet, ours_pet),
        ):
            rows.append([pair.car, name, _shown(theirs), _shown(mine)])
    return rows


def _shown(found: tuple[float, float] | None) -> str:
    if found is None or not math.isfinite(found[0]):
        return "-"
    return f"{found[0]:.2f} ({found[1]:.2f} s)"


def main() -> None:
    print("# SUMO's SSM device against scengen's criticality, same replay")
    print(f"{'case':36s} {'car':5s} {'measure':8s} {'SUMO (at)':18s} scengen (at)")
    made: dict[Callable[[], TestCase], TestCase] = {}
    for name, (make, controller) in CASES.items():
        testcase = made.setdefault(make, make())
        replay = ssm_replay(testcase, controller)
        for car, measure, sumo, ours in rows_of(replay.verdict, replay.conflicts):
            print(f"{name:36s} {car:5s} {measure:8s} {sumo:18s} {ours}")


if __name__ == "__main__":
    main()
