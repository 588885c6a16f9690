"""The major road of a ``priority_stop`` or ``priority`` junction: the two roads in that
keep the right of way while the others stop (``priority_stop``) or yield (``priority``).

netconvert picks it from the roads' priorities and, when they are equal, from a score of
angles, lane counts and speeds, which on real maps can make the stem of a T the major road
(more lanes, or a higher priority in the map) and put stop signs on the through road. The
rule set of a priority_stop junction is the T's (the stop signs on the terminating road),
so on a junction of three roads scengen always picks by geometry: the pair of roads
closest to straight across (one road through the junction); on more roads it does so when
every road in has the same priority, and otherwise keeps the map's priorities. Pairs
within STRAIGHT_MARGIN of the straightest are told apart by lanes, then speed, then how
straight, then their ids. The user can name the pair instead (``--major EDGE,EDGE``, the
test-case's ``major_road``).

A ``priority`` junction's links say which roads netconvert made major (it writes no road's
rank into the network): a link of the major road going straight or turning left has state
``M`` (major); every link of a minor road that crosses or merges with the major road is
``m`` (minor), only a right turn nobody crosses may be ``M``. ``yielding_roads`` reads
them so (see its docstring), the same links SUMO's own drivers obey.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from itertools import combinations
from typing import Any

from shapely.geometry import LineString

from service.core.errors import InvalidInput, choices
from service.core.network.lanes import (
    approach_polyline,
    heading_difference,
    heading_of,
    roads_in,
)
from service.core.network.model import ControlType, Route, Turn

STRAIGHT_MARGIN = 10.0  # degrees: pairs this close to the straightest count as straight too
HEADING_WINDOW = 10.0  # metres of approach whose chord gives a road's heading
MAJOR_ROAD_TYPES = (ControlType.PRIORITY_STOP, ControlType.PRIORITY)


def choose_major_road(
    net: Any, node: Any, target: str, current: str, major_road: Sequence[str] | None
) -> tuple[str, str] | None:
    """The major road of ``node`` made a ``target`` junction (its type now ``current``):
    the one given (for a priority_stop or priority junction only), else, when it becomes
    one of those with netconvert and it has three roads in or every road in has the same
    priority, the straightest pair. None leaves the choice to the network's priorities."""
    if major_road is not None:
        if target not in MAJOR_ROAD_TYPES:
            raise InvalidInput(
                f"a major road applies to a priority_stop or priority junction; junction "
                f"{node.getID()!r} is {target} (give --control priority_stop or priority)",
                junction=str(node.getID()),
            )
        return check_major_road(node, major_road)
    if target not in MAJOR_ROAD_TYPES or current == target:
        return None
    if len(roads_in(node)) == 3 or same_priority(node):  # a T or a Y: its stem stops
        return straightest_pair(net, node)
    return None


def check_major_road(node: Any, major_road: Sequence[str]) -> tuple[str, str]:
    """``major_road`` as two distinct roads into ``node``; InvalidInput naming the roads in
    otherwise."""
    valid = [str(edge.getID()) for edge in roads_in(node)]
    given = [str(edge) for edge in major_road]
    where = f"junction {node.getID()!r}"
    if len(given) != 2 or given[0] == given[1]:
        raise InvalidInput(
            f"major road {','.join(given) or '(none)'}: name two different roads into {where}, "
            f"EDGE,EDGE; roads into it: {choices(valid)}",
            junction=str(node.getID()),
        )
    for edge in given:
        if edge not in valid:
            raise InvalidInput(
                f"major road: {edge!r} is not a road into {where}; roads into it: {choices(valid)}",
                junction=str(node.getID()),
            )
    return given[0], given[1]


def lifted_priorities(node: Any, major_road: tuple[str, str]) -> dict[str, int]:
    """New priorities for the two roads of ``major_road``: one above every road into
    ``node``, so that netconvert makes them the major road."""
    highest = max((int(edge.getPriority()) for edge in roads_in(node)), default=0)
    return dict.fromkeys(major_road, highest + 1)


def same_priority(node: Any) -> bool:
    """Every road into ``node`` has the same priority (netconvert then guesses)."""
    return len({edge.getPriority() for edge in roads_in(node)}) <= 1


def straightest_pair(net: Any, node: Any) -> tuple[str, str]:
    """The two roads into ``node`` closest to straight across (see the module's docstring)."""
    junction = str(node.getID())
    heading = {str(edge.getID()): _heading(net, edge, junction) for edge in roads_in(node)}
    edges = {str(edge.getID()): edge for edge in roads_in(node)}
    pairs = list(combinations(sorted(heading), 2))
    if not pairs:
        raise InvalidInput(f"junction {junction!r} has fewer than two roads into it")

    def bend(pair: tuple[str, str]) -> float:
        """Degrees away from straight across: 0 when the two approach head-on."""
        return 180.0 - heading_difference(heading[pair[0]], heading[pair[1]])

    straightest = min(bend(pair) for pair in pairs)
    straight = [pair for pair in pairs if bend(pair) <= straightest + STRAIGHT_MARGIN]

    def rank(pair: tuple[str, str]) -> tuple[int, float, float, tuple[str, str]]:
        first, second = edges[pair[0]], edges[pair[1]]
        lanes = first.getLaneNumber() + second.getLaneNumber()
        speed = first.getSpeed() + second.getSpeed()
        return -lanes, -speed, round(bend(pair), 6), pair

    return min(straight, key=rank)


def _heading(net: Any, edge: Any, junction: str) -> float:
    """The heading of ``edge``'s approach over its last HEADING_WINDOW metres (from its
    start node towards the junction when its lanes have no length)."""
    points = approach_polyline(net, edge.getLanes()[0], junction, HEADING_WINDOW)
    if len(points) < 2:
        return heading_of(edge.getFromNode().getCoord()[:2], net.getNode(junction).getCoord()[:2])
    line = LineString(points)
    start = line.interpolate(max(0.0, line.length - HEADING_WINDOW))
    return heading_of((start.x, start.y), points[-1])


def yielding_roads(routes: Iterable[Route]) -> frozenset[str]:
    """The roads (edge ids) of a ``priority`` junction's minor road, read from its links
    (``routes``): the major road is the roads with a link ``M`` going straight or turning
    left, and when that makes one road, with it the one road whose only links ``M`` are
    right turns (a major road that bends: one turns left into it, it turns right out; a
    minor road's right turn that nobody crosses is ``M`` too, but then the major road has
    its two straight roads already). Every other road yields."""
    routes = list(routes)
    roads = sorted({_road(route.fork) for route in routes})
    free = {_road(r.fork) for r in routes if r.link_state == "M"}
    through = {_road(r.fork) for r in routes if r.link_state == "M" and r.turn is not Turn.RIGHT}
    major = set(through)
    bending = sorted(free - through)
    if len(major) == 1 and len(bending) == 1:
        major.update(bending)
    if not major:
        return frozenset()  # no link keeps the right of way: nobody is told to yield
    return frozenset(road for road in roads if road not in major)


def _road(lane: str) -> str:
    """The edge of a lane id (``-35_0`` -> ``-35``)."""
    return lane.rpartition("_")[0]
