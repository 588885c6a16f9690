"""Test helpers: trajectories with chosen speed profiles along Step 1 poses."""

from __future__ import annotations

from collections.abc import Callable

from service.core.poses import PoseSample, PoseTrack


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
