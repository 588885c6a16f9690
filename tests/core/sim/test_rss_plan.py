"""What the RSS guard is told of the junction: relations, conflict areas, priorities."""

from __future__ import annotations

import itertools
import math

import pytest

from service.core.motion.poses import generate_poses
from service.core.network import Intersection
from service.core.sim.rss_plan import conflict_area, priority, rss_section
from service.core.testcase import load_testcase_intersection, new_testcase
from tests.helpers import with_nonegos
from tests.walkers import crosswalk_scene, straight_walk, with_pedestrians


@pytest.mark.parametrize(
    ("ego", "other", "expected"),
    [
        ("S2C_0:C2W_0", "W2C_0:C2E_0", "other"),  # the stem's stop sign yields to the major road
        ("W2C_0:C2E_0", "S2C_0:C2W_0", "ego"),
        ("E2C_0:C2S_0", "W2C_0:C2E_0", "other"),  # on the major road the left turn yields
        ("W2C_0:C2E_0", "E2C_0:C2S_0", "ego"),
    ],
)
def test_priority_at_a_priority_stop(
    t_stop: Intersection, ego: str, other: str, expected: str
) -> None:
    assert priority(t_stop, t_stop.route(ego), t_stop.route(other)) == {"priority": expected}


@pytest.mark.parametrize(
    ("ego", "other", "expected"),
    [
        ("S2C_0:C2N_0", "W2C_0:C2E_0", "other"),  # the yield sign yields to the major road
        ("W2C_0:C2E_0", "S2C_0:C2N_0", "ego"),
        ("E2C_0:C2S_0", "W2C_0:C2E_0", "other"),  # on the major road the left turn yields
        ("S2C_0:C2W_0", "N2C_0:C2S_0", "other"),  # two yield signs head-on: 21801
        ("N2C_0:C2S_0", "S2C_0:C2W_0", "ego"),
    ],
)
def test_priority_at_a_yield_sign(
    skewed_yield: Intersection, ego: str, other: str, expected: str
) -> None:
    junction = skewed_yield
    assert priority(junction, junction.route(ego), junction.route(other)) == {"priority": expected}


def test_priority_at_an_uncontrolled_junction_goes_to_the_car_on_the_right(
    y_junction: Intersection,
) -> None:
    first, second = y_junction.route("N2C_0:C2SE_0"), y_junction.route("SW2C_0:C2N_0")
    found = {priority(y_junction, first, second)["priority"],
             priority(y_junction, second, first)["priority"]}  # fmt: skip
    assert found == {"ego", "other"}  # one of the two comes from the other's right
    right = second.fork in y_junction.to_its_right[first.fork]
    assert priority(y_junction, first, second)["priority"] == ("other" if right else "ego")


def test_the_conflict_area_lies_on_both_connecting_lanes(four_way: Intersection) -> None:
    ego, other = four_way.route("E2C_1:C2W_1"), four_way.route("N2C_1:C2S_1")
    ego_area, other_area = conflict_area(four_way, ego, other)
    for (start, end), route in ((ego_area, ego), (other_area, other)):
        assert 0.0 <= start < end <= four_way.connecting_lane_of(route).length + 1e-6
        assert end - start >= 2.0  # two lanes about 3 m wide cross at right angles


def test_the_plan_names_only_the_cars_that_matter() -> None:
    """A car ahead on the ego's fork and a car crossing are in the plan, with where each
    stop line lies along its trajectory; a right turn from the opposite side is not."""
    alone = new_testcase("4way-stop", "E2C_1:C2W_1", start_distance=30.0)
    junction = load_testcase_intersection(alone)
    cars = {"ahead": ("E2C_1:C2S_1", 15.0), "cross": ("N2C_1:C2S_1", 40.0),
            "aside": ("W2C_0:C2S_0", 20.0)}  # fmt: skip
    tracks = generate_poses(junction, [(junction.route(r), d) for r, d in cars.values()],
                            8.0, 10.0, 0.1)  # fmt: skip
    nonegos = [(car, route, track.at_time_steps(0.1))
               for (car, (route, _)), track in zip(cars.items(), tracks, strict=True)]  # fmt: skip
    section = rss_section(with_nonegos(alone, nonegos), junction)
    assert rss_section(alone, junction)["cars"] == {}
    assert set(section["cars"]) == {"ahead", "cross"}
    assert section["cars"]["ahead"]["relation"] == "same_fork"
    cross = section["cars"]["cross"]
    assert (cross["relation"], cross["priority"]) == ("crossing", "same")  # all-way stop
    assert cross["stop_line"] == pytest.approx(40.0, abs=0.1)


def test_the_plan_names_the_pedestrians_in_the_ego_path() -> None:
    """ped1 walks the crosswalk the ego (from the skewed east arm) crosses first: her
    conflict area lies at its stop line along the ego's route and over the ego's lane
    along her walk, and her place grows from before the curb (negative) as she walks;
    a pedestrian on the crosswalk across the ego's way out to the north is not in its
    path (it goes west)."""
    _, testcase, junction = crosswalk_scene("E2C_1:C2W_1", "C_c1+", lead=2.0, wait=0.0)
    other = straight_walk(junction, "C_c0+", testcase.duration)
    both = with_pedestrians(testcase, {"ped1": ("C_c1+", [s.model_dump() for s in
                                                         testcase.pedestrians[0].trajectory]),
                                       "ped2": ("C_c0+", other)})  # fmt: skip
    section = rss_section(both, junction)
    assert set(section["pedestrians"]) == {"ped1"}
    assert "E2C_1:C2W_1" not in junction.walk("C_c0+").conflicts
    spec = section["pedestrians"]["ped1"]
    ego_in, ego_out = spec["ego_area"]
    her_in, her_out = spec["other_area"]
    assert 0.0 <= ego_in < ego_out <= 6.0  # the crosswalk at the ego's stop line
    lane = junction.connecting_lane_of(junction.route("E2C_1:C2W_1")).width
    assert her_out - her_in == pytest.approx(lane / math.sin(math.radians(65.0)), abs=0.5)
    places = spec["places"]
    assert places[0] == pytest.approx(-2.0 + 0.1075, abs=1e-3)  # her front, 2 m before
    assert all(b - a == pytest.approx(0.13, abs=2e-3) for a, b in itertools.pairwise(places))
