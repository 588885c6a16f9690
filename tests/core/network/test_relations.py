"""Conflict decisions compared with SUMO's own conflict matrix and across real junctions."""

from __future__ import annotations

import itertools
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from service.core.network import Intersection, load_intersection
from service.core.network.relations import SLIVER_RADIUS, overlap_thickness
from tests.conftest import TOWN05, TOWN07

JUNCTIONS = [
    ("4way-stop", None, None),
    ("t-stop", None, None),
    ("y-uncontrolled", None, None),
    (str(TOWN07), "358", "right_before_left"),
    (str(TOWN07), "169", "allway_stop"),
    (str(TOWN05), "396", "allway_stop"),
    (str(TOWN05), "720", "allway_stop"),
    (str(TOWN05), "2062", "priority_stop"),
]


@pytest.fixture(scope="module", params=JUNCTIONS, ids=lambda j: f"{Path(j[0]).stem}-{j[1]}")
def junction(request: pytest.FixtureRequest, cache_dir: Path) -> Intersection:
    network, junction_id, control = request.param
    return load_intersection(network, junction_id, control, cache_dir)


def sumo_foes(intersection: Intersection) -> dict[str, set[str]]:
    """SUMO's foe matrix (<request foes=...>), keyed by first internal lane of each link.

    SUMO numbers internal lane ``:J_k_j`` after link k + j, which is the request index.
    """
    root = ET.parse(intersection.network_file).getroot()
    node = next(j for j in root.iter("junction") if j.get("id") == intersection.junction)

    def link_index(lane: str) -> int:
        edge, _, lane_index = lane.rpartition("_")
        return int(edge.rpartition("_")[2]) + int(lane_index)

    lane_of = {
        link_index(r.connecting_lane): r.connecting_lane for r in intersection.routes.values()
    }
    foes: dict[str, set[str]] = {}
    for request in node.iter("request"):
        index = int(request.get("index", "-1"))
        bits = request.get("foes", "")[::-1]
        if index in lane_of:
            foes[lane_of[index]] = {
                lane_of[k] for k, bit in enumerate(bits) if bit == "1" and k in lane_of
            }
    return foes


def test_conflicts_agree_with_sumo_except_side_by_side_merges(junction: Intersection) -> None:
    # SUMO makes every two links into the same edge foes. Two cars that end in different
    # lanes of that edge never share space, so for us they do not conflict.
    foes = sumo_foes(junction)
    for first, second in itertools.combinations(junction.routes.values(), 2):
        if first.fork == second.fork:
            continue
        ours = second.id in junction.conflicts[first.id]
        theirs = second.connecting_lane in foes.get(first.connecting_lane, set())
        if ours == theirs:
            continue
        exit_a, exit_b = junction.exits[first.exit], junction.exits[second.exit]
        assert theirs and not ours, (first.id, second.id)
        assert exit_a.edge == exit_b.edge and exit_a.lane != exit_b.lane, (first.id, second.id)


def test_overlaps_are_clearly_slivers_or_clearly_real(junction: Intersection) -> None:
    # The threshold sits in a wide gap: slivers are under 0.2 m, real overlaps over 1.3 m.
    for first, second in itertools.combinations(junction.routes.values(), 2):
        if first.fork == second.fork:
            continue
        radius = overlap_thickness(
            junction.connecting_lane_of(first).polygon, junction.connecting_lane_of(second).polygon
        )
        assert radius < 0.2 or radius > 1.3, (first.id, second.id, radius)
        assert (radius >= SLIVER_RADIUS) == (second.id in junction.conflicts[first.id])


def test_connecting_lanes_start_at_the_stop_line(junction: Intersection) -> None:
    # Cut square to the fork, a connecting lane never reaches behind its own stop line.
    for route in junction.routes.values():
        fork = junction.forks[route.fork]
        polygon = junction.connecting_lane_of(route).polygon
        behind = fork.approach.interpolate(fork.approach.length - 0.05)
        assert not polygon.contains(behind), route.id
