"""Where the pictures draw a signal head: past the fork's stop line, a lane's links side by
side as its driver sees them (past the crosswalk after the line); a crossing's zebra and
its pedestrian signal's heads."""

from __future__ import annotations

import itertools
import math

import pytest
from shapely.geometry import Point, Polygon

from service.core.network import Intersection, load_intersection
from service.core.network.geometry import (
    STRIPE,
    STRIPE_END,
    STRIPE_GAP,
    STRIPE_SIDE,
    WALK_HEAD_DEPTH,
    WALK_HEAD_SETBACK,
    junction_geometry,
    pedestrian_heads,
    signal_heads,
    zebra_stripes,
)


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


def test_a_zebra_lies_on_its_crossing_clear_of_the_curbs() -> None:
    """Every bar inside its crossing's strip, parallel to the road it crosses (its long
    side across the walking direction), STRIPE_GAP apart, none within STRIPE_END of a
    curb; the geometry carries them with the crossing's width, and the sidewalks."""
    intersection = load_intersection("crosswalk-stop")
    assert len(intersection.crossings) == 4
    shapes = {c["id"]: c for c in junction_geometry(intersection)["crossings"]}
    for crossing in intersection.crossings.values():
        bars = zebra_stripes(crossing)
        line = crossing.centreline
        assert len(bars) == math.floor((line.length - 2 * STRIPE_END + STRIPE_GAP) / 1.0)
        centres = []
        for bar in bars:
            shape = Polygon(bar)
            assert crossing.polygon.buffer(1e-6).contains(shape)
            assert shape.area == pytest.approx(STRIPE * (crossing.width - 2 * STRIPE_SIDE))
            along = sorted(line.project(Point(p)) for p in bar)
            assert along[0] >= STRIPE_END - 1e-6 and along[-1] <= line.length - STRIPE_END + 1e-6
            assert along[-1] - along[0] == pytest.approx(STRIPE)  # a bar STRIPE along
            centres.append(line.project(shape.centroid))
        gaps = [b - a for a, b in itertools.pairwise(centres)]
        assert gaps == pytest.approx([STRIPE + STRIPE_GAP] * (len(bars) - 1))
        assert shapes[crossing.id]["width"] == crossing.width
        assert len(shapes[crossing.id]["stripes"]) == len(bars)
    sidewalks = {r["lane"] for r in junction_geometry(intersection)["roads"] if r["sidewalk"]}
    assert sidewalks == {f"{e}_0" for e in ("C2E", "C2N", "C2S", "C2W", "E2C", "N2C", "S2C", "W2C")}
    assert pedestrian_heads(intersection) == []  # an all-way stop: no pedestrian signal
    assert junction_geometry(intersection)["pedestrian_heads"] == []


def test_a_signalized_crossing_has_a_head_at_each_curb_and_the_cars_heads_stand_past_it() -> None:
    """crosswalk-signal: two pedestrian heads per crossing, just inside its strip at each
    curb (the one where its + walk starts first), in its link's colour; the cars' heads
    past the crosswalk after their stop line, on no crossing."""
    intersection = load_intersection("crosswalk-signal")
    heads = pedestrian_heads(intersection)
    assert len(heads) == 2 * len(intersection.crossings) == 8
    for crossing in intersection.crossings.values():
        two = [h for h in heads if h.crossing == crossing.id]
        assert [h.walk for h in two] == [f"{crossing.id[1:]}+", f"{crossing.id[1:]}-"]
        assert {h.link_index for h in two} == {crossing.link_index} and crossing.link_index >= 0
        for head, curb in zip(two, (0.0, crossing.length), strict=True):
            bar = Polygon(head.corners)
            assert crossing.polygon.buffer(1e-6).contains(bar)
            along = [crossing.centreline.project(Point(p)) for p in head.corners]
            assert max(abs(a - curb) for a in along) <= WALK_HEAD_SETBACK + WALK_HEAD_DEPTH + 1e-6
    for head in signal_heads(intersection):
        bar = Polygon(head.corners)
        assert not any(c.polygon.intersects(bar) for c in intersection.crossings.values())
        fork = intersection.forks[head.fork]
        assert bar.distance(Point(fork.stop_line)) < 6.0  # just past the crosswalk
    shapes = junction_geometry(intersection)["pedestrian_heads"]
    assert [(h["crossing"], h["walk"]) for h in shapes] == [(h.crossing, h.walk) for h in heads]
