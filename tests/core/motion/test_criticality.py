"""Criticality on hand-made drives at the four-way stop: cars at constant speeds placed
along their routes' paths, so that each measure has a value known by hand."""

from __future__ import annotations

import math

import pytest

from service.core.motion.criticality import (
    Mover,
    area_bounds,
    conflict_area,
    measure_criticality,
    merge_bounds,
    route_path,
)
from service.core.motion.criticality_records import Criticality
from service.core.motion.poses import PoseSample
from service.core.network import Intersection

STEP = 0.1
EAST = "W2C_0:C2E_0"  # straight on, west to east
NORTH = "S2C_1:C2N_1"  # straight on, south to north: crosses EAST at right angles


def drive(
    junction: Intersection, car: str, route: str, front: float, speed: float, end: float = 1.0
) -> Mover:
    """A 5 x 1.8 m car whose front is at place ``front`` (m along its path) at t = 0 and
    that holds ``speed`` until ``end``."""
    path = route_path(junction, junction.route(route))
    samples = []
    for k in range(round(end / STEP) + 1):
        t = k * STEP
        place = front + speed * t
        tip, tail = path.line.interpolate(place), path.line.interpolate(place - 5.0)
        heading = math.degrees(math.atan2(tip.x - tail.x, tip.y - tail.y)) % 360.0
        samples.append(PoseSample(t, (tip.x + tail.x) / 2, (tip.y + tail.y) / 2, heading,
                                  speed, speed * t))  # fmt: skip
    return Mover(car, junction.route(route), 5.0, 1.8, samples)


def test_following_gives_gap_over_closing_speed(four_way: Intersection) -> None:
    line = route_path(four_way, four_way.route(EAST)).stop_line
    ego = drive(four_way, "ego", EAST, line - 40.0, 10.0)
    ahead = drive(four_way, "car1", EAST, line - 20.0, 6.0)  # its back 15 m ahead of the ego
    found = measure_criticality(four_way, ego, [ahead]).others[0]
    gap = 15.0 - (10.0 - 6.0) * 1.0  # closest at the last sample, t = 1 s
    assert found.ttc is not None and found.drac is not None and found.distance is not None
    assert found.ttc.value == pytest.approx(gap / 4.0, abs=2e-3)
    assert found.ttc.t == pytest.approx(1.0)
    assert found.drac.value == pytest.approx(4.0**2 / (2 * gap), abs=2e-3)
    assert found.distance.value == pytest.approx(gap, abs=2e-3)
    assert found.pet == ()  # one lane: no conflict area


def test_a_slower_follower_closes_in_on_nobody(four_way: Intersection) -> None:
    line = route_path(four_way, four_way.route(EAST)).stop_line
    ego = drive(four_way, "ego", EAST, line - 40.0, 5.0)
    ahead = drive(four_way, "car1", EAST, line - 20.0, 6.0)
    found = measure_criticality(four_way, ego, [ahead]).others[0]
    assert found.ttc is None and found.drac is None


def test_crossing_gives_the_second_cars_entry_time_and_pet(four_way: Intersection) -> None:
    ego_route, other_route = four_way.route(EAST), four_way.route(NORTH)
    probe = drive(four_way, "ego", EAST, 0.0, 1.0), drive(four_way, "car1", NORTH, 0.0, 1.0)
    area = conflict_area(four_way, *probe)
    assert area is not None
    ego_in, ego_out = area_bounds(four_way, probe[0], area) or (0.0, 0.0)
    other_in, _ = area_bounds(four_way, probe[1], area) or (0.0, 0.0)
    assert ego_out - ego_in == pytest.approx(1.8 + 5.0, abs=0.1)  # perpendicular: as SUMO
    # the ego enters at 2 s and leaves at 2 + 6.8 / 8 s; car1 enters 1.5 s after that
    ego = drive(four_way, "ego", EAST, ego_in - 16.0, 8.0, end=6.0)
    leaves = 2.0 + (ego_out - ego_in) / 8.0
    other = drive(four_way, "car1", NORTH, other_in - 6.0 * (leaves + 1.5), 6.0, end=6.0)
    found = measure_criticality(four_way, ego, [other]).others[0]
    assert [p.area for p in found.pet] == [
        f"{ego_route.connecting_lane}|{other_route.connecting_lane}"
    ]
    assert found.pet[0].value == pytest.approx(1.5, abs=0.01)
    assert found.pet[0].t == pytest.approx(leaves + 1.5, abs=0.01)
    assert found.ttc is None  # at constant speeds they never meet


def test_a_predicted_crossing_crash_gives_ttc_and_drac(four_way: Intersection) -> None:
    probe = drive(four_way, "ego", EAST, 0.0, 1.0), drive(four_way, "car1", NORTH, 0.0, 1.0)
    area = conflict_area(four_way, *probe)
    assert area is not None
    ego_in, ego_out = area_bounds(four_way, probe[0], area) or (0.0, 0.0)
    other_in, other_out = area_bounds(four_way, probe[1], area) or (0.0, 0.0)
    # at 8 m/s the ego is in the area from 2 s to 2.85 s; car1 at 6 m/s enters at 2.5 s
    ego = drive(four_way, "ego", EAST, ego_in - 16.0, 8.0)
    other = drive(four_way, "car1", NORTH, other_in - 15.0, 6.0)
    found = measure_criticality(four_way, ego, [other]).others[0]
    assert found.ttc is not None and found.drac is not None
    assert found.ttc.value == pytest.approx(1.5, abs=2e-3)  # car1's entry, seen at t = 1 s
    assert found.ttc.t == pytest.approx(1.0)
    # at t = 1 s: the ego could arrive as car1 leaves, or car1 as the ego leaves
    ego_wait = (
        2
        * (8.0 - 8.0 / ((other_out - other_in + 9.0) / 6.0))
        / ((other_out - other_in + 9.0) / 6.0)
    )
    leaves = (ego_out - ego_in + 8.0) / 8.0
    other_wait = 2 * (6.0 - 9.0 / leaves) / leaves
    assert found.drac.value == pytest.approx(min(ego_wait, other_wait), abs=2e-3)


def test_distance_is_the_gap_between_the_outlines(four_way: Intersection) -> None:
    line = route_path(four_way, four_way.route(EAST)).stop_line
    ego = drive(four_way, "ego", EAST, line - 30.0, 5.0)
    beside = drive(four_way, "car1", "W2C_1:C2E_1", line - 30.0, 5.0)  # the next lane
    found = measure_criticality(four_way, ego, [beside])
    assert found.others[0].distance is not None
    lanes = four_way.forks["W2C_0"].width  # lanes of one road are as wide as each other
    assert found.others[0].distance.value == pytest.approx(lanes - 1.8, abs=0.05)
    assert found.others[0].ttc is None  # side by side: neither follows the other


def test_overall_takes_each_extreme_with_its_car(four_way: Intersection) -> None:
    line = route_path(four_way, four_way.route(EAST)).stop_line
    ego = drive(four_way, "ego", EAST, line - 40.0, 10.0)
    near = drive(four_way, "car1", EAST, line - 20.0, 6.0)
    far = drive(four_way, "car2", EAST, line - 5.0, 6.0)
    found = measure_criticality(four_way, ego, [far, near])
    assert found.ttc is not None and found.ttc.car == "car1"
    assert found.distance is not None and found.distance.car == "car1"
    assert found.pet is None
    document = found.to_dict()
    assert list(document) == ["others", "overall"]
    assert list(document["others"]["car1"]) == ["ttc", "pet", "drac", "distance"]
    assert document["overall"]["ttc"] == {"value": found.ttc.value, "car": "car1",
                                          "t": found.ttc.t}  # fmt: skip
    assert Criticality.from_dict(document) == found


def test_at_a_merge_a_car_past_the_merge_point_is_followed_not_crossed(
    four_way: Intersection,
) -> None:
    """N2C_0:C2W_0 (a right turn) and E2C_0:C2W_0 (straight on) merge into C2W_0. car1 is
    9 m into the merge area at 5 m/s, the ego 1 m before it at 6 m/s: as SUMO's SSM device
    does, the ego follows car1 now (gap over closing speed: about 4.3 m at 1 m/s), where
    measuring the area as a crossing said 0.058 s with the cars 3.1 m apart, a collision no
    closing speed under 54 m/s could bring about."""
    ego_route, lead_route = "N2C_0:C2W_0", "E2C_0:C2W_0"
    probe = (
        drive(four_way, "ego", ego_route, 0.0, 1.0),
        drive(four_way, "car1", lead_route, 0.0, 1.0),
    )
    area = conflict_area(four_way, *probe)
    assert area is not None
    ego_in, _ = area_bounds(four_way, probe[0], area) or (0.0, 0.0)
    lead_in, _ = area_bounds(four_way, probe[1], area) or (0.0, 0.0)
    ego = drive(four_way, "ego", ego_route, ego_in - 1.0, 6.0, end=0.1)
    lead = drive(four_way, "car1", lead_route, lead_in + 9.0, 5.0, end=0.1)
    found = measure_criticality(four_way, ego, [lead]).others[0]
    assert found.ttc is not None and found.distance is not None and found.drac is not None
    assert found.distance.value == pytest.approx(3.1, abs=0.05)
    assert found.ttc.value == pytest.approx(4.28, abs=0.05)  # following, not 0.058
    assert found.ttc.value >= found.distance.value / (6.0 - 5.0)
    assert found.drac.value == pytest.approx(1.0 / (2 * 4.28), abs=0.01)


MERGE = ("N2C_0:C2W_0", "E2C_0:C2W_0")  # a right turn and a straight on, both into C2W_0


def test_at_a_merge_cars_one_behind_the_other_are_not_in_the_conflict_at_once(
    four_way: Intersection,
) -> None:
    """car1 (straight on) passes the merge point first at 6 m/s, the ego (turning right)
    reaches it 0.5 s after car1's back has passed it, at the same speed: 3 m apart, never
    closing. The strips' overlap runs 4.3 m along the lanes before the merge point, so
    measured as an area the ego entered it while car1's back was still in it: a PET of 0
    and a TTC predicted as for a crash. At the merge point (SUMO's) the PET is 0.5 s and
    no crash is predicted."""
    probe = drive(four_way, "ego", MERGE[0], 0.0, 1.0), drive(four_way, "car1", MERGE[1], 0.0, 1.0)
    area = conflict_area(four_way, *probe)
    assert area is not None
    ego_merge, _ = merge_bounds(four_way, probe[0])
    lead_merge, lead_out = merge_bounds(four_way, probe[1])
    assert lead_out - lead_merge == pytest.approx(5.0)  # its back has passed the merge point
    ego_area, _ = area_bounds(four_way, probe[0], area) or (0.0, 0.0)
    _, lead_area_out = area_bounds(four_way, probe[1], area) or (0.0, 0.0)
    assert lead_area_out == pytest.approx(lead_out, abs=0.1)  # the area ends at the merge
    lead = drive(four_way, "car1", MERGE[1], lead_merge - 10.0, 6.0, end=5.0)  # out at 2.5 s
    ego = drive(four_way, "ego", MERGE[0], ego_merge - 18.0, 6.0, end=5.0)  # in at 3 s
    # measured as the area: the ego in it from (18 - (ego_merge - ego_area)) / 6 s, before 2.5 s
    assert (18.0 - (ego_merge - ego_area)) / 6.0 < 2.5
    found = measure_criticality(four_way, ego, [lead]).others[0]
    assert len(found.pet) == 1
    assert found.pet[0].value == pytest.approx(0.5, abs=0.02)
    assert found.pet[0].t == pytest.approx(3.0, abs=0.02)
    assert found.ttc is None and found.drac is None


def test_at_a_merge_a_crash_is_predicted_at_the_merge_point(four_way: Intersection) -> None:
    """car1 10 m before the merge point at 6 m/s (its back past it at 2.5 s), the ego 15 m
    before it at 8 m/s (there at 1.875 s): SUMO's merging TTC, the second car's time to the
    merge point, 0.875 s at the last sample (1 s); DRAC the smaller of car1's and the ego's
    deceleration to reach the merge point just as the other has passed it."""
    probe = drive(four_way, "ego", MERGE[0], 0.0, 1.0), drive(four_way, "car1", MERGE[1], 0.0, 1.0)
    ego_merge, _ = merge_bounds(four_way, probe[0])
    lead_merge, _ = merge_bounds(four_way, probe[1])
    lead = drive(four_way, "car1", MERGE[1], lead_merge - 10.0, 6.0)
    ego = drive(four_way, "ego", MERGE[0], ego_merge - 15.0, 8.0)
    found = measure_criticality(four_way, ego, [lead]).others[0]
    assert found.ttc is not None and found.drac is not None
    assert found.ttc.value == pytest.approx(0.875, abs=2e-3)
    assert found.ttc.t == pytest.approx(1.0)
    # at 1 s: the ego 7 m before the merge point, car1 4 m; car1 out in 9 / 6 s, the ego in 12 / 8
    ego_waits = 2 * (8.0 - 7.0 / 1.5) / 1.5
    lead_waits = 2 * (6.0 - 4.0 / 1.5) / 1.5
    assert found.drac.value == pytest.approx(min(ego_waits, lead_waits), abs=2e-3)
