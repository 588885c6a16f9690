"""The drawable shape of a junction as plain data, for the results browser's pictures.

Coordinates are SUMO's network coordinates in metres, rounded to centimetres. Roads are
the whole lanes of the junction's incoming and outgoing edges (cars start far up them),
the junction's area, the paths through it, and each fork's stop line.
"""

from __future__ import annotations

import math
from typing import Any

from shapely.geometry import LineString, Polygon
from shapely.geometry.base import BaseGeometry

from service.core.network.load import read_network
from service.core.network.model import Intersection


def _points(line: Any) -> list[list[float]]:
    return [[round(x, 2), round(y, 2)] for x, y in line.coords]


def _rings(shape: BaseGeometry) -> list[list[list[float]]]:
    parts = getattr(shape, "geoms", [shape])
    return [_points(part.exterior) for part in parts if isinstance(part, Polygon)]


def junction_geometry(intersection: Intersection) -> dict[str, Any]:
    """Roads, junction area, connecting paths and stop lines of ``intersection``."""
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
        "bounds": [min(xs), min(ys), max(xs), max(ys)],
    }
