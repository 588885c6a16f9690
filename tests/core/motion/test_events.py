"""Lane events from poses: Step 1 drives and hand-built speed profiles on real SUMO poses."""

from __future__ import annotations

import pytest

from service.core.motion.events import EventKind, LaneEvent, compute_events
from service.core.motion.poses import PoseSample, PoseTrack, generate_poses
from service.core.network import Intersection
from tests.helpers import retime, stop_and_go

ARRIVAL, V_STOP = 10.0, 0.1


def _events(intersection: Intersection, samples: list[PoseSample], fork: str) -> list[LaneEvent]:
    return compute_events(samples, 5.0, 1.8, intersection, fork, ARRIVAL, V_STOP)


def _kinds(events: list[LaneEvent], kind: EventKind) -> list[LaneEvent]:
    return [e for e in events if e.kind is kind]


@pytest.fixture(scope="module")
def tracks(four_way: Intersection) -> dict[str, PoseTrack]:
    routes = ["S2C_1:C2W_1", "S2C_0:C2N_0"]
    found = generate_poses(four_way, [(four_way.route(r), 30.0) for r in routes], 8.0, 20.0, 0.1)
    return {track.route: track for track in found}


def test_left_turn_events_in_order(four_way: Intersection, tracks: dict[str, PoseTrack]) -> None:
    events = _events(four_way, list(tracks["S2C_1:C2W_1"].samples), "S2C_1")
    arrived, entered, exited = (
        _kinds(events, k)[0] for k in (EventKind.ARRIVED, EventKind.ENTERED, EventKind.EXITED)
    )
    assert not _kinds(events, EventKind.STOPPED)
    assert arrived.lane == entered.lane == "S2C_1"
    assert exited.lane == "C"
    assert arrived.time < entered.time < exited.time
    own = four_way.route("S2C_1:C2W_1").connecting_lane
    into_own = next(e for e in events if e.kind is EventKind.ENTERED_LANE and e.lane == own)
    out_of_own = next(e for e in events if e.kind is EventKind.LEFT_LANE and e.lane == own)
    assert into_own.time < out_of_own.time
    assert into_own.distance == pytest.approx(entered.distance, abs=1e-3)  # square-cut lane
    assert out_of_own.time >= exited.time - 0.05
    times = [e.time for e in events]
    assert times == sorted(times)


def test_left_turn_touches_every_crossing_lane(
    four_way: Intersection, tracks: dict[str, PoseTrack]
) -> None:
    events = _events(four_way, list(tracks["S2C_1:C2W_1"].samples), "S2C_1")
    entered = {e.lane for e in _kinds(events, EventKind.ENTERED_LANE)}
    left = {e.lane for e in _kinds(events, EventKind.LEFT_LANE)}
    assert entered == left
    crossing = {four_way.routes[r].connecting_lane for r in four_way.conflicts["S2C_1:C2W_1"]}
    assert crossing <= entered
    for route_id in ("E2C_0:C2N_0", "N2C_0:C2W_0", "S2C_0:C2E_0"):  # right turns elsewhere
        assert four_way.routes[route_id].connecting_lane not in entered
    for lane in entered:  # each lane once, entered before left
        ins = [e for e in events if e.lane == lane and e.kind is EventKind.ENTERED_LANE]
        outs = [e for e in events if e.lane == lane and e.kind is EventKind.LEFT_LANE]
        assert len(ins) == len(outs) == 1
        assert ins[0].time < outs[0].time


def test_event_distances_are_refined_between_samples(
    four_way: Intersection, tracks: dict[str, PoseTrack]
) -> None:
    # Straight on: the front meets the junction border at the stop line, 30 m after the
    # start, and arrives 10 m before it. Samples are 0.8 m apart, so truncating to a step
    # would miss both by up to 0.8 m.
    events = _events(four_way, list(tracks["S2C_0:C2N_0"].samples), "S2C_0")
    entered = _kinds(events, EventKind.ENTERED)[0]
    arrived = _kinds(events, EventKind.ARRIVED)[0]
    assert entered.distance == pytest.approx(30.0, abs=1e-3)
    assert entered.time == pytest.approx(30.0 / 8.0, abs=1e-3)
    assert arrived.distance == pytest.approx(20.0, abs=1e-6)
    exited = _kinds(events, EventKind.EXITED)[0]
    # The junction is 20.8 m deep; the car is 5 m long.
    assert exited.distance - entered.distance == pytest.approx(20.8 + 5.0, abs=1e-3)


def test_stop_before_the_stop_line_then_go(
    four_way: Intersection, tracks: dict[str, PoseTrack]
) -> None:
    profile = stop_and_go(cruise=8.0, stop_at=28.0, brake=3.0, wait=2.0, accelerate=2.0)
    samples = retime(tracks["S2C_1:C2W_1"], profile, 20.0, 0.1)
    events = _events(four_way, samples, "S2C_1")
    kinds = [
        e.kind
        for e in events
        if e.kind in (EventKind.ARRIVED, EventKind.STOPPED, EventKind.ENTERED, EventKind.EXITED)
    ]
    assert kinds == [EventKind.ARRIVED, EventKind.STOPPED, EventKind.ENTERED, EventKind.EXITED]
    stopped = _kinds(events, EventKind.STOPPED)[0]
    # Braking at 3 m/s^2 from 8 m/s reaches 0.1 m/s 0.1/3 s before standing still.
    t_stand = (28.0 - 8.0 * 8.0 / 3.0 / 2.0) / 8.0 + 8.0 / 3.0
    assert stopped.time == pytest.approx(t_stand - V_STOP / 3.0, abs=1e-6)
    assert stopped.distance == pytest.approx(28.0, abs=0.01)
    assert stopped.lane == "S2C_1"
    assert _kinds(events, EventKind.ENTERED)[0].distance == pytest.approx(30.0, abs=0.01)


def test_car_that_stops_short_never_enters(
    four_way: Intersection, tracks: dict[str, PoseTrack]
) -> None:
    profile = stop_and_go(cruise=8.0, stop_at=25.0, brake=3.0, wait=100.0, accelerate=2.0)
    samples = retime(tracks["S2C_1:C2W_1"], profile, 20.0, 0.1)
    events = _events(four_way, samples, "S2C_1")
    assert [e.kind for e in events] == [EventKind.ARRIVED, EventKind.STOPPED]


def test_slow_rolling_is_not_a_stop(four_way: Intersection, tracks: dict[str, PoseTrack]) -> None:
    def crawl(t: float) -> tuple[float, float]:
        return 0.5 * t + 15.0, 0.5  # at 0.5 m/s, starting 15 m before the stop line

    samples = retime(tracks["S2C_1:C2W_1"], crawl, 40.0, 0.1)
    events = _events(four_way, samples, "S2C_1")
    assert _kinds(events, EventKind.ARRIVED)
    assert _kinds(events, EventKind.ENTERED)
    assert not _kinds(events, EventKind.STOPPED)


def test_stop_inside_the_junction_is_not_a_stop_at_the_fork(
    four_way: Intersection, tracks: dict[str, PoseTrack]
) -> None:
    profile = stop_and_go(cruise=8.0, stop_at=36.0, brake=3.0, wait=2.0, accelerate=2.0)
    samples = retime(tracks["S2C_1:C2W_1"], profile, 20.0, 0.1)
    events = _events(four_way, samples, "S2C_1")
    assert not _kinds(events, EventKind.STOPPED)


def test_events_on_a_real_y_junction(town07_y: Intersection) -> None:
    route = town07_y.route("-40_0:35_0")  # left turn from the side road
    track = generate_poses(town07_y, [(route, 25.0)], 8.0, 12.0, 0.1)[0]
    events = compute_events(track.samples, 5.0, 1.8, town07_y, route.fork, ARRIVAL, V_STOP)
    order = [
        e.kind for e in events if e.kind in (EventKind.ARRIVED, EventKind.ENTERED, EventKind.EXITED)
    ]
    assert order == [EventKind.ARRIVED, EventKind.ENTERED, EventKind.EXITED]
    touched = {e.lane for e in _kinds(events, EventKind.ENTERED_LANE)}
    assert route.connecting_lane in touched
    assert {town07_y.routes[r].connecting_lane for r in town07_y.conflicts[route.id]} <= touched
