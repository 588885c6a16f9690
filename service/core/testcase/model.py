"""The test-case document's models and their validation (design section 8): a versioned
JSON contract, each field within physical bounds.

Conventions: coordinates are SUMO network coordinates (m); ``x``, ``y`` of a sample are the
centre of the car's rectangle; ``heading`` is in degrees clockwise from north (+y), as in
SUMO; ``distance`` is metres travelled along the route since t = 0; the ego's start is the
front bumper's distance before the stop line of its fork.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    SerializerFunctionWrapHandler,
    field_validator,
    model_serializer,
    model_validator,
)

from service.core.errors import InvalidTestCase
from service.core.motion.events import EventKind
from service.core.network import ControlType, SignalProgram
from service.core.network.signals import (
    MAX_OFFSET,
    MAX_PHASE_DURATION,
    MAX_PHASES,
    MIN_CYCLE,
    MIN_PHASE_DURATION,
    VALID_COLOURS,
    make_program,
    program_problems,
)

SCHEMA = "scengen/testcase/1"
# A document with pedestrians is written in version 2, the first that can hold them; one
# without stays in version 1, byte for byte as before (every stored hash stays valid).
SCHEMA_WITH_PEDESTRIANS = "scengen/testcase/2"
RESERVED_IDS = frozenset({"ego", "illegal"})

# Bounds on the work one test-case can ask for (every sample is simulated, stored, checked).
MIN_TIMESTEP = 0.001  # s, SUMO's smallest step length
MAX_TIMESTEP = 1.0  # s
MAX_DURATION = 600.0  # s
MAX_SAMPLES = 60_000  # per car: 600 s at 0.01 s
MAX_NAME_LENGTH = 200
# Physical bounds on what a document may say (the parameters' own are in Params).
MAX_SPEED = 100.0  # m/s: any speed a sample or a start may have (v_max is at most 70)
MAX_START_DISTANCE = 10_000.0  # m before the stop line
MAX_TRAVEL = MAX_SPEED * MAX_DURATION + MAX_START_DISTANCE  # m: a sample's distance
MAX_COORDINATE = 1e7  # m: network coordinates (netconvert moves a map's origin near it)

Seconds = Annotated[float, Field(ge=0, le=MAX_DURATION)]


class _Model(BaseModel):
    # no NaN or infinity anywhere: such a number is bad input, never a solver's crash later
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False, strict=True)


def check_name(value: str) -> str:
    """A test-case's name: printable (it goes into JUnit XML, READMEs, file listings)."""
    bad = next((c for c in value if ord(c) < 32 or 127 <= ord(c) < 160), None)
    if bad is not None:
        raise ValueError(
            f"must not contain control characters (U+{ord(bad):04X} at position {value.index(bad)})"
        )
    return value


class WalkingParams(_Model):
    """Bounds of the pedestrians' walking (Step 3's speed profiles, the plausibility of a
    document): people on foot walk at most a brisk 2.5 m/s, speed up and slow down gently,
    and may stand (at or below `Params.v_stop`), at the curb or anywhere else."""

    v_max: float = Field(2.0, gt=0.2, le=2.5, description="fastest walking speed (m/s)")
    a_max: float = Field(1.0, ge=0.1, le=3.0, description="strongest speeding up (m/s^2)")
    a_min: float = Field(
        -1.5, ge=-5.0, le=-0.1, description="strongest slowing down (m/s^2, negative)"
    )
    arrival_distance: float = Field(
        1.0,
        ge=0.1,
        le=10,
        description="a pedestrian is at the curb when its front is this close to the crossing (m)",
    )


class Params(_Model):
    """Parameters of the rules and of the speed profiles, each within a physically
    meaningful range (PARAM_BOUNDS): a number outside cannot describe a car at a junction,
    and the solvers' arithmetic is only sound inside."""

    m: float = Field(1.0, ge=0.01, le=10, description="minimum perceptible time difference (s)")
    a_min: float = Field(
        -4.0, ge=-15, le=-0.1, description="strongest deceleration (m/s^2, negative)"
    )
    a_max: float = Field(3.0, ge=0.1, le=15, description="strongest acceleration (m/s^2)")
    v_stop: float = Field(
        0.1, ge=0, le=5, description="at or below this speed a car is stopped (m/s)"
    )
    v_run: float = Field(
        2.0, gt=0, le=30, description="at or above this speed a car runs a sign (m/s)"
    )
    v_max: float = Field(15.0, ge=1, le=70, description="speed limit of every car (m/s)")
    arrival_distance: float = Field(
        10.0,
        ge=0.1,
        le=100,
        description="a car has arrived at its fork when its front is this close (m)",
    )
    gap: float = Field(
        2.0, ge=0, le=50, description="distance a car keeps behind the car ahead on its lane (m)"
    )
    headway: float = Field(
        1.0,
        ge=0,
        le=10,
        description="time headway a car keeps on top of the gap: gap + headway x speed (s)",
    )
    walking: WalkingParams | None = Field(
        None, description="the pedestrians' bounds (absent: WalkingParams' defaults)"
    )

    @property
    def walk(self) -> WalkingParams:
        """The pedestrians' bounds in force."""
        return self.walking or WalkingParams()

    @model_validator(mode="after")
    def _speeds_ordered(self) -> Params:
        if not self.v_stop < self.v_run < self.v_max:
            raise ValueError(
                f"speeds must satisfy v_stop < v_run < v_max, got {self.v_stop:g}, "
                f"{self.v_run:g}, {self.v_max:g}"
            )
        return self


class NetworkRef(_Model):
    """The network: a bundled name, a path, or an uploaded id; with its content hash, and
    where a file written by the command line last saw the network's file."""

    ref: str = Field(min_length=1)
    sha256: str = Field(pattern=r"^[0-9a-f]{64}$")
    path: str | None = Field(
        None,
        min_length=1,
        max_length=4096,
        description="the network's file relative to the test-case's folder (POSIX), written "
        "when the command line writes the test-case to a file; a hint, checked by sha256",
    )

    @field_validator("path")
    @classmethod
    def _printable_path(cls, value: str | None) -> str | None:
        return None if value is None else check_name(value)


class RouteRef(_Model):
    fork: str = Field(min_length=1, description="incoming lane id")
    exit: str = Field(min_length=1, description="outgoing lane id")

    @property
    def id(self) -> str:
        return f"{self.fork}:{self.exit}"


class Start(_Model):
    distance: float = Field(
        ge=0, le=MAX_START_DISTANCE, description="front bumper before the stop line (m)"
    )
    speed: float = Field(ge=0, le=MAX_SPEED, description="speed at t = 0 (m/s)")


CarLength = Annotated[float, Field(ge=1, le=30, description="m")]
CarWidth = Annotated[float, Field(ge=0.5, le=5, description="m")]


class Ego(_Model):
    route: RouteRef
    start: Start
    length: CarLength = 5.0
    width: CarWidth = 1.8


class Sample(_Model):
    t: Seconds
    x: float = Field(ge=-MAX_COORDINATE, le=MAX_COORDINATE)
    y: float = Field(ge=-MAX_COORDINATE, le=MAX_COORDINATE)
    heading: float = Field(ge=0, lt=360)
    speed: float = Field(ge=0, le=MAX_SPEED)
    distance: float = Field(ge=0, le=MAX_TRAVEL)


class EventRecord(_Model):
    kind: EventKind = Field(strict=False)  # a name in JSON is an enum member
    lane: str
    t: Seconds
    distance: float = Field(ge=0, le=MAX_TRAVEL)


class NonEgo(_Model):
    id: str = Field(pattern=r"^[A-Za-z][A-Za-z0-9_]*$")
    route: RouteRef
    length: CarLength = 5.0
    width: CarWidth = 1.8
    trajectory: list[Sample] = Field(min_length=2)
    events: list[EventRecord] = []
    added_in: int = Field(ge=1, description="extension level that added this car")

    @field_validator("id")
    @classmethod
    def _not_reserved(cls, value: str) -> str:
        if value in RESERVED_IDS:
            raise ValueError(f"{value!r} is reserved for the ego certificates")
        return value

    @field_validator("trajectory")
    @classmethod
    def _monotone(cls, samples: list[Sample]) -> list[Sample]:
        for k in range(1, len(samples)):
            if samples[k].t <= samples[k - 1].t:
                raise ValueError(f"sample {k}: times must increase")
            if samples[k].distance < samples[k - 1].distance:
                raise ValueError(f"sample {k}: distance must not decrease (cars never back up)")
        return samples


PedestrianLength = Annotated[float, Field(ge=0.1, le=2, description="m, front to back")]
PedestrianWidth = Annotated[float, Field(ge=0.2, le=2, description="m, shoulder to shoulder")]
PEDESTRIAN_LENGTH = 0.215  # SUMO's default pedestrian (vType DEFAULT_PEDTYPE)
PEDESTRIAN_WIDTH = 0.478


class Pedestrian(_Model):
    """A person on foot who walks over one crossing of the junction (a walk of the
    intersection, ``Intersection.walks``). Its trajectory is of the same kind as a car's:
    ``x``, ``y`` the centre of its rectangle, ``heading`` its walking direction, and
    ``distance`` the metres walked along its path since t = 0."""

    id: str = Field(pattern=r"^[A-Za-z][A-Za-z0-9_]*$")
    walk: str = Field(
        min_length=1,
        max_length=200,
        description="the crossing walked and its direction: the crossing's id without SUMO's "
        "leading colon, then + along its centreline or - against it (C_c0+)",
    )
    length: PedestrianLength = PEDESTRIAN_LENGTH
    width: PedestrianWidth = PEDESTRIAN_WIDTH
    trajectory: list[Sample] = Field(min_length=2)
    events: list[EventRecord] = []
    added_in: int = Field(ge=1, description="extension level that added this pedestrian")

    _not_reserved = field_validator("id")(NonEgo._not_reserved.__func__)  # type: ignore[attr-defined]
    _monotone = field_validator("trajectory")(NonEgo._monotone.__func__)  # type: ignore[attr-defined]


class SignalPhaseDoc(_Model):
    duration: float = Field(
        ge=MIN_PHASE_DURATION,
        le=MAX_PHASE_DURATION,
        description=f"seconds, from {MIN_PHASE_DURATION:g} (SUMO's step) to {MAX_PHASE_DURATION:g}",
    )
    state: str = Field(
        min_length=1,
        max_length=1000,
        description="one SUMO colour per link of the traffic light, by link index: G "
        "protected green, g permissive green, y yellow, Y yellow with priority, r red, u "
        "red-yellow, s right on red after a stop, O off with priority (read as G), o off "
        "and blinking, yielding (read as g)",
        # in the schema only: the model's check names the unknown colours and the valid ones
        json_schema_extra={"pattern": f"^[{VALID_COLOURS}]+$"},
    )


class Signals(_Model):
    """A fixed-time traffic-light program, as SUMO's tlLogic (service.core.network.signals)."""

    tls: str = Field(min_length=1, description="the traffic light's id in the network")
    program: str = Field("0", min_length=1, description="the program's id (programID)")
    offset: float = Field(
        0.0, ge=-MAX_OFFSET, le=MAX_OFFSET, description="s: phase 0 starts at offset"
    )
    phases: list[SignalPhaseDoc] = Field(
        min_length=1,
        max_length=MAX_PHASES,
        description=f"the cycle in order, {MAX_PHASES} phases at most, lasting at least "
        f"{MIN_CYCLE:g} s in all; every state has one colour per link of the traffic light, "
        "so all states are equally long",
    )
    note: str | None = Field(
        None,
        min_length=1,
        max_length=1000,
        description="how the program was read from its source when not as given: an "
        "actuated or delay_based program read as fixed-time, each phase lasting its "
        "duration; absent: as given (a static program)",
    )

    @model_validator(mode="after")
    def _consistent(self) -> Signals:
        problems = program_problems((p.duration, p.state) for p in self.phases)
        if problems:
            raise ValueError("; ".join(problems))
        return self

    def to_program(self) -> SignalProgram:
        return make_program(
            self.tls,
            self.program,
            self.offset,
            [(p.duration, p.state) for p in self.phases],
            self.note,
        )


Control = Literal[
    "allway_stop",
    "priority",
    "priority_stop",
    "right_before_left",
    "traffic_light",
    "traffic_light_right_on_red",
]


class Certificates(_Model):
    complexity: list[Sample] = Field(min_length=2)
    solvability: list[Sample] = Field(min_length=2)


class TestCase(_Model):
    """A test-case: intersection, rules, ego, non-egos, timing and parameters."""

    __test__ = False  # not a pytest class

    schema_: Literal["scengen/testcase/1", "scengen/testcase/2"] = Field(
        "scengen/testcase/1",
        alias="schema",
        description="scengen/testcase/2 when the test-case has pedestrians, else /1",
    )
    name: str = Field("", max_length=MAX_NAME_LENGTH)
    network: NetworkRef
    junction: str = Field(min_length=1)
    control: Control
    major_road: list[Annotated[str, Field(min_length=1)]] | None = Field(
        None,
        min_length=2,
        max_length=2,
        description="the two roads (edge ids) into a priority_stop or priority junction that "
        "keep the right of way, as the user named them; absent: the network's, or scengen's "
        "choice",
    )
    crossings_guessed: bool = Field(
        False,
        description="the network is rebuilt with guessed sidewalks and crossings (netconvert "
        "--sidewalks.guess --crossings.guess; car lanes' indices move up by one) before use; "
        "absent: false, the network as it is",
    )
    rules: str
    signals: Signals | None = Field(
        None,
        description="the traffic-light program of a signalized junction (fixed-time); "
        "extending never changes it",
    )
    timestep: float = Field(0.1, ge=MIN_TIMESTEP, le=MAX_TIMESTEP)
    duration: float = Field(20.0, gt=0, le=MAX_DURATION)
    params: Params = Params()
    ego: Ego
    nonegos: list[NonEgo] = []
    pedestrians: list[Pedestrian] = Field(
        [], description="people on foot (schema scengen/testcase/2); absent: none"
    )
    certificates: Certificates | None = None
    provenance: dict[str, Any] | None = None

    model_config = ConfigDict(
        extra="forbid", frozen=True, populate_by_name=True, allow_inf_nan=False, strict=True
    )

    @field_validator("name")
    @classmethod
    def _printable_name(cls, value: str) -> str:
        return check_name(value)

    @model_validator(mode="before")
    @classmethod
    def _schema_of_contents(cls, data: Any) -> Any:
        """Version 2 with pedestrians (a version 1 document cannot have them), version 1
        without: a document states the first version that can hold it."""
        if not isinstance(data, dict):
            return data
        walking = bool(data.get("pedestrians"))
        given = data.get("schema", data.get("schema_"))
        if walking and given == SCHEMA:
            raise ValueError(f"pedestrians need schema {SCHEMA_WITH_PEDESTRIANS}, not {SCHEMA}")
        if given not in (None, SCHEMA, SCHEMA_WITH_PEDESTRIANS):
            return data  # an unknown schema: refused as it is
        key = "schema_" if "schema_" in data and "schema" not in data else "schema"
        return {**data, key: SCHEMA_WITH_PEDESTRIANS if walking else SCHEMA}

    @model_serializer(mode="wrap")
    def _without_empty_pedestrians(self, handler: SerializerFunctionWrapHandler) -> Any:
        """No ``pedestrians`` key when there are none (a version 1 document, as before),
        and no ``crossings_guessed`` key when the network is used as it is."""
        dumped = handler(self)
        if isinstance(dumped, dict) and not dumped.get("pedestrians"):
            dumped.pop("pedestrians", None)
        if isinstance(dumped, dict) and dumped.get("crossings_guessed") is False:
            dumped.pop("crossings_guessed")
        return dumped

    @property
    def road_users(self) -> list[NonEgo | Pedestrian]:
        """Every non-ego: the cars, then the pedestrians."""
        return [*self.nonegos, *self.pedestrians]

    @model_validator(mode="after")
    def _consistent(self) -> TestCase:
        expected = ControlType(self.control).rule_set
        if self.rules != expected:
            raise ValueError(
                f"rules {self.rules!r} do not match the control type {self.control!r} (rule "
                f"set {expected!r}); the rule set is chosen by the control type"
            )
        signalized = ControlType(self.control).signalized
        if signalized and self.signals is None:
            raise ValueError(
                f"a {self.control} junction needs its signal program: the signals field"
            )
        if not signalized and self.signals is not None:
            raise ValueError(f"signals applies to a signalized junction, not to {self.control}")
        if self.major_road is not None and self.control not in ("priority_stop", "priority"):
            raise ValueError(
                f"major_road applies to a priority_stop or priority junction, not to {self.control}"
            )
        if self.major_road is not None and self.major_road[0] == self.major_road[1]:
            raise ValueError("major_road must name two different roads")
        if self.duration < self.timestep:
            raise ValueError("duration must be at least one time step")
        if self.duration / self.timestep > MAX_SAMPLES:
            raise ValueError(_too_many_samples(self.duration, self.timestep, MAX_SAMPLES))
        ids = [n.id for n in self.road_users]
        duplicates = sorted({i for i in ids if ids.count(i) > 1})
        if duplicates:
            raise ValueError(
                f"non-ego ids must be unique among cars and pedestrians; repeated: "
                f"{', '.join(duplicates)}"
            )
        for index, nonego in enumerate(self.nonegos):
            _check_timing(nonego.trajectory, self.timestep, f"nonegos.{index}.trajectory")
        for index, person in enumerate(self.pedestrians):
            _check_timing(person.trajectory, self.timestep, f"pedestrians.{index}.trajectory")
        return self


def _check_timing(samples: list[Sample], timestep: float, where: str) -> None:
    for k, sample in enumerate(samples):
        if abs(sample.t - k * timestep) > 1e-6:
            raise ValueError(
                f"{where}.{k}.t is {sample.t:g}; samples must be at every time step "
                f"({timestep:g} s) from 0"
            )


def check_samples(duration: float, timestep: float, limit: int) -> None:
    """InvalidTestCase when a test-case of ``duration`` at ``timestep`` has more than
    ``limit`` samples per car (a server may allow fewer than MAX_SAMPLES)."""
    if duration / timestep > limit:
        raise InvalidTestCase(_too_many_samples(duration, timestep, limit))


def _too_many_samples(duration: float, timestep: float, limit: int) -> str:
    return (
        f"duration {duration:g} s at time step {timestep:g} s is {duration / timestep:.0f} "
        f"samples per car; at most {limit} (a longer time step or a shorter duration)"
    )
