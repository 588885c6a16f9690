"""Crossings and walks of a test network, read from its net file with sumolib and its XML.

The network loader does not read crossings yet (``Intersection.crossings`` and ``walks``
are empty on every network today); until it does, the checker's tests build them here the
way docs/pedestrians.md describes them: a crossing's polygon is its centreline widened to
its width, a walk's path is the centreline (``+``) or its reverse (``-``), and its
conflicts are the routes whose connecting lane overlaps the crossing's polygon by more than
a sliver (as two routes' lanes conflict: service.core.network.relations).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from pathlib import Path
from xml.etree import ElementTree as ET

from shapely.geometry import LineString

from service.core.network import Crossing, Intersection, Walk, load_intersection, parsed_network
from service.core.network.model import walk_id
from service.core.network.relations import SLIVER_RADIUS, overlap_thickness


def with_crossings(intersection: Intersection) -> Intersection:
    """``intersection`` with the crossings of its junction and the walks over them."""
    crossings = _crossings(intersection)
    walks: dict[str, Walk] = {}
    for crossing in crossings.values():
        conflicts = tuple(
            sorted(
                route.id
                for route in intersection.routes.values()
                if overlap_thickness(
                    intersection.connecting_lanes[route.connecting_lane].polygon,
                    crossing.polygon,
                )
                >= SLIVER_RADIUS
            )
        )
        for along in (True, False):
            path = crossing.centreline if along else LineString(crossing.centreline.coords[::-1])
            start, end = crossing.ends if along else crossing.ends[::-1]
            walk = Walk(
                walk_id(crossing.id, along), crossing.id, start, end, path, _heading(path),
                _sidewalk(intersection, start, into=True), _sidewalk(intersection, end, into=False),
                conflicts,
            )  # fmt: skip
            walks[walk.id] = walk
    return dataclasses.replace(intersection, crossings=crossings, walks=walks)


def _crossings(intersection: Intersection) -> dict[str, Crossing]:
    net = parsed_network(intersection.network_file)
    edges = _crossing_edges(str(intersection.network_file))
    found = {}
    for edge_id, crossed in edges.items():
        if not edge_id.startswith(f":{intersection.junction}_c"):
            continue
        lane = net.getEdge(edge_id).getLanes()[0]
        centreline = LineString(lane.getShape())
        width = lane.getWidth()
        (before,) = lane.getIncomingConnections()
        (after,) = lane.getOutgoing()
        found[edge_id] = Crossing(
            edge_id, lane.getID(), crossed, centreline,
            centreline.buffer(width / 2.0, cap_style="flat"), width,
            (before.getFromLane().getEdge().getID(), after.getToLane().getEdge().getID()),
            before.getTLLinkIndex(),
        )  # fmt: skip
    return found


@functools.cache
def _crossing_edges(network_file: str) -> dict[str, tuple[str, ...]]:
    """Crossing edge id -> the road edges it crosses (SUMO's crossingEdges)."""
    root = ET.parse(network_file).getroot()
    return {
        edge.get("id", ""): tuple(edge.get("crossingEdges", "").split())
        for edge in root.iter("edge")
        if edge.get("function") == "crossing"
    }


def _sidewalk(intersection: Intersection, walking_area: str, into: bool) -> str:
    """A sidewalk lane that leads into (or out of) a walking area."""
    net = parsed_network(intersection.network_file)
    area = net.getEdge(walking_area)
    edges = area.getIncoming() if into else area.getOutgoing()
    roads = sorted(e.getID() for e in edges if e.getFunction() == "")
    return f"{roads[0]}_0"


def _heading(path: LineString) -> float:
    (x0, y0), (x1, y1) = path.coords[0], path.coords[-1]
    return math.degrees(math.atan2(x1 - x0, y1 - y0)) % 360.0


JUNCTIONS = Path(__file__).parents[2] / "data" / "junctions"


@functools.cache
def stop_crossings() -> Intersection:
    """The bundled four-way all-way stop with sidewalks and crossings (car lanes 1 and 2)."""
    return with_crossings(load_intersection(JUNCTIONS / "stop-crossings.net.xml"))


@functools.cache
def signal_crossings() -> Intersection:
    """The bundled signalized four-way with sidewalks and crossings, its program in
    signal-crossings.tll.xml: north-south green 0-20 s (walk on :C_c1 and :C_c3 0-14 s,
    flashing 14-20 s), yellow 20-23, all red 23-25; east-west green 25-45 s (walk on :C_c0
    and :C_c2 25-39 s, flashing 39-45 s), yellow 45-48, all red 48-50."""
    return with_crossings(load_intersection(JUNCTIONS / "signal-crossings.net.xml"))
