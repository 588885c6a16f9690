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

Pedestrians in the ego's path (the section's ``pedestrians``: one whose walk crosses the
ego's route, until she has walked past the ego's connecting lane or the ego has left the
crossing) are ad-rss's own: each step an unstructured constellation of the ego and her
(``ObjectType.Pedestrian``, CARLA's pedestrian dynamics), built from both poses in the
plane, in which ad-rss's pedestrian model lets her turn and speed up within its bounds;
the response (brake, or go on) restricts the ego as a car's does.

When ``ad_rss`` is not installed, or refuses a world model (it checks every input range),
the guard says so (``fallback``) and uses a time-gap rule from then on (see
``time_gap_ceiling``; a pedestrian in the ego's path is a crossing road user with
priority there); never silently.

This file is standalone like ``run.py`` (the standard library and ``ad_rss`` only): every
exported bundle ships it next to ``run.py``, with ``rss_world.py`` (ad-rss's world models,
which this file loads from beside itself when ad-rss is there).
"""

from __future__ import annotations

import importlib.util
import json
import math
import sys
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NamedTuple

GUARD_FILE = "rss_guard.py"
WORLD_FILE = "rss_world.py"  # ad-rss's world models, next to this file (loaded with ad-rss)
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
# CARLA's pedestrians (carla::rss::RssCheck::GetDefaultPedestrianDynamics), for every
# pedestrian: ``{"pedestrians": {...}}`` in the RSS parameters overrides them.
CARLA_PEDESTRIAN_DYNAMICS: dict[str, float] = {
    "accel_max": 2.0,
    "brake_max": -4.0,
    "brake_min": -2.0,
    "brake_min_correct": -2.0,
    "lat_accel_max": 0.001,
    "lat_brake_min": -0.001,
    "lateral_fluctuation_margin": 0.1,
    "response_time": 0.5,
    "max_speed_on_acceleration": 10.0,
}
# Every value the guard takes: a number (not a boolean), within a physical range, both ends
# included (m/s^2, m, s, m/s). Beyond them ad-rss's world model is out of its own ranges or
# the replay's arithmetic overflows (accel_max 1e308 killed the replay).
DYNAMICS_RANGES: dict[str, tuple[float, float, str]] = {
    "accel_max": (0.01, 20.0, "m/s^2"),
    "brake_max": (-20.0, -0.01, "m/s^2"),
    "brake_min": (-20.0, -0.01, "m/s^2"),
    "brake_min_correct": (-20.0, -0.01, "m/s^2"),
    "lat_accel_max": (0.001, 10.0, "m/s^2"),
    "lat_brake_min": (-10.0, -0.001, "m/s^2"),
    "lateral_fluctuation_margin": (0.0, 5.0, "m"),
    "response_time": (0.01, 10.0, "s"),
    "max_speed_on_acceleration": (0.0, 150.0, "m/s"),
}
# An RSS parameter file (--rss-params) is read up to this many bytes; JSON nested deeper
# than ``ego`` / ``others`` / ``pedestrians`` objects of numbers is refused by its shape.
MAX_PARAMS_BYTES = 1_000_000
HOLD_GAP = 2.0  # s: the time-gap rule forbids acceleration below this gap
BRAKE_GAP = 1.0  # s: and brakes at brake_min below this one
PRIORITIES = ("ego", "other", "same", "signal")
INTERSECTION_SCENES = {  # RSS's constellation type by who has priority
    "ego": "IntersectionEgoHasPriority",
    "other": "IntersectionObjectHasPriority",
    "same": "IntersectionSamePriority",
}
# a colour's claim to go; others (r, u) 0. O and o (signal off) rank as G and g: the
# junction's priority (service.core.network.signals.RULE_COLOURS)
SIGNAL_RANK = {"G": 3, "O": 3, "g": 2, "o": 2, "y": 1, "Y": 1, "s": 1}


class GuardError(ValueError):
    """The RSS parameters or the plan's ``rss`` section are not usable."""


def dynamics_from(params: dict[str, Any] | None) -> tuple[dict[str, float], dict[str, float]]:
    """The ego's and the other cars' dynamics: CARLA's defaults overridden by ``params``
    (keys of CARLA_DYNAMICS for both, or ``{"ego": {...}, "others": {...}}`` per side;
    ``{"pedestrians": {...}}`` is ``pedestrian_dynamics_from``'s)."""
    params = dict(params or {})
    pedestrian_dynamics_from(params)
    params.pop("pedestrians", None)
    sides = {"ego": params.pop("ego", {}), "others": params.pop("others", {})}
    for side, changes in sides.items():
        if not isinstance(changes, dict):
            raise GuardError(f"RSS parameters for {side}: expected an object of parameters")
    return _checked("ego", CARLA_DYNAMICS, {**params, **sides["ego"]}), _checked(
        "others", CARLA_DYNAMICS, {**params, **sides["others"]}
    )


def pedestrian_dynamics_from(params: dict[str, Any] | None) -> dict[str, float]:
    """The pedestrians' dynamics: CARLA's overridden by ``params["pedestrians"]`` (keys of
    CARLA_DYNAMICS; the parameters for both sides of cars do not reach them)."""
    return _checked("pedestrians", CARLA_PEDESTRIAN_DYNAMICS, (params or {}).get("pedestrians", {}))


def _checked(side: str, defaults: dict[str, float], changes: dict[str, Any]) -> dict[str, float]:
    """``defaults`` with ``changes``, each key and value checked."""
    if not isinstance(changes, dict):
        raise GuardError(f"RSS parameters for {side}: expected an object of parameters")
    values = dict(defaults)
    for key, value in changes.items():
        if key not in CARLA_DYNAMICS:
            raise GuardError(
                f"unknown RSS parameter {key!r}; valid: {', '.join(CARLA_DYNAMICS)}, "
                "and 'ego' / 'others' / 'pedestrians' objects of them"
            )
        low, high, unit = DYNAMICS_RANGES[key]
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise GuardError(
                f"RSS parameter {key!r} ({side}) must be a number from {low:g} to {high:g} "
                f"{unit}, got {_shown(value)}"
            )
        if not (math.isfinite(value) and low <= value <= high):
            raise GuardError(
                f"RSS parameter {key!r} ({side}) is {value:g}; valid: {low:g} to {high:g} {unit}"
            )
        values[key] = float(value)
    if not (values["brake_max"] <= values["brake_min"] <= values["brake_min_correct"] < 0):
        raise GuardError(
            f"RSS {side}: need brake_max <= brake_min <= brake_min_correct < 0, got "
            f"{values['brake_max']:g}, {values['brake_min']:g}, "
            f"{values['brake_min_correct']:g}"
        )
    return values


def _shown(value: Any) -> str:
    """A value as an error shows it: short (an object of a million keys is not printed)."""
    text = json.dumps(value) if isinstance(value, bool) or value is None else repr(value)
    return text if len(text) <= 40 else f"{type(value).__name__} {text[:30]}..."


def load_params(path: Path) -> dict[str, Any]:
    """RSS dynamics from a JSON file (``--rss-params``), checked: at most MAX_PARAMS_BYTES
    (a link to /dev/zero is refused, not read whole), nested no deeper than json.loads
    can (RecursionError is refused too)."""
    try:
        with Path(path).open("rb") as stream:
            data = stream.read(MAX_PARAMS_BYTES + 1)
    except OSError as exc:
        raise GuardError(f"cannot read RSS parameters {path}: {exc.strerror or exc}") from None
    if len(data) > MAX_PARAMS_BYTES:
        raise GuardError(f"RSS parameters {path}: larger than {MAX_PARAMS_BYTES:,} bytes")
    try:
        params = json.loads(data)
    except RecursionError:
        raise GuardError(f"RSS parameters {path}: nested too deeply") from None
    except ValueError as exc:  # not UTF-8, not JSON
        raise GuardError(f"RSS parameters {path} are not JSON: {exc}") from None
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


class WalkerState(NamedTuple):
    """A pedestrian at one step: her front's metres along her walk from the curb (negative
    before it), her speed, and the centre of her rectangle with her walking direction."""

    front: float
    speed: float
    x: float
    y: float
    heading: float  # degrees clockwise from north


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
        self.walkers: dict[str, dict[str, Any]] = dict(self.section.get("pedestrians", {}))
        self.ids = {car: k + 1 for k, car in enumerate([*sorted(self.cars), *sorted(self.walkers)])}
        self.pedestrian_dynamics = pedestrian_dynamics_from(self.params)
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
        self._world = _sibling(WORLD_FILE).RssWorld(
            ad_rss, self.ego_dynamics, self.other_dynamics, self.pedestrian_dynamics,
            INTERSECTION_SCENES.values(),
        )  # fmt: skip
        self._check = ad_rss.rss.core.RssCheck()

    def step(
        self,
        t: float,
        ego: CarState,
        others: dict[str, CarState],
        signals: str | None,
        pedestrians: dict[str, WalkerState] | None = None,
        ego_pose: tuple[float, float, float] | None = None,
    ) -> Restriction | None:
        """The restriction at this step (None: the ego may do as it likes); kept as
        ``current`` for ``limit``. ``pedestrians``: each one on the map; ``ego_pose``: the
        centre of the ego's rectangle and its heading (ad-rss places her and the ego in the
        plane)."""
        ego = CarState(*ego)
        others = {car: CarState(*state) for car, state in others.items()}
        self.steps += 1
        relevant = {car: state for car, state in others.items() if car in self.cars}
        walkers = {
            name: WalkerState(*state)
            for name, state in (pedestrians or {}).items()
            if name in self.walkers and self._in_path(name, ego, WalkerState(*state))
        }
        for car, state in relevant.items():
            spec = self.cars[car]
            if "ego_area" in spec and ego.front > spec["ego_area"][0]:
                self._entered.setdefault((car, "ego"), self.steps)
            if "other_area" in spec and state.front > spec["other_area"][0]:
                self._entered.setdefault((car, "other"), self.steps)
        self.current = None
        if self.fallback is None and walkers and ego_pose is None:
            self.fallback = "the ego's pose was not given: ad-rss places pedestrians in the plane"
        if self.fallback is None:
            try:
                self.current = self._rss_restriction(ego, relevant, signals, walkers, ego_pose)
            except _Refused as exc:
                self.fallback = f"ad-rss could not model the situation at {t:.2f} s: {exc}"
        if self.fallback is not None:
            self.current = self._time_gap_restriction(ego, relevant, signals, walkers)
        return self.current

    def _in_path(self, name: str, ego: CarState, walker: WalkerState) -> bool:
        """Whether a pedestrian is still in the ego's path: she has not walked past the
        ego's connecting lane (her rear beyond its far side), and the ego has not left the
        crossing (its rear beyond it)."""
        spec = self.walkers[name]
        ego_rear = ego.front - float(self.section["ego_length"])
        return bool(
            walker.front - float(spec["length"]) <= float(spec["other_area"][1])
            and ego_rear <= float(spec["ego_area"][1])
        )

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
        self,
        ego: CarState,
        others: dict[str, CarState],
        signals: str | None,
        walkers: dict[str, WalkerState],
        ego_pose: tuple[float, float, float] | None,
    ) -> Restriction | None:
        world = self._world
        model = world.model(self.steps)
        ego_size = (float(self.section["ego_length"]), float(self.section.get("ego_width", 1.8)))
        for name, walker in sorted(walkers.items()):
            assert ego_pose is not None
            spec = self.walkers[name]
            model.constellations.append(
                world.unstructured(
                    self.ids[name],
                    (*ego_pose, ego.speed),
                    (walker.x, walker.y, walker.heading, walker.speed),
                    (*ego_size, float(spec["length"]), float(spec["width"])),
                )
            )
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
        self,
        ego: CarState,
        others: dict[str, CarState],
        signals: str | None,
        walkers: dict[str, WalkerState] | None = None,
    ) -> Restriction | None:
        found: Restriction | None = None
        for name, walker in sorted((walkers or {}).items()):  # she has priority there
            spec = self.walkers[name]
            (ego_in, ego_out), (her_in, her_out) = spec["ego_area"], spec["other_area"]
            path = ("intersection", (ego.front, float(ego_in), float(ego_out)),
                    (walker.front, float(her_in), float(her_out)))  # fmt: skip
            her = CarState(walker.front, walker.speed)
            length = float(spec["length"])
            ceiling = time_gap_ceiling(path, ego, her, length, "other", self.ego_dynamics)
            if ceiling is not None and (found is None or ceiling < found.ceiling):
                found = Restriction(ceiling, name, "time gap (pedestrian)")
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


def _sibling(file_name: str) -> Any:
    """The module in ``file_name`` next to this file (scengen's own, or a bundle's copy:
    this file is loaded by path in a bundle, so it has no package to import from)."""
    name = file_name.removesuffix(".py")
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(name, Path(__file__).with_name(file_name))
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # dataclasses look their module up by name
    spec.loader.exec_module(module)
    return module
