"""ad-rss's world models for the RSS guard (``rss_guard.py``): the scenes of the ego and one
other road user each, built with ``ad_rss`` 5.

Cars: one road per car, one lane each, from ROAD_START metres in the scene's coordinate,
ROAD_LENGTH long; an intersection scene marks the conflict area on both roads, a same
direction scene puts both cars on one road. Pedestrians: an unstructured scene of the ego
and her in the plane (``ObjectType.Pedestrian``).

This file is standalone like ``rss_guard.py``, which loads it from beside itself; every
exported bundle ships both next to ``run.py``.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Any

ROAD_START = -1000.0  # m: every scene's road runs from here (in the scene's coordinate)
ROAD_LENGTH = 3000.0  # m, the road's length: the test-cases' places lie well inside


class RssWorld:
    """Builds ``ad_rss`` world models. Each car's constellation is made once (its roads
    do not move: one lane from ROAD_START metres, ROAD_LENGTH long, in the coordinate of
    the scene) and only the cars' places and speeds are set at each step: making ad-rss's
    values is what costs."""

    def __init__(
        self,
        ad_rss: Any,
        ego: dict[str, float],
        others: dict[str, float],
        pedestrians: dict[str, float],
        scenes: Iterable[str],
    ) -> None:
        self.ad_rss = ad_rss
        self.world = ad_rss.rss.world
        self.physics = ad_rss.physics
        self.ego_dynamics = self.dynamics(ego)
        self.other_dynamics = self.dynamics(others)
        self.pedestrian_dynamics = self.dynamics(pedestrians)
        self.types = {
            name: getattr(self.world.ConstellationType, name) for name in ("SameDirection", *scenes)
        }

    def dynamics(self, values: dict[str, float]) -> Any:
        p, d = self.physics, self.world.RssDynamics()
        d.alpha_lon.accel_max = p.Acceleration(values["accel_max"])
        d.alpha_lon.brake_max = p.Acceleration(values["brake_max"])
        d.alpha_lon.brake_min = p.Acceleration(values["brake_min"])
        d.alpha_lon.brake_min_correct = p.Acceleration(values["brake_min_correct"])
        d.alpha_lat.accel_max = p.Acceleration(values["lat_accel_max"])
        d.alpha_lat.brake_min = p.Acceleration(values["lat_brake_min"])
        d.lateral_fluctuation_margin = p.Distance(values["lateral_fluctuation_margin"])
        d.response_time = p.Duration(values["response_time"])
        d.max_speed_on_acceleration = p.Speed(values["max_speed_on_acceleration"])
        # the unstructured scenes' settings (CARLA's, for cars and pedestrians alike)
        u = d.unstructured_settings
        u.pedestrian_turning_radius = p.Distance(2.0)
        u.drive_away_max_angle = p.Angle(2.4)
        u.vehicle_yaw_rate_change = p.AngularAcceleration(0.3)
        u.vehicle_min_radius = p.Distance(3.5)
        u.vehicle_trajectory_calculation_step = p.Duration(0.2)
        return d

    def unstructured(
        self,
        number: int,
        ego: tuple[float, float, float, float],
        walker: tuple[float, float, float, float],
        sizes: tuple[float, float, float, float],
    ) -> Any:
        """An unstructured constellation of the ego and pedestrian ``number``: both where
        they are in the plane (``ego``, ``walker``: centre x, y, heading in degrees
        clockwise from north, speed; ``sizes``: the ego's length and width, hers), placed
        relative to the ego (ad-rss's coordinates: east, north, yaw counter-clockwise from
        east)."""
        w = self.world
        x, y, heading, speed = ego
        c = w.Constellation()
        c.constellation_type = w.ConstellationType.Unstructured
        c.ego_vehicle = self.placed(0, w.ObjectType.EgoVehicle, (0.0, 0.0, heading, speed),
                                    sizes[:2])  # fmt: skip
        place = (walker[0] - x, walker[1] - y, walker[2], walker[3])
        c.object = self.placed(number, w.ObjectType.Pedestrian, place, sizes[2:])
        c.ego_vehicle_rss_dynamics = self.ego_dynamics
        c.object_rss_dynamics = self.pedestrian_dynamics
        return c

    def placed(
        self, number: int, kind: Any, pose: tuple[float, float, float, float],
        size: tuple[float, float],
    ) -> Any:  # fmt: skip
        """A road user at ``pose`` (centre x, y, heading in degrees clockwise from north,
        speed) of ``size`` (length, width), for an unstructured constellation."""
        p, w = self.physics, self.world
        x, y, heading, speed = pose
        o = w.Object()
        o.object_id = number
        o.object_type = kind
        v = o.velocity
        v.speed_lon_min = v.speed_lon_max = p.Speed(speed)
        v.speed_lat_min = v.speed_lat_max = p.Speed(0.0)
        s = o.state
        s.yaw = p.Angle(math.radians(90.0 - heading))
        s.yaw_rate, s.steering_angle = p.AngularVelocity(0.0), p.Angle(0.0)
        s.center_point.x, s.center_point.y = p.Distance(x), p.Distance(y)
        s.dimension.length, s.dimension.width = p.Distance(size[0]), p.Distance(size[1])
        s.speed_range.minimum = s.speed_range.maximum = p.Speed(speed)
        return o

    def model(self, time_index: int) -> Any:
        model = self.world.WorldModel()
        model.time_index = time_index
        model.default_ego_vehicle_rss_dynamics = self.ego_dynamics
        return model

    def template(
        self,
        same_direction: bool,
        ego_area: tuple[float, float],
        other_area: tuple[float, float],
        number: int,
        lengths: tuple[float, float],
        lane_width: float,
    ) -> tuple[Any, Any, Any, tuple[float, float]]:
        """A constellation of the ego and car ``number``: one road for both (same
        direction), or each its own with the conflict area marked (intersection)."""
        w = self.world
        c = w.Constellation()
        c.ego_vehicle_road.append(self.road(1, None if same_direction else ego_area, lane_width))
        other_segment = 1
        if not same_direction:
            c.intersecting_road.append(self.road(2, other_area, lane_width))
            other_segment = 2
        c.ego_vehicle = self.vehicle(0, w.ObjectType.EgoVehicle, 1, lengths[0], lane_width)
        c.object = self.vehicle(
            number, w.ObjectType.OtherVehicle, other_segment, lengths[1], lane_width
        )
        c.ego_vehicle_rss_dynamics = self.ego_dynamics
        c.object_rss_dynamics = self.other_dynamics
        # the regions as Python holds them: ad-rss's vectors hand out copies, so each step
        # changes these and puts them back (``place``)
        return c, c.ego_vehicle.occupied_regions[0], c.object.occupied_regions[0], lengths

    def place(
        self,
        template: tuple[Any, Any, Any, tuple[float, float]],
        kind: str,
        ego: tuple[float, float],
        other: tuple[float, float],
    ) -> Any:
        """The template's constellation of type ``kind`` with both cars' (front, speed) in
        the scene's coordinate."""
        c, ego_region, other_region, lengths = template
        c.constellation_type = self.types[kind]
        cars = ((c.ego_vehicle, ego_region, ego, lengths[0]),
                (c.object, other_region, other, lengths[1]))  # fmt: skip
        for vehicle, region, (front, speed), length in cars:
            span = region.lon_range
            span.minimum.mParametricValue = _parametric(front - length)
            span.maximum.mParametricValue = _parametric(front)
            vehicle.occupied_regions[0] = region
            v = vehicle.velocity
            v.speed_lon_min.mSpeed = v.speed_lon_max.mSpeed = speed
            r = vehicle.state.speed_range
            r.minimum.mSpeed = r.maximum.mSpeed = speed
        return c

    def road(self, segment: int, area: tuple[float, float] | None, width: float) -> Any:
        """One road segment of one lane; with ``area`` an intersection segment whose
        intersecting area lies between area[0] and area[1]."""
        p, w = self.physics, self.world
        r = w.RoadSegment()
        r.type = w.RoadSegmentType.Normal
        if area is not None:
            r.type = w.RoadSegmentType.Intersection
            start, end = (min(max(x, ROAD_START), ROAD_START + ROAD_LENGTH) for x in area)
            r.minimum_length_before_intersecting_area = p.Distance(start - ROAD_START)
            r.minimum_length_after_intersecting_area = p.Distance(ROAD_START + ROAD_LENGTH - end)
        lane = w.LaneSegment()
        lane.id = segment
        lane.length.minimum = lane.length.maximum = p.Distance(ROAD_LENGTH)
        lane.width.minimum = lane.width.maximum = p.Distance(width)
        lane.driving_direction = w.LaneDrivingDirection.Positive
        r.lane_segments.append(lane)
        return r

    def vehicle(
        self, number: int, kind: Any, segment: int, length: float, lane_width: float
    ) -> Any:
        """A car of ``length`` (and 1.8 m wide, centred in its lane), not yet placed."""
        p, w = self.physics, self.world
        width = min(1.8, lane_width)
        o = w.Object()
        o.object_id = number
        o.object_type = kind
        region = w.OccupiedRegion()
        region.segment_id = segment
        region.lon_range.minimum = p.ParametricValue(0.0)
        region.lon_range.maximum = p.ParametricValue(0.0)
        half = width / 2.0 / lane_width
        region.lat_range.minimum = p.ParametricValue(0.5 - half)
        region.lat_range.maximum = p.ParametricValue(0.5 + half)
        o.occupied_regions.append(region)
        v = o.velocity
        v.speed_lon_min = v.speed_lon_max = p.Speed(0.0)
        v.speed_lat_min = v.speed_lat_max = p.Speed(0.0)
        s = o.state
        s.yaw, s.yaw_rate, s.steering_angle = p.Angle(0.0), p.AngularVelocity(0.0), p.Angle(0.0)
        s.center_point.x = s.center_point.y = p.Distance(0.0)
        s.dimension.length, s.dimension.width = p.Distance(length), p.Distance(width)
        s.speed_range.minimum = s.speed_range.maximum = p.Speed(0.0)
        return o

    def respond(self, check: Any, model: Any) -> tuple[float, tuple[int, str] | None] | None:
        """(the ceiling, (the car, the scene) that asks for it) or None: refused."""
        core, state = self.ad_rss.rss.core, self.ad_rss.rss.state
        situations, states = core.RssSituationSnapshot(), state.RssStateSnapshot()
        response = state.ProperResponse()
        if not check.calculateProperResponse(model, situations, states, response):
            return None
        ceiling = float(response.acceleration_restrictions.longitudinal_range.maximum.mAcceleration)
        if response.is_safe:
            return ceiling, None
        for individual in states.individual_responses:
            scene = str(individual.constellation_type).rsplit(".", 1)[-1]
            if scene == "Unstructured":  # its longitudinal state is not its verdict
                unsafe = not individual.unstructured_constellation_state.is_safe
            else:
                longitudinal = individual.longitudinal_state
                unsafe = not longitudinal.is_safe and str(longitudinal.response) != "None"
            if unsafe:
                return ceiling, (int(individual.object_id), scene)
        return ceiling, None


def _parametric(place: float) -> float:
    """A place on a scene's road as ad-rss takes it: its share of the road from ROAD_START
    (out of range when the place is: ad-rss then refuses the scene, and says so)."""
    return (place - ROAD_START) / ROAD_LENGTH
