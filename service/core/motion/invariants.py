"""What every trajectory the generator returns keeps, checked on the samples themselves.

A curve whose speed is clamped at zero can still move backwards, and a solver's model can
keep every bound while its sampled, rounded trajectory does not; so the generator checks the
samples it is about to return, before the pass-fail checker runs: distance never decreases;
speed within [0, v_max] as sampled and as differenced from the distances; acceleration
within [a_min, a_max] as differenced from the speeds and (second differences) from the
distances; the speeds agree with the distances travelled, so a car stands still exactly
where its speed says it does; a certificate starts at the ego's start speed.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol


class Sampled(Protocol):
    @property
    def t(self) -> float: ...
    @property
    def speed(self) -> float: ...
    @property
    def distance(self) -> float: ...


class Limits(Protocol):
    @property
    def a_min(self) -> float: ...
    @property
    def a_max(self) -> float: ...
    @property
    def v_max(self) -> float: ...


ROUNDING = 1e-6  # the samples are rounded to this many metres (and m/s)
SLACK = 1e-3  # m/s or m/s^2 beyond a bound that float arithmetic may cost


def motion_fault(
    samples: Sequence[Sampled],
    limits: Limits,
    timestep: float,
    start_speed: float | None = None,
) -> str | None:
    """The first broken invariant of a sampled trajectory, or None when it keeps them all."""
    if start_speed is not None and abs(samples[0].speed - start_speed) > SLACK:
        return f"starts at {samples[0].speed:.3f} m/s instead of {start_speed:g} m/s"
    noise = 4 * ROUNDING / timestep**2 + SLACK  # what rounding does to a second difference
    # A cubic piece's speed over one step differs from its chord by at most this much.
    chord = (limits.a_max - limits.a_min) * timestep / 4 + 2 * ROUNDING / timestep + SLACK
    for k, sample in enumerate(samples):
        where = f"at {sample.t:.2f} s"
        if not -ROUNDING <= sample.speed <= limits.v_max + SLACK:
            return f"speed {sample.speed:.4f} m/s {where} is outside [0, v_max]"
        if k == 0:
            continue
        before = samples[k - 1]
        moved = sample.distance - before.distance
        if moved < 0:
            return f"backs up by {-moved:.4f} m {where}"
        pace = moved / timestep
        if pace > limits.v_max + noise * timestep:
            return f"covers {moved:.3f} m in one step {where}: faster than v_max"
        if abs(pace - (before.speed + sample.speed) / 2) > chord:
            return (
                f"its speed ({before.speed:.3f} to {sample.speed:.3f} m/s) does not match the "
                f"{moved:.4f} m it covers {where}"
            )
        change = (sample.speed - before.speed) / timestep
        if not limits.a_min - SLACK <= change <= limits.a_max + SLACK:
            return f"accelerates at {change:.3f} m/s^2 {where}, outside [a_min, a_max]"
        if k >= 2:
            second = (sample.distance - 2 * before.distance + samples[k - 2].distance) / timestep**2
            if not limits.a_min - noise <= second <= limits.a_max + noise:
                return f"its distances accelerate at {second:.3f} m/s^2 {where}, outside the bounds"
    return None
