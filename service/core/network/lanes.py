"""Walking SUMO's lane graph: internal-lane chains, and straight-ahead continuations.

Real maps (OpenDRIVE, OSM) have forks and exits shorter than a metre, so anything that needs
the approach to or the departure from a junction walks on to the upstream or downstream lanes.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

Point = tuple[float, float]
SumoNet = Any  # sumolib.net.Net; sumolib ships no type information
SumoLane = Any
SumoConnection = Any


def is_internal(lane_id: str) -> bool:
    return lane_id.startswith(":")


def roads_in(node: Any) -> list[Any]:
    """The roads cars drive into ``node`` on (internal edges do not count), by id."""
    edges = [
        edge
        for edge in node.getIncoming()
        if edge.getFunction() != "internal" and edge.allows("passenger")
    ]
    return sorted(edges, key=lambda edge: str(edge.getID()))


def shape_2d(lane: SumoLane) -> list[Point]:
    return [(float(p[0]), float(p[1])) for p in lane.getShape()]


def heading_of(start: Point, end: Point) -> float:
    """Heading of the vector start->end in degrees clockwise from north, in [0, 360)."""
    return math.degrees(math.atan2(end[0] - start[0], end[1] - start[1])) % 360.0


def heading_difference(a: float, b: float) -> float:
    """Smallest absolute angle between two headings, in [0, 180]."""
    diff = abs(a - b) % 360.0
    return min(diff, 360.0 - diff)


def via_chain(net: SumoNet, connection: SumoConnection) -> list[str]:
    """Internal lanes of a connection in driving order (SUMO splits some at internal junctions)."""
    chain: list[str] = []
    via = connection.getViaLaneID()
    target = connection.getToLane().getID()
    while via:
        chain.append(via)
        following = [c for c in net.getLane(via).getOutgoing() if c.getToLane().getID() == target]
        via = following[0].getViaLaneID() if following else ""
    return chain


def _end_heading(shape: Sequence[Point]) -> float:
    return heading_of(shape[-2], shape[-1])


def _start_heading(shape: Sequence[Point]) -> float:
    return heading_of(shape[0], shape[1])


def straightest_predecessor(net: SumoNet, lane: SumoLane, avoid_node: str) -> SumoConnection | None:
    """The incoming connection from a normal lane that bends least, not from ``avoid_node``."""
    candidates = [
        c
        for c in lane.getIncomingConnections()
        if not is_internal(c.getFromLane().getID())
        and c.getFromLane().getEdge().getFromNode().getID() != avoid_node
        and c.getFromLane().allows("passenger")
    ]
    if not candidates:
        return None
    own = _start_heading(shape_2d(lane))
    return min(
        candidates,
        key=lambda c: (
            heading_difference(_end_heading(shape_2d(c.getFromLane())), own),
            c.getFromLane().getID(),
        ),
    )


def straightest_successor(net: SumoNet, lane: SumoLane, avoid_node: str) -> SumoConnection | None:
    """The outgoing connection to a normal lane that bends least, not into ``avoid_node``."""
    candidates = [
        c
        for c in lane.getOutgoing()
        if not is_internal(c.getToLane().getID())
        and c.getToLane().getEdge().getToNode().getID() != avoid_node
        and c.getToLane().allows("passenger")
        and c.getDirection() != "t"
    ]
    if not candidates:
        return None
    own = _end_heading(shape_2d(lane))
    return min(
        candidates,
        key=lambda c: (
            heading_difference(_start_heading(shape_2d(c.getToLane())), own),
            c.getToLane().getID(),
        ),
    )


def approach_polyline(net: SumoNet, lane: SumoLane, junction: str, length: float) -> list[Point]:
    """The last ``length`` metres (or what exists) of driving that ends at ``lane``'s end."""
    points = shape_2d(lane)
    covered = lane.getLength()
    current = lane
    while covered < length:
        connection = straightest_predecessor(net, current, junction)
        if connection is None:
            break
        for via in reversed(via_chain(net, connection)):
            points = shape_2d(net.getLane(via)) + points
        current = connection.getFromLane()
        points = shape_2d(current) + points
        covered += current.getLength()
    return dedupe(points)


def departure_polyline(net: SumoNet, lane: SumoLane, junction: str, length: float) -> list[Point]:
    """The first ``length`` metres (or what exists) of driving that starts at ``lane``'s start."""
    points = shape_2d(lane)
    covered = lane.getLength()
    current = lane
    while covered < length:
        connection = straightest_successor(net, current, junction)
        if connection is None:
            break
        for via in via_chain(net, connection):
            points = points + shape_2d(net.getLane(via))
        current = connection.getToLane()
        points = points + shape_2d(current)
        covered += current.getLength()
    return dedupe(points)


def dedupe(points: Sequence[Point]) -> list[Point]:
    """``points`` without repeats: SUMO writes zero-length lanes as two equal points."""
    if not points:
        return []
    kept = [points[0]]
    for point in points[1:]:
        if math.dist(point, kept[-1]) > 1e-6:
            kept.append(point)
    return kept


SIDE_LANE_SPEED_SHARE = 0.5  # a lane slower than half its road's fastest lane is a side lane


def side_lane_reason(lane: SumoLane, into_junction: bool) -> str | None:
    """Why ``lane`` is not for driving through a junction, or None when it is.

    A side lane (a parking lane, a bay) is one whose speed limit is below half of the
    fastest lane of its own road, or, as a fork (``into_junction``), one no lane leads into
    while another lane of its road is fed; as an exit, one that leads nowhere while another
    lane of its road leads on. A road at the map's border (no lane fed, or none leading on)
    is a road like any other: the comparison is always with the lane's own road.
    """
    siblings = [
        other
        for other in lane.getEdge().getLanes()
        if other is not lane and other.allows("passenger")
    ]
    fastest = max((other.getSpeed() for other in siblings), default=0.0)
    if lane.getSpeed() < SIDE_LANE_SPEED_SHARE * fastest:
        return f"{lane.getSpeed():g} m/s where its road allows {fastest:g} m/s (parking or a bay)"
    if into_junction and not _fed(lane) and any(_fed(other) for other in siblings):
        return "no lane leads into it, while its road's other lanes are fed"
    if not into_junction and not _leads_on(lane) and any(_leads_on(o) for o in siblings):
        return "it leads nowhere, while its road's other lanes lead on"
    return None


def _fed(lane: SumoLane) -> bool:
    return any(not is_internal(c.getFromLane().getID()) for c in lane.getIncomingConnections())


def _leads_on(lane: SumoLane) -> bool:
    return any(not is_internal(c.getToLane().getID()) for c in lane.getOutgoing())
