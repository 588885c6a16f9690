"""Where the pictures draw a signal head: past the fork's stop line, a lane's links side by
side as its driver sees them."""

from __future__ import annotations

from service.core.network import Intersection, load_intersection
from service.core.network.geometry import junction_geometry, signal_heads


def test_signal_heads_stand_past_the_stop_line_left_turn_on_the_left() -> None:
    intersection = load_intersection("4way-signal")
    heads = signal_heads(intersection)
    assert sorted(h.link_index for h in heads) == list(range(intersection.tls_links))
    north = [h for h in heads if h.fork == "S2C_1"]  # northbound: its left is the west
    assert [h.turn for h in north] == ["left", "straight"]
    assert max(x for x, _ in north[0].corners) < min(x for x, _ in north[1].corners)
    line = intersection.forks["S2C_1"].stop_line[1]
    assert all(line < y < line + 2.0 for h in north for _, y in h.corners)
    south = [h for h in heads if h.fork == "N2C_1"]  # southbound: its left is the east
    assert [h.turn for h in south] == ["left", "straight"]
    assert min(x for x, _ in south[0].corners) > max(x for x, _ in south[1].corners)
    shapes = junction_geometry(intersection)["signal_heads"]
    assert [(h["fork"], h["link_index"]) for h in shapes] == [
        (h.fork, h.link_index) for h in heads
    ]  # fmt: skip


def test_a_junction_without_lights_has_no_heads(four_way: Intersection) -> None:
    assert signal_heads(four_way) == []
    assert junction_geometry(four_way)["signal_heads"] == []
