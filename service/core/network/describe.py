"""The intersection as plain data: the contract of ``scengen intersection --json``."""

from __future__ import annotations

from typing import Any

from service.core.network.model import Intersection


def describe_intersection(
    intersection: Intersection, horizon: float | None = None
) -> dict[str, Any]:
    """JSON-ready description: junction, control, the forks and routes it offers with their
    relations and conflicts, the side lanes it does not offer (each with the reason; a
    route on one works when named), the major road when scengen chose or was given it, and
    at a signalized junction the program with each route's signal (its link index and its
    colours over ``horizon`` seconds, default one cycle)."""
    routes = intersection.offered_routes
    forks = intersection.offered_forks

    def offered(lanes: frozenset[str]) -> list[str]:
        return sorted(lane for lane in lanes if lane in forks)

    program = intersection.signals
    until = horizon if horizon is not None else (program.cycle if program else 0.0)

    def signal(link: int) -> dict[str, Any] | None:
        if program is None or link < 0:
            return None
        timeline = [[round(a, 3), round(b, 3), c] for a, b, c in program.timeline(link, until)]
        return {"link_index": link, "timeline": timeline}

    return {
        "network": str(intersection.source_file),
        "junction": intersection.junction,
        "control": intersection.control.value,
        "control_overridden": intersection.overridden,
        "major_road": list(intersection.major_road) if intersection.major_road else None,
        "forks": [
            {
                "lane": fork.lane,
                "edge": fork.edge,
                "heading": round(fork.heading, 2),
                "stop_sign": fork.stop_sign,
                "yield_sign": fork.yield_sign,
                "to_its_right": offered(intersection.to_its_right[fork.lane]),
                "opposite": offered(intersection.opposite[fork.lane]),
                "same_direction": offered(intersection.same_direction[fork.lane]),
            }
            for fork in sorted(forks.values(), key=lambda f: f.lane)
        ],
        "exits": [
            {"lane": e.lane, "edge": e.edge, "heading": round(e.heading, 2)}
            for e in sorted(intersection.exits.values(), key=lambda e: e.lane)
            if e.lane not in intersection.side_lanes
        ],
        "routes": [
            {
                "id": route.id,
                "fork": route.fork,
                "exit": route.exit,
                "turn": route.turn.value,
                "connecting_lane": route.connecting_lane,
                "length": round(intersection.connecting_lanes[route.connecting_lane].length, 2),
                "conflicts": sorted(c for c in intersection.conflicts[route.id] if c in routes),
                "signal": signal(route.link_index),
            }
            for route in routes.values()
        ],
        "signals": None
        if program is None
        else {**program.to_document(), "cycle": program.cycle, "horizon": until},
        "side_lanes": [
            {"lane": lane, "reason": reason} for lane, reason in intersection.side_lanes.items()
        ],
        "crossings_guessed": intersection.crossings_guessed,
        "walks": [
            {
                "id": walk.id,
                "crossing": walk.crossing,
                "from": walk.start,
                "to": walk.end,
                "before": walk.before,
                "after": walk.after,
                "heading": round(walk.heading, 2),
                "length": round(walk.length, 2),
                "width": round(intersection.crossings[walk.crossing].width, 2),
                "conflicts": [c for c in walk.conflicts if c in routes],
                "signal": signal(intersection.crossings[walk.crossing].link_index),
            }
            for walk in intersection.walks.values()
        ],
    }
