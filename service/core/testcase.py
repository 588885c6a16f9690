"""The test-case document (design section 8): a versioned JSON contract with validation.

Conventions: coordinates are SUMO network coordinates (m); ``x``, ``y`` of a sample are the
centre of the car's rectangle; ``heading`` is in degrees clockwise from north (+y), as in
SUMO; ``distance`` is metres travelled along the route since t = 0; the ego's start is the
front bumper's distance before the stop line of its fork.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
from collections.abc import Sequence
from pathlib import Path, PurePosixPath
from typing import Annotated, Any, Literal

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    SerializerFunctionWrapHandler,
    ValidationError,
    field_validator,
    model_serializer,
    model_validator,
)

from service.core.errors import InvalidInput, InvalidTestCase, UnknownNetwork
from service.core.motion.events import EventKind
from service.core.motion.plausibility import first_jump
from service.core.motion.poses import (
    check_start_speed,
    longest_start,
    plan_drive,
    start_speed_limit,
)
from service.core.network import (
    ControlType,
    Intersection,
    Route,
    SignalProgram,
    bundled_networks,
    file_sha256,
    load_intersection,
    resolve_network,
    with_signals,
)
from service.core.network.convert import source_format
from service.core.network.signals import (
    MAX_PHASE_DURATION,
    MAX_PHASES,
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
    duration: float = Field(gt=0, le=MAX_PHASE_DURATION, description="seconds")
    state: str = Field(
        min_length=1,
        max_length=1000,
        description="one SUMO colour per link of the traffic light, by link index: G "
        "protected green, g permissive green, y yellow, r red, u red-yellow, s right on red "
        "after a stop",
        # in the schema only: the model's check names the unknown colours and the valid ones
        json_schema_extra={"pattern": f"^[{VALID_COLOURS}]+$"},
    )


class Signals(_Model):
    """A fixed-time traffic-light program, as SUMO's tlLogic (service.core.network.signals)."""

    tls: str = Field(min_length=1, description="the traffic light's id in the network")
    program: str = Field("0", min_length=1, description="the program's id (programID)")
    offset: float = Field(0.0, ge=-1e6, le=1e6, description="s: phase 0 starts at offset")
    phases: list[SignalPhaseDoc] = Field(
        min_length=1,
        max_length=MAX_PHASES,
        description="the cycle in order; every state has one colour per link of the traffic "
        "light, so all states are equally long",
    )

    @model_validator(mode="after")
    def _consistent(self) -> Signals:
        problems = program_problems((p.duration, p.state) for p in self.phases)
        if problems:
            raise ValueError("; ".join(problems))
        return self

    def to_program(self) -> SignalProgram:
        return make_program(
            self.tls, self.program, self.offset, [(p.duration, p.state) for p in self.phases]
        )


Control = Literal[
    "allway_stop",
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
        description="the two roads (edge ids) into a priority_stop junction that keep the "
        "right of way, as the user named them; absent: the network's, or scengen's choice",
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
        if self.major_road is not None and self.control != "priority_stop":
            raise ValueError(
                f"major_road applies to a priority_stop junction, not to {self.control}"
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


def _describe(error: ValidationError) -> str:
    parts = []
    for item in first_errors(error, 5):
        where = ".".join(str(p) for p in item["loc"]) or "document"
        message = re.sub(r"^Value error, ", "", item["msg"])
        parts.append(f"{where}: {message}")
    more = error.error_count() - len(parts)
    return "; ".join(parts) + (f" (and {more} more)" if more > 0 else "")


def first_errors(error: ValidationError, count: int) -> list[dict[str, Any]]:
    """The first ``count`` errors of ``error``. ``errors()`` builds a dict for every error
    (3.4 s for a million); pydantic writes them all as JSON ten times faster, and only the
    first few are decoded from that."""
    text = error.json(include_url=False, include_context=False, include_input=False)
    decoder = json.JSONDecoder()
    found: list[dict[str, Any]] = []
    position = 1  # after "["
    while len(found) < count and text[position] != "]":
        item, position = decoder.raw_decode(text, position)
        found.append(item)
        position += 1 if text[position] == "," else 0
    return found


def parse_testcase(document: str | bytes | dict[str, Any]) -> TestCase:
    """A validated test-case; InvalidTestCase naming the first bad fields otherwise."""
    try:
        if isinstance(document, dict):
            return TestCase.model_validate(document)
        return TestCase.model_validate_json(document)
    except ValidationError as exc:
        raise InvalidTestCase(f"invalid test-case: {_describe(exc)}") from None


def read_testcase(path: Path) -> TestCase:
    try:
        text = path.read_text()
    except OSError as exc:
        raise InvalidTestCase(f"cannot read test-case {path}: {exc.strerror}") from None
    try:
        json.loads(text)
    except json.JSONDecodeError as exc:
        raise InvalidTestCase(f"{path} is not JSON: {exc}") from None
    return parse_testcase(text)


def implausible_trajectories(testcase: TestCase) -> list[str]:
    """Each stored trajectory that jumps further between two samples than any car can
    drive (service.core.motion.plausibility), in words: a warning, not an error, since the
    checker judges a document as it is written."""
    found = [(f"{car.id}'s trajectory", first_jump(car.trajectory)) for car in testcase.road_users]
    if testcase.certificates is not None:
        found += [
            ("the complexity certificate", first_jump(testcase.certificates.complexity)),
            ("the solvability certificate", first_jump(testcase.certificates.solvability)),
        ]
    return [f"{what} {jump}: no car can" for what, jump in found if jump is not None]


def dump_testcase(testcase: TestCase) -> str:
    """The JSON text of a test-case (stable key order, two-space indent, newline at end)."""
    return (
        json.dumps(testcase.model_dump(mode="json", by_alias=True, exclude_none=True), indent=2)
        + "\n"
    )


def testcase_level(testcase: TestCase) -> int:
    """0 for an ego-only test-case, else the level of the extension that added its last cars."""
    return max((n.added_in for n in testcase.road_users), default=0)


def readable_name(testcase: TestCase, stem: str = "", network: str = "") -> str:
    """A name a test engineer reads at a glance: ``STEM level N``, or without a stem the
    network's short name (a bundled name, or the file name without ``.net.xml``), the
    junction, the ego's route and the level: ``Town05 396 -44_1:-9_1 level 2``. ``network``
    names the network's file where the reference does not say it (a server's network id):
    the short name is then made from it."""
    if not stem:
        short = PurePosixPath(network or testcase.network.ref).name.removesuffix(".xml")
        stem = f"{short.removesuffix('.net')} {testcase.junction} {testcase.ego.route.id}"
    suffix = f" level {testcase_level(testcase)}"
    return stem[: MAX_NAME_LENGTH - len(suffix)] + suffix


def renamed(testcase: TestCase, name: str) -> TestCase:
    """``testcase`` named ``name``, validated like any document (InvalidTestCase names a
    name that is too long or holds control characters)."""
    document = testcase.model_dump(mode="json", by_alias=True, exclude_none=True)
    return parse_testcase({**document, "name": name})


def name_stem(name: str) -> str:
    """``name`` without a trailing ``level N`` (so the next level renames it, not nests)."""
    return re.sub(r" level \d+$", "", name)


# Where this process has read a non-bundled network from, by content hash: a test-case
# names such a network by its file name (no machine's paths), and a library caller that made
# it from a path can go on without saying the path again.
_READ_FROM: dict[str, Path] = {}


def network_ref(network: str | Path) -> NetworkRef:
    """How a test-case names a network: a bundled short name; else the path as given when
    it is relative (to the working directory), or the file's name: never an absolute path
    of this machine. The content hash identifies the file wherever it is."""
    path = resolve_network(network)
    digest = file_sha256(path)
    name = str(network)
    if bundled_networks().get(name) == path:
        return NetworkRef(ref=name, sha256=digest)
    _READ_FROM[digest] = path
    given = Path(network)
    named = given if source_format(given) else path  # an imported map: its own name
    return NetworkRef(ref=named.name if given.is_absolute() else given.as_posix(), sha256=digest)


def local_network_name(ref: str) -> str:
    """The file name a network has next to a test-case that names it ``ref`` (where
    ``scengen export`` puts it): the reference's file name; a server's network id gets the
    ``.net.xml`` suffix."""
    name = PurePosixPath(ref).name
    return name if name.endswith(".xml") else f"{name}.net.xml"


def with_network_path(testcase: TestCase, network_file: Path | None, folder: Path) -> TestCase:
    """``testcase`` as it is written into ``folder``: its network's ``path`` is
    ``network_file`` relative to that folder, so that the test-case finds the file from
    wherever it is read, and moving both together keeps it so. A bundled network (found by
    name anywhere) and a test-case without a known file get no path."""
    path = None
    if network_file is not None and testcase.network.ref not in bundled_networks():
        path = Path(os.path.relpath(network_file.resolve(), folder.resolve())).as_posix()
    if path == testcase.network.path:
        return testcase
    network = testcase.network.model_copy(update={"path": path})
    return testcase.model_copy(update={"network": network})


def without_network_path(testcase: TestCase) -> TestCase:
    """``testcase`` without its network's ``path``: the same test-case wherever it was
    written (a server stores it so, and a parent's hash is taken of it)."""
    return with_network_path(testcase, None, Path())


def document_sha256(testcase: TestCase) -> str:
    """The hash of a test-case's document, the same wherever the file was written."""
    return hashlib.sha256(dump_testcase(without_network_path(testcase)).encode()).hexdigest()


def find_network_file(
    testcase: TestCase,
    network_file: Path | None = None,
    near: Path | None = None,
    search_path: Sequence[Path] = (),
) -> tuple[Path, str]:
    """The file of a test-case's network (a map as it is, not converted) and how it was
    found. The places, in order: the network's ``path`` from ``near`` (the folder the
    test-case was read from); a file of its name in ``near``; ``network_file``; a file of
    its name in a folder of ``search_path``; the bundled network of that name; the
    reference as a path from the working directory (older test-cases); a file this process
    made a test-case from. The first whose bytes have the test-case's sha256 wins; when
    files are found but none has it, InvalidTestCase names each file and both hashes."""
    candidates = _network_candidates(testcase, network_file, near, search_path)
    ref, digest = testcase.network.ref, testcase.network.sha256
    present = [(path, how) for path, how in candidates if path.is_file()]
    found = [(path, how, file_sha256(resolve_network(path))) for path, how in present]
    for path, how, sha256 in found:
        if sha256 == digest:
            return path.resolve(), how
    if found:
        others = "; ".join(f"{path.resolve()} ({how}) has sha256 {sha}" for path, how, sha in found)
        raise InvalidTestCase(
            f"network.sha256: the test-case was made on {ref} with sha256 {digest}, but "
            f"{others}: the network has changed since; pass the file it was made on "
            "with --network FILE"
        )
    looked = ", ".join(f"{path.resolve()} ({how})" for path, how in candidates)
    raise UnknownNetwork(
        f"network {ref!r} (sha256 {digest[:12]}...) is not at {looked}: pass its file with "
        "--network FILE, or name its folder in SCENGEN_NETWORK_PATH",
        network=ref,
    )


def _network_candidates(
    testcase: TestCase, network_file: Path | None, near: Path | None, search_path: Sequence[Path]
) -> list[tuple[Path, str]]:
    """Where ``find_network_file`` looks, in order, each place once."""
    ref = testcase.network.ref
    names = [local_network_name(ref)]
    if source_format(ref):  # the map itself, converted again
        names.append(PurePosixPath(ref).name)
    candidates: list[tuple[Path, str]] = []
    if near is not None:
        if testcase.network.path is not None:
            candidates.append((near / testcase.network.path, "its path from the test-case"))
        candidates += [(near / name, "next to the test-case") for name in names]
    if network_file is not None:
        candidates.append((network_file, "given with --network"))
    for folder in search_path:
        candidates += [(folder / name, "on SCENGEN_NETWORK_PATH") for name in names]
    if ref in bundled_networks():
        candidates.append((bundled_networks()[ref], "bundled"))
    else:
        candidates.append((Path(ref), "as named"))
    if testcase.network.sha256 in _READ_FROM:
        candidates.append((_READ_FROM[testcase.network.sha256], "read before by this process"))
    unique: dict[Path, tuple[Path, str]] = {}
    for path, how in candidates:  # next to the test-case and as named can be one place
        unique.setdefault(path.resolve(), (path, how))
    return list(unique.values())


DEFAULT_START_DISTANCE = 30.0  # m: the ego's automatic start, where the road is that long
DEFAULT_START_SPEED = 8.0  # m/s: the ego's automatic start speed, where its lane allows it


def new_testcase(
    network: str | Path,
    ego_route: str,
    junction: str | None = None,
    control: str | None = None,
    start_distance: float | None = None,
    start_speed: float | None = None,
    duration: float = 20.0,
    timestep: float = 0.1,
    params: Params | None = None,
    cache_dir: Path | None = None,
    name: str = "",
    major_road: Sequence[str] | None = None,
    signals: SignalProgram | None = None,
    guess_crossings: bool = False,
) -> TestCase:
    """An ego-only test-case; checks that the route exists and the start lies on the map.

    ``start_distance`` None is automatic: DEFAULT_START_DISTANCE, or the whole road before
    the fork where it is shorter (a start given is refused when the road is shorter).
    ``start_speed`` None is automatic: DEFAULT_START_SPEED, or the speed limit of the lane
    the ego starts on (or v_max) where that is lower; a speed given above either is refused.
    ``major_road``: two roads into a priority_stop junction that keep the right of way
    (service.core.network.load_intersection); the test-case keeps it (``major_road``), so
    every later command rebuilds the same network. ``signals``: the program of a signalized
    junction (default: the network's, when it is fixed-time); the test-case carries it.
    ``guess_crossings``: the network gets sidewalks and crossings (netconvert guesses them;
    the route's lane indices are those of the rebuilt network); the test-case keeps it
    (``crossings_guessed``) like ``major_road``."""
    intersection = load_intersection(
        network,
        junction,
        control,
        cache_dir,
        major_road=major_road,
        guess_crossings=guess_crossings,
    )
    intersection = _signalled(intersection, signals)
    route = intersection.route(ego_route)
    _check_ego_can_go(intersection, route, duration)
    chosen = params or Params()
    if start_speed is not None and start_speed > chosen.v_max:
        raise InvalidTestCase(
            f"ego start speed {start_speed:g} m/s exceeds v_max {chosen.v_max:g} m/s"
        )
    speed = min(DEFAULT_START_SPEED, chosen.v_max) if start_speed is None else start_speed
    if start_distance is None:
        start_distance = longest_start(intersection, route, DEFAULT_START_DISTANCE)
    document: dict[str, Any] = {
        "schema": SCHEMA,
        "name": name,
        "network": network_ref(network).model_dump(),
        "junction": intersection.junction,
        "control": intersection.control.value,
        "rules": intersection.control.rule_set,
        "timestep": timestep,
        "duration": duration,
        "params": chosen.model_dump(),
        "ego": {
            "route": {"fork": route.fork, "exit": route.exit},
            "start": {"distance": start_distance, "speed": speed},
        },
    }
    if major_road is not None:
        document["major_road"] = list(major_road)
    if guess_crossings:
        document["crossings_guessed"] = True
    if intersection.signals is not None:
        document["signals"] = intersection.signals.to_document()
    testcase = parse_testcase(document)
    # Fails with a clear message when the start lies beyond the mapped road.
    plan = plan_drive(intersection, route, start_distance, max(speed, 1.0), duration, timestep)
    if start_speed is not None:
        check_start_speed(intersection, plan, start_speed)
    elif speed > start_speed_limit(intersection, plan):
        document["ego"]["start"]["speed"] = start_speed_limit(intersection, plan)
        testcase = parse_testcase(document)
    return testcase


def load_testcase_intersection(
    testcase: TestCase,
    cache_dir: Path | None = None,
    network_file: Path | None = None,
    near: Path | None = None,
) -> Intersection:
    """The intersection of a test-case, after checking that its network is unchanged
    (``find_network_file``: ``network_file`` stands in for the reference, for example when
    the test-case names a network that only a server knows; ``near`` is the folder the
    test-case was read from)."""
    path, _ = find_network_file(testcase, network_file, near)
    intersection = load_intersection(
        path,
        testcase.junction,
        testcase.control,
        cache_dir,
        major_road=testcase.major_road,
        guess_crossings=testcase.crossings_guessed,
    )
    return under_testcase_signals(intersection, testcase)


def under_testcase_signals(intersection: Intersection, testcase: TestCase) -> Intersection:
    """``intersection`` under the test-case's signal program (the one it carries, not the
    network's); InvalidTestCase when the program does not fit the junction."""
    if testcase.signals is None:
        return intersection
    try:
        return with_signals(intersection, testcase.signals.to_program())
    except InvalidInput as exc:
        raise InvalidTestCase(f"signals: {exc}") from None


def _check_ego_can_go(intersection: Intersection, route: Route, duration: float) -> None:
    """InvalidInput when the ego's signal shows red for the whole test-case: no ego could
    pass it lawfully, so the test-case would have no solution to make harder."""
    program = intersection.signals
    if program is None or route.link_index < 0 or program.goes_within(route.link_index, duration):
        return
    go = program.first_go(route.link_index)
    when = "never shows a colour to go" if go is None else f"first lets it go at {go:g} s"
    raise InvalidInput(
        f"the ego's signal (link {route.link_index} of traffic light {program.tls!r}) is red "
        f"for the whole test-case ({duration:g} s) and {when}: no ego could pass it; give "
        "a longer duration, another ego route, or a program with another offset (--signals; "
        "the API's signals field)"
    )


def _signalled(intersection: Intersection, signals: SignalProgram | None) -> Intersection:
    """The intersection under the program given, or its network's; InvalidInput when a
    signalized junction has no fixed-time program, or a program is given to another."""
    if signals is not None:
        return with_signals(intersection, signals)
    if intersection.control.signalized and intersection.signals is None:
        raise InvalidInput(intersection.signals_refused or "the junction has no signal program")
    return intersection


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
