"""The drawable shape of a junction as plain data, for the results browser's pictures.

Coordinates are SUMO's network coordinates in metres, rounded to centimetres. Roads are
the whole lanes of the junction's incoming and outgoing edges (cars start far up them),
the junction's area, the paths through it, each fork's stop line, at a signalized
junction each signal head (``signal_heads``: where the pictures draw a link's colour), and
the pedestrian crossings (``crossings``: each strip with its centreline and its signal's
link) with the walking areas at their ends (``walking_areas``; both empty without
crossings).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from shapely.geometry import LineString, Polygon
from shapely.geometry.base import BaseGeometry

from service.core.network.load import read_network
from service.core.network.model import Intersection, Point

HEAD_DEPTH = 1.2  # m along the lane: how long a signal head's bar is
HEAD_SETBACK = 0.3  # m past the stop line: a car waiting at the line does not cover it
HEAD_GAP = 0.2  # m between the bars of one lane


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
        for k, (_, link, routes) in enumerate(ordered):
            across = -fork.width / 2 + share * (k + 0.5)  # from the driver's left
            half = max(share - HEAD_GAP, share / 2) / 2
            corners = _bar(fork.stop_line, fork.heading, across, half)
            turn = intersection.routes[routes[0]].turn.value
            heads.append(SignalHead(lane, link, tuple(routes), turn, corners))
    return heads


def _bend(intersection: Intersection, route_ref: str) -> float:
    """How far a route turns (degrees, right positive, a U-turn -180): the lane's order."""
    route = intersection.routes[route_ref]
    turned = intersection.exits[route.exit].heading - intersection.forks[route.fork].heading
    return (turned + 180.0) % 360.0 - 180.0


def _bar(
    stop_line: Point, heading: float, across: float, half: float
) -> tuple[Point, Point, Point, Point]:
    """The corners of a bar ``across`` metres right of a stop line's centre (left when
    negative), ``half`` metres to each side, from HEAD_SETBACK to HEAD_SETBACK + HEAD_DEPTH
    past the line (heading: degrees clockwise from north)."""
    rad = math.radians(heading)
    forward, right = (math.sin(rad), math.cos(rad)), (math.cos(rad), -math.sin(rad))

    def at(side: float, ahead: float) -> Point:
        return (
            stop_line[0] + right[0] * side + forward[0] * ahead,
            stop_line[1] + right[1] * side + forward[1] * ahead,
        )

    near, far = HEAD_SETBACK, HEAD_SETBACK + HEAD_DEPTH
    return (
        at(across - half, near),
        at(across + half, near),
        at(across + half, far),
        at(across - half, far),
    )


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
    """Roads, junction area, connecting paths, stop lines, signal heads, crossings and
    walking areas of ``intersection`` (each head: its fork, link index, routes, turn and
    its bar's corners; the colour is the test-case's program's at the moment drawn; each
    crossing: its id, lane, the roads it crosses, its signal's link index or -1, its
    centreline and its polygon; each walking area: its id and polygon)."""
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
                roads.append({"lane": lane.getID(), "polygon": _rings(shape)})
    stop_lines = []
    for fork in sorted(intersection.forks.values(), key=lambda f: f.lane):
        x, y = fork.stop_line
        heading = math.radians(fork.heading)  # clockwise from north
        dx, dy = math.cos(heading) * fork.width / 2, -math.sin(heading) * fork.width / 2
        stop_lines.append(
            {
                "lane": fork.lane,
                "stop_sign": fork.stop_sign,
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
         "polygon": _rings(crossing.polygon)}
        for crossing in intersection.crossings.values()
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
        "bounds": [min(xs), min(ys), max(xs), max(ys)],
    }
