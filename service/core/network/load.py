"""Load a SUMO network and build the intersection model of one of its junctions."""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import sumolib

from service.core.errors import (
    InvalidInput,
    UnknownJunction,
    UnknownNetwork,
    UnsupportedIntersection,
    choices,
)
from service.core.names import bundled_networks as bundled_networks
from service.core.network.convert import convert_network, source_format
from service.core.network.crossings import build_crossings, build_walks
from service.core.network.forks import Limit, build_exit, build_fork, fork_limit
from service.core.network.lanes import (
    is_internal,
    roads_in,
    side_lane_reason,
    via_chain,
)
from service.core.network.major import choose_major_road, lifted_priorities, yielding_roads
from service.core.network.model import (
    ConnectingLane,
    ControlType,
    Exit,
    Fork,
    Intersection,
    Route,
    Turn,
)
from service.core.network.override import rebuild_network
from service.core.network.paths import connecting_lane, junction_area
from service.core.network.relations import (
    SLIVER_RADIUS,
    conflicting_routes,
    fork_relations,
)
from service.core.network.signals import SignalProgram, network_program

SUPPORTED = tuple(c.value for c in ControlType)
# SUMO's junction types and the rule set each is tested under (every other type is refused:
# zipper, rail_crossing, rail_signal, left_before_right, unregulated, ...)
RULE_SETS = ", ".join(f"{c.value} -> {c.rule_set}" for c in ControlType)
TURNS = {"s": Turn.STRAIGHT, "l": Turn.LEFT, "L": Turn.LEFT, "r": Turn.RIGHT, "R": Turn.RIGHT}


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
        net = sumolib.net.readNet(str(path), withInternal=True, withPrograms=True)
    except Exception as exc:  # sumolib raises bare SAX and key errors on bad files
        raise InvalidInput(f"cannot read SUMO network {path}: {exc}", network=str(path)) from exc
    _check_geometry(net, path)
    return net


def _version(path: Path) -> tuple[int, int]:
    status = path.stat()
    return status.st_mtime_ns, status.st_size


@functools.lru_cache(maxsize=8)
def _read_version(path: Path, version: tuple[int, int]) -> Any:
    return read_network(path)


def parsed_network(path: Path) -> Any:
    """``read_network(path)``, parsed once per version of the file (its modification time
    and size) in this process: a junction's model reads its network and the rebuilt copy,
    Step 1 reads it again, and many junctions share one network. Callers only read it."""
    return _read_version(path, _version(path))


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
    """How many roads cars drive into a junction on (its approaches; internal lanes do
    not count)."""
    return len(roads_in(node))


def _choose_junction(
    net: Any, path: Path, junction: str | None, control: ControlType | None
) -> str:
    """The junction named; else the only junction with 3 or more approaches, of a
    supported type unless ``control`` overrides the type."""
    nodes: dict[str, Any] = {
        str(node.getID()): node for node in net.getNodes() if node.getType() != "internal"
    }
    crossings = [j for j, node in nodes.items() if junction_arms(node) >= 3]
    if junction is not None:
        if junction not in nodes:
            raise UnknownJunction(
                f"junction {junction!r} is not in {path.name}; junctions with 3 or more "
                f"approaches: {choices(crossings)}",
                network=str(path),
            )
        return junction
    if control is not None:
        if len(crossings) == 1:
            return crossings[0]
        reason = "several junctions" if crossings else "no junction"
        raise UnknownJunction(
            f"{path.name} has {reason} with 3 or more approaches; name one with --junction: "
            f"{choices(f'{j} ({nodes[j].getType()})' for j in crossings)}",
            network=str(path),
        )
    supported = [j for j in crossings if nodes[j].getType() in SUPPORTED]
    if len(supported) == 1:
        return supported[0]
    if len(crossings) == 1:
        only = crossings[0]
        raise UnsupportedIntersection(
            f"the only junction of {path.name} with 3 or more approaches, {only!r}, has "
            f"control type {nodes[only].getType()!r}, which has no traffic-rule set; give "
            f"--control ({', '.join(SUPPORTED)}). SUMO junction types and their rule sets: "
            f"{RULE_SETS}",
            junction=only,
        )
    reason = "several junctions" if supported else "no junction"
    raise UnknownJunction(
        f"{path.name} has {reason} of a supported control type ({', '.join(SUPPORTED)}); "
        f"name one with --junction (and --control to override its type). Junctions with 3 or "
        f"more approaches: {choices(f'{j} ({nodes[j].getType()})' for j in crossings)}",
        network=str(path),
    )


def _check_approaches(node: Any) -> None:
    """UnsupportedIntersection for a node that is not a junction: fewer than three roads in."""
    roads = [str(edge.getID()) for edge in roads_in(node)]
    if len(roads) < 3:
        raise UnsupportedIntersection(
            f"node {node.getID()!r} is not a junction to test: {len(roads)} "
            f"{'road leads' if len(roads) == 1 else 'roads lead'} into it "
            f"({', '.join(roads) or 'none'}), a junction has 3 or more approaches",
            junction=str(node.getID()),
        )


def _parse_control(control: ControlType | str | None) -> ControlType | None:
    if control is None or isinstance(control, ControlType):
        return control
    try:
        return ControlType(control)
    except ValueError:
        raise InvalidInput(
            f"control type {control!r} is not supported; valid choices: {', '.join(SUPPORTED)} "
            f"(SUMO junction types and their rule sets: {RULE_SETS})"
        ) from None


def load_intersection(
    network: str | Path,
    junction: str | None = None,
    control: ControlType | str | None = None,
    cache_dir: Path | None = None,
    sliver_radius: float = SLIVER_RADIUS,
    major_road: Sequence[str] | None = None,
    guess_crossings: bool = False,
) -> Intersection:
    """Build the intersection model of ``junction`` (default: the only junction with 3 or
    more approaches, of a supported type unless ``control`` is given).

    With ``control``, the junction is rebuilt with netconvert to that control type first
    (the rebuilt network is cached in ``cache_dir``). ``major_road``: the two roads into a
    ``priority_stop`` or ``priority`` junction that keep the right of way (rebuilt too); by
    default the network's, or for a junction made priority_stop or priority whose roads all
    have the same priority, the pair closest to straight across. ``guess_crossings``: the
    network gets sidewalks and crossings (netconvert --sidewalks.guess --crossings.guess, in
    the same rebuild): every road's car lanes then move up by one lane index, and a signalized
    junction gets a program with its crossings' links. A node that is not a junction
    (fewer than three approaches, no two routes that cross or merge) is
    UnsupportedIntersection.
    """
    source = resolve_network(network)
    wanted = _parse_control(control)
    net = parsed_network(source)
    named = Path(network) if str(network) not in bundled_networks() else Path(source.name)
    junction_id = _choose_junction(net, named, junction, wanted)
    node = net.getNode(junction_id)
    _check_approaches(node)
    current = node.getType()
    target = wanted.value if wanted is not None else current
    major = choose_major_road(net, node, target, current, major_road)
    effective = source
    retyped = target != current or major_road is not None
    if retyped or guess_crossings:
        priorities = lifted_priorities(node, major) if major else None
        effective = rebuild_network(
            source,
            junction_id if retyped else None,
            target if retyped else None,
            cache_dir,
            priorities,
            guess_crossings,
        )
        net = parsed_network(effective)
        current = net.getNode(junction_id).getType()
    if current not in SUPPORTED:
        raise UnsupportedIntersection(
            f"junction {junction_id!r} has control type {current!r}, which has no traffic-rule "
            f"set; SUMO junction types and their rule sets: {RULE_SETS} (override with "
            "--control)",
            junction=junction_id,
        )
    intersection = _model(
        source, effective, _version(effective), junction_id, ControlType(current), sliver_radius
    )
    return dataclasses.replace(
        intersection, overridden=retyped, crossings_guessed=guess_crossings, major_road=major
    )


@functools.lru_cache(maxsize=32)
def _model(
    source: Path,
    effective: Path,
    version: tuple[int, int],
    junction: str,
    control: ControlType,
    sliver_radius: float,
) -> Intersection:
    """The model of ``junction`` in (this ``version`` of) ``effective``, built once per
    process: commands and workers load one junction many times. Nobody changes a model."""
    intersection = _build(
        parsed_network(effective), source, effective, junction, control, sliver_radius
    )
    _check_conflicts(intersection)
    return intersection


def _check_conflicts(intersection: Intersection) -> None:
    """UnsupportedIntersection when no two routes cross or merge: nobody gives way."""
    if not any(intersection.conflicts.values()):
        raise UnsupportedIntersection(
            f"junction {intersection.junction!r} is not a junction to test: none of its "
            f"{len(intersection.routes)} routes crosses or merges with another, so no car "
            "ever gives way",
            junction=intersection.junction,
        )


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
    lights: set[str] = set()
    limits: dict[str, tuple[Any, Limit]] = {}  # fork lane id -> (lane, its limit line)
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
                lanes[chain[0]] = connecting_lane(net, chain, lane, to_lane)
                tls = connection.getTLSID() if control.signalized else ""
                lights.add(str(connection.getTLSID() or ""))
                if lane.getID() not in limits:
                    limits[lane.getID()] = (lane, fork_limit(net, lane, junction, tls))
                limit = limits[lane.getID()][1]
                own = int(connection.getTLLinkIndex()) if tls else -1
                route = Route(
                    fork=lane.getID(),
                    exit=to_lane.getID(),
                    connecting_lane=chain[0],
                    turn=turn,
                    link_state=connection.getState(),
                    link_index=own if limit.link is None else limit.link,
                )
                routes[route.id] = route
                exits.setdefault(to_lane.getID(), build_exit(net, to_lane, junction))
    if not routes:
        raise UnsupportedIntersection(
            f"junction {junction!r} has no connections for cars", junction=junction
        )
    lights.discard("")
    _check_unsignalized(net, junction, control, lights)
    area = junction_area(node, lanes)
    minor = yielding_roads(routes.values()) if control == ControlType.PRIORITY else frozenset()
    for lane_id, (lane, limit) in limits.items():
        fork = build_fork(net, lane, junction, routes, limit, area)
        forks[lane_id] = dataclasses.replace(fork, yield_sign=fork.edge in minor)
    right, opposite, same = fork_relations(forks)
    tls, links, program, refused = _traffic_light(net, junction, control, lights)
    crossings = build_crossings(net, node, effective, tls)
    return Intersection(
        network_file=effective,
        source_file=source,
        junction=junction,
        control=control,
        overridden=False,  # load_intersection says whether it retyped the junction
        polygon=area,
        forks=forks,
        exits=exits,
        connecting_lanes=lanes,
        routes=dict(sorted(routes.items())),
        conflicts=conflicting_routes(routes, lanes, sliver_radius),
        to_its_right=right,
        opposite=opposite,
        same_direction=same,
        side_lanes=_side_lanes(net, [*forks, *exits], set(forks)),
        tls=tls,
        tls_links=links,
        signals=program,
        signals_refused=refused,
        crossings=crossings,
        walks=build_walks(net, crossings, routes, lanes, sliver_radius),
    )


def _check_unsignalized(net: Any, junction: str, control: ControlType, lights: set[str]) -> None:
    """UnsupportedIntersection for a junction of a type without signals whose links still
    belong to a traffic light: netconvert keeps them in a light the junction shares with
    other nodes (a joined cluster's ``joinedS_*``) when its type is changed, so SUMO's
    drivers would still obey that light while the rules know of none."""
    if control.signalized or not lights:
        return
    shared = sorted(
        {
            str(c[0].getEdge().getToNode().getID())
            for tls in lights
            for c in net.getTLS(tls).getConnections()
        }
        - {junction}
    )
    raise UnsupportedIntersection(
        f"junction {junction!r} is of type {control.value} but its links belong to traffic "
        f"light {', '.join(sorted(lights))}, which also controls {', '.join(shared) or 'it'}; "
        "netconvert keeps them there when the type is changed, so SUMO's drivers would obey "
        "the light: test it as traffic_light",
        junction=junction,
    )


def _traffic_light(
    net: Any, junction: str, control: ControlType, lights: set[str]
) -> tuple[str | None, int, SignalProgram | None, str | None]:
    """The traffic light of a signalized junction: its id, how many links it controls, its
    program when that is fixed-time, and otherwise why not (a test-case may give one)."""
    if not control.signalized:
        return None, 0, None, None
    if len(lights) != 1:
        what = (
            f"{len(lights)} traffic lights ({', '.join(sorted(lights))})"
            if lights
            else ("no traffic light")
        )
        raise UnsupportedIntersection(
            f"junction {junction!r} is of type {control.value} but its connections have "
            f"{what}; scengen tests a junction controlled by one traffic light",
            junction=junction,
        )
    tls = next(iter(lights))
    links = 1 + max(int(c[2]) for c in net.getTLS(tls).getConnections())
    try:
        program = network_program(net, tls)
    except InvalidInput as refused:
        return tls, links, None, str(refused)
    if program.links != links:
        return (
            tls,
            links,
            None,
            (
                f"the program {program.program_id!r} of traffic light {tls!r} has "
                f"{program.links} colours per phase but the light controls {links} links; give "
                "a program with --signals FILE"
            ),
        )
    return tls, links, program, None


def _side_lanes(net: Any, lanes: Sequence[str], forks: set[str]) -> dict[str, str]:
    """The forks and exits that are not for driving through, each with the reason."""
    found = {lane: side_lane_reason(net.getLane(lane), lane in forks) for lane in sorted(lanes)}
    return {lane: reason for lane, reason in found.items() if reason is not None}


def with_signals(intersection: Intersection, program: SignalProgram) -> Intersection:
    """``intersection`` under ``program`` (a test-case's or the user's): InvalidInput when
    the junction has no traffic light, or the program is for another light or has the
    wrong number of colours per phase. A program without a light's id is this one's."""
    if not intersection.control.signalized or intersection.tls is None:
        raise InvalidInput(
            f"junction {intersection.junction!r} is of type {intersection.control.value}, "
            "without traffic lights: a signal program applies to a junction of type "
            "traffic_light or traffic_light_right_on_red (leave the program out, or make the "
            "junction one of those with the control type override)"
        )
    if program.tls and program.tls != intersection.tls:
        raise InvalidInput(
            f"the signal program is for traffic light {program.tls!r}, but junction "
            f"{intersection.junction!r} is controlled by traffic light {intersection.tls!r}"
        )
    if program.links != intersection.tls_links:
        raise InvalidInput(
            f"the signal program's states have {program.links} colours, but traffic light "
            f"{intersection.tls!r} controls {intersection.tls_links} links (indices 0 to "
            f"{intersection.tls_links - 1}, one colour each: "
            f"{_link_listing(intersection)})"
        )
    if not program.tls:
        program = dataclasses.replace(program, tls=intersection.tls)
    return dataclasses.replace(intersection, signals=program, signals_refused=None)


def _link_listing(intersection: Intersection) -> str:
    """Which route each link index is (the first few)."""
    named = sorted((r.link_index, r.id) for r in intersection.routes.values() if r.link_index >= 0)
    text = ", ".join(f"{k} {route}" for k, route in named[:6])
    return text + (", ..." if len(named) > 6 else "")
