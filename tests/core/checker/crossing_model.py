"""The checker's test networks with crossings (tests/data/junctions): the bundled four-ways
with sidewalks and crossings guessed, as the network loader reads them."""

from __future__ import annotations

import functools
from pathlib import Path

from service.core.network import Intersection, load_intersection

JUNCTIONS = Path(__file__).parents[2] / "data" / "junctions"


@functools.cache
def stop_crossings() -> Intersection:
    """The all-way stop with sidewalks and a crossing over every arm."""
    return load_intersection(JUNCTIONS / "stop-crossings.net.xml")


@functools.cache
def signal_crossings() -> Intersection:
    """The signalized four-way with sidewalks and crossings, its program in
    signal-crossings.tll.xml: north-south green 0-20 s (walk on :C_c1 and :C_c3 0-14 s,
    flashing 14-20 s), yellow 20-23, all red 23-25; east-west green 25-45 s (walk on :C_c0
    and :C_c2 25-39 s, flashing 39-45 s), yellow 45-48, all red 48-50."""
    return load_intersection(JUNCTIONS / "signal-crossings.net.xml")
