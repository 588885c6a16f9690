"""A pedestrian's events and a car's at the crosswalks (service.core.checker.pedestrians),
against times worked out by hand on straight walks over the all-way stop's south crossing
:C_c2 (12.8 m long, 4 m wide; tests/data/junctions/stop-crossings)."""

from __future__ import annotations

import pytest

from service.core.checker.pedestrians import crossing_events, pedestrian_events
from service.core.motion.events import EventKind, LaneEvent
from service.core.motion.poses import PoseSample
from service.core.network import Intersection, Walk
from tests.core.checker.crossing_model import stop_crossings

LENGTH, WIDTH = 0.215, 0.478  # SUMO's default pedestrian
PACE = 1.3


@pytest.fixture(scope="module")
def stop() -> Intersection:
    return stop_crossings()


def straight(
    walk: Walk, lead: float, stand: float = 0.0, duration: float = 20.0
) -> list[PoseSample]:
    """Standing with its centre ``lead`` m before the crossing until ``stand``, then at PACE
    at once (no speeding up), along the walk's line."""
    (x0, y0), (x1, y1) = walk.path.coords[0], walk.path.coords[-1]
    ux, uy = (x1 - x0) / walk.length, (y1 - y0) / walk.length
    samples = []
    for k in range(round(duration / 0.1) + 1):
        t = k * 0.1
        distance = max(0.0, t - stand) * PACE
        speed = PACE if t > stand else 0.0
        along = distance - lead
        samples.append(PoseSample(t, x0 + ux * along, y0 + uy * along, walk.heading, speed,
                                  distance))  # fmt: skip
    return samples


def _of(events: list[LaneEvent], kind: EventKind, lane: str | None = None) -> list[float]:
    return [e.time for e in events if e.kind is kind and (lane is None or e.lane == lane)]


def test_a_walk_across_has_its_events_where_the_rectangle_meets_the_crossing(
    stop: Intersection,
) -> None:
    walk = stop.walk("C_c2+")
    events = pedestrian_events(stop, walk, straight(walk, 5.0), LENGTH, WIDTH, 1.0, 0.1)
    # the front within 1 m of the crossing: centre 1.1075 m before it
    assert _of(events, EventKind.ARRIVED, ":C_c2") == pytest.approx([(5.0 - 1.1075) / PACE],
                                                                    abs=1e-3)  # fmt: skip
    assert _of(events, EventKind.STOPPED) == []  # it never stood at the curb
    (entered,) = _of(events, EventKind.ENTERED, ":C_c2")
    (exited,) = _of(events, EventKind.EXITED, ":C_c2")
    assert entered == pytest.approx((5.0 - LENGTH / 2) / PACE, abs=1e-3)
    assert exited == pytest.approx((5.0 + walk.length + LENGTH / 2) / PACE, abs=1e-3)
    # its own crossing's lane, and every car lane it crosses, in and out once
    assert _of(events, EventKind.ENTERED_LANE, ":C_c2_0") == [entered]
    assert _of(events, EventKind.LEFT_LANE, ":C_c2_0") == [exited]
    ego_lane = stop.route("S2C_1:C2N_1").connecting_lane
    (into,), (out,) = (_of(events, kind, ego_lane) for kind in (EventKind.ENTERED_LANE,
                                                                EventKind.LEFT_LANE))  # fmt: skip
    assert entered < into < out <= exited
    assert [e.distance for e in events] == sorted(e.distance for e in events)


def test_a_pedestrian_waiting_at_the_curb_has_arrived_and_stopped(stop: Intersection) -> None:
    walk = stop.walk("C_c2-")
    events = pedestrian_events(stop, walk, straight(walk, 0.8, stand=3.0), LENGTH, WIDTH, 1.0,
                               0.1)  # fmt: skip
    assert _of(events, EventKind.ARRIVED) == [0.0]
    assert _of(events, EventKind.STOPPED) == [0.0]
    assert _of(events, EventKind.ENTERED) == pytest.approx([3.0 + (0.8 - LENGTH / 2) / PACE],
                                                           abs=1e-3)  # fmt: skip


def test_a_pedestrian_who_never_reaches_the_crossing_has_no_crossing_event(
    stop: Intersection,
) -> None:
    walk = stop.walk("C_c2+")
    events = pedestrian_events(stop, walk, straight(walk, 5.0, stand=100.0), LENGTH, WIDTH, 1.0,
                               0.1)  # fmt: skip
    assert events == []


def test_a_cars_crosswalk_events_are_not_doubled(stop: Intersection) -> None:
    """A car driving north along S2C_1's lane centre (x = 154.8) at 10 m/s crosses :C_c2
    (y 139.6 to 143.6) and :C_c0 (y 156.4 to 160.4): in and out of each once; events the
    car already has for a crossing lane (the events stage's, once it computes them) are
    not computed again."""
    samples = [PoseSample(t / 10, 154.8, 120.0 + t, 0.0, 10.0, float(t)) for t in range(61)]
    events = crossing_events(stop, samples, 5.0, 1.8)
    found = sorted((e.lane, e.kind.value, round(e.time, 3)) for e in events)
    # the rectangle (5 m long) meets a strip when its front is at the strip's near edge
    assert found == [
        (":C_c0_0", "entered_lane", round((156.4 - 2.5 - 120.0) / 10, 3)),
        (":C_c0_0", "left_lane", round((160.4 + 2.5 - 120.0) / 10, 3)),
        (":C_c2_0", "entered_lane", round((139.6 - 2.5 - 120.0) / 10, 3)),
        (":C_c2_0", "left_lane", round((143.6 + 2.5 - 120.0) / 10, 3)),
    ]
    known = [e for e in events if e.lane == ":C_c2_0"]
    assert {e.lane for e in crossing_events(stop, samples, 5.0, 1.8, known)} == {":C_c0_0"}
