"""Collision checks between two sampled motions, including between the samples."""

from __future__ import annotations

import numpy as np
import shapely

from service.core.motion.collisions import Motion, first_collision
from service.core.motion.poses import PoseSample


def straight(x0: float, y0: float, heading: float, speed: float, dt: float, n: int) -> Motion:
    """A 5 x 1.8 m car driving straight from (x0, y0) at ``heading`` (degrees from north)."""
    rad = np.radians(heading)
    samples = [
        PoseSample(k * dt, x0 + np.sin(rad) * speed * k * dt, y0 + np.cos(rad) * speed * k * dt,
                   heading, speed, speed * k * dt)
        for k in range(n)
    ]  # fmt: skip
    return Motion(samples, 5.0, 1.8)


def test_crossing_cars_collide_where_they_meet() -> None:
    east = straight(-20.0, 0.0, 90.0, 10.0, 0.1, 50)  # passes x = 0 at t = 2 s
    north = straight(0.0, -20.0, 0.0, 10.0, 0.1, 50)  # passes y = 0 at t = 2 s
    hit = first_collision(east, north)
    assert hit is not None
    assert 1.5 < hit.time < 2.0
    assert abs(hit.x) < 3.0 and abs(hit.y) < 3.0


def test_near_miss_is_not_a_collision() -> None:
    # The northbound car arrives just after the eastbound one has passed: it misses the
    # eastbound car's back corner by 5 cm of travel.
    east = straight(-20.0, 0.0, 90.0, 10.0, 0.1, 60)
    # East car's back clears x = 0.9 (north car's right side) at t = (20 + 0.9 + 2.5) / 10.
    clear = (20.0 + 0.9 + 2.5) / 10.0
    # The north car's front reaches y = -0.9 (the east car's near side) 5 mm later.
    north = straight(0.0, -0.9 - 2.5 - 10.0 * clear - 0.05, 0.0, 10.0, 0.1, 60)
    assert first_collision(east, north) is None
    north_early = straight(0.0, -0.9 - 2.5 - 10.0 * clear + 0.3, 0.0, 10.0, 0.1, 60)
    assert first_collision(east, north_early) is not None  # 3 cm earlier, they touch


def test_crossing_between_coarse_samples_is_caught() -> None:
    # One sample a second at 20 m/s: each car jumps 20 m between samples and the two cross
    # entirely between t = 1 and t = 2. The samples alone never overlap.
    east = straight(-30.0, 0.0, 90.0, 20.0, 1.0, 4)  # x = -30, -10, 10, 30
    north = straight(0.0, -30.0, 0.0, 20.0, 1.0, 4)
    rects_a = east.rectangles(east.t)
    rects_b = north.rectangles(north.t)
    assert not shapely.intersects(rects_a, rects_b).any()
    hit = first_collision(east, north)
    assert hit is not None and 1.0 < hit.time < 2.0


def test_cars_in_parallel_lanes_do_not_collide() -> None:
    first = straight(0.0, 0.0, 90.0, 10.0, 0.1, 50)
    beside = straight(0.0, 3.2, 90.0, 10.0, 0.1, 50)
    assert first_collision(first, beside) is None


def test_a_car_that_has_left_cannot_collide() -> None:
    gone = straight(0.0, 0.0, 90.0, 10.0, 0.1, 10)  # its samples end at t = 0.9
    later = Motion(
        [PoseSample(t, 9.0, 0.0, 90.0, 0.0, 0.0) for t in (2.0, 3.0)], 5.0, 1.8
    )  # stands where the first car was
    assert first_collision(gone, later) is None
