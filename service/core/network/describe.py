"""The intersection as plain data: the contract of ``scengen intersection --json``."""

from __future__ import annotations

from typing import Any

from service.core.network.model import Intersection


def describe_intersection(intersection: Intersection) -> dict[str, Any]:
    """JSON-ready description: junction, control, forks with relations, routes with conflicts."""
    return {
        "network": str(intersection.source_file),
        "junction": intersection.junction,
        "control": intersection.control.value,
        "control_overridden": intersection.overridden,
        "forks": [
            {
                "lane": fork.lane,
                "edge": fork.edge,
                "heading": round(fork.heading, 2),
                "stop_sign": fork.stop_sign,
                "to_its_right": sorted(intersection.to_its_right[fork.lane]),
                "opposite": sorted(intersection.opposite[fork.lane]),
                "same_direction": sorted(intersection.same_direction[fork.lane]),
            }
            for fork in sorted(intersection.forks.values(), key=lambda f: f.lane)
        ],
        "exits": [
            {"lane": e.lane, "edge": e.edge, "heading": round(e.heading, 2)}
            for e in sorted(intersection.exits.values(), key=lambda e: e.lane)
        ],
        "routes": [
            {
                "id": route.id,
                "fork": route.fork,
                "exit": route.exit,
                "turn": route.turn.value,
                "connecting_lane": route.connecting_lane,
                "length": round(intersection.connecting_lanes[route.connecting_lane].length, 2),
                "conflicts": sorted(intersection.conflicts[route.id]),
            }
            for route in intersection.routes.values()
        ],
    }
