"""The crossings of the network in the OpenDRIVE export: crosswalk objects, and at a
signalized junction the heads of the pedestrian signals.

netconvert writes every SUMO crossing as an ``<object type="crosswalk">`` (id the
crossing's, ``:C_c0``) on the road of an edge it crosses, but not as OpenDRIVE 1.5 has it:
the object lacks attributes the schema requires (``dynamic``, ``zOffset``,
``validLength``, ``orientation``, ``pitch``, ``roll``, ``height``), and its rectangle is
centred on the road's end (s = 0, or past the road's length), half the crossing's width
away from the crossing, which lies inside the junction just before the roads begin.
scengen writes each again, on the road netconvert chose:

- its origin: the reference line's point at the road's end nearer the crossing (s = 0 or
  the road's length: the crossing lies off the road's s range, in the junction), moved
  sideways (``t``) level with the crossing's centroid; ``hdg`` turns the local u axis along
  the crossing's centreline (the walking direction, as CARLA reads a crosswalk: it widens
  the outline along u to meet the sidewalks);
- its outline: the crossing's polygon, every corner as a ``cornerLocal`` (u, v) in that
  frame, counter-clockwise, closed; one ``<outline>`` directly in the object (OpenDRIVE
  1.4's form, which 1.5 keeps and CARLA reads). The polygon is ``Crossing.polygon`` for the
  crossings of the test-case's junction (where scengen's events and rules place them),
  and the crossing lane's shape widened to its width, the model's definition, for the
  other crossings of the network.

A reader computes a corner as origin + u (cos a, sin a) + v (-sin a, cos a), with a the
road's heading at the origin plus ``hdg``; scengen evaluates the reference line's ends from
the road's own geometry records (lines, arcs and netconvert's arc-length ``paramPoly3``).

At a signalized junction a crossing's link in the traffic light's program is its
pedestrian signal, for which netconvert writes no head. scengen adds one per crossing link,
id ``<tls>_<link index>`` as a vehicle link's head, type 1000002 (the German catalogue's
pedestrian light, a traffic light to CARLA), on the crosswalk's road at the curb where the
crossing's centreline starts, and lists it in the traffic light's ``<controller>``.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass

from shapely.geometry import LineString, Polygon
from shapely.geometry.polygon import orient

from service.core.errors import NetworkBuildFailed
from service.core.export.openscenario_signals import crossing_links, head_id
from service.core.network import Intersection, parsed_network
from service.core.network.lanes import dedupe, shape_2d

CROSSWALK = "crosswalk"
PEDESTRIAN_LIGHT = "1000002"  # German catalogue: a pedestrian light (red, green)


@dataclass(frozen=True)
class Pose:
    """A point of a road's reference line: its s, where it is, and the line's heading
    there (radians counter-clockwise from the x axis)."""

    s: float
    x: float
    y: float
    heading: float


@dataclass(frozen=True)
class Placement:
    """A crosswalk on its road: the object's origin (road coordinates ``s``, ``t``; world
    ``x``, ``y``), ``hdg`` relative to the road, and ``axis``, the world heading of its
    local u axis (the road's heading there plus ``hdg``)."""

    road: ET.Element
    s: float
    t: float
    x: float
    y: float
    hdg: float
    axis: float

    def local(self, x: float, y: float) -> tuple[float, float]:
        """The world point (x, y) in the object's local u, v."""
        dx, dy = x - self.x, y - self.y
        cos, sin = math.cos(self.axis), math.sin(self.axis)
        return dx * cos + dy * sin, -dx * sin + dy * cos

    def world(self, u: float, v: float) -> tuple[float, float]:
        """The local point (u, v) in world x, y."""
        cos, sin = math.cos(self.axis), math.sin(self.axis)
        return self.x + u * cos - v * sin, self.y + u * sin + v * cos

    def lateral(self, x: float, y: float) -> float:
        """``t`` of the world point (x, y) at the object's s: its offset to the left of the
        reference line."""
        heading = self.axis - self.hdg
        return self.t + (x - self.x) * -math.sin(heading) + (y - self.y) * math.cos(heading)


def _number(element: ET.Element, name: str) -> float:
    value = element.get(name)
    if value is None:
        raise NetworkBuildFailed(f"netconvert's OpenDRIVE: a <{element.tag}> without {name}")
    return float(value)


def _geometry_end(geometry: ET.Element) -> tuple[float, float, float]:
    """x, y and heading at the end of a ``<geometry>`` record of a plan view."""
    x, y, heading = (_number(geometry, k) for k in ("x", "y", "hdg"))
    length = _number(geometry, "length")
    shape = geometry[0] if len(geometry) else None
    if shape is not None and shape.tag == "line":
        return x + length * math.cos(heading), y + length * math.sin(heading), heading
    if shape is not None and shape.tag == "arc":
        k = _number(shape, "curvature")
        if k == 0.0:
            return x + length * math.cos(heading), y + length * math.sin(heading), heading
        end = heading + k * length
        dx, dy = math.sin(end) - math.sin(heading), math.cos(heading) - math.cos(end)
        return x + dx / k, y + dy / k, end
    if shape is not None and shape.tag == "paramPoly3":
        p = length if shape.get("pRange") == "arcLength" else 1.0
        a = [_number(shape, f"{c}U") for c in "abcd"]
        b = [_number(shape, f"{c}V") for c in "abcd"]
        u, v = (c[0] + c[1] * p + c[2] * p**2 + c[3] * p**3 for c in (a, b))
        du, dv = (c[1] + 2 * c[2] * p + 3 * c[3] * p**2 for c in (a, b))
        cos, sin = math.cos(heading), math.sin(heading)
        return x + u * cos - v * sin, y + u * sin + v * cos, heading + math.atan2(dv, du)
    kind = "empty" if shape is None else shape.tag
    raise NetworkBuildFailed(
        f"netconvert's OpenDRIVE: a {kind} geometry; scengen places crosswalks on roads of "
        "lines, arcs and paramPoly3 curves"
    )


def road_ends(road: ET.Element) -> tuple[Pose, Pose]:
    """The start (s = 0) and the end (s = the road's length) of a road's reference line."""
    geometries = road.findall("planView/geometry")
    if not geometries:
        raise NetworkBuildFailed(f"netconvert's OpenDRIVE: road {road.get('id')} has no geometry")
    first = geometries[0]
    start = Pose(0.0, *(_number(first, k) for k in ("x", "y", "hdg")))
    return start, Pose(_number(road, "length"), *_geometry_end(geometries[-1]))


def placement(road: ET.Element, polygon: Polygon, centreline: LineString) -> Placement:
    """Where a crossing's object stands on ``road`` (module docstring)."""
    centre = polygon.centroid
    near = min(road_ends(road), key=lambda p: math.hypot(p.x - centre.x, p.y - centre.y))
    left = (-math.sin(near.heading), math.cos(near.heading))
    t = (centre.x - near.x) * left[0] + (centre.y - near.y) * left[1]
    (x0, y0), (x1, y1) = centreline.coords[0], centreline.coords[-1]
    turn = math.atan2(y1 - y0, x1 - x0) - near.heading
    hdg = math.atan2(math.sin(turn), math.cos(turn))  # in [-pi, pi]
    return Placement(
        road, near.s, t, near.x + t * left[0], near.y + t * left[1], hdg, near.heading + hdg
    )


def _crossing_shapes(intersection: Intersection, crossing: str) -> tuple[Polygon, LineString]:
    """The polygon and centreline of a crossing: the model's for the junction's crossings,
    else the crossing lane's shape widened to its width."""
    known = intersection.crossings.get(crossing)
    if known is not None:
        return known.polygon, known.centreline
    net = parsed_network(intersection.network_file)
    try:
        lane = net.getEdge(crossing).getLanes()[0]
    except (KeyError, IndexError):
        raise NetworkBuildFailed(
            f"netconvert's OpenDRIVE has a crosswalk {crossing!r} that is no crossing of the "
            "network",
            junction=intersection.junction,
        ) from None
    line = LineString(dedupe(shape_2d(lane)))  # as the model reads a crossing
    return line.buffer(lane.getWidth() / 2, cap_style="flat"), line


def _f(value: float) -> str:
    return f"{round(value, 8) + 0.0:.8f}"  # netconvert's precision; never "-0.00000000"


def _crosswalk(crossing: str, where: Placement, polygon: Polygon) -> ET.Element:
    """The crosswalk object of ``crossing`` at ``where``, its outline ``polygon``."""
    element = ET.Element("object", {
        "type": CROSSWALK, "id": crossing, "name": f"crosswalk {crossing}",
        "s": _f(where.s), "t": _f(where.t), "zOffset": "0", "validLength": "0",
        "orientation": "none", "hdg": _f(where.hdg), "pitch": "0", "roll": "0",
        "height": "0", "dynamic": "no",
    })  # fmt: skip
    # the carriageway's surface, an area: its corners counter-clockwise, once each
    outline = ET.SubElement(element, "outline", {
        "id": "0", "fillType": "asphalt", "outer": "true", "closed": "true",
        "laneType": "driving",
    })  # fmt: skip
    for k, (x, y) in enumerate(orient(polygon, 1.0).exterior.coords[:-1]):
        u, v = where.local(x, y)
        ET.SubElement(outline, "cornerLocal", {
            "u": _f(u), "v": _f(v), "z": "0", "height": "0", "id": str(k),
        })  # fmt: skip
    return element


def replace_crosswalks(root: ET.Element, intersection: Intersection) -> dict[str, Placement]:
    """Write every crosswalk object netconvert wrote again (module docstring), on its
    road; where each stands, by crossing id. NetworkBuildFailed when a crossing of the
    junction has none."""
    placed: dict[str, Placement] = {}
    for road in root.iter("road"):
        objects = road.find("objects")
        if objects is None:
            continue
        for index, old in enumerate(list(objects)):
            if old.tag != "object" or old.get("type") != CROSSWALK:
                continue
            crossing = old.get("id", "")
            polygon, centreline = _crossing_shapes(intersection, crossing)
            placed[crossing] = placement(road, polygon, centreline)
            objects[index] = _crosswalk(crossing, placed[crossing], polygon)
    missing = sorted(set(intersection.crossings) - set(placed))
    if missing:
        raise NetworkBuildFailed(
            f"netconvert's OpenDRIVE has no crosswalk for the crossings {', '.join(missing)} "
            f"of junction {intersection.junction!r}",
            junction=intersection.junction,
        )
    return placed


def add_pedestrian_heads(
    root: ET.Element, intersection: Intersection, placed: dict[str, Placement]
) -> None:
    """A head for every crossing link of the junction's traffic light (module docstring),
    listed in its controller; nothing where the junction has none."""
    links = crossing_links(intersection)
    if not links or intersection.tls is None:
        return
    tls = intersection.tls
    controller = next((c for c in root.findall("controller") if c.get("id") == tls), None)
    for link, crossing in sorted(links.items()):
        where = placed.get(crossing)
        if where is None or controller is None:
            raise NetworkBuildFailed(
                f"netconvert's OpenDRIVE has no {'crosswalk' if where is None else 'controller'}"
                f" for the pedestrian signal {head_id(tls, link)} of crossing {crossing!r}",
                junction=intersection.junction,
            )
        _, centreline = _crossing_shapes(intersection, crossing)
        signals = where.road.find("signals")
        if signals is None:
            signals = ET.SubElement(where.road, "signals")
        # the schema's order: every <signal> before the first <signalReference>
        before = next((k for k, e in enumerate(signals) if e.tag != "signal"), len(signals))
        signals.insert(before, ET.Element("signal", {
            "s": _f(where.s), "t": _f(where.lateral(*centreline.coords[0])),
            "id": head_id(tls, link), "name": f"pedestrian signal {crossing}",
            "dynamic": "yes", "orientation": "none", "zOffset": "2.0",
            "country": "OpenDRIVE", "type": PEDESTRIAN_LIGHT, "subtype": "-1",
            "height": "0.6", "width": "0.3",
        }))  # fmt: skip
        ET.SubElement(controller, "control", {"signalId": head_id(tls, link)})
