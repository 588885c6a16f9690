"""A junction's forks and exits: where each fork's limit line is, and what a car crosses it into.

The limit line of a fork is where SUMO's driver stops for the fork's link: the end of the
lane that carries the first controlled connection on the way into the junction. That is
the fork's own end, except at a signalized junction whose light also controls the node
just before it, over a fork shorter than a car (``SHORT_APPROACH``): netconvert's joined
clusters (``joinedS_*``) have such forks, 0.2 m between two nodes of one light. There
SUMO's driver stops at the end of the lane before that node, for the light's link there,
and a car waiting at the fork's own end would stand across that line. So the limit line is
the end of that upstream lane (further upstream while the lanes stay that short), the
route's signal is that link's, and ``limit_offset`` is how far the line lies before the
fork's end.

A car of the fork enters the junction when its rectangle first overlaps the fork's
``entry`` area: the junction polygon (and, before a short fork, the lanes from the limit
line to it) without the road behind the limit line. A junction's polygon may reach
upstream of a limit line (the Nuremberg cluster's by 2.3 m): a car that waits at the line
has not entered.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from shapely.geometry import LineString, MultiPolygon, Polygon
from shapely.ops import substring, unary_union

from service.core.errors import UnsupportedIntersection
from service.core.network.lanes import (
    approach_polyline,
    dedupe,
    departure_polyline,
    heading_of,
    shape_2d,
    straightest_predecessor,
    via_chain,
)
from service.core.network.model import Exit, Fork, Route
from service.core.network.relations import APPROACH_WINDOW

DRAWN_LENGTH = 30.0  # metres of approach and departure kept for pictures
SHORT_APPROACH = 5.0  # metres (SUMO's default car length): lanes between two stop lines of
# one light this short hold no waiting car, so the upstream line is the limit line
STOP_STATES = {"s", "w"}
NO_AREA = 1e-9  # square metres: a clip that removes no more than this removes nothing


@dataclass(frozen=True)
class Limit:
    """Where a fork's limit line is: the lane whose end it is, metres from it to the fork's
    end, and the traffic light's link there (None: the fork's own connections')."""

    lane: Any  # sumolib lane
    offset: float
    link: int | None
    between: tuple[str, ...]  # the lanes from the limit line to the fork's end (internal
    # lanes and short lanes, in driving order, the fork last)


def fork_limit(net: Any, lane: Any, junction: str, tls: str) -> Limit:
    """The limit line of fork ``lane`` of ``junction`` whose links belong to traffic light
    ``tls`` ("" without one): see the module docstring."""
    current, offset, link = lane, 0.0, None
    between = [lane.getID()]
    while tls:
        connection = straightest_predecessor(net, current, junction)
        if connection is None or connection.getTLSID() != tls:
            break
        chain = via_chain(net, connection)
        further = offset + current.getLength() + sum(net.getLane(v).getLength() for v in chain)
        if further >= SHORT_APPROACH:
            break
        between = [*chain, *([] if current is lane else [current.getID()]), *between]
        current, offset = connection.getFromLane(), further
        link = int(connection.getTLLinkIndex())
    return Limit(current, offset, link, tuple(between))


def build_fork(
    net: Any, lane: Any, junction: str, routes: dict[str, Route], limit: Limit, area: Polygon
) -> Fork:
    """The fork on ``lane``: its limit line, heading there, drawn approach and entry area
    (``area``: the junction's polygon)."""
    drawn = _drawn(approach_polyline(net, lane, junction, DRAWN_LENGTH), lane)
    behind = drawn  # the road that ends at the limit line
    if limit.lane is not lane:
        behind = _drawn(approach_polyline(net, limit.lane, junction, DRAWN_LENGTH), lane)
    states = {r.link_state for r in routes.values() if r.fork == lane.getID()}
    return Fork(
        lane=lane.getID(),
        edge=lane.getEdge().getID(),
        heading=round(chord_heading(behind, at_end=True), 6),
        stop_line=shape_2d(limit.lane)[-1],
        stop_sign=bool(states & STOP_STATES),
        width=lane.getWidth(),
        approach=clip(drawn, DRAWN_LENGTH, at_end=True),
        limit_lane=limit.lane.getID(),
        limit_offset=round(limit.offset, 6),
        entry=entry_area(net, area, behind, limit, lane.getWidth()),
    )


def entry_area(
    net: Any, area: Polygon, behind: list[tuple[float, float]], limit: Limit, width: float
) -> Polygon | MultiPolygon:
    """What a car of the fork enters by crossing its limit line: ``area`` (with the lanes
    from the limit line to the fork's end when they lie before it) without the road
    behind the line, a lane width to either side of the approach's centreline. ``area``
    itself where that removes nothing."""
    if limit.offset > 0:
        points = dedupe([p for lane_id in limit.between for p in shape_2d(net.getLane(lane_id))])
        if len(points) >= 2:
            corridor = LineString(points).buffer(width / 2.0, cap_style="flat")
            area = unary_union([area, corridor])
    road = LineString(behind).buffer(width, cap_style="flat") if len(behind) >= 2 else None
    if road is None or (limit.offset == 0 and area.intersection(road).area <= NO_AREA):
        return area
    clipped = area.difference(road)
    return clipped if isinstance(clipped, (Polygon, MultiPolygon)) else area


def chord_heading(points: list[tuple[float, float]], at_end: bool) -> float:
    """The heading of the chord over the last (``at_end``) or first APPROACH_WINDOW metres."""
    line = LineString(points)
    window = min(APPROACH_WINDOW, line.length)
    if at_end:
        start = line.interpolate(line.length - window)
        return heading_of((start.x, start.y), points[-1])
    end = line.interpolate(window)
    return heading_of(points[0], (end.x, end.y))


def _drawn(points: list[tuple[float, float]], lane: Any) -> list[tuple[float, float]]:
    """``points``, the road through ``lane``; UnsupportedIntersection when they are one
    point (a lane of no length, and no road before or after it)."""
    if len(points) < 2:
        raise UnsupportedIntersection(
            f"lane {lane.getID()!r} and the road before and after it have no length (one "
            f"point, {points[0] if points else 'none'}): no car can drive on it"
        )
    return points


def clip(points: list[tuple[float, float]], length: float, at_end: bool) -> LineString:
    """The last (``at_end``) or first ``length`` metres of ``points``."""
    line = LineString(points)
    if line.length <= length:
        return line
    if at_end:
        return substring(line, line.length - length, line.length)
    return substring(line, 0.0, length)


def build_exit(net: Any, lane: Any, junction: str) -> Exit:
    """The exit on ``lane``: its departure heading and drawn departure."""
    polyline = _drawn(departure_polyline(net, lane, junction, DRAWN_LENGTH), lane)
    return Exit(
        lane=lane.getID(),
        edge=lane.getEdge().getID(),
        heading=round(chord_heading(polyline, at_end=False), 6),
        width=lane.getWidth(),
        departure=clip(polyline, DRAWN_LENGTH, at_end=False),
    )
