"""Our criticality against SUMO's SSM device on the same replays (bench.ssm_compare):
the same values within the tolerances of docs/criticality.md where both define a measure alike."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench.ssm_compare import FOLLOWING, crossing_case, following_case, ssm_replay

TTC_TOLERANCE = 0.2  # s
PET_TOLERANCE = 0.2  # s: two time steps
FOLLOWING_TOLERANCE = 0.02  # relative, and 0.01 absolute


def test_crossing_ttc_and_pet_agree_with_sumo() -> None:
    replay = ssm_replay(crossing_case(), "certificate:complexity")
    sumo = replay.conflicts["car1"]
    assert replay.verdict.criticality is not None
    ours = replay.verdict.criticality.others[0]
    assert sumo.ttc is not None and ours.ttc is not None
    assert ours.ttc.value == pytest.approx(sumo.ttc[0], abs=TTC_TOLERANCE)
    assert ours.ttc.t == pytest.approx(sumo.ttc[1], abs=0.11)
    assert sumo.pet is not None and len(ours.pet) == 1
    assert ours.pet[0].value == pytest.approx(sumo.pet[0], abs=PET_TOLERANCE)
    assert ours.pet[0].t == pytest.approx(sumo.pet[1], abs=PET_TOLERANCE)


def test_following_ttc_and_drac_agree_with_sumo_at_every_step() -> None:
    """At every step SUMO logs as following while the car ahead holds its speed (while it
    brakes SUMO's values lag ours, as if it saw that car a step late) and is still on the
    fork (SUMO measures the gap along its lanes, we along the ego's path: one line up to
    the stop line)."""
    testcase = following_case()
    replay = ssm_replay(testcase, "sumo")
    ahead = testcase.nonegos[0]
    entered = next(e.t for e in ahead.events if e.kind == "entered")
    times, ttc, drac = replay.series(ahead.id)
    ours = {round(float(t), 2): (a, b) for t, a, b in zip(times, ttc, drac, strict=True)}
    steady = _steady([s.speed for s in ahead.trajectory])
    compared = 0
    for t, kind, sumo_ttc, sumo_drac in replay.conflicts[ahead.id].steps:
        k = round(t / testcase.timestep)
        if kind not in FOLLOWING or t >= entered or math.isnan(sumo_ttc) or not steady[k]:
            continue
        our_ttc, our_drac = ours[round(t, 2)]
        assert our_ttc == pytest.approx(sumo_ttc, rel=FOLLOWING_TOLERANCE, abs=0.01), t
        assert our_drac == pytest.approx(sumo_drac, rel=FOLLOWING_TOLERANCE, abs=0.01), t
        compared += 1
    assert compared >= 20
    assert replay.verdict.criticality is not None
    drac = replay.verdict.criticality.others[0].drac
    sumo = replay.conflicts[ahead.id].drac
    assert drac is not None and sumo is not None
    assert drac.value == pytest.approx(sumo[0], rel=FOLLOWING_TOLERANCE)
    assert np.isfinite(ttc).any()


def _steady(speeds: list[float]) -> np.ndarray:
    """Samples whose speed is within 0.01 m/s of the one before (the first: of the next)."""
    change = np.abs(np.diff(speeds))
    return np.concatenate([change[:1], change]) <= 0.01  # type: ignore[no-any-return]
