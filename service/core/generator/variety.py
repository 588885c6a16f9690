"""When two extensions are the same test-case, and where in an order's timings to aim.

A test-case is its cars' trajectories; its certificates only prove what it is. So two
extensions of one test-case are the same when they add cars on the same routes that
either both stop at their sign or both do not, keep the same order of events among the
cars of the test-case (Step 2's relations without the certificates' events: orders that
differ only in how the ego could drive make the same test), and every new car arrives at
its line and enters the junction within DISTINCT_GAP seconds of its counterpart; else
they are distinct. Extensions of different test-cases are always distinct (they keep
their parents' cars). The signature is read from the test-case itself (its provenance and
its new cars' events), so test-cases from a store, a campaign or another process compare
the same way.

Within one order, the timings differ by when the new cars arrive at their line and enter
the junction: Step 3 can aim at a point of each new car's window of entry times
(``timing.entry_window``) and, given that entry, of its window of arrival times.
``AIMS`` lists the entry points, as shares of the window, in the order they are tried: the
ends first, then halves, quarters and eighths, so any first k spread over the window. A
seed picks a point of ``seed_aim``'s sequence, so that seeds 1, 2, 3, ... land on points
apart. ``--count`` goes on over both windows at once (``aim_points``) until it has its
test-cases or its count of points runs out.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from service.core.names import MAX_COUNT as MAX_COUNT  # the CLI's, API's and batches' limit
from service.core.testcase import MAX_NAME_LENGTH, Pedestrian, TestCase, testcase_level

DISTINCT_GAP = 1.0  # seconds: new cars entering the junction this far apart make a new test-case
AIMS = (0.0, 1.0, 0.5, 0.25, 0.75, 0.125, 0.375, 0.625, 0.875)  # shares of the entry window
AIM_POINTS = 256  # points of the timings --count looks at, at most (a count)
# ... over all the orders alike to the verified ones (each point costs a window's program)
ALIKE_POINTS = 2 * AIM_POINTS
LATTICE = 1.02  # entries aimed this many DISTINCT_GAPs apart are distinct test-cases
AimPoint = tuple[float, float | None]  # (share of the entry window, of the arrival window)


def aim_points(step: float | None = None) -> list[AimPoint]:
    """Where ``--count`` aims in the timings of an order, in turn. With ``step`` (the share
    of the entry window that LATTICE x DISTINCT_GAP seconds make): the entry at every
    multiple of it, the halves of the window first, so that as many entries as the window
    holds DISTINCT_GAP apart are aimed at; without: the points of AIMS. The arrival as the
    plan has it for these; then the points of the Halton sequence over the entry window
    and the window of arrival times that the aimed entry leaves (bases 2 and 3).
    AIM_POINTS in all (points near a test-case already found are passed over without
    solving)."""
    points: list[AimPoint] = []
    if step is not None and 0 < step < 1:
        last = math.floor(1 / step)
        multiples: dict[int, None] = {}
        k = 0
        while len(multiples) < last + 1:
            multiples.setdefault(round(_radical_inverse(k, 2) * last), None)
            k += 1
        points += [(j * step, None) for j in multiples]
    else:
        points += [(aim, None) for aim in AIMS]
    points += joint_points(AIM_POINTS - len(points))
    return points[:AIM_POINTS]


def joint_points(count: int = AIM_POINTS) -> list[AimPoint]:
    """The first ``count`` points of the Halton sequence (bases 2 and 3) over the entry
    window and the window of arrival times that the aimed entry leaves: inside both
    windows, spread over them jointly."""
    return [(_radical_inverse(n, 2), _radical_inverse(n, 3)) for n in range(1, count + 1)]


def _radical_inverse(n: int, base: int) -> float:
    """The van der Corput point of ``n`` in ``base`` (the digits of n mirrored)."""
    point, scale = 0.0, 1.0 / base
    while n:
        n, digit = divmod(n, base)
        point += digit * scale
        scale /= base
    return point


@dataclass(frozen=True)
class Signature:
    """What tells one extension from another: the parent, each new car (its route, whether
    it stops at its sign, when it arrives at its line and enters the junction), and the
    order of events among the test-case's cars."""

    parent: str | None
    level: int
    cars: tuple[NewCar, ...]  # by id
    order: tuple[str, ...]  # relations without the certificates' events

    def same_as(self, other: Signature, gap: float = DISTINCT_GAP) -> bool:
        if (self.parent, self.level, self.order) != (other.parent, other.level, other.order):
            return False
        if [c.kind for c in self.cars] != [c.kind for c in other.cars]:
            return False
        return all(
            abs(a.arrival - b.arrival) < gap and abs(a.entry - b.entry) < gap
            for a, b in zip(self.cars, other.cars, strict=True)
        )

    def to_dict(self) -> dict[str, Any]:
        """The signature as JSON (a campaign keeps it beside each level)."""
        return {
            "parent": self.parent,
            "level": self.level,
            "cars": [dataclasses.asdict(car) for car in self.cars],
            "order": list(self.order),
        }

    @classmethod
    def from_dict(cls, document: Mapping[str, Any]) -> Signature:
        """The signature ``to_dict`` wrote."""
        cars = tuple(NewCar(**car) for car in document["cars"])
        return cls(document["parent"], document["level"], cars, tuple(document["order"]))


@dataclass(frozen=True)
class NewCar:
    """A new car as its signature sees it (times in seconds; its last event's time when it
    never arrives or never enters)."""

    car: str
    route: str  # FORK:EXIT, or a pedestrian's walk
    stops: bool
    arrival: float
    entry: float

    @property
    def kind(self) -> tuple[str, str, bool]:
        return self.car, self.route, self.stops


def signature(testcase: TestCase) -> Signature:
    """The signature of a test-case as its last level made it (the cars it added)."""
    level = testcase_level(testcase)
    provenance = testcase.provenance or {}
    cars = []
    for car in sorted(testcase.road_users, key=lambda n: n.id):
        if car.added_in != level:
            continue
        times: dict[str, float] = {}
        for event in reversed(car.events):  # the first of each kind wins
            times[str(event.kind)] = event.t
        last = car.events[-1].t if car.events else 0.0
        way = car.walk if isinstance(car, Pedestrian) else f"{car.route.fork}:{car.route.exit}"
        cars.append(
            NewCar(
                car.id,
                way,
                "stopped" in times,
                round(times.get("arrived", last), 3),
                round(times.get("entered", last), 3),
            )
        )
    order = test_relations(provenance.get("order") or ())
    return Signature(provenance.get("parent"), level, tuple(cars), tuple(order))


def test_relations(order: Iterable[str]) -> list[str]:
    """The relations of an order (as provenance["order"] states them) among the
    test-case's cars: without those that speak of a certificate's (the ego's or the
    illegal ego's) events."""
    return [r for r in order if '"ego"' not in r and '"illegal"' not in r]


def is_new(candidate: Signature, taken: Iterable[Signature], gap: float = DISTINCT_GAP) -> bool:
    """Whether ``candidate`` differs from every one of ``taken``."""
    return not any(candidate.same_as(other, gap) for other in taken)


def distinct_count(testcases: Sequence[TestCase], gap: float = DISTINCT_GAP) -> int:
    """How many of ``testcases`` differ from every one before them."""
    kept: list[Signature] = []
    for testcase in testcases:
        mark = signature(testcase)
        if is_new(mark, kept, gap):
            kept.append(mark)
    return len(kept)


def seed_aim(seed: int) -> float | None:
    """Where in the entry window seed ``seed`` aims: nothing for seed 0 (Step 3's smoothest
    plan), else the van der Corput point of the seed (1: 0.5, 2: 0.25, 3: 0.75, 4: 0.125,
    ...), so that the first seeds spread over the window and no two seeds share a point."""
    if seed <= 0:
        return None
    return _radical_inverse(seed, 2)


def describe_variants(testcases: Sequence[TestCase]) -> list[str]:
    """What tells each of ``testcases`` (extensions of one test-case) from the others, a
    line each: its order of events among the test's cars (numbered by first appearance:
    ``order 2 of 3``), each new car's route, whether it stops, when it arrives at its line
    and enters the junction, the rule its complexity certificate breaks, and where in the
    entry window Step 3 aimed (``smoothest timing`` when it did not)."""
    marks = [signature(t) for t in testcases]
    orders = list(dict.fromkeys(order_key(mark) for mark in marks))
    lines = []
    for testcase, mark in zip(testcases, marks, strict=True):
        provenance = testcase.provenance or {}
        parts = [f"order {orders.index(order_key(mark)) + 1} of {len(orders)}"]
        parts += [
            f"{c.car} ({c.route}) {'stops' if c.stops else 'does not stop'}, arrives at "
            f"{c.arrival:.2f} s, enters at {c.entry:.2f} s"
            for c in mark.cars
        ]
        violated = provenance.get("complexity_certificate_violates", [])
        broken = [f"{v['rule']} of {v['car']}" for v in violated]
        rear_end = (provenance.get("complexity_certificate") or {}).get("rear_end") or []
        broken += [f"drives into {car} (rear-end)" for car in rear_end]
        parts.append(f"breaks {', '.join(broken)}" if broken else "breaks no rule named")
        parts.append(describe_aim(provenance.get("timing_aim")))
        lines.append("; ".join(parts))
    return _told_apart(lines, testcases, marks)


def _told_apart(
    lines: list[str], testcases: Sequence[TestCase], marks: Sequence[Signature]
) -> list[str]:
    """``lines`` where two read alike but for their order's number (their cars' times
    round alike; the orders differ in relations the line does not name) told apart: the
    variants alike (numbered from 1), each new car's lowest speed before it enters, and how
    many relations of its order of events the others' do not hold."""
    rests = [line.split("; ", 1)[1] for line in lines]
    told = []
    for k, (line, testcase, mark) in enumerate(zip(lines, testcases, marks, strict=True)):
        alike = [j for j, rest in enumerate(rests) if rest == rests[k] and j != k]
        if not alike:
            told.append(line)
            continue
        speeds = [
            f"{car.car} slows to {_lowest_before(testcase, car.car, car.entry):.2f} m/s"
            for car in mark.cars
        ]
        own = set(mark.order) - set().union(*(marks[j].order for j in alike))
        if own:
            speeds.append(f"{len(own)} relation(s) of its order of events are not theirs")
        others = ", ".join(str(j + 1) for j in alike)
        told.append(f"{line}; reads like variant {others} but: {', '.join(speeds)}")
    return told


def _lowest_before(testcase: TestCase, car: str, until: float) -> float:
    """The lowest speed of ``car`` before ``until`` (its entry into the junction)."""
    found = next(n for n in testcase.nonegos if n.id == car)
    return min((s.speed for s in found.trajectory if s.t <= until), default=0.0)


def describe_aim(aim: dict[str, Any] | None) -> str:
    """Where Step 3 aimed the new cars' entries (provenance["timing_aim"]: ``share`` of
    their entry windows, ``arrival_share`` of their arrival windows), in words."""
    if not aim:
        return "smoothest timing"
    share = float(aim["share"])
    ends = {0.0: "the earliest entry", 1.0: "the latest entry"}
    said = f"timing aimed at {ends.get(share, f'{share * 100:.3g} % of the entry window')}"
    arrival = aim.get("arrival_share")
    if arrival is not None:
        said += f" and {float(arrival) * 100:.3g} % of the arrival window"
    return said


def order_key(mark: Signature) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """An order of events as a test-case keeps it: its relations and which new cars stop
    (what a campaign's diversity counts and what ``describe_variants`` numbers)."""
    return mark.order, tuple(c.car for c in mark.cars if c.stops)


def variant_name(name: str, number: int) -> str:
    """The name of variant ``number`` of an extension named ``name``: ``STEM variant K level
    N`` for ``STEM level N`` (so that the next level renames it, as ``name_stem`` expects),
    else ``NAME variant K``; within the test-case's name length."""
    stem, level = name, ""
    head, space, tail = name.rpartition(" level ")
    if space and tail.isdigit():
        stem, level = head, f" level {tail}"
    suffix = f" variant {number}{level}"
    return stem[: MAX_NAME_LENGTH - len(suffix)] + suffix
