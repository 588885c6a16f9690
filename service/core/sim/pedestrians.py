"""The pedestrians of a replay: where each one is in SUMO, step by step (the run plan's
``pedestrians``, read by service.core.sumo.run, which imports nothing of ours).

A pedestrian of the test-case walks over her walk's crossing on a recorded trajectory. In
SUMO she is a person walking her walk's edges (the sidewalk before, the walking area at the
curb, the crossing, the walking area at the far curb, the sidewalk after), and the runner
places her at her recorded pose every step with ``person.moveToXY(..., keepRoute=1)``:
mapped onto the nearest edge of her walking stage, so that SUMO knows her on the crossing's
lane while she is on it and its drivers yield to her (``jmCrossingGap``).

What SUMO 1.28 needs for that, found by driving its own driver at a replayed person:

- keepRoute 1. With keepRoute 0, 2, 4 or 6 SUMO crashed (a segmentation fault; with 0 at
  the step her pose reached the walking area past the crossing); a person without a
  walking stage over the crossing (a waiting stage) is never on it for SUMO's junctions.
- Three walking stages, not one: up to the curb, the crossing alone, and from the far
  curb on; the runner moves her on to the next stage (``person.removeStage(id, 0)``).
  ``moveToXY`` guesses a person's direction on an edge from the next edge of her stage,
  and on a crossing followed by a walking area it always guesses "along the crossing's
  lane": a pedestrian walking a crossing against its lane (a ``-`` walk) was then seen by
  SUMO's drivers only once she stood in their path, and they drove on in front of her as
  she came. On a stage of the crossing alone SUMO takes her direction from where she
  enters it and where the stage ends (its far curb), and keeps it.
- The runner moves her on SWITCH metres before she reaches the crossing's strip (its far
  curb). SUMO moves a person on to her next stage by itself once her place on a walking
  area passes the end of SUMO's path across it, a few tenths of a metre before her front
  reaches the strip, and puts her where the next stage begins: for one step up to the
  crossing's length off her pose. Moved on earlier, she is in the crossing's stage while
  her front is still on the walking area, and SUMO has her at the crossing's curb for
  the steps of her last metre to it. On sidewalks and on the crossing she is exactly at
  her pose; on a walking area SUMO keeps a person near its own path across it, within
  2 m of her pose (measured for straight walks that cut a skewed corner).

SUMO, like a car's, reports a person's front: every pose here is the front of the
rectangle (``centre_to_front`` of the recorded centre and heading). A pose is on the map
while its front lies on one of her route's lanes (within ``ON_MAP`` metres: a sidewalk's
strip, a walking area, the crossing's strip); her trajectory in SUMO ends at the first pose
after that, where she has left the map (as a car's ends at the end of its road).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from shapely.geometry import LineString, Point, Polygon

from service.core.errors import InvalidTestCase
from service.core.motion.poses import centre_to_front
from service.core.network import Intersection, parsed_network
from service.core.network.lanes import dedupe, shape_2d
from service.core.testcase import Pedestrian, TestCase

ON_MAP = 0.5  # metres: how far off her route's lanes a pedestrian's front may be
SWITCH = 1.0  # metres before the crossing's strip (before its far curb) where the runner
# moves her on to the crossing's stage (the stage after it): before SUMO would by itself


@dataclass(frozen=True)
class Walker:
    """Where and how a pedestrian is in SUMO: her walking stages, her start, her poses."""

    id: str
    length: float
    width: float
    stages: tuple[tuple[tuple[str, ...], float], ...]  # from the one she departs in: each
    # stage's edges and its arrival position on its last edge (its far end as she walks)
    depart_pos: float  # on the first stage's first edge: her first pose's nearest place
    poses: tuple[tuple[float, float, float, float], ...]  # per step while she is on the
    # map: her front (x, y), heading (degrees clockwise from north), speed (m/s)
    on: tuple[tuple[int, int], ...]  # per pose, her stage in SUMO and the edge in it
    edges_at: tuple[str, ...]  # per pose, the edge her front is on

    def edge_at(self, step: int) -> str:
        """The edge her front is on at ``step`` (one of her poses)."""
        return self.edges_at[step]


@dataclass(frozen=True)
class _Stretch:
    """One edge of a walk's route: its id, the area people walk on, its lane's shape."""

    edge: str
    area: Polygon
    line: LineString | None  # the lane's centreline; None for a walking area
    length: float


def walkers(testcase: TestCase, intersection: Intersection) -> list[Walker]:
    """Every pedestrian of ``testcase`` as SUMO walks her (same order)."""
    return [_walker(person, intersection) for person in testcase.pedestrians]


def _walker(person: Pedestrian, intersection: Intersection) -> Walker:
    route, crossing, along = _route(intersection, person.walk)
    poses: list[tuple[float, float, float, float]] = []
    at: list[int] = []  # per pose, the stretch of the route she is on
    for sample in person.trajectory:
        x, y = centre_to_front(sample.x, sample.y, sample.heading, person.length)
        where = _stretch_of(route, Point(x, y), at[-1] if at else 0)
        if where is None:
            if not at:
                raise InvalidTestCase(
                    f"pedestrian {person.id!r} starts off her walk {person.walk!r}: her front "
                    f"({x:.2f}, {y:.2f}) is on none of {', '.join(s.edge for s in route)}"
                )
            break  # she has left the map
        poses.append((x, y, sample.heading % 360.0, sample.speed))
        at.append(where)
    staged = [_stage_stretch(route, crossing, along, Point(pose[:2]), k)
              for pose, k in zip(poses, at, strict=True)]  # fmt: skip
    # her stages: up to the curb, the crossing, from the far curb (none before or after a
    # traffic island), each as (first stretch, end)
    bounds = [(a, b) for a, b in ((0, crossing), (crossing, crossing + 1),
                                  (crossing + 1, len(route))) if a < b]  # fmt: skip
    stage_of = [k for k, (a, b) in enumerate(bounds) for _ in range(a, b)]
    first = _depart_stretch(route, at[0], {a for a, _ in bounds})
    depart = 0.0  # on a walking area: SUMO's place on it is no point of its own
    line = route[first].line
    if line is not None:
        depart = min(max(float(line.project(Point(poses[0][:2]))), 0.0), route[first].length)
    skipped = stage_of[first]
    begins = [max(a, first) for a, _ in bounds]  # where each stage's edges begin
    stages = tuple(
        (tuple(s.edge for s in route[begins[k] : b]), round(_far_end(route, b - 1, along), 3))
        for k, (_, b) in enumerate(bounds)
        if k >= skipped
    )
    return Walker(
        id=person.id,
        length=person.length,
        width=person.width,
        stages=stages,
        depart_pos=round(depart, 3),
        poses=tuple(poses),
        on=tuple((stage_of[k] - skipped, k - begins[stage_of[k]]) for k in staged),
        edges_at=tuple(route[k].edge for k in at),
    )


def _stage_stretch(
    route: Sequence[_Stretch], crossing: int, along: bool, front: Point, at: int
) -> int:
    """The stretch whose stage she is in at a pose on stretch ``at``: its own, but within
    SWITCH metres of the crossing's strip the crossing's, and within SWITCH metres of its far
    curb the far walking area's. SUMO moves a person on to her next stage by itself when
    her place on a walking area (on the crossing) passes the end of its path (of her
    stage's arrival), a few tenths of a metre before her front gets there, and starts
    the next stage where that begins (on a crossing walked against its lane, its far end):
    a step metres off her pose; the runner moves her on before that can happen, and SUMO
    keeps her on the nearest place of the new stage's edge (the curb) until she is on it."""
    strip = route[crossing]
    if at == crossing - 1 and strip.area.distance(front) < SWITCH:
        return crossing
    if at == crossing and crossing + 1 < len(route):
        assert strip.line is not None
        place = float(strip.line.project(front))
        walked = place if along else strip.length - place
        if walked > strip.length - SWITCH:
            return crossing + 1
    return at


def _route(intersection: Intersection, walk_id: str) -> tuple[list[_Stretch], int, bool]:
    """The stretches of the walk's route in walking order: the sidewalk before (none where
    the walk starts on a traffic island), the walking area, the crossing, and unless the
    walk ends on an island (``after`` is then the crossing's lane) the walking area and the
    sidewalk after; the crossing's index among them, and whether she walks along the
    crossing's lane (a ``+`` walk)."""
    walk = intersection.walk(walk_id)
    crossing = intersection.crossings[walk.crossing]
    net = parsed_network(intersection.network_file)
    stretches = []
    if walk.before:
        stretches.append(_sidewalk(net.getLane(walk.before)))
    stretches.append(_walking_area(net, walk.start))
    index = len(stretches)
    length = float(net.getLane(crossing.lane).getLength())  # SUMO's, not the shape's
    stretches.append(_Stretch(crossing.id, crossing.polygon, crossing.centreline, length))
    if walk.after != crossing.lane:
        stretches.append(_walking_area(net, walk.end))
        stretches.append(_sidewalk(net.getLane(walk.after)))
    return stretches, index, walk.start == crossing.ends[0]


def _sidewalk(lane: Any) -> _Stretch:
    line = LineString(dedupe(shape_2d(lane)))
    area = line.buffer(float(lane.getWidth()) / 2.0, cap_style="flat")
    return _Stretch(lane.getEdge().getID(), area, line, float(lane.getLength()))


def _walking_area(net: Any, edge: str) -> _Stretch:
    lane = net.getEdge(edge).getLanes()[0]
    area = Polygon(dedupe(shape_2d(lane))).buffer(0)
    return _Stretch(edge, area, None, float(lane.getLength()))


def _stretch_of(route: Sequence[_Stretch], point: Point, since: int) -> int | None:
    """The index of the stretch ``point`` is on, from ``since`` on (a pedestrian walks her
    route forwards): the first that holds it, else the nearest within ON_MAP; None when
    it is on none of them (she has left the map)."""
    distances = [(route[k].area.distance(point), k) for k in range(since, len(route))]
    inside = [k for distance, k in distances if distance == 0.0]
    if inside:
        return inside[0]
    distance, nearest = min(distances)
    return nearest if distance <= ON_MAP else None


def _depart_stretch(route: Sequence[_Stretch], first: int, stage_starts: set[int]) -> int:
    """Where SUMO inserts her: on the stretch of her first pose, or where that is a walking
    area after a sidewalk in the same stage (SUMO's place on a walking area is no point of
    its own) on that sidewalk, so that her stage still holds the walking area she stands
    on; a walking area that begins its stage (at the far curb, or a traffic island) is
    where she departs."""
    if route[first].line is not None or first in stage_starts:
        return first
    return first - 1


def _far_end(route: Sequence[_Stretch], index: int, along: bool) -> float:
    """Where a stage that ends on stretch ``index`` arrives: the far end of that stretch as
    she walks it. The crossing's far curb (its length along its lane, 0 against it); the
    sidewalk after, its length when it leads away from the walking area before it, 0 when
    she walks it against its direction; a walking area (the stage up to the curb), 0: the
    runner moves her on to the crossing's stage before she could arrive."""
    last = route[index]
    if last.line is None:
        return 0.0
    if index + 1 < len(route):  # the crossing
        return last.length if along else 0.0
    previous = route[index - 1].area
    start, end = Point(last.line.coords[0]), Point(last.line.coords[-1])
    return last.length if previous.distance(start) <= previous.distance(end) else 0.0


def plan_section(people: Sequence[Walker]) -> list[dict[str, Any]]:
    """The run plan's ``pedestrians``: each one's walking stages (edges and arrival
    position), her departure on the first stage's first edge, and her pose per step (the
    front: x, y, heading, speed; her stage and the index of her edge in it)."""
    return [
        {
            "id": person.id,
            "length": person.length,
            "width": person.width,
            "stages": [
                {"edges": list(edges), "arrival": arrival} for edges, arrival in person.stages
            ],
            "depart_pos": person.depart_pos,
            "poses": [[*pose, *where] for pose, where in zip(person.poses, person.on, strict=True)],
        }
        for person in people
    ]
