"""People on foot as the checker sees them (docs/pedestrians.md): each pedestrian of a
test-case with its walk, its crossing and its events (service.core.motion.events.
pedestrian_events: at the curb, waiting there, onto and off the crossing, and in and out
of every car lane it touches). A car's events at the crosswalks come with its other
events (service.core.motion.events.compute_events)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from service.core.motion.events import LaneEvent, pedestrian_events
from service.core.motion.poses import PoseSample
from service.core.network import Intersection


@dataclass(frozen=True)
class Walker:
    """A pedestrian as the checker sees it: id, walk, crossing, size, samples and events."""

    id: str
    walk: str
    crossing: str  # the crossing's id (":C_c0"): its events' lane
    lane: str  # the crossing's lane (":C_c0_0"): what the rules name
    length: float
    width: float
    samples: Sequence[PoseSample]
    events: tuple[LaneEvent, ...]


def walker(
    junction: Intersection,
    person: str,
    walk_id: str,
    length: float,
    width: float,
    samples: Sequence[PoseSample],
    arrival_distance: float,
    v_stop: float,
) -> Walker:
    """The pedestrian ``person`` on walk ``walk_id`` (raises UnknownWalk naming the walks)."""
    walk = junction.walk(walk_id)
    crossing = junction.crossings[walk.crossing]
    events = pedestrian_events(samples, length, width, junction, walk.id, arrival_distance,
                               v_stop)  # fmt: skip
    return Walker(person, walk.id, crossing.id, crossing.lane, length, width, samples,
                  tuple(events))  # fmt: skip
