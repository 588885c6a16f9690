"""Ego trajectories from files: our JSON sample format or SUMO FCD output.

JSON: a list of samples ``{t, x, y, heading[, speed, distance]}``, or an object holding one
under ``samples`` or ``trajectory`` (so ``scengen drive --json`` output works too). SUMO FCD
(``--fcd-output``): the vehicle's front-bumper positions are converted to rectangle centres
with the car's length; distances are SUMO's ``odometer`` (from the first sample) when every
sample has one. Missing distances are the path length travelled by the centre;
missing speeds are the distance over the following step.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any
from xml.etree import ElementTree as ET

from service.core.errors import InvalidTrajectory
from service.core.motion.poses import PoseSample, front_to_centre


def read_trajectory(path: Path, vehicle: str = "ego", length: float = 5.0) -> list[PoseSample]:
    """Samples of the ego from a JSON trajectory or a SUMO FCD file."""
    try:
        text = path.read_text()
    except OSError as exc:
        raise InvalidTrajectory(f"cannot read trajectory {path}: {exc.strerror}") from None
    if text.lstrip().startswith("<"):
        return read_fcd(text, vehicle, length, str(path))
    try:
        document = json.loads(text)
    except json.JSONDecodeError as exc:
        raise InvalidTrajectory(f"{path} is neither JSON nor SUMO FCD XML: {exc}") from None
    return parse_samples(document, str(path))


def parse_samples(document: Any, source: str = "trajectory") -> list[PoseSample]:
    """Samples from a JSON document (list, or object with ``samples``/``trajectory``)."""
    if isinstance(document, dict):
        document = document.get("samples", document.get("trajectory"))
    if not isinstance(document, list) or len(document) < 2:
        raise InvalidTrajectory(
            f"{source}: expected a list of at least 2 samples {{t, x, y, heading}} (or an "
            "object with 'samples' or 'trajectory')"
        )
    rows = []
    for k, sample in enumerate(document):
        try:
            row = {key: float(sample[key]) for key in ("t", "x", "y", "heading")}
            for key in ("speed", "distance"):
                if sample.get(key) is not None:
                    row[key] = float(sample[key])
        except (KeyError, TypeError, ValueError, AttributeError) as exc:
            raise InvalidTrajectory(
                f"{source}: sample {k} needs numbers t, x, y, heading ({exc!r} is wrong)"
            ) from None
        rows.append(row)
    return complete_samples(rows, source)


def read_fcd(text: str, vehicle: str, length: float, source: str) -> list[PoseSample]:
    """The samples of ``vehicle`` in SUMO FCD XML, centred with the car's ``length``."""
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise InvalidTrajectory(f"{source}: not well-formed XML: {exc}") from None
    rows = []
    seen: set[str] = set()
    for step in root.iter("timestep"):
        for car in step.iter("vehicle"):
            seen.add(car.get("id", ""))
            if car.get("id") != vehicle:
                continue
            heading = float(car.get("angle", "0")) % 360.0
            x, y = front_to_centre(float(car.get("x", "nan")), float(car.get("y", "nan")),
                                   heading, length)  # fmt: skip
            row = {"t": float(step.get("time", "nan")), "x": x, "y": y, "heading": heading,
                   "speed": float(car.get("speed", "nan"))}  # fmt: skip
            if car.get("odometer") is not None:
                row["distance"] = float(car.get("odometer", "nan"))
            rows.append(row)
    if len(rows) >= 2 and all("distance" in row for row in rows):
        start = rows[0]["distance"]  # SUMO's odometer counts from the car's departure
        for row in rows:
            row["distance"] -= start
    else:
        for row in rows:
            row.pop("distance", None)
    if len(rows) < 2:
        names = ", ".join(sorted(seen)) or "(none)"
        raise InvalidTrajectory(
            f"{source}: vehicle {vehicle!r} has fewer than 2 samples; vehicles in the file: "
            f"{names} (choose one with --vehicle)"
        )
    return complete_samples(rows, source)


def complete_samples(rows: list[dict[str, float]], source: str) -> list[PoseSample]:
    """Samples with distances and speeds filled in; checks times and values."""
    for k, row in enumerate(rows):
        if not all(math.isfinite(v) for v in row.values()):
            raise InvalidTrajectory(f"{source}: sample {k} has a value that is not a number")
        if k and row["t"] <= rows[k - 1]["t"]:
            raise InvalidTrajectory(f"{source}: sample {k}: times must increase")
    if "distance" not in rows[0]:
        travelled = 0.0
        for k, row in enumerate(rows):
            if k:
                travelled += math.dist((row["x"], row["y"]), (rows[k - 1]["x"], rows[k - 1]["y"]))
            row["distance"] = travelled
    for k, row in enumerate(rows):
        if "speed" not in row:
            j = min(k, len(rows) - 2)
            a, b = rows[j], rows[j + 1]
            row["speed"] = (b["distance"] - a["distance"]) / (b["t"] - a["t"])
    return [
        PoseSample(r["t"], r["x"], r["y"], r["heading"] % 360.0, r["speed"], r["distance"])
        for r in rows
    ]
