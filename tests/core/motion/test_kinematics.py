"""The necessary conditions of service.core.motion.kinematics hold for real motions.

Step 2 refuses every order that breaks them, so a condition that some motion within the
bounds breaks would hide real test-cases: each is checked on random drives (constant
accelerations within the bounds, some with a stand on the way)."""

from __future__ import annotations

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from service.core.motion.kinematics import Bounds, lingering
from tests.core.generator.test_timing import PARAMS, STEP, Drive, drives

BOUNDS = Bounds(PARAMS.v_max, PARAMS.a_max, PARAMS.a_min)
SLACK = 3 * STEP  # the drives are integrated in steps of STEP seconds


@st.composite
def drives_with_points(draw: st.DrawFn) -> tuple[Drive, list[float]]:
    drive, _ = draw(drives(draw(st.sampled_from([None, 8.0])), stop=draw(st.booleans())))
    end = drive.distances[-1]
    shares = draw(st.lists(st.floats(0.02, 0.98), min_size=2, max_size=6, unique=True))
    points = sorted({round(share * end, 3) for share in shares})
    return drive, [0.0, *(p for p in points if p > 0.05)]


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(drives_with_points())
def test_lingering_bounds_hold_for_every_drive(case: tuple[Drive, list[float]]) -> None:
    """A segment that took long slows the points around it, for every motion."""
    drive, distances = case
    times = [drive.time_at(d) for d in distances]
    for linger in lingering(distances, BOUNDS):
        took = times[linger.segment] - times[linger.segment - 1]
        if took < linger.seconds:
            continue
        if linger.other > linger.segment:
            gap = times[linger.other] - times[linger.segment]
        else:
            gap = times[linger.segment - 1] - times[linger.other]
        assert gap >= linger.least - SLACK, (linger, took, gap)


def test_lingering_gives_bounds_beyond_the_least_gaps() -> None:
    """A car that took long over ten metres to the line cannot cross the next ten at full
    speed: some bound is stated, and it asks for more than v_max would."""
    found = lingering([0.0, 20.0, 30.0, 40.0], BOUNDS)
    after = [f for f in found if f.segment == 2 and f.other == 3]
    assert after
    assert min(f.least for f in after) > 10.0 / PARAMS.v_max
