"""Jumps no car can drive: found in a teleporting trajectory, never in generated ones."""

from __future__ import annotations

import gzip
import math
from dataclasses import dataclass

from service.core.motion.plausibility import first_jump
from service.core.testcase import implausible_trajectories, parse_testcase
from tests.conftest import DATA


@dataclass(frozen=True)
class Pose:
    t: float
    x: float
    y: float
    speed: float


def test_a_generated_level_4_testcase_has_no_jump() -> None:
    """Four levels of generated cars, queues included."""
    testcase = parse_testcase(
        gzip.decompress((DATA / "queues" / "t-stop-level4.json.gz").read_bytes())
    )
    assert len(testcase.nonegos) >= 4
    assert implausible_trajectories(testcase) == []


def test_a_hard_stop_and_a_tight_turn_are_plausible() -> None:
    braking = [
        Pose(k / 10, 0.0, 15 * k / 10 - 4.5 * (k / 10) ** 2, 15 - 9 * k / 10) for k in range(16)
    ]
    assert first_jump(braking) is None
    radius = 6.0  # a right turn at 5 m/s, the centre on the arc
    turning = [
        Pose(
            k / 10,
            radius * math.cos(5 * k / 10 / radius),
            radius * math.sin(5 * k / 10 / radius),
            5.0,
        )
        for k in range(20)
    ]
    assert first_jump(turning) is None


def test_a_teleport_and_a_false_speed_are_found() -> None:
    teleport = [Pose(0.0, 0.0, 0.0, 10.0), Pose(0.1, 0.0, 1.0, 10.0), Pose(0.2, 0.0, 31.0, 10.0)]
    assert first_jump(teleport) == (
        "moves 30.0 m between 0.10 s and 0.20 s, where its speeds (10.0 and 10.0 m/s) allow "
        "at most 1.6 m"
    )
    claimed = [Pose(0.0, 0.0, 0.0, 400.0), Pose(0.1, 0.0, 40.0, 400.0)]  # 400 m/s is no car
    assert first_jump(claimed) is not None
