"""Test helpers: pedestrians written by hand, walking straight along a walk's path."""

from __future__ import annotations

import json
import math
from collections.abc import Sequence

from shapely.geometry import Point, Polygon

from service.core.motion.poses import PoseSample
from service.core.network import Intersection
from service.core.testcase import (
    TestCase,
    dump_testcase,
    load_testcase_intersection,
    new_testcase,
    parse_testcase,
)

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


def on_crossing_times(
    testcase: TestCase, junction: Intersection, ego: Sequence[PoseSample]
) -> list[float]:
    """The times the ego's rectangle overlaps the pedestrian's crosswalk."""
    crossing = junction.crossings[junction.walk(testcase.pedestrians[0].walk).crossing].polygon
    size = testcase.ego.length, testcase.ego.width
    return [s.t for s in ego if rectangle(s.x, s.y, s.heading, *size).intersects(crossing)]


def in_path_times(testcase: TestCase, junction: Intersection) -> list[float]:
    """The times she is in the ego's path (docs/pedestrians.md): on the crosswalk and not
    yet past the far side of the ego's connecting lane (her rear along her walk)."""
    person = testcase.pedestrians[0]
    walk = junction.walk(person.walk)
    crossing = junction.crossings[walk.crossing].polygon
    lane = junction.connecting_lane_of(junction.route(testcase.ego.route.id)).polygon
    far = max(walk.path.project(Point(p)) for p in lane.intersection(crossing).exterior.coords)
    times = []
    for s in person.trajectory:
        rad = math.radians(s.heading)
        rear = Point(
            s.x - math.sin(rad) * person.length / 2, s.y - math.cos(rad) * person.length / 2
        )
        body = rectangle(s.x, s.y, s.heading, person.length, person.width)
        if body.intersects(crossing) and walk.path.project(rear) <= far:
            times.append(s.t)
    return times


def crosswalk_scene(
    route: str, walk: str, lead: float, wait: float, duration: float = 25.0, name: str = ""
) -> tuple[TestCase, TestCase, Intersection]:
    """On crosswalk-stop (an all-way stop whose east arm leaves 25 degrees off, a crosswalk
    over every arm that drivers yield on): the ego on ``route`` alone, the same with
    ``ped1`` walking straight over ``walk`` (``straight_walk``), and the junction."""
    alone = new_testcase("crosswalk-stop", route, duration=duration, name=name)
    junction = load_testcase_intersection(alone)
    samples = straight_walk(junction, walk, duration, lead=lead, wait=wait)
    return alone, with_pedestrians(alone, {"ped1": (walk, samples)}), junction
