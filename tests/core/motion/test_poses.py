"""Step 1: poses from libsumo (real SUMO runs, nothing mocked)."""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import pytest
from shapely.geometry import LineString, Point

from service.core.errors import InvalidInput
from service.core.motion.poses import (
    PoseTrack,
    centre_to_front,
    front_to_centre,
    generate_poses,
    interpolate_heading,
    longest_start,
    plan_drive,
    start_front,
)
from service.core.network import Intersection, load_intersection
from tests.conftest import TOWN07


@pytest.mark.parametrize(
    ("heading", "front", "centre"),
    [
        (0.0, (10.0, 10.0), (10.0, 7.5)),  # north: centre is south of the bumper
        (90.0, (10.0, 10.0), (7.5, 10.0)),  # east
        (180.0, (10.0, 10.0), (10.0, 12.5)),
        (270.0, (10.0, 10.0), (12.5, 10.0)),
        (45.0, (0.0, 0.0), (-2.5 / math.sqrt(2), -2.5 / math.sqrt(2))),
    ],
)
def test_front_to_centre_follows_sumo_heading_convention(
    heading: float, front: tuple[float, float], centre: tuple[float, float]
) -> None:
    x, y = front_to_centre(front[0], front[1], heading, 5.0)
    assert (x, y) == pytest.approx(centre)
    assert centre_to_front(x, y, heading, 5.0) == pytest.approx(front)


def test_interpolate_heading_goes_the_short_way() -> None:
    assert interpolate_heading(350.0, 10.0, 0.5) == pytest.approx(0.0)
    assert interpolate_heading(10.0, 350.0, 0.25) == pytest.approx(5.0)
    assert interpolate_heading(90.0, 180.0, 0.5) == pytest.approx(135.0)
    assert interpolate_heading(0.0, 359.0, 1e-15) == 0.0  # never 360 (float rounding)


def _route_path(intersection: Intersection, route_id: str) -> LineString:
    route = intersection.route(route_id)
    points = list(intersection.forks[route.fork].approach.coords)
    points += list(intersection.connecting_lane_of(route).centreline.coords)
    points += list(intersection.exits[route.exit].departure.coords)
    return LineString(points)


@pytest.fixture(scope="module")
def left_turn(four_way: Intersection) -> PoseTrack:
    return generate_poses(four_way, [(four_way.route("S2C_1:C2W_1"), 30.0)], 8.0, 20.0, 0.1)[0]


def test_left_turn_starts_with_the_front_at_the_start_distance(
    four_way: Intersection, left_turn: PoseTrack
) -> None:
    first = left_turn.samples[0]
    stop_x, stop_y = four_way.forks["S2C_1"].stop_line
    assert (first.x, first.y) == pytest.approx((stop_x, stop_y - 30.0 - 2.5))
    assert first.heading == pytest.approx(0.0)
    assert first.distance == 0.0


def test_left_turn_samples_are_at_constant_speed_every_step(left_turn: PoseTrack) -> None:
    # at most 0.1 m apart: at 8 m/s, 10 SUMO steps of 10 ms in every 0.1 s time step
    samples = left_turn.samples
    assert len(samples) == 2001  # 0 .. 20 s
    assert [s.t for s in samples] == pytest.approx([k * 0.01 for k in range(2001)])
    steps = [b.distance - a.distance for a, b in itertools.pairwise(samples)]
    assert steps == pytest.approx([0.08] * 2000)
    assert all(s.speed == pytest.approx(8.0) for s in samples)


def test_left_turn_poses_follow_the_connecting_lane(
    four_way: Intersection, left_turn: PoseTrack
) -> None:
    path = _route_path(four_way, "S2C_1:C2W_1")
    lane = four_way.connecting_lane_of(four_way.route("S2C_1:C2W_1"))
    inside = [s for s in left_turn.samples if lane.polygon.contains(Point(s.x, s.y))]
    assert len(inside) > 10
    # SUMO keeps the front bumper on the lane's centreline ...
    near = [s for s in left_turn.samples if s.distance < 70.0]  # the drawn path is 78 m long
    fronts = [Point(centre_to_front(s.x, s.y, s.heading, 5.0)) for s in near]
    assert max(path.distance(front) for front in fronts) < 0.05
    # ... and the centre on the chord to the back bumper: on this 12 m-radius turn, drawn as
    # a coarse polyline, it cuts the corner by at most the chord's sagitta plus the polyline's.
    assert max(path.distance(Point(s.x, s.y)) for s in inside) < 0.6
    assert left_turn.samples[-1].heading == pytest.approx(270.0)


def test_pose_at_interpolates_between_samples(left_turn: PoseTrack) -> None:
    a, b = left_turn.samples[10], left_turn.samples[11]
    x, y, heading = left_turn.pose_at((a.distance + b.distance) / 2)
    assert (x, y) == pytest.approx(((a.x + b.x) / 2, (a.y + b.y) / 2))
    assert heading == pytest.approx(0.0)


def test_pose_at_goes_on_straight_past_the_last_sample(left_turn: PoseTrack) -> None:
    """Past the end of its road a car drives on off the map along its last heading."""
    last = left_turn.samples[-1]
    x, y, heading = left_turn.pose_at(last.distance + 10.0)
    rad = math.radians(last.heading)
    assert (x, y) == pytest.approx((last.x + 10.0 * math.sin(rad), last.y + 10.0 * math.cos(rad)))
    assert heading == pytest.approx(last.heading)


def test_short_fork_continues_upstream_on_a_real_map(town07_y: Intersection) -> None:
    # Fork -35_0 is 0.7 m long: the approach comes from the lanes before it.
    route = town07_y.route("-35_0:40_0")
    track = generate_poses(town07_y, [(route, 40.0)], 8.0, 10.0, 0.1)[0]
    path = _route_path(town07_y, route.id)
    stop_line = Point(town07_y.forks["-35_0"].stop_line)
    first = track.samples[0]
    front = Point(*first_front(first.x, first.y, first.heading))
    assert front.distance(stop_line) == pytest.approx(40.0, abs=2.0)  # the road curves
    crossing = [s for s in track.samples if path.distance(Point(s.x, s.y)) < 0.5]
    assert len(crossing) > 20


def first_front(x: float, y: float, heading: float) -> tuple[float, float]:
    return centre_to_front(x, y, heading, 5.0)


def test_drive_covers_the_duration_and_leaves_the_junction(four_way: Intersection) -> None:
    slow = generate_poses(four_way, [(four_way.route("N2C_0:C2W_0"), 10.0)], 2.0, 5.0, 0.1)[0]
    assert slow.samples[-1].t >= 5.0
    assert not four_way.polygon.intersects(Point(slow.samples[-1].x, slow.samples[-1].y))


def test_several_drives_in_one_sumo_process(four_way: Intersection) -> None:
    routes = [four_way.route(r) for r in ("S2C_0:C2N_0", "E2C_1:C2S_1", "W2C_0:C2S_0")]
    tracks = generate_poses(four_way, [(r, 20.0) for r in routes], 10.0, 8.0, 0.1)
    assert [t.route for t in tracks] == [r.id for r in routes]
    assert tracks[2].samples[-1].heading == pytest.approx(180.0)


def test_start_beyond_the_road_is_invalid_input(four_way: Intersection) -> None:
    with pytest.raises(InvalidInput, match="longer than the road before fork 'S2C_1'"):
        generate_poses(four_way, [(four_way.route("S2C_1:C2W_1"), 500.0)], 8.0, 20.0, 0.1)


def test_a_start_too_far_to_reach_the_junction_is_not_an_exit_error(
    town07_y: Intersection,
) -> None:
    """Exit 35_0 is 0.7 m long. A start farther than the drive goes (200 m at 5 m/s for
    20 s) used to be refused with "the road after exit '35_0' ends 0.7 m after the
    junction" (the lanes after the exit were only added up to the drive's length, short
    of where the car leaves the junction); Step 1 now drives on until it has left it."""
    route = town07_y.route("-40_0:35_0")
    track = generate_poses(town07_y, [(route, 200.0)], 5.0, 20.0, 0.1)[0]
    assert track.samples[-1].distance > 205.0
    assert not town07_y.polygon.intersects(Point(track.samples[-1].x, track.samples[-1].y))


@pytest.mark.parametrize("start_distance", [0.0, 0.005])
def test_a_start_at_the_stop_line_is_on_the_fork_lane(
    four_way: Intersection, start_distance: float
) -> None:
    """SUMO inserts no further than a centimetre before a lane's end (found by the fuzzer:
    start_distance 0 crashed the worker)."""
    track = generate_poses(
        four_way, [(four_way.route("S2C_1:C2W_1"), start_distance)], 8.0, 5.0, 0.1
    )[0]
    first = track.samples[0]
    stop_x, stop_y = four_way.forks["S2C_1"].stop_line
    assert (first.x, first.y) == pytest.approx((stop_x, stop_y - start_distance - 2.5), abs=1e-3)
    assert first.distance == 0.0


def test_longest_start_fits_the_road_before_the_fork(cache_dir: Path) -> None:
    """Town07 725: the road before fork -26#1_0 ends 17.91 m before the line (SUMO's lane
    lengths and the drawn shape agree to the centimetre); other forks go on far enough."""
    junction = load_intersection(TOWN07, "725", "allway_stop", cache_dir)
    short = junction.route("-26#1_0:14_0")
    assert longest_start(junction, short, 30.0) == 17.91
    assert longest_start(junction, short, 12.5) == 12.5
    assert longest_start(junction, junction.route("15_0:14_0"), 30.0) == 30.0
    plan_drive(junction, short, 17.91, 8.0, 20.0, 0.1)  # the fitted start is driven
    assert start_front(junction, short, 17.91)  # and placed where the checker expects it
    with pytest.raises(
        InvalidInput,
        match=r"start distance 18 m is longer than the road before "
        r"fork '-26#1_0' \(17\.9 m\)",
    ):
        plan_drive(junction, short, 18.0, 8.0, 20.0, 0.1)  # fmt: skip
