"""The RSS guard: Responsibility-Sensitive Safety (``ad-rss`` 5) around an ego controller.

Every step the guard builds RSS's world model of the ego and each other car that matters
(a car whose route crosses or merges into the ego's, a car on the ego's lane), asks
``ad_rss`` for the proper response, and gives the ceiling on the ego's acceleration that
the response allows: the wrapped controller keeps its command when it is below the
ceiling, and gets the ceiling (braking) when it is not. Each step where the guard cut the
command is recorded with the car and the scene.

What the guard knows of the junction comes from the run plan's ``rss`` section, written by
scengen from its intersection model: for each relevant car, its relation to the ego
(``crossing``, ``merge``, ``same_fork``, ``same_route``), the conflict area along both
routes (metres from each car's stop line), and who has priority (``ego``, ``other``,
``same``, or ``signal``: the signal colours decide at every step; where the same priority
remains, the car that entered the conflict area first has it). Positions are metres of
the front bumper from the car's own stop line (negative before it).

When ``ad_rss`` is not installed, or refuses a world model (it checks every input range),
the guard says so (``fallback``) and uses a time-gap rule from then on (see
``time_gap_ceiling``); never silently.

This file is standalone like ``run.py`` (the standard library and ``ad_rss`` only): every
exported bundle ships it next to ``run.py``.
"""

from __future__ import annotations

import json
import math
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NamedTuple

GUARD_FILE = "rss_guard.py"
RSS_SUFFIX = "+rss"

# CARLA's RssSensor defaults (carla::rss::RssCheck::GetDefaultVehicleDynamics), used by
# CARLA for the ego and for every other vehicle alike.
CARLA_DYNAMICS: dict[str, float] = {
    "accel_max": 3.5,  # alphaLon.accelMax, m/s^2
    "brake_max": -8.0,  # alphaLon.brakeMax
    "brake_min": -4.0,  # alphaLon.brakeMin
    "brake_min_correct": -3.0,  # alphaLon.brakeMinCorrect
    "lat_accel_max": 0.2,  # alphaLat.accelMax
    "lat_brake_min": -0.8,  # alphaLat.brakeMin
    "lateral_fluctuation_margin": 0.1,  # m
    "response_time": 1.0,  # s
    "max_speed_on_acceleration": 100.0,  # m/s
}
HOLD_GAP = 2.0  # s: the time-gap rule forbids acceleration below this gap
BRAKE_GAP = 1.0  # s: and brakes at brake_min below this one
ROAD_START = -1000.0  # m: every scene's road runs from here (in the scene's coordinate)
ROAD_LENGTH = 3000.0  # m, the road's length: the test-cases' places lie well inside
PRIORITIES = ("ego", "other", "same", "signal")
INTERSECTION_SCENES = {  # RSS's constellation type by who has priority
    "ego": "IntersectionEgoHasPriority",
    "other": "IntersectionObjectHasPriority",
    "same": "IntersectionSamePriority",
}
SIGNAL_RANK = {"G": 3, "g": 2, "y": 1, "s": 1}  # a colour's claim to go; others (r, u, o) 0


class GuardError(ValueError):
    """The RSS parameters or the plan's ``rss`` section are not usable."""


def dynamics_from(params: dict[str, Any] | None) -> tuple[dict[str, float], dict[str, float]]:
    """The ego's and the other cars' dynamics: CARLA's defaults overridden by ``params``
    (keys of CARLA_DYNAMICS for both, or ``{"ego": {...}, "others": {...}}`` per side)."""
    params = dict(params or {})
    sides = {"ego": dict(params.pop("ego", {})), "others": dict(params.pop("others", {}))}
    result = []
    for side in ("ego", "others"):
        values = dict(CARLA_DYNAMICS)
        for key, value in {**params, **sides[side]}.items():
            if key not in CARLA_DYNAMICS:
                raise GuardError(
                    f"unknown RSS parameter {key!r}; valid: {', '.join(CARLA_DYNAMICS)}, "
                    "and 'ego' / 'others' objects of them"
                )
            if not isinstance(value, int | float) or not math.isfinite(value):
                raise GuardError(f"RSS parameter {key!r} must be a number, got {value!r}")
            values[key] = float(value)
        if not (values["brake_max"] <= values["brake_min"] <= values["brake_min_correct"] < 0):
            raise GuardError(
                f"RSS {side}: need brake_max <= brake_min <= brake_min_correct < 0, got "
                f"{values['brake_max']:g}, {values['brake_min']:g}, "
                f"{values['brake_min_correct']:g}"
            )
        if values["accel_max"] <= 0 or values["response_time"] <= 0:
            raise GuardError(f"RSS {side}: accel_max and response_time must be > 0")
        result.append(values)
    return result[0], result[1]


def load_params(path: Path) -> dict[str, Any]:
    """RSS dynamics from a JSON file (``--rss-params``), checked."""
    try:
        params = json.loads(Path(path).read_text())
    except (OSError, ValueError) as exc:
        raise GuardError(f"cannot read RSS parameters {path}: {exc}") from exc
    if not isinstance(params, dict):
        raise GuardError(f"RSS parameters {path}: expected a JSON object")
    dynamics_from(params)
    return params


@dataclass(frozen=True)
class Restriction:
    """A ceiling on the ego's acceleration at one step, and what asked for it."""

    ceiling: float  # m/s^2
    car: str
    scene: str  # RSS's constellation type, or the time-gap rule's case

    @property
    def kind(self) -> str:
        return "brake" if self.ceiling < 0 else "no-accel"


class CarState(NamedTuple):
    """A car at one step: its front's metres from its own stop line, its speed (a plain
    ``(front, speed)`` tuple does as well: run.py passes those)."""

    front: float
    speed: float


@dataclass
class RssGuard:
    """The guard of one run: the plan's ``rss`` section, the dynamics, the record."""

    section: dict[str, Any]
    params: dict[str, Any] | None = None
    use_ad_rss: bool = True  # False: the time-gap rule only (as when ad_rss is absent)
    fallback: str | None = None
    steps: int = 0
    interventions: int = 0
    braking: int = 0
    by_car: dict[str, int] = field(default_factory=dict)
    first: dict[str, Any] | None = None
    current: Restriction | None = None
    spans: list[dict[str, Any]] = field(default_factory=list)  # consecutive interventions
    _last_step: int = -2
    _check: Any = None
    _world: Any = None
    _templates: dict[tuple[str, bool], Any] = field(default_factory=dict)
    _entered: dict[tuple[str, str], int] = field(default_factory=dict)  # (car, "ego" or
    # "other"): the step that one's front first entered their conflict area

    def __post_init__(self) -> None:
        self.ego_dynamics, self.other_dynamics = dynamics_from(self.params)
        self.cars: dict[str, dict[str, Any]] = dict(self.section.get("cars", {}))
        for car, spec in self.cars.items():
            if spec.get("priority", "same") not in PRIORITIES:
                raise GuardError(f"car {car}: priority must be one of {', '.join(PRIORITIES)}")
        self.ids = {car: k + 1 for k, car in enumerate(sorted(self.cars))}
        if not self.use_ad_rss:
            self.fallback = "the time-gap rule was asked for instead of ad-rss"
            return
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # boost: "to-Python converter already registered"
                import ad_rss
        except ImportError as exc:
            self.fallback = f"ad-rss is not installed ({exc}): pip install ad-rss"
            return
        ad_rss.rss.core.setLogLevel("off")
        self._world = _RssWorld(ad_rss, self.ego_dynamics, self.other_dynamics)
        self._check = ad_rss.rss.core.RssCheck()

    def step(
        self, t: float, ego: CarState, others: dict[str, CarState], signals: str | None
    ) -> Restriction | None:
        """The restriction at this step (None: the ego may do as it likes); kept as
        ``current`` for ``limit``."""
        ego = CarState(*ego)
        others = {car: CarState(*state) for car, state in others.items()}
        self.steps += 1
        relevant = {car: state for car, state in others.items() if car in self.cars}
        for car, state in relevant.items():
            spec = self.cars[car]
            if "ego_area" in spec and ego.front > spec["ego_area"][0]:
                self._entered.setdefault((car, "ego"), self.steps)
            if "other_area" in spec and state.front > spec["other_area"][0]:
                self._entered.setdefault((car, "other"), self.steps)
        self.current = None
        if self.fallback is None:
            try:
                self.current = self._rss_restriction(ego, relevant, signals)
            except _Refused as exc:
                self.fallback = f"ad-rss could not model the situation at {t:.2f} s: {exc}"
        if self.fallback is not None:
            self.current = self._time_gap_restriction(ego, relevant, signals)
        return self.current

    def limit(self, t: float, wanted: float) -> float:
        """The acceleration the ego gets for ``wanted`` (``math.inf``: whatever the
        wrapped driver does), recording the step when the guard cut it."""
        restriction = self.current
        if restriction is None or wanted <= restriction.ceiling:
            return wanted
        self.interventions += 1
        self.braking += restriction.kind == "brake"
        self.by_car[restriction.car] = self.by_car.get(restriction.car, 0) + 1
        self._record_span(t, restriction)
        if self.first is None:
            why = (
                f"{restriction.scene} with {restriction.car}: "
                + (f"brake at {restriction.ceiling:.1f} m/s^2" if restriction.kind == "brake"
                   else "no acceleration")
            )  # fmt: skip
            self.first = {"t": round(t, 9), "car": restriction.car, "why": why}
        return restriction.ceiling

    def _record_span(self, t: float, restriction: Restriction) -> None:
        """Every intervention, as spans of consecutive steps with one car, scene and kind."""
        what = {"car": restriction.car, "scene": restriction.scene, "kind": restriction.kind}
        last = self.spans[-1] if self.spans else None
        if (
            last is not None
            and self._last_step == self.steps - 1
            and all(last[key] == value for key, value in what.items())
        ):
            last["to"] = round(t, 9)
        else:
            self.spans.append({"from": round(t, 9), "to": round(t, 9), **what})
        self._last_step = self.steps

    def summary(self) -> dict[str, Any]:
        """What the verdict's ``guard`` field says."""
        return {
            "kind": "rss",
            "steps": self.steps,
            "interventions": self.interventions,
            "braking": self.braking,
            "by_car": dict(sorted(self.by_car.items())),
            "fallback": self.fallback,
            "first": self.first,
            "spans": [dict(span) for span in self.spans],
        }

    def priority(self, car: str, signals: str | None) -> str:
        """``ego``, ``other`` or ``same`` for ``car`` now: at a signal, the better colour
        (G over g over yellow over red) goes first, equal colours fall back on the
        junction's own rule (``tie``). Where that leaves the same priority, the car that
        entered their conflict area first goes first (CVC 21800(a), 21802(b): yield to a
        car already in the junction); before either has, the same priority."""
        spec = self.cars[car]
        found = str(spec["priority"])
        if found == "signal":
            own = _colour(signals, self.section.get("ego_link", -1))
            theirs = _colour(signals, spec.get("link", -1))
            found = str(spec.get("tie", "same"))
            if own != theirs:
                found = "ego" if own > theirs else "other"
        if found != "same":
            return found
        ego, other = self._entered.get((car, "ego")), self._entered.get((car, "other"))
        if ego is not None and (other is None or ego < other):
            return "ego"
        if other is not None and (ego is None or other < ego):
            return "other"
        return "same"

    def _rss_restriction(
        self, ego: CarState, others: dict[str, CarState], signals: str | None
    ) -> Restriction | None:
        world = self._world
        model = world.model(self.steps)
        for car, state in sorted(others.items()):
            scene = self._scene(car, ego, state)
            if scene is None:
                continue
            kind, ego_road, other_road = scene
            if kind == "intersection":
                kind = INTERSECTION_SCENES[self.priority(car, signals)]
            template = self._templates.get((car, kind == "SameDirection"))
            if template is None:
                template = world.template(
                    kind == "SameDirection", (ego_road[1], ego_road[2]),
                    (other_road[1], other_road[2]), self.ids[car],
                    (float(self.section["ego_length"]), float(self.cars[car]["length"])),
                    float(self.section["lane_width"]),
                )  # fmt: skip
                self._templates[(car, kind == "SameDirection")] = template
            places = (ego_road[0], ego.speed), (other_road[0], state.speed)
            model.constellations.append(world.place(template, kind, *places))
        if not model.constellations:
            return None
        response = world.respond(self._check, model)
        if response is None:
            raise _Refused("calculateProperResponse returned false")
        ceiling, dangerous = response
        if ceiling >= self.ego_dynamics["accel_max"] - 1e-9 or dangerous is None:
            return None
        names = {number: car for car, number in self.ids.items()}
        return Restriction(ceiling, names.get(dangerous[0], "?"), dangerous[1])

    def _scene(
        self, car: str, ego: CarState, other: CarState
    ) -> tuple[str, tuple[float, float, float], tuple[float, float, float]] | None:
        """RSS's scene of ``car`` and the ego now: ("intersection" or "SameDirection", each
        car's road as (front, conflict start, conflict end) in one coordinate per road), or
        None when the car no longer matters (it or the ego has cleared their conflict area
        and they share no lane)."""
        spec = self.cars[car]
        ego_rear = ego.front - float(self.section["ego_length"])
        other_rear = other.front - float(spec["length"])
        relation = spec["relation"]
        if relation in ("crossing", "merge"):
            (ego_in, ego_out), (other_in, other_out) = spec["ego_area"], spec["other_area"]
            if ego_rear <= ego_out and other_rear <= other_out:
                return "intersection", (ego.front, ego_in, ego_out), (other.front, other_in,
                                                                       other_out)  # fmt: skip
            if relation == "crossing":
                return None
            # past the merge both are on the exit lane: metres from the junction's exit
            ego_front = ego.front - float(spec["ego_exit"])
            other_front = other.front - float(spec["other_exit"])
            return "SameDirection", (ego_front, 0.0, 0.0), (other_front, 0.0, 0.0)
        if relation == "same_fork" and max(ego_rear, other_rear) > 0.0:
            return None  # one has left the shared fork: their routes part in the junction
        return "SameDirection", (ego.front, 0.0, 0.0), (other.front, 0.0, 0.0)

    def _time_gap_restriction(
        self, ego: CarState, others: dict[str, CarState], signals: str | None
    ) -> Restriction | None:
        found: Restriction | None = None
        for car, state in sorted(others.items()):
            scene = self._scene(car, ego, state)
            if scene is None:
                continue
            ceiling = time_gap_ceiling(
                scene, ego, state, float(self.cars[car]["length"]), self.priority(car, signals),
                self.ego_dynamics,
            )  # fmt: skip
            if ceiling is not None and (found is None or ceiling < found.ceiling):
                found = Restriction(ceiling, car, f"time gap ({scene[0]})")
        return found


def time_gap_ceiling(
    scene: tuple[str, tuple[float, float, float], tuple[float, float, float]],
    ego: CarState,
    other: CarState,
    other_length: float,
    priority: str,
    dynamics: dict[str, float],
) -> float | None:
    """The fallback rule. Same lane, the other ahead: a time gap (bumper to bumper over
    the ego's speed) below BRAKE_GAP brakes at brake_min, below HOLD_GAP forbids
    acceleration. Crossing without priority (the other has it, or neither): while the ego
    is before its conflict area and the other is in its own area at some time from HOLD_GAP
    before the ego would arrive to HOLD_GAP after (at their present speeds), the ego brakes
    when it is within its stopping distance at brake_min plus one response time of the
    area, and may not accelerate before that."""
    kind, (ego_front, ego_in, _), (other_front, other_in, other_out) = scene
    brake = dynamics["brake_min"]
    speed = max(ego.speed, 0.1)
    if kind == "SameDirection":
        gap = other_front - other_length - ego_front
        if gap < 0.0 or other_front <= ego_front:
            return None  # the other is behind (or beside): not the ego's to keep the gap
        return brake if gap / speed < BRAKE_GAP else 0.0 if gap / speed < HOLD_GAP else None
    if priority == "ego" or ego_front >= ego_in:
        return None
    ego_time = (ego_in - ego_front) / speed
    other_speed = max(other.speed, 0.1)
    arrives = max(0.0, other_in - other_front) / other_speed
    leaves = (other_out + other_length - other_front) / other_speed
    if arrives > ego_time + HOLD_GAP or leaves < ego_time - HOLD_GAP:
        return None
    stopping = ego.speed**2 / (2.0 * -brake) + ego.speed * dynamics["response_time"]
    return brake if ego_in - ego_front <= stopping else 0.0


def _colour(signals: str | None, link: int) -> int:
    if signals is None or not 0 <= link < len(signals):
        return 0
    return SIGNAL_RANK.get(signals[link], 0)


class _Refused(Exception):
    """ad-rss refused the world model."""


class _RssWorld:
    """Builds ``ad_rss`` world models. Each car's constellation is made once (its roads
    do not move: one lane from ROAD_START metres, ROAD_LENGTH long, in the coordinate of
    the scene) and only the cars' places and speeds are set at each step: making ad-rss's
    values is what costs."""

    def __init__(self, ad_rss: Any, ego: dict[str, float], others: dict[str, float]) -> None:
        self.ad_rss = ad_rss
        self.world = ad_rss.rss.world
        self.physics = ad_rss.physics
        self.ego_dynamics = self.dynamics(ego)
        self.other_dynamics = self.dynamics(others)
        self.types = {
            name: getattr(self.world.ConstellationType, name)
            for name in ("SameDirection", *INTERSECTION_SCENES.values())
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
        # the unstructured scenes are not used; ad-rss still checks their ranges (CARLA's)
        u = d.unstructured_settings
        u.pedestrian_turning_radius = p.Distance(2.0)
        u.drive_away_max_angle = p.Angle(2.4)
        u.vehicle_yaw_rate_change = p.AngularAcceleration(0.3)
        u.vehicle_min_radius = p.Distance(3.5)
        u.vehicle_trajectory_calculation_step = p.Duration(0.2)
        return d

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
            longitudinal = individual.longitudinal_state
            if not longitudinal.is_safe and str(longitudinal.response) != "None":
                scene = str(individual.constellation_type).rsplit(".", 1)[-1]
                return ceiling, (int(individual.object_id), scene)
        return ceiling, None


def _parametric(place: float) -> float:
    """A place on a scene's road as ad-rss takes it: its share of the road from ROAD_START
    (out of range when the place is: ad-rss then refuses the scene, and says so)."""
    return (place - ROAD_START) / ROAD_LENGTH
