"""Request and response bodies, one family per resource, with examples that work as they
stand on the bundled four-way stop (the OpenAPI UI's "Try it out")."""

from __future__ import annotations

import json
from datetime import datetime
from functools import lru_cache
from typing import Annotated, Any

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    StringConstraints,
    field_validator,
    model_validator,
)

from service.core.generator.variety import MAX_COUNT
from service.core.network import ControlType
from service.core.testcase import (
    MAX_DURATION,
    MAX_NAME_LENGTH,
    MAX_SPEED,
    MAX_TIMESTEP,
    MIN_TIMESTEP,
    Params,
    Signals,
    check_name,
)
from service.start_distances import DESCRIPTION as START_DISTANCES
from service.start_distances import (
    StartDistancesField,
    check_new_road_users,
    check_start_count,
)

MAX_SEED = 2**32 - 1  # clingo's and z3's seeds are unsigned 32-bit
EXAMPLE_NETWORK = "4way-stop"
EXAMPLE_EGO = "E2C_1:C2S_1"  # east arm, left turn to the south
EXAMPLE_NEW_ROUTE = "S2C_1:C2N_1"  # south arm, straight on to the north


@lru_cache
def example_document() -> str:
    """An ego-only test-case on the bundled four-way stop (its real network hash): what
    the POST /testcases example creates, and what the /extend example sends inline."""
    from service.core.testcase import dump_testcase, new_testcase, readable_name, renamed

    testcase = new_testcase(EXAMPLE_NETWORK, EXAMPLE_EGO)
    return dump_testcase(renamed(testcase, readable_name(testcase)))


def example_testcase() -> dict[str, Any]:
    return dict(json.loads(example_document()))


MAX_OFFSET = 10**12  # pagination offsets: far beyond any store, well inside SQL's integers

# A route is "fork lane id:exit lane id": a lane id of a road is never empty and never starts
# with ':' (SUMO keeps that for a junction's internal lanes); the first ':' splits the two.
ROUTE_PATTERN = r"^[^:]+:[^:].*$"
RouteText = Annotated[
    str,
    StringConstraints(pattern=ROUTE_PATTERN, max_length=2000),
    Field(description="fork lane id:exit lane id, from the junction's routes"),
]
Ident = Annotated[str, StringConstraints(min_length=1, max_length=2000)]
# A walk is a crossing's id without SUMO's leading colon, then + or - (docs/pedestrians.md).
WALK_PATTERN = r"^[^:\s]+[+-]$"
WalkText = Annotated[
    str,
    StringConstraints(pattern=WALK_PATTERN, max_length=2000),
    Field(description="a crossing walked one way, from the junction's walks (C_c0+)"),
]
MAX_NEW_ROAD_USERS = 6  # cars and pedestrians one extension adds at most


def no_null_base(value: Any) -> Any:
    """A base left out is absent; sent as null it is refused, as the schema says (one of
    the two, an object or an id, never null)."""
    if value is None:
        raise ValueError("leave it out rather than send null")
    return value


class _Body(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, strict=True)


class Links(BaseModel):
    model_config = ConfigDict(extra="allow")
    self: str


class NetworkPublic(BaseModel):
    id: str = Field(description="bundled name, or <file stem>-<hash> of an upload")
    filename: str
    sha256: str
    size: int = Field(description="bytes")
    bundled: bool
    controls: dict[str, str] = Field(description="junction -> control type overridden at upload")
    source: dict[str, str] | None = Field(
        None,
        description="where an imported network came from: format (opendrive or openstreetmap), "
        "filename and sha256 of the original file (GET /networks/{id}/source); the network "
        "itself is netconvert's conversion",
    )
    created_at: datetime | None
    links: Links


class JunctionSummary(BaseModel):
    id: str
    type: str = Field(description="control type in the network file")
    control: str | None = Field(description="the control type test-cases use (override applied)")
    supported: bool = Field(description="whether the effective control type has a rule set")
    approaches: int
    links: Links


class TestCaseCreate(_Body):
    """An ego-only test-case: the root of a chain of extensions."""

    model_config = ConfigDict(
        extra="forbid",
        json_schema_extra={"examples": [{"network": EXAMPLE_NETWORK, "ego_route": EXAMPLE_EGO}]},
    )
    network: Ident = Field(description="a network id from GET /networks")
    ego_route: RouteText = Field(description="fork lane id:exit lane id, a route of the junction")
    junction: Ident | None = Field(None, description="default: the network's only supported one")
    control: ControlType | None = Field(
        None,
        strict=False,
        description="override the junction's control type (default: the network's)",
    )
    guess_crossings: bool = Field(
        False,
        description="add sidewalks and pedestrian crossings (netconvert --sidewalks.guess "
        "--crossings.guess): the junction gets walks, every car lane's index moves up by "
        "one (the ego route names the rebuilt lanes); the test-case keeps it "
        "(crossings_guessed)",
    )
    start_distance: float | None = Field(
        None,
        ge=0,
        description="ego front before the stop line (m); default 30 m, or the whole road "
        "before the fork where that is shorter (a start given here is never shortened)",
    )
    start_speed: float | None = Field(
        None,
        ge=0,
        le=MAX_SPEED,
        description="ego speed at t = 0 (m/s); default 8 m/s, or the speed limit of the lane "
        "it starts on where that is lower (a speed given must be at most that limit and v_max)",
    )
    duration: float = Field(20.0, gt=0, le=MAX_DURATION, description="length of the test (s)")
    timestep: float = Field(0.1, ge=MIN_TIMESTEP, le=MAX_TIMESTEP, description="sample spacing (s)")
    params: Params | None = Field(None, description="rule and speed parameters")
    name: str = Field("", max_length=MAX_NAME_LENGTH, description="printable characters")
    signals: Signals | None = Field(
        None,
        description="a traffic_light junction: a fixed-time program replacing the network's "
        "(the test-case's signals field: tls, program, offset, phases with duration and "
        "state); default: the network's, when it is fixed-time",
    )

    @field_validator("name")
    @classmethod
    def _printable_name(cls, value: str) -> str:
        return check_name(value)


class TestCaseSummary(BaseModel):
    id: str = Field(description="content address: the first 16 hex digits of its sha256")
    name: str = Field(
        description="the test-case's name: by default its network, junction, ego route and "
        "level, as in '4way-stop C E2C_1:C2S_1 level 2' (empty for a document sent inline "
        "without one)"
    )
    network: str
    junction: str
    parent: str | None
    nonegos: int
    level: int = Field(description="the extension level that added its last cars; 0: ego only")
    duration: float = Field(description="how long the test-case lasts (s)")
    created_at: datetime
    links: Links


class TestCasePublic(TestCaseSummary):
    testcase: dict[str, Any] = Field(description="the test-case document (scengen/testcase/1)")


class TestCasePage(BaseModel):
    items: list[TestCaseSummary]
    total: int
    limit: int
    offset: int
    next: str | None = Field(description="the next page, if any")


class Lineage(BaseModel):
    id: str
    ancestors: list[TestCaseSummary] = Field(description="parent first, root last")
    children: list[TestCaseSummary]


class Attempt(BaseModel):
    index: int = Field(description="answer set number (Step 2), from 1")
    outcome: str


class ExtendRequest(_Body):
    """Extend a test-case (inline, or stored by id) with new cars on `routes` and new
    pedestrians on `pedestrians` (walks): at least one new road user, six at most."""

    testcase: dict[str, Any] | None = Field(None, description="the old test-case document")
    testcase_id: Ident | None = Field(None, description="or the id of a stored test-case")
    routes: list[RouteText] = Field(
        [], max_length=MAX_NEW_ROAD_USERS, description="one new car per route"
    )
    pedestrians: list[WalkText] = Field(
        [], max_length=MAX_NEW_ROAD_USERS, description="one new pedestrian per walk"
    )

    seed: int = Field(0, ge=0, le=MAX_SEED, description="same seed, same bytes")
    budget: float | None = Field(None, gt=0, description="seconds (default SCENGEN_EXTEND_BUDGET)")
    start_distance: StartDistancesField = Field(None, description=START_DISTANCES)
    count: int = Field(
        1,
        ge=1,
        le=MAX_COUNT,
        description="up to this many distinct extensions (different orders of events first, "
        "then timings a second apart); above 1 the answer is an `ExtensionsPublic`",
    )

    _no_null = field_validator("testcase", "testcase_id", mode="before")(no_null_base)

    @model_validator(mode="after")
    def _one_base(self) -> ExtendRequest:
        if (self.testcase is None) == (self.testcase_id is None):
            raise ValueError("give exactly one of testcase (inline) and testcase_id")
        check_new_road_users(self.routes, self.pedestrians)
        check_start_count(self.routes, self.start_distance)
        return self


class ExtensionPublic(TestCasePublic):
    new_cars: list[str]
    attempts: list[Attempt]
    seconds: dict[str, float] = Field(description="time spent per step")


class ExtensionVariantPublic(ExtensionPublic):
    difference: str = Field(
        description="what tells it from the others: its order of events among the test's "
        "cars, each new car's route, stop, arrival and entry, the rule its complexity "
        "certificate breaks, and where Step 3 aimed its timing"
    )


class ExtensionsPublic(BaseModel):
    """The answer to `POST /extend` with `count` above 1: every extension found (each
    stored, with the old test-case as its parent), and why fewer than asked came back."""

    extensions: list[ExtensionVariantPublic] = Field(description="distinct, in the order found")
    shortfall: str | None = Field(
        description="why fewer than `count` came back (null when that many did)"
    )


class EvaluationCreate(_Body):
    """Drive a controller through a test-case in SUMO and judge it."""

    testcase_id: Ident | None = Field(None, description="a stored test-case")
    testcase: dict[str, Any] | None = Field(None, description="or an inline test-case")
    controller: Ident = Field("sumo", description="a name from GET /controllers")
    budget: float | None = Field(
        None, gt=0, description="seconds (default SCENGEN_EVALUATE_BUDGET)"
    )

    _no_null = field_validator("testcase", "testcase_id", mode="before")(no_null_base)

    @model_validator(mode="after")
    def _one_base(self) -> EvaluationCreate:
        if (self.testcase is None) == (self.testcase_id is None):
            raise ValueError("give exactly one of testcase (inline) and testcase_id")
        return self


class EvaluationPublic(BaseModel):
    id: str
    testcase: str
    controller: str
    passed: bool = Field(description="whether the ego passed, judged until its goal")
    reasons: list[str] = Field(description="why it failed, until its goal (empty: it passed)")
    information: list[str] = Field(
        description="what happened after its goal, in words (the verdict's `after_goal`): "
        "not judged, never a reason"
    )
    verdict: dict[str, Any] = Field(
        description="the checker's verdict (scengen/verdict/1): `passed`, `goal`, "
        "`judged_until` (the judgement ends with the goal, or at the duration when it is "
        "missed), `collisions` and `violations` until then, `after_goal` {`collisions`, "
        "`violations`} after it (information), `reasons`, `information`, with its "
        "criticality until the goal: TTC, PET, DRAC and distance against each car and "
        "each pedestrian, and overall (README, Criticality)"
    )
    seconds: float
    created_at: datetime
    links: Links


class EvaluationPage(BaseModel):
    items: list[EvaluationPublic]
    total: int
    limit: int
    offset: int
    next: str | None


class Controller(BaseModel):
    name: str
    description: str


class Health(BaseModel):
    status: str
    database: str
    workers: int
    running: int
    waiting: int


class JobItemPublic(BaseModel):
    position: int = Field(description="the item's index in the batch")
    kind: str
    state: str = Field(description="queued, running, succeeded, failed or cancelled")
    attempts: int = Field(description="times a worker started it")
    progress: str
    needs: list[int] = Field(description="items it waits for")
    testcases: list[str] = Field(description="ids of the test-cases it made, in order")
    evaluations: list[str] = Field(description="ids of its evaluations")
    links: list[str] = Field(description="its test-cases and evaluations")
    error: str | None
    started_at: datetime | None
    finished_at: datetime | None


class JobPublic(BaseModel):
    id: str
    name: str
    state: str = Field(description="queued, running, succeeded, failed or cancelled")
    created_at: datetime
    started_at: datetime | None
    finished_at: datetime | None
    done: int = Field(description="items finished")
    total: int
    evaluations: dict[str, int] = Field(description="passed and failed evaluations so far")
    items: list[JobItemPublic]
    links: Links


class JobPage(BaseModel):
    items: list[JobPublic]
    total: int
    limit: int
    offset: int
    next: str | None
