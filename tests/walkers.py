"""Test helpers: pedestrians written by hand, walking straight along a walk's path."""

from __future__ import annotations

import json
import math

from shapely.geometry import Polygon

from service.core.network import Intersection
from service.core.testcase import TestCase, dump_testcase, parse_testcase

PACE = 1.3  # m/s


def straight_walk(
    intersection: Intersection,
    walk: str,
    duration: float,
    timestep: float = 0.1,
    lead: float = 2.0,
    wait: float = 0.0,
    pace: float = PACE,
    until: float | None = None,
) -> list[dict[str, float]]:
    """Samples (the rectangle's centre) of a pedestrian who stands ``lead`` metres before
    the curb on the line of ``walk``'s path (negative: already on the crossing) for
    ``wait`` seconds, then walks straight along that line at ``pace``, on past the far
    curb; ``until``: her trajectory ends at that time (she has gone)."""
    path = intersection.walks[walk].path
    (x0, y0), (x1, y1) = path.coords[0], path.coords[-1]
    ux, uy = (x1 - x0) / path.length, (y1 - y0) / path.length
    heading = math.degrees(math.atan2(ux, uy)) % 360.0
    end = duration if until is None else until
    samples = []
    for k in range(round(end / timestep) + 1):
        t = k * timestep
        walked = pace * max(t - wait, 0.0)
        s = walked - lead
        samples.append({
            "t": round(t, 9), "x": x0 + ux * s, "y": y0 + uy * s, "heading": heading,
            "speed": pace if t > wait else 0.0, "distance": walked,
        })  # fmt: skip
    return samples


def with_pedestrians(testcase: TestCase, people: dict[str, tuple[str, list]]) -> TestCase:  # type: ignore[type-arg]
    """``testcase`` with pedestrians ``{id: (walk, samples)}`` (schema /2)."""
    document = json.loads(dump_testcase(testcase))
    document["schema"] = "scengen/testcase/2"
    document["pedestrians"] = [
        {"id": name, "walk": walk, "trajectory": samples, "added_in": 1}
        for name, (walk, samples) in people.items()
    ]
    return parse_testcase(document)


def rectangle(x: float, y: float, heading: float, length: float, width: float) -> Polygon:
    """A road user's rectangle from its centre and heading (degrees clockwise from north)."""
    rad = math.radians(heading)
    fx, fy = math.sin(rad), math.cos(rad)  # forward
    rx, ry = fy, -fx  # to the right
    hl, hw = length / 2.0, width / 2.0
    return Polygon([
        (x + fx * hl + rx * hw, y + fy * hl + ry * hw),
        (x + fx * hl - rx * hw, y + fy * hl - ry * hw),
        (x - fx * hl - rx * hw, y - fy * hl - ry * hw),
        (x - fx * hl + rx * hw, y - fy * hl + ry * hw),
    ])  # fmt: skip
