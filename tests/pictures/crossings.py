"""Test-cases with people on foot, for the pictures' tests: a pedestrian walking straight
over a crossing at a constant pace (she may wait at the curb first) with her events, as a
test-case holds her, added to a test-case."""

from __future__ import annotations

import math
from typing import Any

from service.core.motion.events import pedestrian_events
from service.core.motion.poses import PoseSample
from service.core.network import Intersection
from service.core.testcase import (
    PEDESTRIAN_LENGTH,
    PEDESTRIAN_WIDTH,
    TestCase,
    WalkingParams,
    parse_testcase,
)

PACE = 1.3  # m/s


def straight_walk(
    intersection: Intersection, walk_ref: str, testcase: TestCase, ident: str = "ped1",
    lead: float = 3.0, beyond: float = 3.0, wait: float = 0.0, added_in: int = 1,
) -> dict[str, Any]:  # fmt: skip
    """A pedestrian's document: ``lead`` metres before the curb on the line of the walk's
    path, she waits ``wait`` seconds, walks over at PACE and on to ``beyond`` metres past
    the far curb, where her trajectory ends (she leaves the picture); her events as the
    checker computes them."""
    walk = intersection.walk(walk_ref)
    (x0, y0), (x1, y1) = walk.path.coords[0], walk.path.coords[-1]
    along = math.hypot(x1 - x0, y1 - y0)
    ux, uy = (x1 - x0) / along, (y1 - y0) / along
    total = lead + along + beyond
    samples = []
    for k in range(round(testcase.duration / testcase.timestep) + 1):
        t = round(k * testcase.timestep, 9)
        walked = min(max(t - wait, 0.0) * PACE, total)
        moving = wait < t and walked < total
        samples.append(PoseSample(t, round(x0 + ux * (walked - lead), 4),
                                  round(y0 + uy * (walked - lead), 4), round(walk.heading, 4),
                                  PACE if moving else 0.0, round(walked, 4)))  # fmt: skip
        if walked >= total:
            break
    events = pedestrian_events(samples, PEDESTRIAN_LENGTH, PEDESTRIAN_WIDTH, intersection,
                               walk.id, WalkingParams().arrival_distance,
                               testcase.params.v_stop)  # fmt: skip
    return {
        "id": ident, "walk": walk.id, "added_in": added_in,
        "trajectory": [{"t": s.t, "x": s.x, "y": s.y, "heading": s.heading, "speed": s.speed,
                        "distance": s.distance} for s in samples],
        "events": [{"kind": e.kind.value, "lane": e.lane, "t": round(e.time, 4),
                    "distance": round(e.distance, 4)} for e in events],
    }  # fmt: skip


def with_pedestrians(testcase: TestCase, pedestrians: list[dict[str, Any]]) -> TestCase:
    """``testcase`` with ``pedestrians`` (documents) added: schema version 2."""
    document = testcase.model_dump(mode="json", by_alias=True)
    document["pedestrians"] = [*document.get("pedestrians", []), *pedestrians]
    document["schema"] = "scengen/testcase/2"
    return parse_testcase(document)
