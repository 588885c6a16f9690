"""A junction's pedestrian crossings and the walks over them (docs/pedestrians.md).

SUMO models a crosswalk as an internal edge of the junction with ``function="crossing"``
(``:J_cN``, one lane ``:J_cN_0``, ``crossingEdges`` naming the roads it crosses) between
two walking areas (``:J_wN``, the corners where sidewalks and crossings meet). The net
holds one connection into the crossing (walking area -> crossing) and one out of it
(crossing -> walking area): they give its two ends in the direction of its centreline, and
at a signalized junction the connection into it carries the pedestrian signal's link
(``tl``/``linkIndex``; netconvert numbers the crossings after the vehicles' links).

Decisions (tested in tests/core/network/test_crossings.py):

- The crossing's polygon is its centreline widened to its width, flat at both curbs.
- A walk's ``before`` and ``after`` are sidewalk lanes that touch its start and end
  walking areas, preferring a lane of a road the crossing does *not* cross: a person
  route ``[before's edge, after's edge]`` then joins two roads that meet only at this
  junction, and SUMO's router takes the shortest way between them, over this crossing
  (the other way round the junction crosses three roads). A road the crossing crosses
  would meet its opposite direction again at the node at its far end, so SUMO could walk
  round there.
- A walking area without any sidewalk is a traffic island between two crossings (a road
  split by a median: Town05's junctions 2014 and 2328 with guessed crossings). A walk
  that ends on an island has the crossing's own lane as ``after``: libsumo walks a person
  from ``before``'s edge to the crossing's and she arrives on it at the island's curb
  (arrival position: the crossing's length walking along its centreline, 0 against it);
  SUMO refuses a walk that ends on the walking area itself ("Disconnected walk"). A walk
  that starts on an island has no ``before`` (""): a person added on the island's walking
  area only ever leaves it forwards, along the lane that SUMO's connections lead into
  from there, so against the crossing's centreline SUMO walks her the other way round
  the junction; Step 1 places such a person on the walk's path itself.
- A walk conflicts with a vehicle route when the route's connecting lane overlaps the
  crossing's polygon in a region that holds a disc of ``SLIVER_RADIUS`` (relations.py):
  the same test as two routes, so a lane grazing the crossing's corner does not count.
"""

from __future__ import annotations

import functools
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from shapely.geometry import LineString

from service.core.errors import UnsupportedIntersection
from service.core.network.lanes import dedupe, heading_of, is_internal, shape_2d
from service.core.network.model import ConnectingLane, Crossing, Route, Walk, walk_id
from service.core.network.relations import SLIVER_RADIUS, overlap_thickness


def crossed_edges(path: Path) -> dict[str, tuple[str, ...]]:
    """Crossing edge id -> the road edges it crosses (``crossingEdges``), for every crossing
    of the network file ``path`` (read once per version of the file). sumolib's lxml reader
    never fills ``Edge.getCrossingEdges``, so the attribute is read here."""
    status = path.stat()
    return _crossed_edges(path, status.st_mtime_ns, status.st_size)


@functools.lru_cache(maxsize=8)
def _crossed_edges(path: Path, mtime: int, size: int) -> dict[str, tuple[str, ...]]:
    found: dict[str, tuple[str, ...]] = {}
    for _, element in ET.iterparse(path, events=("end",)):
        if element.tag == "edge" and element.get("function") == "crossing":
            found[element.get("id", "")] = tuple(element.get("crossingEdges", "").split())
        if element.tag in ("edge", "connection", "junction", "tlLogic"):
            element.clear()
    return found


def build_crossings(
    net: Any, node: Any, network_file: Path, tls: str | None
) -> dict[str, Crossing]:
    """The crossings of ``node`` by id; ``tls``: the junction's traffic light, whose links
    give the crossings' pedestrian signals (None: no signals)."""
    edges = [e for e in node.getIncoming() if e.getFunction() == "crossing"]
    if not edges:
        return {}
    crossed = crossed_edges(network_file)
    crossings: dict[str, Crossing] = {}
    for edge in sorted(edges, key=_crossing_order):
        lane = edge.getLanes()[0]
        points = dedupe(shape_2d(lane))
        into = [c for c in lane.getIncomingConnections() if _walking_area(c.getFromLane())]
        out = [c for c in lane.getOutgoing() if _walking_area(c.getToLane())]
        if len(points) < 2 or not into or not out:
            raise UnsupportedIntersection(
                f"crossing {edge.getID()!r} of junction {node.getID()!r} "
                + ("has no length" if len(points) < 2 else "does not join two walking areas")
                + ": rebuild the network's crossings (netconvert --crossings.guess)",
                junction=str(node.getID()),
            )
        signal = into[0]
        link = int(signal.getTLLinkIndex()) if tls and signal.getTLSID() == tls else -1
        centreline = LineString(points)
        width = float(lane.getWidth())
        crossings[edge.getID()] = Crossing(
            id=edge.getID(),
            lane=lane.getID(),
            edges=crossed.get(edge.getID(), ()),
            centreline=centreline,
            polygon=centreline.buffer(width / 2.0, cap_style="flat"),
            width=width,
            ends=(into[0].getFromLane().getEdge().getID(), out[0].getToLane().getEdge().getID()),
            link_index=link,
        )
    return crossings


def build_walks(
    net: Any,
    crossings: Mapping[str, Crossing],
    routes: Mapping[str, Route],
    lanes: Mapping[str, ConnectingLane],
    sliver_radius: float = SLIVER_RADIUS,
) -> dict[str, Walk]:
    """Two walks per crossing, along its centreline (``+``) and against it (``-``), by id."""
    walks: dict[str, Walk] = {}
    for crossing in crossings.values():
        conflicts = tuple(
            sorted(
                route.id
                for route in routes.values()
                if overlap_thickness(lanes[route.connecting_lane].polygon, crossing.polygon)
                >= sliver_radius
            )
        )
        for along in (True, False):
            start, end = crossing.ends if along else crossing.ends[::-1]
            points = list(crossing.centreline.coords)
            path = LineString(points if along else points[::-1])
            walk = Walk(
                id=walk_id(crossing.id, along),
                crossing=crossing.id,
                start=start,
                end=end,
                path=path,
                heading=round(heading_of(path.coords[0], path.coords[-1]), 6),
                before=sidewalk(net, start, crossing.edges),
                after=sidewalk(net, end, crossing.edges) or crossing.lane,
                conflicts=conflicts,
            )
            walks[walk.id] = walk
    return walks


def sidewalk(net: Any, walking_area: str, crossed: tuple[str, ...]) -> str:
    """A lane that people walk on to or from ``walking_area`` (not a crossing): of a road
    the crossing does not cross first, then lanes for people only, then by id ("" when
    there is none: a traffic island, see the module docstring)."""
    area = net.getEdge(walking_area).getLanes()[0]
    touching = {c.getFromLane() for c in area.getIncomingConnections()}
    touching |= {c.getToLane() for c in area.getOutgoing()}
    candidates = [lane for lane in touching if not is_internal(lane.getID())]
    if not candidates:
        return ""
    best = min(
        candidates,
        key=lambda lane: (
            lane.getEdge().getID() in crossed,
            lane.allows("passenger"),
            lane.getID(),
        ),
    )
    return str(best.getID())


def _walking_area(lane: Any) -> bool:
    return bool(lane.getEdge().getFunction() == "walkingarea")


def _crossing_order(edge: Any) -> tuple[int, str]:
    """``:J_c2`` before ``:J_c10``: SUMO's numbering, not the text's order."""
    tail = str(edge.getID()).rpartition("_c")[2]
    return (int(tail) if tail.isdigit() else 1 << 30, str(edge.getID()))
