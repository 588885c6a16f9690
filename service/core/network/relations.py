"""Relations between forks and routes that the traffic rules need.

Decisions (tested in tests/core/network):

- Two routes conflict when their connecting-lane polygons overlap in a region that holds a
  disc of radius ``SLIVER_RADIUS`` (the overlap is at least 1 m thick). Thinner overlaps are
  slivers: neighbouring lanes grazing at the junction border, opposite left turns nicking
  each other, curved lanes of one road rubbing at the centre line. Cars 1.8 m wide centred
  in 3.2 m lanes keep 0.7 m to each lane edge, so a graze thinner than 1.4 m cannot bring
  them together; 1 m stays on the safe side. On the bundled and CARLA junctions every real
  crossing or merge holds a disc of radius 1.4 m or more, every sliver less than 0.2 m.
- Routes that share a fork never conflict: their cars queue in the same lane, which is
  car-following, not right-of-way. (SUMO's conflict matrix has no link between them either.)
- Merges into the same exit lane conflict: both cars want the same space. Links that end in
  different lanes of one exit edge do not: the cars end side by side. SUMO's conflict matrix
  makes every two links into one edge foes; otherwise it and this rule agree on the bundled
  and CARLA junctions (tests/core/network/test_relations.py).
- Fork relations use approach headings (the chord over the last ``APPROACH_WINDOW`` metres
  before the stop line, walking upstream when the fork lane is short), so they hold for skewed
  and Y-shaped junctions: forks of one edge are the same road (``same_direction``); forks on
  other edges whose headings differ by at least 180 - ``OPPOSITE_TOLERANCE`` degrees are
  ``opposite`` (the same highway, head-on); of the rest, a fork whose traffic moves to the
  left across this fork's path, i.e. heads at 180-360 degrees relative to it, comes from its
  right. Near-parallel forks of different edges are placed by where their stop line lies.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import shapely
from shapely.geometry import Polygon
from shapely.geometry.base import BaseGeometry

from service.core.network.lanes import heading_difference
from service.core.network.model import ConnectingLane, Fork, Route

SLIVER_RADIUS = 0.5  # m
APPROACH_WINDOW = 10.0  # m
OPPOSITE_TOLERANCE = 45.0  # degrees
PARALLEL_TOLERANCE = 20.0  # degrees


def conflicting_routes(
    routes: Mapping[str, Route],
    lanes: Mapping[str, ConnectingLane],
    sliver_radius: float = SLIVER_RADIUS,
) -> dict[str, frozenset[str]]:
    """Route id -> ids of routes from other forks whose connecting lanes overlap it."""
    found: dict[str, set[str]] = {route_id: set() for route_id in routes}
    ordered = sorted(routes.values(), key=lambda r: r.id)
    for i, first in enumerate(ordered):
        for second in ordered[i + 1 :]:
            if first.fork == second.fork:
                continue
            polygon_a = lanes[first.connecting_lane].polygon
            polygon_b = lanes[second.connecting_lane].polygon
            if overlap_thickness(polygon_a, polygon_b) >= sliver_radius:
                found[first.id].add(second.id)
                found[second.id].add(first.id)
    return {route_id: frozenset(ids) for route_id, ids in found.items()}


def overlap_thickness(first: BaseGeometry, second: BaseGeometry) -> float:
    """Radius of the largest disc inside the overlap of two polygons (0 when they only touch)."""
    overlap = first.intersection(second)
    parts = getattr(overlap, "geoms", [overlap])
    radii = [
        shapely.maximum_inscribed_circle(part, 0.01).length
        for part in parts
        if isinstance(part, Polygon) and part.area > 0
    ]
    return max(radii, default=0.0)


def relative_heading(own: float, other: float) -> float:
    """Heading of ``other`` relative to ``own``, degrees clockwise in [0, 360)."""
    return (other - own) % 360.0


def _is_right_of(own: Fork, other: Fork) -> bool:
    if heading_difference(own.heading, other.heading) < PARALLEL_TOLERANCE:
        # Side by side: on the right when its stop line lies right of our direction of travel.
        dx = other.stop_line[0] - own.stop_line[0]
        dy = other.stop_line[1] - own.stop_line[1]
        rad = math.radians(own.heading)
        return dx * math.cos(rad) - dy * math.sin(rad) > 0
    return relative_heading(own.heading, other.heading) > 180.0


def fork_relations(
    forks: Mapping[str, Fork],
) -> tuple[dict[str, frozenset[str]], dict[str, frozenset[str]], dict[str, frozenset[str]]]:
    """(to_its_right, opposite, same_direction) for every fork."""
    right: dict[str, set[str]] = {lane: set() for lane in forks}
    opposite: dict[str, set[str]] = {lane: set() for lane in forks}
    same: dict[str, set[str]] = {lane: set() for lane in forks}
    for lane, own in forks.items():
        for other_lane, other in forks.items():
            if other_lane == lane:
                continue
            if other.edge == own.edge:
                same[lane].add(other_lane)
            elif heading_difference(own.heading, other.heading) >= 180.0 - OPPOSITE_TOLERANCE:
                opposite[lane].add(other_lane)
            elif _is_right_of(own, other):
                right[lane].add(other_lane)
    return (
        {k: frozenset(v) for k, v in right.items()},
        {k: frozenset(v) for k, v in opposite.items()},
        {k: frozenset(v) for k, v in same.items()},
    )
