"""What the RSS guard is told of the junction: relations, conflict areas, priorities."""

from __future__ import annotations

import pytest

from service.core.motion.poses import generate_poses
from service.core.network import Intersection
from service.core.sim.rss_plan import conflict_area, priority, rss_section
from service.core.testcase import load_testcase_intersection, new_testcase
from tests.helpers import with_nonegos


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
    nonegos = [(car, route, list(track.samples))
               for (car, (route, _)), track in zip(cars.items(), tracks, strict=True)]  # fmt: skip
    section = rss_section(with_nonegos(alone, nonegos), junction)
    assert rss_section(alone, junction)["cars"] == {}
    assert set(section["cars"]) == {"ahead", "cross"}
    assert section["cars"]["ahead"]["relation"] == "same_fork"
    cross = section["cars"]["cross"]
    assert (cross["relation"], cross["priority"]) == ("crossing", "same")  # all-way stop
    assert cross["stop_line"] == pytest.approx(40.0, abs=0.1)
