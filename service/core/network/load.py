"""Load a SUMO network and build the intersection model of one of its junctions."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import sumolib
from shapely.geometry import LineString, Polygon
from shapely.ops import substring, unary_union

from service.core.errors import (
    InvalidInput,
    UnknownJunction,
    UnknownNetwork,
    UnsupportedIntersection,
    choices,
)
from service.core.network.convert import convert_network, source_format
from service.core.network.lanes import (
    approach_polyline,
    departure_polyline,
    heading_of,
    is_internal,
    shape_2d,
    via_chain,
)
from service.core.network.model import (
    ConnectingLane,
    ControlType,
    Exit,
    Fork,
    Intersection,
    Route,
    Turn,
)
from service.core.network.override import rebuild_with_control
from service.core.network.relations import (
    APPROACH_WINDOW,
    SLIVER_RADIUS,
    conflicting_routes,
    fork_relations,
)

SUPPORTED = tuple(c.value for c in ControlType)
TURNS = {"s": Turn.STRAIGHT, "l": Turn.LEFT, "L": Turn.LEFT, "r": Turn.RIGHT, "R": Turn.RIGHT}
STOP_STATES = {"s", "w"}
DRAWN_LENGTH = 30.0  # metres of approach and departure kept for pictures


def bundled_networks_dir() -> Path:
    """``sumo_nets/``: inside the installed package, or beside it in a source checkout."""
    package = Path(__file__).resolve().parents[2]
    for candidate in (package / "sumo_nets", package.parent / "sumo_nets"):
        if candidate.is_dir():
            return candidate
    raise UnknownNetwork("the bundled networks (sumo_nets/) are missing from this installation")


def bundled_networks() -> dict[str, Path]:
    """Short name -> path of every bundled network."""
    return {
        path.name.removesuffix(".net.xml"): path
        for path in sorted(bundled_networks_dir().glob("*.net.xml"))
    }


def resolve_network(ref: str | Path) -> Path:
    """A bundled network's short name or a path to a ``.net.xml``, as a path that exists;
    a ``.xodr`` or ``.osm`` file is converted first (service.core.network.convert)."""
    bundled = bundled_networks()
    if str(ref) in bundled:
        return bundled[str(ref)]
    path = Path(ref)
    if path.is_file():
        return convert_network(path.resolve()) if source_format(path) else path.resolve()
    raise UnknownNetwork(
        f"network {str(ref)!r} is neither a bundled network ({choices(bundled)}) "
        "nor a readable .net.xml, .xodr (OpenDRIVE) or .osm (OpenStreetMap) file",
        network=str(ref),
    )


def read_network(path: Path) -> Any:
    try:
        net = sumolib.net.readNet(str(path), withInternal=True)
    except Exception as exc:  # sumolib raises bare SAX and key errors on bad files
        raise InvalidInput(f"cannot read SUMO network {path}: {exc}", network=str(path)) from exc
    _check_geometry(net, path)
    return net


def _check_geometry(net: Any, path: Path) -> None:
    """A network a drive can use: lanes, and finite coordinates everywhere (a NaN would only
    surface later, inside SUMO or the checker)."""
    lanes = [lane for edge in net.getEdges() for lane in edge.getLanes()]
    if not lanes:
        raise InvalidInput(f"SUMO network {path.name} has no lanes", network=str(path))
    for node in net.getNodes():
        if not all(math.isfinite(c) for c in node.getCoord()):
            raise InvalidInput(
                f"SUMO network {path.name}: junction {node.getID()!r} has a coordinate that "
                "is not a finite number",
                network=str(path),
            )
    for lane in lanes:
        if not all(math.isfinite(c) for point in lane.getShape() for c in point):
            raise InvalidInput(
                f"SUMO network {path.name}: lane {lane.getID()!r} has a shape point that is "
                "not a finite number",
                network=str(path),
            )


def junction_arms(node: Any) -> int:
    """How many roads come into a junction (internal lanes do not count)."""
    return sum(1 for edge in node.getIncoming() if edge.getFunction() != "internal")


def _choose_junction(net: Any, path: Path, junction: str | None) -> str:
    nodes: dict[str, Any] = {
        str(node.getID()): node for node in net.getNodes() if node.getType() != "internal"
    }
    if junction is not None:
        if junction not in nodes:
            crossings = [j for j, node in nodes.items() if junction_arms(node) >= 3]
            raise UnknownJunction(
                f"junction {junction!r} is not in {path.name}; junctions with 3 or more "
                f"approaches: {choices(crossings)}",
                network=str(path),
            )
        return junction
    supported = [j for j, node in nodes.items() if node.getType() in SUPPORTED]
    if len(supported) == 1:
        return supported[0]
    crossings = [f"{j} ({n.getType()})" for j, n in nodes.items() if junction_arms(n) >= 3]
    reason = "several junctions" if supported else "no junction"
    raise UnknownJunction(
        f"{path.name} has {reason} of a supported control type ({', '.join(SUPPORTED)}); "
        f"name one with --junction (and --control to override its type). Junctions with 3 or "
        f"more approaches: {choices(crossings)}",
        network=str(path),
    )


def _parse_control(control: ControlType | str | None) -> ControlType | None:
    if control is None or isinstance(control, ControlType):
        return control
    try:
        return ControlType(control)
    except ValueError:
        raise InvalidInput(
            f"control type {control!r} is not supported; valid choices: {', '.join(SUPPORTED)}"
        ) from None


def load_intersection(
    network: str | Path,
    junction: str | None = None,
    control: ControlType | str | None = None,
    cache_dir: Path | None = None,
    sliver_radius: float = SLIVER_RADIUS,
) -> Intersection:
    """Build the intersection model of ``junction`` (default: the only supported one).

    With ``control``, the junction is rebuilt with netconvert to that control type first
    (the rebuilt network is cached in ``cache_dir``).
    """
    source = resolve_network(network)
    wanted = _parse_control(control)
    net = read_network(source)
    junction_id = _choose_junction(net, source, junction)
    current = net.getNode(junction_id).getType()
    effective = source
    if wanted is not None and wanted.value != current:
        effective = rebuild_with_control(source, junction_id, wanted.value, cache_dir)
        net = read_network(effective)
        current = net.getNode(junction_id).getType()
    if current not in SUPPORTED:
        raise UnsupportedIntersection(
            f"junction {junction_id!r} has control type {current!r}, which has no traffic-rule "
            f"set; supported types: {', '.join(SUPPORTED)} (override with --control)",
            junction=junction_id,
        )
    return _build(net, source, effective, junction_id, ControlType(current), sliver_radius)


def _build(
    net: Any,
    source: Path,
    effective: Path,
    junction: str,
    control: ControlType,
    sliver_radius: float,
) -> Intersection:
    node = net.getNode(junction)
    forks: dict[str, Fork] = {}
    exits: dict[str, Exit] = {}
    lanes: dict[str, ConnectingLane] = {}
    routes: dict[str, Route] = {}
    for edge in node.getIncoming():
        if edge.getFunction() == "internal":
            continue
        for lane in edge.getLanes():
            if not lane.allows("passenger"):
                continue
            for connection in lane.getOutgoing():
                turn = TURNS.get(connection.getDirection())
                to_lane = connection.getToLane()
                if turn is None or is_internal(to_lane.getID()) or not to_lane.allows("passenger"):
                    continue
                chain = via_chain(net, connection)
                if not chain:
                    raise UnsupportedIntersection(
                        f"junction {junction!r} has no internal lanes (network built with "
                        "--no-internal-links); rebuild it with internal links",
                        junction=junction,
                    )
                lanes[chain[0]] = _connecting_lane(net, chain, lane, to_lane)
                route = Route(
                    fork=lane.getID(),
                    exit=to_lane.getID(),
                    connecting_lane=chain[0],
                    turn=turn,
                    link_state=connection.getState(),
                )
                routes[route.id] = route
                exits.setdefault(to_lane.getID(), _exit(net, to_lane, junction))
            if any(r.fork == lane.getID() for r in routes.values()):
                forks[lane.getID()] = _fork(net, lane, junction, routes)
    if not routes:
        raise UnsupportedIntersection(
            f"junction {junction!r} has no connections for cars", junction=junction
        )
    right, opposite, same = fork_relations(forks)
    return Intersection(
        network_file=effective,
        source_file=source,
        junction=junction,
        control=control,
        overridden=effective != source,
        polygon=Polygon(shape_2d(node)).buffer(0),
        forks=forks,
        exits=exits,
        connecting_lanes=lanes,
        routes=dict(sorted(routes.items())),
        conflicts=conflicting_routes(routes, lanes, sliver_radius),
        to_its_right=right,
        opposite=opposite,
        same_direction=same,
    )


def _connecting_lane(net: Any, chain: list[str], fork: Any, exit_lane: Any) -> ConnectingLane:
    """One centreline and one polygon for a chain of internal lanes.

    The polygon ends square to the fork at the stop line and square to the exit where the
    exit lane starts; a flat buffer cap would end square to the curve instead and poke out
    of the junction by a few centimetres on turns.
    """
    points: list[tuple[float, float]] = []
    width = net.getLane(chain[0]).getWidth()
    for lane_id in chain:
        shape = shape_2d(net.getLane(lane_id))
        points.extend(p for p in shape if not points or p != points[-1])
    fork_shape, exit_shape = shape_2d(fork), shape_2d(exit_lane)
    into = _unit(fork_shape[-2], fork_shape[-1])
    out = _unit(exit_shape[0], exit_shape[1])
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


def _unit(a: tuple[float, float], b: tuple[float, float]) -> tuple[float, float]:
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


def _chord_heading(points: list[tuple[float, float]], at_end: bool) -> float:
    line = LineString(points)
    window = min(APPROACH_WINDOW, line.length)
    if at_end:
        start = line.interpolate(line.length - window)
        return heading_of((start.x, start.y), points[-1])
    end = line.interpolate(window)
    return heading_of(points[0], (end.x, end.y))


def _fork(net: Any, lane: Any, junction: str, routes: dict[str, Route]) -> Fork:
    polyline = approach_polyline(net, lane, junction, DRAWN_LENGTH)
    states = {r.link_state for r in routes.values() if r.fork == lane.getID()}
    return Fork(
        lane=lane.getID(),
        edge=lane.getEdge().getID(),
        heading=round(_chord_heading(polyline, at_end=True), 6),
        stop_line=shape_2d(lane)[-1],
        stop_sign=bool(states & STOP_STATES),
        width=lane.getWidth(),
        approach=_clip(polyline, DRAWN_LENGTH, at_end=True),
    )


def _clip(points: list[tuple[float, float]], length: float, at_end: bool) -> LineString:
    line = LineString(points)
    if line.length <= length:
        return line
    if at_end:
        return substring(line, line.length - length, line.length)
    return substring(line, 0.0, length)


def _exit(net: Any, lane: Any, junction: str) -> Exit:
    polyline = departure_polyline(net, lane, junction, DRAWN_LENGTH)
    return Exit(
        lane=lane.getID(),
        edge=lane.getEdge().getID(),
        heading=round(_chord_heading(polyline, at_end=False), 6),
        width=lane.getWidth(),
        departure=_clip(polyline, DRAWN_LENGTH, at_end=False),
    )
