"""The checker on trajectories: Step 1 poses of real SUMO drives, retimed by hand.

Each rule has a scenario whose failing ego breaks exactly that rule (no collision, goal
reached) and a variant of the ego that passes. The timings were chosen with the events
printed; each comment says what happens.
"""

from __future__ import annotations

from dataclasses import dataclass

import pytest
from shapely.geometry import Point

from service.core.checker.check import Judge, check_testcase
from service.core.errors import InvalidTrajectory
from service.core.motion.poses import PoseSample, PoseTrack, generate_poses
from service.core.network import Intersection, load_intersection
from service.core.testcase import TestCase, new_testcase
from tests.conftest import DATA
from tests.helpers import drive_with_stops, retime, with_nonegos

START = 40.0  # every car starts with its front 40 m before its stop line
LINE = START - 0.5  # standing half a metre before the stop line
DURATION = 20.0
SKEWED_YIELD = str(DATA / "junctions" / "skewed-yield.net.xml")  # SUMO type priority

Stops = list[tuple[float, float]]


@dataclass(frozen=True)
class Driving:
    stops: Stops
    cruise: float = 8.0
    crawl: float | None = None

    def samples(self, track: PoseTrack) -> list[PoseSample]:
        profile = drive_with_stops(self.stops, self.cruise, crawl=self.crawl, start_speed=8.0)
        return retime(track, profile, DURATION, 0.1)


@dataclass(frozen=True)
class Scenario:
    law: str
    rule: str
    network: str
    ego_route: str
    breaks: Driving
    keeps: Driving
    car_route: str | None = None
    car: Driving | None = None


SCENARIOS = [
    # All-way stop, ego alone: rolling through the sign, or stopping half a metre before it.
    Scenario("22450(a)", "stopAtSign", "4way-stop", "S2C_1:C2W_1",
             breaks=Driving([]), keeps=Driving([(LINE, 0.5)])),
    # car1 crosses from the left and crawls at 3 m/s; the ego enters 1 s after it and pulls
    # 0.2 m into car1's lane while car1 is still in the ego's; keeping back 0.5 m is fine.
    Scenario("21800(a)", "yieldToInside", "4way-stop", "S2C_1:C2W_1",
             breaks=Driving([(LINE, 1.5), (44.2, 3.0)]), keeps=Driving([(LINE, 1.5), (43.5, 3.0)]),
             car_route="W2C_0:C2E_0", car=Driving([(LINE, 0.5)], crawl=3.0)),
    # Both stop; the ego enters 0.5 s before car1 (from its right) and turns across it.
    Scenario("21800(c)", "yieldToRightAtAllWayStop", "4way-stop", "S2C_1:C2W_1",
             breaks=Driving([(LINE, 0.5)]), keeps=Driving([(LINE, 6.0)]),
             car_route="E2C_1:C2S_1", car=Driving([(LINE, 1.0)])),
    # Through road of the T: the ego turns left while car1 arrives from the opposite side.
    Scenario("21801(a)", "leftTurnYieldsToOncoming", "t-stop", "E2C_0:C2S_0",
             breaks=Driving([]), keeps=Driving([(38.0, 5.0)]),
             car_route="W2C_0:C2E_0", car=Driving([(30.0, 1.0)], crawl=4.0)),
    # car1 turns left before the ego arrives; the ego pulls into its path while it crawls.
    Scenario("21801(b)", "oncomingYieldsToLeftTurn", "t-stop", "W2C_0:C2E_0",
             breaks=Driving([(25.0, 2.0), (45.5, 2.0)]),
             keeps=Driving([(25.0, 2.0), (44.5, 3.5)]),
             car_route="E2C_0:C2S_0", car=Driving([(LINE, 0.0)], crawl=2.0)),
    # Minor road of the T: the ego stops, then pulls out while car1 approaches at 3.5 m/s.
    Scenario("21802(a)", "yieldAfterStop", "t-stop", "S2C_0:C2W_0",
             breaks=Driving([(LINE, 0.5)]), keeps=Driving([(LINE, 8.0)]),
             car_route="W2C_0:C2E_0", car=Driving([], cruise=3.5)),
    # car1 stopped at the sign and entered before the ego arrived; the ego cuts into its path.
    Scenario("21802(b)", "yieldToCarFromStop", "t-stop", "W2C_0:C2E_0",
             breaks=Driving([(25.0, 3.0), (44.0, 2.5)]),
             keeps=Driving([(25.0, 3.0), (43.0, 2.5)]),
             car_route="S2C_0:C2W_0", car=Driving([(LINE, 1.0)], crawl=2.0)),
    # Minor road of a priority junction (yield sign): the ego slows to a halt for 0.5 s, then
    # pulls out while car1 approaches on the major road at 3.5 m/s; waiting 8 s is fine.
    Scenario("21803(a)", "yieldAtYieldSign", SKEWED_YIELD, "S2C_0:C2N_0",
             breaks=Driving([(LINE, 0.5)]), keeps=Driving([(LINE, 8.0)]),
             car_route="W2C_0:C2E_0", car=Driving([], cruise=3.5)),
    # Uncontrolled Y: the ego (10 m/s) and car1 from its right (8 m/s) enter 0.9 s apart.
    Scenario("21800(b)", "yieldOnSimultaneousEntry", "y-uncontrolled", "N2C_0:C2SE_0",
             breaks=Driving([], cruise=10.0), keeps=Driving([(38.0, 3.0)]),
             car_route="SW2C_0:C2N_0", car=Driving([], cruise=8.0)),
]  # fmt: skip


@pytest.fixture(scope="module")
def tracks() -> dict[tuple[str, str], PoseTrack]:
    """Step 1 poses of every route the scenarios use, one SUMO process per network."""
    found = {}
    for network in sorted({s.network for s in SCENARIOS}):
        intersection = load_intersection(network)
        used = [s for s in SCENARIOS if s.network == network]
        routes = {s.ego_route for s in used} | {s.car_route for s in used if s.car_route}
        if network == "4way-stop":
            routes.add("S2C_1:C2N_1")  # straight on instead of the ego's left turn
        requests = [(intersection.route(r), START) for r in sorted(routes)]
        for track in generate_poses(intersection, requests, 8.0, DURATION, 0.1):
            found[(network, track.route)] = track
    return found


def _setup(
    scenario: Scenario, tracks: dict[tuple[str, str], PoseTrack]
) -> tuple[TestCase, Intersection]:
    intersection = load_intersection(scenario.network)
    base = new_testcase(scenario.network, scenario.ego_route, start_distance=START)
    nonegos = []
    if scenario.car_route and scenario.car:
        track = tracks[(scenario.network, scenario.car_route)]
        nonegos.append(("car1", scenario.car_route, scenario.car.samples(track)))
    return with_nonegos(base, nonegos), intersection


@pytest.mark.parametrize("scenario", SCENARIOS, ids=lambda s: s.law)
def test_checker_fails_exactly_the_broken_rule(
    scenario: Scenario, tracks: dict[tuple[str, str], PoseTrack]
) -> None:
    testcase, intersection = _setup(scenario, tracks)
    ego = scenario.breaks.samples(tracks[(scenario.network, scenario.ego_route)])
    verdict = check_testcase(testcase, ego, "hand-built", intersection)
    assert not verdict.passed
    assert [(v.rule, v.law) for v in verdict.violations] == [(scenario.rule, scenario.law)]
    assert verdict.violations[0].other == (None if scenario.car is None else "car1")
    assert verdict.collisions == ()
    assert verdict.goal_reached
    assert scenario.law in verdict.reasons[0]


@pytest.mark.parametrize("scenario", SCENARIOS, ids=lambda s: s.law)
def test_checker_passes_the_variant_that_keeps_the_rule(
    scenario: Scenario, tracks: dict[tuple[str, str], PoseTrack]
) -> None:
    testcase, intersection = _setup(scenario, tracks)
    ego = scenario.keeps.samples(tracks[(scenario.network, scenario.ego_route)])
    verdict = check_testcase(testcase, ego, "hand-built", intersection)
    assert verdict.passed, verdict.reasons
    assert verdict.goal_time is not None and verdict.goal_time <= DURATION


def test_violation_names_the_events_involved(tracks: dict[tuple[str, str], PoseTrack]) -> None:
    scenario = SCENARIOS[1]  # 21800 (a)
    testcase, intersection = _setup(scenario, tracks)
    ego = scenario.breaks.samples(tracks[(scenario.network, scenario.ego_route)])
    violation = check_testcase(testcase, ego, "x", intersection).violations[0]
    kinds = [(e.car, e.kind) for e in violation.events]
    assert kinds == [("car1", "entered"), ("ego", "entered"), ("ego", "entered_lane"),
                     ("car1", "left_lane")]  # fmt: skip
    car_entered, ego_entered, into, out = (e.t for e in violation.events)
    assert ego_entered - car_entered >= 1.0 - 1e-9
    assert out - into >= 1.0


def test_collision_is_reported_with_time_and_place(
    tracks: dict[tuple[str, str], PoseTrack],
) -> None:
    scenario = SCENARIOS[2]  # both stop 0.5 s and 1 s; an ego that waits 2 s hits car1
    testcase, intersection = _setup(scenario, tracks)
    ego = Driving([(LINE, 2.0)]).samples(tracks[(scenario.network, scenario.ego_route)])
    verdict = check_testcase(testcase, ego, "x", intersection)
    assert [c.other for c in verdict.collisions] == ["car1"]
    collision = verdict.collisions[0]
    assert 8.0 < collision.t < 14.0
    assert intersection.polygon.buffer(1.0).contains(Point(collision.x, collision.y))
    assert "collided with car1" in " ".join(verdict.reasons)


def test_goal_not_reached_when_the_ego_stays_before_the_line(
    tracks: dict[tuple[str, str], PoseTrack],
) -> None:
    testcase, intersection = _setup(SCENARIOS[0], tracks)
    ego = Driving([(LINE, 100.0)]).samples(tracks[("4way-stop", "S2C_1:C2W_1")])
    verdict = check_testcase(testcase, ego, "x", intersection)
    assert not verdict.goal_reached and not verdict.passed
    assert verdict.violations == ()
    assert verdict.reasons == ["did not reach its exit lane, out of the junction, within 20 s"]


def test_goal_not_reached_on_the_wrong_exit(tracks: dict[tuple[str, str], PoseTrack]) -> None:
    testcase, intersection = _setup(SCENARIOS[0], tracks)
    straight_on = Driving([(LINE, 0.5)]).samples(tracks[("4way-stop", "S2C_1:C2N_1")])
    assert not check_testcase(testcase, straight_on, "x", intersection).goal_reached


def test_goal_not_reached_after_the_duration(tracks: dict[tuple[str, str], PoseTrack]) -> None:
    testcase, intersection = _setup(SCENARIOS[0], tracks)
    slow = Driving([(LINE, 0.5)], crawl=1.0).samples(tracks[("4way-stop", "S2C_1:C2W_1")])
    verdict = check_testcase(testcase, slow, "x", intersection)
    assert not verdict.goal_reached


def test_trajectory_that_starts_elsewhere_is_refused(
    tracks: dict[tuple[str, str], PoseTrack],
) -> None:
    testcase, intersection = _setup(SCENARIOS[0], tracks)
    ego = Driving([(LINE, 0.5)]).samples(tracks[("4way-stop", "S2C_1:C2W_1")])[30:]
    with pytest.raises(InvalidTrajectory, match=r"m from the test-case's start"):
        check_testcase(testcase, ego, "x", intersection)


def test_the_signal_rules_a_nonego_breaks_are_found() -> None:
    """4way-signal: north-south green 0-20 s, east-west red until 25 s. A car cruising from
    the north enters on green and breaks nothing; one cruising from the west runs the red
    (21453 (a)); the verification of every extension at a light asks this of each new car."""
    intersection = load_intersection("4way-signal")
    routes = ("N2C_0:C2S_0", "W2C_0:C2E_0")
    requests = [(intersection.route(r), START) for r in routes]
    drives = generate_poses(intersection, requests, 8.0, DURATION, 0.1)
    samples = [Driving([]).samples(track) for track in drives]
    base = new_testcase("4way-signal", "S2C_0:C2N_0", start_distance=START)
    testcase = with_nonegos(
        base, [("car1", routes[0], samples[0]), ("car2", routes[1], samples[1])]
    )
    judge = Judge(testcase, intersection)
    assert judge.rules_broken_by("car1") == []
    broken = judge.rules_broken_by("car2")
    assert [(v.rule, v.law, v.events[0].kind) for v in broken] == [
        ("stopAtRed", "21453(a)", "entered")
    ]


def test_a_yield_sign_asks_no_stop(tracks: dict[tuple[str, str], PoseTrack]) -> None:
    """Alone at the yield sign the ego drives through at 8 m/s and passes (at a stop sign
    that breaks 22450 (a): the 22450(a) scenario)."""
    testcase = new_testcase(SKEWED_YIELD, "S2C_0:C2N_0", start_distance=START)
    ego = Driving([]).samples(tracks[(SKEWED_YIELD, "S2C_0:C2N_0")])
    verdict = check_testcase(testcase, ego, "hand-built", load_intersection(SKEWED_YIELD))
    assert verdict.passed, verdict.reasons
