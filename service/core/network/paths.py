"""A junction's area and its connecting lanes as shapes: one centreline and one polygon
for each connection's chain of internal lanes, cut square at the fork's end and at the exit."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from shapely.geometry import LineString, Polygon
from shapely.ops import unary_union

from service.core.errors import UnsupportedIntersection
from service.core.network.lanes import dedupe, shape_2d
from service.core.network.model import ConnectingLane


def junction_area(node: Any, lanes: dict[str, ConnectingLane]) -> Polygon:
    """The junction's area: its shape, or where its shape has no area (SUMO writes a
    point for some), the hull of its connecting lanes."""
    shape = dedupe(shape_2d(node))
    area = Polygon(shape).buffer(0) if len(shape) >= 3 else Polygon()
    if area.area > 0:
        return area
    hull = unary_union([lane.polygon for lane in lanes.values()]).convex_hull
    return hull if isinstance(hull, Polygon) else Polygon()


def connecting_lane(net: Any, chain: list[str], fork: Any, exit_lane: Any) -> ConnectingLane:
    """One centreline and one polygon for a chain of internal lanes.

    The polygon ends square to the fork at the stop line and square to the exit where the
    exit lane starts; a flat buffer cap would end square to the curve instead and poke out
    of the junction by a few centimetres on turns. Repeated shape points are dropped; a
    chain whose shape is one point (the fork runs straight into the exit: SUMO writes a
    0.1 m lane as two equal points) becomes a straight line as long as SUMO says the
    chain is, centred on that point, along the direction of travel.
    """
    width = net.getLane(chain[0]).getWidth()
    points = dedupe([p for lane_id in chain for p in shape_2d(net.getLane(lane_id))])
    fork_shape, exit_shape = dedupe(shape_2d(fork)), dedupe(shape_2d(exit_lane))
    into = _direction(fork_shape, at_end=True) or _direction(points, at_end=False)
    out = _direction(exit_shape, at_end=False) or _direction(points, at_end=True) or into
    into = into or out
    if into is None or out is None:
        raise UnsupportedIntersection(
            f"the connection from {fork.getID()!r} to {exit_lane.getID()!r} has no direction: "
            "its fork, internal lanes and exit are all single points",
            route=f"{fork.getID()}:{exit_lane.getID()}",
        )
    if len(points) < 2:
        half = max(sum(net.getLane(lane_id).getLength() for lane_id in chain), MIN_LENGTH) / 2
        (x, y) = points[0]
        points = [(x - half * into[0], y - half * into[1]), (x + half * out[0], y + half * out[1])]
    start, end = points[0], points[-1]
    extended = [
        (start[0] - EXTENSION * into[0], start[1] - EXTENSION * into[1]),
        *points,
        (end[0] + EXTENSION * out[0], end[1] + EXTENSION * out[1]),
    ]
    body = LineString(extended).buffer(width / 2.0, cap_style="flat", join_style="round")
    behind_stop_line = _box_behind(start, into, width)
    beyond_exit = _box_behind(end, (-out[0], -out[1]), width)
    return ConnectingLane(
        id=chain[0],
        internal_lanes=tuple(chain),
        centreline=LineString(points),
        polygon=body.difference(unary_union([behind_stop_line, beyond_exit])),
        width=width,
    )


EXTENSION = 3.0  # metres the centreline is extended before cutting its ends square
MIN_LENGTH = 0.1  # metres: SUMO's shortest lane


def _direction(points: Sequence[tuple[float, float]], at_end: bool) -> tuple[float, float] | None:
    """The unit vector of the last (``at_end``) or first segment of deduplicated
    ``points``; None for a single point."""
    if len(points) < 2:
        return None
    a, b = (points[-2], points[-1]) if at_end else (points[0], points[1])
    length = math.dist(a, b)
    return (b[0] - a[0]) / length, (b[1] - a[1]) / length


def _box_behind(
    point: tuple[float, float], direction: tuple[float, float], width: float
) -> Polygon:
    """The strip of road just behind a line through ``point`` square to ``direction``."""
    (x, y), (ux, uy) = point, direction
    nx, ny = -uy * width, ux * width
    depth = EXTENSION + 1.0
    return Polygon(
        [
            (x + nx, y + ny),
            (x + nx - ux * depth, y + ny - uy * depth),
            (x - nx - ux * depth, y - ny - uy * depth),
            (x - nx, y - ny),
        ]
    )
