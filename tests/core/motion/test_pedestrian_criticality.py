"""Criticality against people on foot (service.core.motion.pedestrian_criticality): on
hand-made walks at the all-way stop with crossings, a car and a pedestrian at constant
speeds whose measures are known by hand, then a generated test-case judged whole.

The geometry (tests/data/junctions/stop-crossings.net.xml): the ego goes straight north on
S2C_1:C2N_1 along x = 154.8 (its front at place p on its path is at y = p - 1000; its
5 x 1.8 m rectangle spans x 153.9 to 155.7); its connecting lane :C_9_0 spans x 153.2 to
156.4. The crosswalk at its exit, :C_c0, spans y 156.4 to 160.4, its centreline at
y = 158.4 from x = 143.6 to 156.4; walk C_c0- goes east along it (heading 90), C_c0+ west.
A pedestrian (SUMO's: 0.215 m long, 0.478 m wide) walking east spans x +- 0.1075 and
y 158.161 to 158.639. The conflict area of the two is x 153.2 to 156.4, y 156.4 to 160.4.
"""

from __future__ import annotations

import json
import math
from xml.etree import ElementTree as ET

import numpy as np
import pytest
import shapely

from service.cli.output import describe_criticality
from service.core.campaign.criticality_by_level import level_criticality, overall_value
from service.core.checker.check import Judge, check_testcase, judged_samples
from service.core.checker.verdict import Verdict
from service.core.generator.extension import extend_testcase
from service.core.motion.criticality import Mover, route_path
from service.core.motion.events import EventKind, rectangles
from service.core.motion.pedestrian_criticality import (
    PedestrianMover,
    measure_pedestrians,
    overlap,
    pedestrian_series,
)
from service.core.motion.poses import PoseSample
from service.core.network import Intersection
from service.core.testcase import TestCase, new_testcase
from tests.core.checker.crossing_model import stop_crossings
from tests.core.motion.test_criticality import drive

EGO = "S2C_1:C2N_1"
LENGTH, WIDTH = 0.215, 0.478  # SUMO's default pedestrian
STEP = 0.1
HALF = LENGTH / 2.0  # along her heading (east or west)
EGO_LEFT, EGO_RIGHT = 153.9, 155.7  # the ego's rectangle across its lane
LANE_LEFT = 153.2  # the ego's connecting lane's west edge
CENTRE = 158.4  # the crosswalk's centreline


@pytest.fixture(scope="module")
def stop() -> Intersection:
    return stop_crossings()


def front_at(junction: Intersection, y: float) -> float:
    """The place on the ego's path of a front at ``y``."""
    line = route_path(junction, junction.route(EGO)).stop_line
    return line + (y - 139.6)


def walking(walk: str, x: float, pace: float, end: float, y: float = CENTRE) -> PedestrianMover:
    """A pedestrian on ``walk`` whose centre is at (x, y) at t = 0 and who walks at
    ``pace`` (east for C_c0-, west for C_c0+) until ``end``."""
    heading = 90.0 if walk.endswith("-") else 270.0
    sign = 1.0 if heading == 90.0 else -1.0
    samples = [
        PoseSample(k * STEP, x + sign * pace * k * STEP, y, heading, pace, pace * k * STEP)
        for k in range(round(end / STEP) + 1)
    ]
    return PedestrianMover("ped1", walk, LENGTH, WIDTH, samples)


def gaps_over_closing(ego: Mover, person: PedestrianMover, times: np.ndarray) -> np.ndarray:
    """The gap between the two rectangles at ``times`` over the sum of their speeds: no
    collision can come sooner."""

    def at(samples: list[PoseSample], name: str) -> np.ndarray:
        return np.interp(times, [s.t for s in samples], [getattr(s, name) for s in samples])

    ego_samples, samples = list(ego.samples), list(person.samples)
    mine = rectangles(at(ego_samples, "x"), at(ego_samples, "y"), at(ego_samples, "heading"),
                      ego.length, ego.width)  # fmt: skip
    theirs = rectangles(at(samples, "x"), at(samples, "y"), at(samples, "heading"),
                        person.length, person.width)  # fmt: skip
    closing = at(ego_samples, "speed") + at(samples, "speed")
    return shapely.distance(mine, theirs) / closing  # type: ignore[no-any-return]


def test_a_pedestrian_crossing_in_front_gives_the_ttc_and_drac_by_hand(stop: Intersection) -> None:
    # the ego at 5 m/s reaches her strip (front past y 158.161) at 2.5 s and is on it until
    # its back passes 158.639 at 3.5956 s; she at 1.25 m/s from x = 150 reaches its side
    # (x 153.9 - 0.1075) at 3.034 s: seen from t = 1 s, a collision in 2.034 s
    ego = drive(stop, "ego", EGO, front_at(stop, 158.161 - 12.5), 5.0)
    person = walking("C_c0-", 150.0, 1.25, 1.0)
    (found,) = measure_pedestrians(stop, ego, [person])
    collision = (EGO_LEFT - HALF - 150.0) / 1.25
    assert found.car == "ped1"
    assert found.ttc is not None and found.drac is not None
    assert found.ttc.value == pytest.approx(collision - 1.0, abs=2e-3)
    assert found.ttc.t == pytest.approx(1.0)
    assert found.drac.value == pytest.approx(5.0 / (2 * (collision - 1.0)), abs=2e-3)
    assert found.drac.t == pytest.approx(1.0)
    times, ttc, drac = pedestrian_series(stop, ego, person)
    assert ttc == pytest.approx(collision - times, abs=2e-3)  # the same crash seen each step
    assert drac == pytest.approx(5.0 / (2 * ttc), abs=2e-3)
    # physically consistent: never sooner than the gap over the closing speed
    assert np.all(ttc >= gaps_over_closing(ego, person, times) - 1e-3)


def test_a_pedestrian_crossing_behind_the_car_gives_no_ttc_and_the_pet_by_hand(
    stop: Intersection,
) -> None:
    # the ego at 8 m/s is in the conflict area (front past y 156.4 until its back passes
    # 160.4, front at 165.4) until 3 s; she reaches the lane (x 153.2 - 0.1075) at 4.5 s
    ego = drive(stop, "ego", EGO, front_at(stop, 141.4), 8.0, end=6.0)
    start = LANE_LEFT - HALF - 1.25 * 4.5
    person = walking("C_c0-", start, 1.25, 6.0)
    (found,) = measure_pedestrians(stop, ego, [person])
    assert found.ttc is None and found.drac is None
    assert [p.area for p in found.pet] == [":C_9_0|:C_c0_0"]
    assert found.pet[0].value == pytest.approx(1.5, abs=0.01)
    assert found.pet[0].t == pytest.approx(4.5, abs=0.01)
    # stepping into the lane at 2.5 s, while the car is in the area, gives a PET of 0;
    # but she reaches its side (x 153.7925) only at 3.06 s, after its back passed her
    # strip (2.78 s): never on a collision course, no TTC (both in the lane-wide area at
    # once is not a crash); closest at 2.8 s, she 0.7 - 0.3 x 1.25 m west of its side, its
    # back (163.8 - 5) past her strip's north edge
    ahead = walking("C_c0-", LANE_LEFT - HALF - 1.25 * 2.5, 1.25, 6.0)
    (found,) = measure_pedestrians(stop, ego, [ahead])
    assert found.pet[0].value == 0.0
    assert found.pet[0].t == pytest.approx(2.5, abs=0.01)  # she entered second
    assert found.ttc is None and found.drac is None
    assert found.distance is not None
    gap = math.hypot(0.7 - 0.3 * 1.25, (141.4 + 8.0 * 2.8 - 5.0) - (CENTRE + WIDTH / 2))
    assert found.distance.value == pytest.approx(gap, abs=1e-3)
    assert found.distance.t == pytest.approx(2.8)


def test_a_pedestrian_past_the_lane_gives_nothing_but_the_distance(stop: Intersection) -> None:
    # she walks east away from x = 157 (clear of the area, whose east edge is 156.4) while
    # the ego drives over the crosswalk at 8 m/s from y 141.4
    ego = drive(stop, "ego", EGO, front_at(stop, 141.4), 8.0, end=6.0)
    person = walking("C_c0-", 157.0, 1.25, 6.0)
    (found,) = measure_pedestrians(stop, ego, [person])
    assert found.ttc is None and found.drac is None and found.pet == ()
    # both rectangles are upright: the gap is the hypotenuse of the gaps along x and y
    times = np.arange(61) * STEP
    front, her_x = 141.4 + 8.0 * times, 157.0 + 1.25 * times
    across = np.maximum(0.0, her_x - HALF - EGO_RIGHT)
    along = np.maximum(
        0.0, np.maximum((CENTRE - WIDTH / 2) - front, (front - 5.0) - (CENTRE + WIDTH / 2))
    )
    gaps = np.hypot(across, along)
    assert found.distance is not None
    assert found.distance.value == pytest.approx(gaps.min(), abs=1e-3)
    assert found.distance.t == pytest.approx(times[np.argmin(gaps)])


def test_a_pedestrian_standing_at_the_curb_gives_no_ttc_and_the_smallest_distance(
    stop: Intersection,
) -> None:
    # she stands 1 m before the crosswalk's east curb (x 156.4), beside the ego's lane,
    # facing the road, while the ego drives past her at 8 m/s
    ego = drive(stop, "ego", EGO, front_at(stop, 141.4), 8.0, end=6.0)
    person = walking("C_c0+", 157.4, 0.0, 6.0)
    (found,) = measure_pedestrians(stop, ego, [person])
    assert found.ttc is None and found.drac is None and found.pet == ()
    assert found.distance is not None
    assert found.distance.value == pytest.approx(157.4 - HALF - EGO_RIGHT, abs=1e-3)
    # closest while the ego's side passes her: its front past her back edge (y 158.161)
    # and its back not past her front edge (158.639), at 8 m/s from y 141.4
    assert 16.761 / 8.0 <= found.distance.t <= (158.639 + 5.0 - 141.4) / 8.0
    # standing in the road in its path, she is on its collision course
    person = walking("C_c0+", 154.8, 0.0, 6.0)
    (found,) = measure_pedestrians(stop, ego, [person])
    assert found.ttc is not None
    assert found.ttc.value == pytest.approx(((CENTRE - WIDTH / 2) - 141.4) / 8.0 - found.ttc.t,
                                            abs=2e-3)  # fmt: skip


def test_the_overlap_test_agrees_with_the_outlines() -> None:
    rng = np.random.default_rng(7)
    ax, ay, bx, by = rng.uniform(-3.0, 3.0, (4, 20000))
    ah, bh = rng.uniform(0.0, 2 * math.pi, (2, 20000))
    mine = rectangles(ax, ay, np.degrees(ah), 5.0, 1.8)
    theirs = rectangles(bx, by, np.degrees(bh), LENGTH, WIDTH)
    outlines = shapely.intersects(mine, theirs) & ~shapely.touches(mine, theirs)
    found = overlap((ax, ay, ah, 5.0, 1.8), (bx, by, bh, LENGTH, WIDTH))
    assert outlines.any() and (~outlines).any()
    assert np.array_equal(found, outlines)


# --- a generated test-case, judged whole ---------------------------------------------------


@pytest.fixture(scope="module")
def crosswalk() -> TestCase:
    """The crosswalk all-way stop's right turn E2C_1:C2N_1, a pedestrian added over its
    exit's crosswalk (C_c0-)."""
    start = new_testcase("crosswalk-stop", "E2C_1:C2N_1", duration=30.0)
    return extend_testcase(start, [], walks=["C_c0-"]).testcase


def certificate(testcase: TestCase, which: str) -> list[PoseSample]:
    return [PoseSample(**s.model_dump()) for s in getattr(testcase.certificates, which)]


@pytest.mark.parametrize("which", ["complexity", "solvability"])
def test_check_testcase_reports_the_pedestrian_in_its_criticality(
    crosswalk: TestCase, which: str
) -> None:
    (person,) = crosswalk.pedestrians
    verdict = check_testcase(crosswalk, certificate(crosswalk, which))
    criticality = verdict.criticality
    assert criticality is not None
    (found,) = criticality.others
    assert found.car == person.id
    # the ego turns right through the crosswalk she walks: both went through the area
    lane = ":C_4_0"
    assert [p.area for p in found.pet] == [f"{lane}|:C_c0_0"]
    # she came second: the PET ends when she reached the ego's lane on the crossing, and
    # began when the ego left the crosswalk (within its lane, the area's edge)
    on = next(e.t for e in person.events if e.kind == EventKind.ENTERED)
    reached = next(
        e.t
        for e in person.events
        if e.kind == EventKind.ENTERED_LANE and e.lane == lane and e.t >= on
    )
    ego_left = next(e.t for e in verdict.ego_events
                    if e.kind == "left_lane" and e.lane == ":C_c0_0")  # fmt: skip
    assert found.pet[0].t == pytest.approx(reached, abs=2e-3)
    assert found.pet[0].value == pytest.approx(reached - ego_left, abs=0.02)
    assert found.distance is not None and found.distance.value > 0.0  # no collision
    assert verdict.collisions == ()
    # every TTC at least the gap over the closing speed, and overall names her
    judge = Judge(crosswalk)
    ego_car = judge.ego_car(certificate(crosswalk, which))
    assert verdict.goal_time is not None
    ego = Mover("ego", judge.junction.route(crosswalk.ego.route.id), ego_car.length,
                ego_car.width, judged_samples(ego_car.samples, verdict.goal_time))  # fmt: skip
    walker = judge.pedestrians[0]
    mover = PedestrianMover(walker.id, walker.walk, walker.length, walker.width, walker.samples)
    times, ttc, _ = pedestrian_series(judge.junction, ego, mover)
    finite = np.isfinite(ttc)
    assert finite.any()
    assert np.all(ttc[finite] >= gaps_over_closing(ego, mover, times[finite]))
    assert found.ttc is not None and found.ttc.value == pytest.approx(ttc[finite].min(), abs=1e-3)
    assert criticality.ttc is not None and criticality.ttc.car == person.id
    assert criticality.pet is not None and criticality.pet.car == person.id
    assert criticality.distance is not None and criticality.distance.car == person.id


def test_the_pedestrian_shows_wherever_criticality_is_shown(crosswalk: TestCase) -> None:
    verdict = check_testcase(crosswalk, certificate(crosswalk, "complexity"))
    assert verdict.criticality is not None
    ttc = verdict.criticality.ttc
    assert ttc is not None and ttc.car == "ped1"
    document = json.loads(verdict.to_json())
    assert list(document["criticality"]["others"]) == ["ped1"]
    assert document["criticality"]["overall"]["ttc"] == {"value": ttc.value, "car": "ped1",
                                                         "t": ttc.t}  # fmt: skip
    assert Verdict.from_dict(document) == verdict
    line = describe_criticality(verdict.criticality)
    assert f"TTC {ttc.value:.2f} s (ped1 at {ttc.t:.2f} s)" in line
    case = ET.fromstring(verdict.to_junit()).find("testsuite/testcase")
    assert case is not None
    properties = {p.get("name"): p.get("value") for p in case.iterfind("properties/property")}
    assert properties["criticality.ttc.car"] == "ped1"
    assert properties["criticality.pet.area"] == ":C_4_0|:C_c0_0"
    assert overall_value(document, "ttc") == ttc.value
    assert level_criticality([document])["ttc"]["values"] == [ttc.value]
