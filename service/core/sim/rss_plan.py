"""What the RSS guard (service.core.sumo.rss_guard) needs to know of the junction, from the
intersection model: the run plan's ``rss`` section.

For each non-ego that matters to the ego: its relation (``crossing`` or ``merge``: the
routes' connecting lanes overlap; ``same_fork``: both queue on one incoming lane;
``same_route``), the conflict area along both routes (metres from each stop line: where the
overlap of the two connecting lanes begins and ends along each centreline), and who has
priority there by the junction's control type:

- ``priority_stop``: a car without a stop sign over one with it (CVC 22450, 21802); two
  without: the left turn yields to the oncoming car (21801); two with: ``same`` (the first
  to stop goes first, which RSS cannot know beforehand).
- ``priority``: a car without a yield sign (the major road) over one with it (CVC 21803);
  two without, or two with: the left turn yields to the oncoming car (21801), else ``same``.
- ``right_before_left``: the car on the right (21800(a)/(b)); head-on, the left turn yields
  (21801); otherwise ``same``.
- ``allway_stop``: ``same`` (the first to stop goes first: RSS then asks each car to be able
  to stop before the area unless the other can).
- signals: ``signal``: the guard compares both links' colours at every step; equal colours
  fall back on the left-turn rule (``tie``).

Where the same priority remains, the guard gives it to the car that entered the conflict
area first (a car already in the intersection: CVC 21800(a), 21802(b)).

And each pedestrian in the ego's path (``pedestrians``): one whose walk crosses the ego's
route (``Walk.conflicts``), with the conflict area along the ego's route (where its
connecting lane overlaps the crossing's strip, metres from its stop line) and along her
walk (metres from the curb she starts at), and per step her front's place along her walk
(negative before the curb). She has priority there (CVC 21950 (a)).
"""

from __future__ import annotations

from typing import Any

from shapely.geometry import LineString, Point

from service.core.motion.poses import centre_to_front, start_distance_of
from service.core.network import ControlType, Intersection, Route
from service.core.network.model import Turn, Walk
from service.core.testcase import Pedestrian, TestCase


def rss_section(testcase: TestCase, intersection: Intersection) -> dict[str, Any]:
    """The plan's ``rss`` section for ``testcase`` (see the module docstring)."""
    ego_route = intersection.route(testcase.ego.route.id)
    cars: dict[str, Any] = {}
    for nonego in testcase.nonegos:
        route = intersection.route(nonego.route.id)
        relation = _relation(intersection, ego_route, route)
        if relation is None:
            continue
        first = nonego.trajectory[0]
        front = centre_to_front(first.x, first.y, first.heading, nonego.length)
        spec: dict[str, Any] = {
            "relation": relation,
            "length": nonego.length,
            # metres from its start to its stop line: its front is at distance - stop_line
            "stop_line": start_distance_of(intersection, route, front) + first.distance,
            "link": route.link_index,
        }
        if relation in ("crossing", "merge"):
            spec["ego_area"], spec["other_area"] = conflict_area(intersection, ego_route, route)
            spec["ego_exit"] = _exit_place(intersection, ego_route)
            spec["other_exit"] = _exit_place(intersection, route)
            spec.update(priority(intersection, ego_route, route))
        else:
            spec["priority"] = "same"
        cars[nonego.id] = spec
    return {
        "control": intersection.control.value,
        "ego_length": testcase.ego.length,
        "ego_width": testcase.ego.width,
        "ego_link": ego_route.link_index,
        "lane_width": intersection.connecting_lane_of(ego_route).width,
        "cars": cars,
        "pedestrians": {
            person.id: _pedestrian_spec(intersection, ego_route, person)
            for person in testcase.pedestrians
            if ego_route.id in intersection.walk(person.walk).conflicts
        },
    }


def _pedestrian_spec(intersection: Intersection, ego: Route, person: Pedestrian) -> dict[str, Any]:
    """A pedestrian in the ego's path: the conflict area along the ego's route and along her
    walk, her size, and her front's place along her walk at every step."""
    walk = intersection.walk(person.walk)
    crossing = intersection.crossings[walk.crossing]
    overlap = intersection.connecting_lane_of(ego).polygon.intersection(crossing.polygon)
    points = list(overlap.convex_hull.exterior.coords)
    along = [walk_place(walk, Point(p[0], p[1])) for p in points]
    places = []
    for sample in person.trajectory:
        front = centre_to_front(sample.x, sample.y, sample.heading, person.length)
        places.append(round(walk_place(walk, Point(front)), 3))
    return {
        "walk": walk.id,
        "length": person.length,
        "width": person.width,
        "ego_area": _along(intersection, ego, points),
        "other_area": [round(max(min(along), 0.0), 3), round(min(max(along), walk.length), 3)],
        "places": places,
    }


def walk_place(walk: Walk, point: Point) -> float:
    """Metres along ``walk``'s path from the curb she starts at to ``point``'s projection;
    before the curb (or past the far one) along the path's first (last) stretch extended."""
    path = walk.path
    place = float(path.project(point))
    coords = list(path.coords)
    if place <= 0.0:
        (x0, y0), (x1, y1) = coords[0], coords[1]
        return _signed(point, (x0, y0), (x1, y1))
    if place >= path.length:
        (x0, y0), (x1, y1) = coords[-2], coords[-1]
        return float(path.length) + _signed(point, (x1, y1), (2 * x1 - x0, 2 * y1 - y0))
    return place


def _signed(point: Point, start: tuple[float, float], toward: tuple[float, float]) -> float:
    """``point``'s distance from ``start`` along the direction to ``toward``."""
    dx, dy = toward[0] - start[0], toward[1] - start[1]
    norm = (dx * dx + dy * dy) ** 0.5
    return float(((point.x - start[0]) * dx + (point.y - start[1]) * dy) / norm)


def _relation(intersection: Intersection, ego: Route, other: Route) -> str | None:
    if ego.id == other.id:
        return "same_route"
    if ego.fork == other.fork:
        return "same_fork"
    if other.id in intersection.conflicts.get(ego.id, frozenset()):
        return "merge" if ego.exit == other.exit else "crossing"
    return None


def conflict_area(
    intersection: Intersection, ego: Route, other: Route
) -> tuple[list[float], list[float]]:
    """Where the two connecting lanes overlap, as [start, end] metres along each route
    from its stop line (the overlap's outline projected onto each centreline; a limit line
    before a short fork adds the metres from it to the fork's end)."""
    ego_lane = intersection.connecting_lane_of(ego)
    other_lane = intersection.connecting_lane_of(other)
    overlap = ego_lane.polygon.intersection(other_lane.polygon)
    points = list(getattr(overlap, "exterior", LineString()).coords)
    if not points:  # several pieces: their hull
        points = list(overlap.convex_hull.exterior.coords)
    return _along(intersection, ego, points), _along(intersection, other, points)


def _along(
    intersection: Intersection, route: Route, points: list[tuple[float, ...]]
) -> list[float]:
    line = intersection.connecting_lane_of(route).centreline
    places = [float(line.project(Point(p[0], p[1]))) for p in points]
    offset = intersection.fork(route.fork).limit_offset
    return [round(min(places) + offset, 3), round(max(places) + offset, 3)]


def _exit_place(intersection: Intersection, route: Route) -> float:
    """Metres from the route's stop line to the end of its connecting lane (the exit)."""
    length = intersection.connecting_lane_of(route).length
    return length + intersection.fork(route.fork).limit_offset


def priority(intersection: Intersection, ego: Route, other: Route) -> dict[str, str]:
    """``{"priority": ...}`` (and at a signal the ``tie``) for a crossing or merge."""
    control = intersection.control
    if control.signalized:
        return {"priority": "signal", "tie": _left_turn_rule(intersection, ego, other)}
    if control in (ControlType.PRIORITY_STOP, ControlType.PRIORITY):
        ego_sign, other_sign = _minor(intersection, ego), _minor(intersection, other)
        if ego_sign != other_sign:
            return {"priority": "other" if ego_sign else "ego"}
        if ego_sign and control == ControlType.PRIORITY_STOP:
            return {"priority": "same"}
        return {"priority": _left_turn_rule(intersection, ego, other)}
    if control == ControlType.RIGHT_BEFORE_LEFT:
        if other.fork in intersection.to_its_right.get(ego.fork, frozenset()):
            return {"priority": "other"}
        if ego.fork in intersection.to_its_right.get(other.fork, frozenset()):
            return {"priority": "ego"}
        return {"priority": _left_turn_rule(intersection, ego, other)}
    return {"priority": "same"}


def _minor(intersection: Intersection, route: Route) -> bool:
    """The route comes from the minor road: a stop sign (priority_stop) or a yield sign
    (priority) on its fork."""
    fork = intersection.fork(route.fork)
    return fork.stop_sign or fork.yield_sign


def _left_turn_rule(intersection: Intersection, ego: Route, other: Route) -> str:
    """CVC 21801: head-on, a left turn yields to the oncoming car that does not turn left."""
    if other.fork not in intersection.opposite.get(ego.fork, frozenset()):
        return "same"
    ego_left, other_left = ego.turn == Turn.LEFT, other.turn == Turn.LEFT
    if ego_left == other_left:
        return "same"
    return "other" if ego_left else "ego"
