"""The criticality measures as records: each measure's extreme against one other road user
(``PairCriticality``), and overall over all of them (``Criticality``), with their JSON.
How they are measured: service.core.motion.criticality (the cars, SUMO's SSM device) and
service.core.motion.pedestrian_criticality (people on foot)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class Measure:
    """A measure's extreme against one road user and when it occurred (s)."""

    value: float
    t: float


@dataclass(frozen=True)
class AreaPet:
    """The post-encroachment time at one conflict area; ``t``: when the second one entered."""

    area: str
    value: float
    t: float


@dataclass(frozen=True)
class PairCriticality:
    """The ego against one other road user, a car or a pedestrian, ``car`` its id (None:
    the measure never applied)."""

    car: str
    ttc: Measure | None
    pet: tuple[AreaPet, ...]
    drac: Measure | None
    distance: Measure | None


@dataclass(frozen=True)
class Extreme:
    """The extreme of a measure over every other road user: which one (``car``: a car's or
    a pedestrian's id), when (and where, for PET)."""

    value: float
    car: str
    t: float
    area: str | None = None


@dataclass(frozen=True)
class Criticality:
    """Every measure against each other car and each pedestrian (in that order), and
    overall: the smallest TTC, PET and distance and the largest DRAC."""

    others: tuple[PairCriticality, ...]

    @property
    def ttc(self) -> Extreme | None:
        return _extreme([(p.car, p.ttc) for p in self.others], smallest=True)

    @property
    def drac(self) -> Extreme | None:
        return _extreme([(p.car, p.drac) for p in self.others], smallest=False)

    @property
    def distance(self) -> Extreme | None:
        return _extreme([(p.car, p.distance) for p in self.others], smallest=True)

    @property
    def pet(self) -> Extreme | None:
        found = [(a.value, a.t, p.car, a.area) for p in self.others for a in p.pet]
        if not found:
            return None
        value, t, car, area = min(found)
        return Extreme(value, car, t, area)

    def to_dict(self) -> dict[str, Any]:
        def measure(m: Measure | None) -> dict[str, float] | None:
            return None if m is None else {"value": m.value, "t": m.t}

        def extreme(e: Extreme | None) -> dict[str, Any] | None:
            if e is None:
                return None
            found: dict[str, Any] = {"value": e.value, "car": e.car, "t": e.t}
            return found if e.area is None else {**found, "area": e.area}

        return {
            "others": {
                p.car: {
                    "ttc": measure(p.ttc),
                    "pet": [{"area": a.area, "value": a.value, "t": a.t} for a in p.pet],
                    "drac": measure(p.drac),
                    "distance": measure(p.distance),
                }
                for p in self.others
            },
            "overall": {
                "ttc": extreme(self.ttc),
                "pet": extreme(self.pet),
                "drac": extreme(self.drac),
                "distance": extreme(self.distance),
            },
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Criticality:
        """The criticality ``to_dict`` wrote (its overall part follows from the others)."""

        def measure(item: dict[str, Any] | None) -> Measure | None:
            return None if item is None else Measure(item["value"], item["t"])

        return cls(
            tuple(
                PairCriticality(
                    car,
                    measure(item["ttc"]),
                    tuple(AreaPet(a["area"], a["value"], a["t"]) for a in item["pet"]),
                    measure(item["drac"]),
                    measure(item["distance"]),
                )
                for car, item in data["others"].items()
            )
        )


def _extreme(found: Sequence[tuple[str, Measure | None]], smallest: bool) -> Extreme | None:
    sign = 1.0 if smallest else -1.0
    present = [(sign * m.value, m.t, car) for car, m in found if m is not None]
    if not present:
        return None
    value, t, car = min(present)
    return Extreme(sign * value, car, t)
