"""The intersection model: forks, exits, connecting lanes, routes and their relations.

Coordinates are SUMO network coordinates in metres. Headings are degrees clockwise from
north (+y), in [0, 360): SUMO's own convention, so 90 points along +x.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import StrEnum
from pathlib import Path

from shapely.geometry import LineString, MultiPolygon, Polygon

from service.core.errors import UnknownLane, UnknownRoute, UnknownWalk, choices
from service.core.names import ControlType as ControlType  # light, for the command line
from service.core.network.signals import SignalProgram

Point = tuple[float, float]


class Turn(StrEnum):
    """Turn direction of a route, from SUMO's connection direction."""

    LEFT = "left"
    RIGHT = "right"
    STRAIGHT = "straight"


@dataclass(frozen=True)
class Fork:
    """An incoming lane of the intersection; cars stop for it at its limit line (the stop
    line), where SUMO's driver stops for its link: the lane's end, or before a fork shorter
    than a car between two nodes of one traffic light, the end of the lane before the
    upstream node (service.core.network.forks)."""

    lane: str
    edge: str
    heading: float  # approach heading over the last metres before the stop line
    stop_line: Point  # centre of the limit line (the end of ``limit_lane``'s centreline)
    stop_sign: bool
    width: float
    approach: LineString  # centreline of the last metres before the lane's end (drawn)
    limit_lane: str  # the lane whose end is the limit line: ``lane`` itself, or upstream
    limit_offset: float  # metres along the road from the limit line to the lane's end
    entry: Polygon | MultiPolygon  # what a car of this fork enters by crossing its limit
    # line: the junction's polygon (with the lanes after the line), not behind the line
    yield_sign: bool = False  # on the minor road of a ``priority`` junction (CVC 21803)


@dataclass(frozen=True)
class Exit:
    """An outgoing lane of the intersection."""

    lane: str
    edge: str
    heading: float  # departure heading over the first metres after the junction
    width: float
    departure: LineString  # centreline of the first metres after the junction


@dataclass(frozen=True)
class ConnectingLane:
    """The path through the junction of one connection: SUMO's chain of internal lanes."""

    id: str  # the first internal lane of the chain, as SUMO names it
    internal_lanes: tuple[str, ...]
    centreline: LineString
    polygon: Polygon
    width: float

    @property
    def length(self) -> float:
        return float(self.centreline.length)


@dataclass(frozen=True)
class Route:
    """A way through the intersection: fork, connecting lane, exit and turn direction."""

    fork: str
    exit: str
    connecting_lane: str
    turn: Turn
    link_state: str  # SUMO's link state: 'w' all-way stop, 's' stop, 'm' minor, 'M' major, ...
    link_index: int = -1  # the traffic light's index of the link whose signal the driver
    # obeys at the fork's limit line: this connection's, or the upstream connection's
    # where the limit line is before the fork (Fork.limit_lane); -1: no signal

    @property
    def id(self) -> str:
        return route_id(self.fork, self.exit)


@dataclass(frozen=True)
class Crossing:
    """A pedestrian crossing of the junction: SUMO's crossing edge (``:J_cN``), the strip
    people on foot walk across the road between two walking areas (``:J_wN``)."""

    id: str  # the crossing edge, as SUMO names it (":C_c0")
    lane: str  # its one lane (":C_c0_0"): events and rule facts name it
    edges: tuple[str, ...]  # the road edges it crosses (SUMO's crossingEdges)
    centreline: LineString  # SUMO's lane shape, from ``ends[0]`` to ``ends[1]``
    polygon: Polygon  # the strip: the centreline widened to ``width``
    width: float
    ends: tuple[str, str]  # the walking areas at the start and at the end of the centreline
    link_index: int = -1  # its link in the traffic light's program (the pedestrian
    # signal); -1: no signal

    @property
    def length(self) -> float:
        return float(self.centreline.length)


@dataclass(frozen=True)
class Walk:
    """One crossing walked in one direction, from the walking area at one end to the
    walking area at the other: what a pedestrian of a test-case does. Its id is the
    crossing's without SUMO's leading colon, then ``+`` (along the crossing's centreline)
    or ``-`` (against it): ``C_c0+``."""

    id: str
    crossing: str  # Crossing.id
    start: str  # the walking area it comes from
    end: str  # the walking area it goes to
    path: LineString  # the crossing's centreline in the walking direction, curb to curb
    heading: float  # of ``path``, degrees clockwise from north
    before: str  # a sidewalk lane that leads into ``start`` (where Step 1's walk begins;
    # "" where ``start`` is a traffic island without sidewalks)
    after: str  # a sidewalk lane that leads out of ``end`` (where it ends; where ``end``
    # is a traffic island, the crossing's own lane: SUMO ends no walk on a walking area)
    # libsumo walks a person added on ``before``'s edge to ``after``'s over this crossing
    # and no other (service.core.network.crossings)
    conflicts: tuple[str, ...]  # ids of the vehicle routes whose connecting lane crosses it

    @property
    def length(self) -> float:
        return float(self.path.length)


def walk_id(crossing: str, along: bool) -> str:
    """The public id of a walk: the crossing's id without SUMO's leading colon, then ``+``
    along its centreline or ``-`` against it."""
    return f"{crossing.lstrip(':')}{'+' if along else '-'}"


def route_id(fork: str, exit_lane: str) -> str:
    """The public id of a route: ``FORK_LANE:EXIT_LANE``."""
    return f"{fork}:{exit_lane}"


@dataclass(frozen=True)
class Intersection:
    """One junction of a network with everything the traffic rules and the steps need."""

    network_file: Path  # the network the model was built from (rebuilt if overridden)
    source_file: Path  # the network the caller named
    junction: str
    control: ControlType
    overridden: bool  # the control type (or the major road) was changed with netconvert
    polygon: Polygon
    forks: dict[str, Fork]
    exits: dict[str, Exit]
    connecting_lanes: dict[str, ConnectingLane]
    routes: dict[str, Route]
    conflicts: dict[str, frozenset[str]]  # route id -> ids of conflicting routes
    to_its_right: dict[str, frozenset[str]]  # fork -> forks whose traffic comes from its right
    opposite: dict[str, frozenset[str]]  # fork -> forks approaching head-on (same highway)
    same_direction: dict[str, frozenset[str]] = field(default_factory=dict)
    # forks and exits that are not for driving through (parking lanes, bays), each with the
    # reason (service.core.network.lanes.side_lane_reason): their routes are not offered
    side_lanes: dict[str, str] = field(default_factory=dict)
    # the two roads into a priority_stop or priority junction rebuilt with netconvert that
    # keep the right of way (given or chosen by service.core.network.major); None: the network's
    major_road: tuple[str, str] | None = None
    # the traffic light of a signalized junction, how many links it controls, and the
    # program in force (the network's, or the test-case's: load_testcase_intersection)
    tls: str | None = None
    tls_links: int = 0
    signals: SignalProgram | None = None
    signals_refused: str | None = None  # why the network's program cannot be used
    # the pedestrian crossings of the junction by id, and the walks over them by id (none
    # on a network without sidewalks and crossings: netconvert --crossings.guess adds them)
    crossings: dict[str, Crossing] = field(default_factory=dict)
    walks: dict[str, Walk] = field(default_factory=dict)
    # the network was rebuilt with guessed sidewalks and crossings (--guess-crossings)
    crossings_guessed: bool = False

    def signal_colour(self, route: Route, t: float) -> str | None:
        """The SUMO colour of ``route``'s signal at time ``t``; None without a signal."""
        if self.signals is None or route.link_index < 0:
            return None
        return self.signals.colour(route.link_index, t)

    @property
    def signal_forks(self) -> frozenset[str]:
        """The forks with a signal on some route."""
        if self.signals is None:
            return frozenset()
        return frozenset(r.fork for r in self.routes.values() if r.link_index >= 0)

    def offered(self, route: Route) -> bool:
        """The route is for driving through: neither its fork nor its exit is a side lane.
        Routes not offered are never chosen on their own, but work when named."""
        return route.fork not in self.side_lanes and route.exit not in self.side_lanes

    @property
    def offered_routes(self) -> dict[str, Route]:
        """The routes the junction offers (``offered``), by id."""
        return {key: route for key, route in self.routes.items() if self.offered(route)}

    @property
    def offered_forks(self) -> dict[str, Fork]:
        """The forks of the offered routes, by lane."""
        used = {route.fork for route in self.offered_routes.values()}
        return {lane: fork for lane, fork in self.forks.items() if lane in used}

    def route(self, route_ref: str) -> Route:
        """The route with id ``FORK:EXIT``; raises UnknownRoute naming the valid ids."""
        if route_ref in self.routes:
            return self.routes[route_ref]
        fork, sep, exit_lane = route_ref.partition(":")
        if not sep:
            raise UnknownRoute(
                f"route {route_ref!r} is not of the form FORK_LANE:EXIT_LANE; "
                f"valid routes at junction {self.junction!r}: {choices(self.offered_routes)}",
                junction=self.junction,
            )
        self.fork(fork)
        self.exit(exit_lane)
        raise UnknownRoute(
            f"no connection from fork {fork!r} to exit {exit_lane!r} at junction "
            f"{self.junction!r}; valid routes: {choices(self.offered_routes)}"
            + self._shifted_note(),
            junction=self.junction,
        )

    def fork(self, lane: str) -> Fork:
        """The fork on ``lane``; raises UnknownLane naming the valid forks."""
        if lane not in self.forks:
            raise UnknownLane(
                f"lane {lane!r} is not a fork (incoming lane) of junction {self.junction!r}; "
                f"valid forks: {choices(self.offered_forks)}" + self._shifted_note(),
                junction=self.junction,
            )
        return self.forks[lane]

    def exit(self, lane: str) -> Exit:
        """The exit on ``lane``; raises UnknownLane naming the valid exits."""
        if lane not in self.exits:
            raise UnknownLane(
                f"lane {lane!r} is not an exit (outgoing lane) of junction {self.junction!r}; "
                f"valid exits: {choices(e for e in self.exits if e not in self.side_lanes)}"
                + self._shifted_note(),
                junction=self.junction,
            )
        return self.exits[lane]

    def _shifted_note(self) -> str:
        """What a lane id not found means on a network with guessed crossings."""
        if not self.crossings_guessed:
            return ""
        return (
            " (with guessed crossings the sidewalk is lane 0: every car lane's index is one "
            "higher than on the network without them)"
        )

    def walk(self, walk_ref: str) -> Walk:
        """The walk with id ``walk_ref``; raises UnknownWalk naming the valid walks, or
        saying how to add crossings to a junction that has none."""
        if walk_ref in self.walks:
            return self.walks[walk_ref]
        if not self.walks:
            raise UnknownWalk(
                f"junction {self.junction!r} has no pedestrian crossings, so no walk "
                f"{walk_ref!r}: add sidewalks and crossings with --guess-crossings (netconvert "
                "--sidewalks.guess --crossings.guess; the car lanes' indices then move up by "
                "one, as the sidewalk becomes lane 0)",
                junction=self.junction,
            )
        raise UnknownWalk(
            f"walk {walk_ref!r} is not a walk of junction {self.junction!r}; valid walks: "
            f"{choices(self.walks)}",
            junction=self.junction,
        )

    def signal_colour_of_crossing(self, crossing: Crossing, t: float) -> str | None:
        """The SUMO colour of ``crossing``'s pedestrian signal at time ``t``; None without."""
        if self.signals is None or crossing.link_index < 0:
            return None
        return self.signals.colour(crossing.link_index, t)

    def connecting_lane_of(self, route: Route) -> ConnectingLane:
        return self.connecting_lanes[route.connecting_lane]

    def on_different_highways(self, fork_a: str, fork_b: str) -> bool:
        """Forks on different highways: neither the same road nor head-on opposite."""
        return (
            fork_a != fork_b
            and fork_b not in self.opposite.get(fork_a, frozenset())
            and fork_b not in self.same_direction.get(fork_a, frozenset())
        )
