"""Test helpers: trajectories with chosen speed profiles along Step 1 poses."""

from __future__ import annotations

import dataclasses
import functools
import json
from collections.abc import Callable

from service.core.poses import PoseSample, PoseTrack
from service.core.testcase import TestCase, dump_testcase, parse_testcase


def retime(
    track: PoseTrack,
    profile: Callable[[float], tuple[float, float]],
    duration: float,
    timestep: float,
) -> list[PoseSample]:
    """Samples every ``timestep`` where ``profile(t)`` gives (distance, speed) on ``track``."""
    samples = []
    for k in range(round(duration / timestep) + 1):
        t = k * timestep
        distance, speed = profile(t)
        x, y, heading = track.pose_at(distance)
        samples.append(PoseSample(t, x, y, heading, speed, distance))
    return samples


def stop_and_go(
    cruise: float, stop_at: float, brake: float, wait: float, accelerate: float
) -> Callable[[float], tuple[float, float]]:
    """Cruise, brake at ``brake`` m/s^2 to stand at ``stop_at`` m, wait, accelerate back."""
    braking_time = cruise / brake
    braking_from = stop_at - cruise * braking_time / 2.0
    t_brake = braking_from / cruise
    t_stand = t_brake + braking_time
    t_go = t_stand + wait
    t_cruise = t_go + cruise / accelerate

    def profile(t: float) -> tuple[float, float]:
        if t <= t_brake:
            return cruise * t, cruise
        if t <= t_stand:
            s = t - t_brake
            return braking_from + cruise * s - brake * s * s / 2.0, cruise - brake * s
        if t <= t_go:
            return stop_at, 0.0
        if t <= t_cruise:
            s = t - t_go
            return stop_at + accelerate * s * s / 2.0, accelerate * s
        s = t - t_cruise
        return stop_at + cruise * cruise / (2 * accelerate) + cruise * s, cruise

    return profile


def drive_with_stops(
    stops: list[tuple[float, float]],
    cruise: float = 8.0,
    accelerate: float = 2.0,
    brake: float = 3.0,
    start_speed: float | None = None,
    crawl: float | None = None,
    step: float = 0.001,
) -> Callable[[float], tuple[float, float]]:
    """A driver that cruises, brakes to stand at each (distance, wait) of ``stops`` and
    waits there, then goes on (at ``crawl`` at most once it has stopped, if given);
    returns its (distance, speed) at any time."""
    times, distances, speeds = [0.0], [0.0], [cruise if start_speed is None else start_speed]
    limit = cruise
    pending = sorted(stops)
    held = 0.0
    t, d, v = 0.0, 0.0, speeds[0]
    while t < 120.0:
        if pending and d >= pending[0][0] - 1e-3 and v <= 1e-6:
            held += step
            if held >= pending[0][1]:
                pending.pop(0)
                held = 0.0
                limit = crawl or cruise
            v = 0.0
        elif pending and v * v / (2 * brake) >= pending[0][0] - d:
            v = max(0.0, v - brake * step)
        elif v > limit:
            v = max(limit, v - brake * step)
        else:
            v = min(limit, v + accelerate * step)
        if pending:
            d = min(d + v * step, pending[0][0])
        else:
            d += v * step
        t += step
        times.append(t)
        distances.append(d)
        speeds.append(v)

    def profile(at: float) -> tuple[float, float]:
        k = min(round(at / step), len(times) - 1)
        return distances[k], speeds[k]

    return profile


def with_nonegos(
    testcase: TestCase, nonegos: list[tuple[str, str, list[PoseSample]]], **changes: object
) -> TestCase:
    """``testcase`` with non-egos (id, route id, samples) added and fields changed."""
    document = json.loads(dump_testcase(testcase))
    document.update(changes)
    for car_id, route, samples in nonegos:
        fork, exit_lane = route.split(":")
        document["nonegos"].append(
            {
                "id": car_id,
                "route": {"fork": fork, "exit": exit_lane},
                "added_in": 1,
                "trajectory": [dataclasses.asdict(s) for s in samples],
            }
        )
    return parse_testcase(document)


@functools.cache
def car_ahead_of_ego() -> TestCase:
    """The README's queue: on the four-way stop the ego (E2C_0:C2N_0, 30 m out) turns
    right, and the generator adds a car ahead of it on its fork that goes straight on."""
    from service.core.generate import extend_testcase
    from service.core.testcase import new_testcase

    old = new_testcase("4way-stop", "E2C_0:C2N_0", duration=45.0, name="queue")
    return extend_testcase(old, ["E2C_0:C2W_0"], seed=0, budget=120).testcase
