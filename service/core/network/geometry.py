"""The drawable shape of a junction as plain data, for the results browser's pictures.

Coordinates are SUMO's network coordinates in metres, rounded to centimetres. Roads are
the whole lanes of the junction's incoming and outgoing edges (cars start far up them),
the junction's area, the paths through it, each fork's stop line, at a signalized
junction each signal head (``signal_heads``: where the pictures draw a link's colour), and
the pedestrian crossings (``crossings``: each strip with its centreline and its signal's
link, and the bars of its zebra, ``zebra_stripes``) with the walking areas at their ends
(``walking_areas``; both empty without crossings), and at a signalized crossing the
pedestrian signal heads (``pedestrian_heads``: a bar at each end, inside the strip).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from shapely.geometry import LineString, Polygon
from shapely.geometry.base import BaseGeometry

from service.core.network.load import read_network
from service.core.network.model import Crossing, Intersection, Point, walk_id

HEAD_DEPTH = 1.2  # m along the lane: how long a signal head's bar is
HEAD_SETBACK = 0.3  # m past the stop line: a car waiting at the line does not cover it
HEAD_GAP = 0.2  # m between the bars of one lane
CROSSWALK_REACH = 12.0  # m past a stop line where a crosswalk moves its heads beyond it
# a crossing's zebra: bars STRIPE wide along the crossing, STRIPE_GAP apart, as long as the
# crossing is wide but STRIPE_SIDE at each side; none within STRIPE_END of a curb, where a
# signalized crossing's heads stand (WALK_HEAD_SETBACK to + WALK_HEAD_DEPTH inside it)
STRIPE, STRIPE_GAP, STRIPE_SIDE, STRIPE_END = 0.5, 0.5, 0.25, 0.9
WALK_HEAD_SETBACK, WALK_HEAD_DEPTH = 0.15, 0.5


@dataclass(frozen=True)
class SignalHead:
    """Where one signalized link of a fork shows its colour: a bar just past the fork's
    stop line, across the link's share of the lane; a lane's links side by side as its
    driver sees them (the left turn on the left, the right turn on the right)."""

    fork: str
    link_index: int  # the traffic light's index of the link: its character in a state
    routes: tuple[str, ...]  # the routes through this link (one, unless SUMO shares it)
    turn: str  # the links' turn direction (left, straight, right)
    corners: tuple[Point, Point, Point, Point]  # the bar, corner after corner


def signal_heads(intersection: Intersection) -> list[SignalHead]:
    """A head for every link of ``intersection``'s traffic light that a route drives
    through, ordered by fork and across each fork from left to right; none at a junction
    without signals."""
    links: dict[tuple[str, int], list[str]] = {}
    for route in sorted(intersection.routes.values(), key=lambda r: r.id):
        if route.link_index >= 0:
            links.setdefault((route.fork, route.link_index), []).append(route.id)
    heads = []
    for lane in sorted({fork for fork, _ in links}):
        fork = intersection.forks[lane]
        ordered = sorted(
            (_bend(intersection, routes[0]), link, routes)
            for (on, link), routes in links.items()
            if on == lane
        )
        share = fork.width / len(ordered)
        near = _past_crosswalk(intersection, fork.stop_line, fork.heading)
        for k, (_, link, routes) in enumerate(ordered):
            across = -fork.width / 2 + share * (k + 0.5)  # from the driver's left
            half = max(share - HEAD_GAP, share / 2) / 2
            corners = _bar(fork.stop_line, fork.heading, across, half, near)
            turn = intersection.routes[routes[0]].turn.value
            heads.append(SignalHead(lane, link, tuple(routes), turn, corners))
    return heads


def _past_crosswalk(intersection: Intersection, stop_line: Point, heading: float) -> float:
    """Metres past a stop line where its heads begin: HEAD_SETBACK, or past the crossing
    that starts right after the line (SUMO's stop line is before the crosswalk), so that
    no head stands on a zebra."""
    rad = math.radians(heading)
    ahead = LineString([stop_line, (stop_line[0] + math.sin(rad) * CROSSWALK_REACH,
                                    stop_line[1] + math.cos(rad) * CROSSWALK_REACH)])  # fmt: skip
    near = HEAD_SETBACK
    for crossing in intersection.crossings.values():
        over = ahead.intersection(crossing.polygon)
        if over.is_empty:
            continue
        along = [math.dist(stop_line, point) for point in _coords(over)]  # ahead is straight
        if min(along) <= near + HEAD_DEPTH:  # the crossing is where the heads would stand
            near = max(near, max(along) + HEAD_SETBACK)
    return near


def _coords(shape: BaseGeometry) -> list[tuple[float, float]]:
    return [(x, y) for part in getattr(shape, "geoms", [shape]) for x, y, *_ in part.coords]


def _bend(intersection: Intersection, route_ref: str) -> float:
    """How far a route turns (degrees, right positive, a U-turn -180): the lane's order."""
    route = intersection.routes[route_ref]
    turned = intersection.exits[route.exit].heading - intersection.forks[route.fork].heading
    return (turned + 180.0) % 360.0 - 180.0


def _bar(
    stop_line: Point,
    heading: float,
    across: float,
    half: float,
    near: float = HEAD_SETBACK,
    depth: float = HEAD_DEPTH,
) -> tuple[Point, Point, Point, Point]:
    """The corners of a bar ``across`` metres right of a stop line's centre (left when
    negative), ``half`` metres to each side, from ``near`` to ``near`` + ``depth`` past the
    line (heading: degrees clockwise from north)."""
    rad = math.radians(heading)
    forward, right = (math.sin(rad), math.cos(rad)), (math.cos(rad), -math.sin(rad))

    def at(side: float, ahead: float) -> Point:
        return (
            stop_line[0] + right[0] * side + forward[0] * ahead,
            stop_line[1] + right[1] * side + forward[1] * ahead,
        )

    far = near + depth
    return (
        at(across - half, near),
        at(across + half, near),
        at(across + half, far),
        at(across - half, far),
    )


@dataclass(frozen=True)
class PedestrianHead:
    """Where a signalized crossing shows its pedestrian signal's colour: a bar across the
    strip just inside it at one curb, where ``walk`` steps onto it (one at each end)."""

    crossing: str
    link_index: int  # the crossing's link in the traffic light's program
    walk: str  # the walk that starts at this end
    corners: tuple[Point, Point, Point, Point]


def _heading(a: Point, b: Point) -> float:
    """Degrees clockwise from north, from ``a`` to ``b``."""
    return math.degrees(math.atan2(b[0] - a[0], b[1] - a[1])) % 360.0


def pedestrian_heads(intersection: Intersection) -> list[PedestrianHead]:
    """Two heads for every crossing with a pedestrian signal, ordered by crossing, the one
    at the start of its centreline first; none at a junction without signals."""
    heads = []
    for crossing in sorted(intersection.crossings.values(), key=lambda c: c.id):
        if crossing.link_index < 0:
            continue
        points = [(float(x), float(y)) for x, y, *_ in crossing.centreline.coords]
        half = max(crossing.width / 2.0 - STRIPE_SIDE, crossing.width / 4.0)
        for along, (curb, inward) in ((True, points[:2]), (False, points[:-3:-1])):
            corners = _bar(curb, _heading(curb, inward), 0.0, half, WALK_HEAD_SETBACK,
                           WALK_HEAD_DEPTH)  # fmt: skip
            heads.append(PedestrianHead(crossing.id, crossing.link_index,
                                        walk_id(crossing.id, along), corners))  # fmt: skip
    return heads


def zebra_stripes(crossing: Crossing) -> list[tuple[Point, Point, Point, Point]]:
    """The bars of ``crossing``'s zebra, along its centreline from its start: each STRIPE
    wide, as long as the strip is wide less STRIPE_SIDE at each side (parallel to the road
    it crosses), STRIPE_GAP apart, centred between the curbs with STRIPE_END clear at each
    (none on a crossing too short for one)."""
    line = crossing.centreline
    room = line.length - 2.0 * STRIPE_END
    count = math.floor((room + STRIPE_GAP) / (STRIPE + STRIPE_GAP) + 1e-9)
    if count < 1:
        return []
    first = (line.length - count * STRIPE - (count - 1) * STRIPE_GAP) / 2.0
    half = max(crossing.width / 2.0 - STRIPE_SIDE, crossing.width / 4.0)
    stripes = []
    for k in range(count):
        start = first + k * (STRIPE + STRIPE_GAP)
        a, b = line.interpolate(start), line.interpolate(start + STRIPE)
        stripes.append(_bar((a.x, a.y), _heading((a.x, a.y), (b.x, b.y)), 0.0, half, 0.0,
                            math.hypot(b.x - a.x, b.y - a.y)))  # fmt: skip
    return stripes


def _points(line: Any) -> list[list[float]]:
    return [[round(x, 2), round(y, 2)] for x, y in line.coords]


def _rings(shape: BaseGeometry) -> list[list[list[float]]]:
    parts = getattr(shape, "geoms", [shape])
    return [_points(part.exterior) for part in parts if isinstance(part, Polygon)]


def _outline(lane: Any) -> BaseGeometry:
    """A walking area's surface: SUMO writes its outline as the lane's shape."""
    points = [(float(x), float(y)) for x, y, *_ in lane.getShape()]
    if len(points) < 3:
        return Polygon()
    shape = Polygon(points)
    return shape if shape.is_valid else shape.buffer(0)


def junction_geometry(intersection: Intersection) -> dict[str, Any]:
    """Roads (each lane's polygon, and whether it is a sidewalk), junction area, connecting
    paths, stop lines, signal heads, crossings and walking areas of ``intersection`` (each
    head: its fork, link index, routes, turn and its bar's corners; the colour is the
    test-case's program's at the moment drawn; each crossing: its id, lane, the roads it
    crosses, its signal's link index or -1, its centreline, polygon, width and zebra's
    bars; each walking area: its id and polygon; each pedestrian head: its crossing, link
    index, the walk that starts at it, its bar)."""
    net = read_network(intersection.network_file)
    edges = {f.edge for f in intersection.forks.values()} | {
        e.edge for e in intersection.exits.values()
    }
    roads = []
    for edge in sorted(edges):
        for lane in net.getEdge(edge).getLanes():
            line = LineString(lane.getShape())
            if line.length > 0:
                shape = line.buffer(lane.getWidth() / 2, cap_style="flat")
                sidewalk = lane.allows("pedestrian") and not lane.allows("passenger")
                roads.append({"lane": lane.getID(), "polygon": _rings(shape), "sidewalk": sidewalk})
    stop_lines = []
    for fork in sorted(intersection.forks.values(), key=lambda f: f.lane):
        x, y = fork.stop_line
        heading = math.radians(fork.heading)  # clockwise from north
        dx, dy = math.cos(heading) * fork.width / 2, -math.sin(heading) * fork.width / 2
        stop_lines.append(
            {
                "lane": fork.lane,
                "stop_sign": fork.stop_sign,
                "yield_sign": fork.yield_sign,
                "line": [
                    [round(x - dx, 2), round(y - dy, 2)],
                    [round(x + dx, 2), round(y + dy, 2)],
                ],
            }
        )
    paths = [
        {"route": route.id, "turn": route.turn.value,
         "line": _points(intersection.connecting_lane_of(route).centreline)}
        for route in sorted(intersection.routes.values(), key=lambda r: r.id)
    ]  # fmt: skip
    heads = [
        {"fork": head.fork, "link_index": head.link_index, "routes": list(head.routes),
         "turn": head.turn, "polygon": _points(LineString(head.corners))}
        for head in signal_heads(intersection)
    ]  # fmt: skip
    crossings = [
        {"id": crossing.id, "lane": crossing.lane, "edges": list(crossing.edges),
         "link_index": crossing.link_index, "line": _points(crossing.centreline),
         "polygon": _rings(crossing.polygon), "width": round(crossing.width, 2),
         "stripes": [_points(LineString(bar)) for bar in zebra_stripes(crossing)]}
        for crossing in intersection.crossings.values()
    ]  # fmt: skip
    walk_heads = [
        {"crossing": head.crossing, "link_index": head.link_index, "walk": head.walk,
         "polygon": _points(LineString(head.corners))}
        for head in pedestrian_heads(intersection)
    ]  # fmt: skip
    areas = sorted({end for crossing in intersection.crossings.values() for end in crossing.ends})
    walking_areas = [
        {"id": area, "polygon": _rings(_outline(net.getEdge(area).getLanes()[0]))} for area in areas
    ]
    every = [p for road in roads for ring in road["polygon"] for p in ring]
    every += [p for ring in _rings(intersection.polygon) for p in ring]
    xs, ys = [p[0] for p in every], [p[1] for p in every]
    return {
        "junction": intersection.junction,
        "control": intersection.control.value,
        "area": _rings(intersection.polygon),
        "roads": roads,
        "stop_lines": stop_lines,
        "paths": paths,
        "signal_heads": heads,
        "crossings": crossings,
        "walking_areas": walking_areas,
        "pedestrian_heads": walk_heads,
        "bounds": [min(xs), min(ys), max(xs), max(ys)],
    }
