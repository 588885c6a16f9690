"""A batch: what a CI pipeline submits as one job (`POST /jobs`, `scengen submit`).

Each item is an extension, a chain of successive extensions, an evaluation of controllers,
or a campaign (chains grown from ego-only test-cases, every level evaluated).
An item can start from a stored test-case, an inline document, or the last test-case an
earlier item made; an evaluation can cover every test-case of earlier items.
"""

from __future__ import annotations

import hashlib
import json
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from service.core.campaign import CAMPAIGN_DURATION
from service.core.errors import InvalidInput
from service.core.generator.variety import MAX_COUNT
from service.core.testcase import Control, Signals
from service.start_distances import DESCRIPTION as START_DISTANCES
from service.start_distances import (
    StartDistancesField,
    check_new_road_users,
    check_start_count,
)

MAX_SEED = 2**32 - 1  # clingo's and z3's seeds are unsigned 32-bit


class _Item(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, strict=True)


class _Based(_Item):
    testcase_id: str | None = Field(None, description="a stored test-case")
    testcase: dict[str, Any] | None = Field(None, description="or an inline test-case document")
    after: int | None = Field(
        None, ge=0, description="or the last test-case made by the item with this index"
    )

    @model_validator(mode="after")
    def _one_source(self) -> _Based:
        given = [self.testcase_id is not None, self.testcase is not None, self.after is not None]
        if sum(given) != 1:
            raise ValueError("give exactly one of testcase_id, testcase (inline) and after")
        return self


class ExtendItem(_Based):
    """One extension: new cars on `routes`, new pedestrians on `pedestrians` (walks)."""

    kind: Literal["extend"]
    routes: list[str] = Field([], max_length=6)
    pedestrians: list[str] = Field([], max_length=6, description="one new pedestrian per walk")

    seed: int = Field(0, ge=0, le=MAX_SEED)
    budget: float | None = Field(None, gt=0, description="seconds (default: the server's)")
    start_distance: StartDistancesField = Field(None, description=START_DISTANCES)
    count: int = Field(
        1,
        ge=1,
        le=MAX_COUNT,
        description="up to this many distinct extensions, each stored (an `after` of a "
        "later item takes the last of them)",
    )

    @model_validator(mode="after")
    def _one_start_per_route(self) -> ExtendItem:
        check_new_road_users(self.routes, self.pedestrians)
        check_start_count(self.routes, self.start_distance)
        return self


class ChainItem(_Based):
    """Successive extensions: `steps` gives each level's routes; or `levels` lets the
    service choose, at each level, a route that conflicts with the ego's or starts ahead
    of it: from a free fork, else joining the queue on a fork in use."""

    kind: Literal["chain"]
    steps: list[list[str]] | None = Field(None, min_length=1, max_length=10)
    levels: int | None = Field(None, ge=1, le=10)
    seed: int = Field(0, ge=0, le=MAX_SEED)
    budget: float | None = Field(None, gt=0, description="seconds per level")

    @model_validator(mode="after")
    def _steps_or_levels(self) -> ChainItem:
        if (self.steps is None) == (self.levels is None):
            raise ValueError("give exactly one of steps (routes per level) and levels")
        if self.steps is not None and any(not step for step in self.steps):
            raise ValueError("every step names at least one route")
        return self

    @property
    def count(self) -> int:
        return len(self.steps) if self.steps is not None else int(self.levels or 0)


class EvaluateItem(_Item):
    """Controllers judged on a test-case, or on every test-case of earlier items."""

    kind: Literal["evaluate"]
    controllers: list[str] = Field(min_length=1, max_length=20)
    testcase_id: str | None = None
    testcase: dict[str, Any] | None = None
    items: list[int] | None = Field(None, min_length=1, description="indices of earlier items")
    budget: float | None = Field(None, gt=0, description="seconds per evaluation")

    @model_validator(mode="after")
    def _one_source(self) -> EvaluateItem:
        given = [self.testcase_id is not None, self.testcase is not None, self.items is not None]
        if sum(given) != 1:
            raise ValueError("give exactly one of testcase_id, testcase (inline) and items")
        return self


class CampaignItem(_Item):
    """A campaign (service.core.campaign): `chains` chains of `depth` levels grown from an
    ego-only test-case per ego route on `network`, every level judged with every controller."""

    kind: Literal["campaign"]
    network: str = Field(min_length=1, description="a bundled network name or a network id")
    junction: str | None = Field(None, description="default: the network's only junction")
    control: Control | None = Field(
        None, description="override the junction's control type (default: the network's)"
    )
    signals: Signals | None = Field(
        None,
        description="a traffic_light junction: a fixed-time program replacing the network's, "
        "for every ego-only start (as POST /testcases takes it); default: the network's, "
        "when it is fixed-time",
    )
    egos: list[str] | None = Field(None, min_length=1, max_length=20, description="routes")
    all_egos: bool = Field(False, description="a chain set for every route of the junction")
    depth: int = Field(ge=1, le=10)
    chains: int = Field(ge=1, le=100, description="chains per ego route")
    controllers: list[str] = Field(min_length=1, max_length=20)
    seed: int = Field(0, ge=0, le=MAX_SEED)
    duration: float = Field(
        CAMPAIGN_DURATION,
        gt=0,
        le=120,
        description=f"seconds each test-case lasts (default {CAMPAIGN_DURATION:g}: room for a "
        "deep chain's ego to wait for the cars added and still leave its junction)",
    )
    budget_per_level: float | None = Field(None, gt=0, description="seconds per level")
    budget: float | None = Field(None, gt=0, description="seconds per evaluation")

    @model_validator(mode="after")
    def _egos_or_all(self) -> CampaignItem:
        if (self.egos is None) == (not self.all_egos):
            raise ValueError("give exactly one of egos (routes) and all_egos: true")
        if self.egos is not None and len(set(self.egos)) < len(self.egos):
            raise ValueError("egos names a route twice")
        certificates = [c for c in self.controllers if c.startswith("certificate:")]
        if certificates:
            raise ValueError(
                f"{', '.join(certificates)} replay a certificate, which the ego-only start of "
                "a campaign has not: use them with evaluate items"
            )
        return self


Item = Annotated[ExtendItem | ChainItem | EvaluateItem | CampaignItem, Field(discriminator="kind")]


class Batch(BaseModel):
    """A job's items, run in dependency order (independent items in parallel)."""

    model_config = ConfigDict(
        extra="forbid",
        frozen=True,
        strict=True,
        json_schema_extra={
            "examples": [
                {
                    "name": "four-way regression",
                    "items": [
                        {
                            "kind": "chain",
                            "testcase_id": "c2de5a280aab66bd",
                            "levels": 2,
                            "seed": 1,
                        },
                        {"kind": "evaluate", "items": [0], "controllers": ["sumo"]},
                    ],
                }
            ]
        },
    )
    name: str = Field("", max_length=200)
    items: list[Item] = Field(min_length=1, max_length=200)

    @model_validator(mode="after")
    def _references_point_back(self) -> Batch:
        for index, item in enumerate(self.items):
            for earlier in _references(item):
                if earlier >= index:
                    raise ValueError(f"items[{index}] refers to item {earlier}, not an earlier one")
                if isinstance(self.items[earlier], EvaluateItem):
                    raise ValueError(
                        f"items[{index}] refers to item {earlier}, an evaluation, which makes "
                        "no test-case"
                    )
        return self

    def fingerprint(self) -> str:
        """What an Idempotency-Key is bound to: the batch, not its formatting. An extend
        item's automatic start (``start_distance`` null) and single extension (``count``
        1), a campaign's network program (``signals`` null) and a program's absent note
        (``signals.note`` null) are left out, so that batches stored before those fields
        existed keep their fingerprint (a campaign folder too: ``scengen campaign``
        resumes)."""
        document = self.model_dump(mode="json")
        for item in document["items"]:
            if item.get("kind") == "extend" and item.get("start_distance") is None:
                item.pop("start_distance", None)
            if item.get("kind") == "extend" and item.get("count") == 1:
                item.pop("count", None)
            if item.get("kind") == "campaign" and item.get("signals") is None:
                item.pop("signals", None)
            if isinstance(item.get("signals"), dict) and item["signals"].get("note") is None:
                item["signals"].pop("note", None)
        canonical = json.dumps(document, sort_keys=True)
        return hashlib.sha256(canonical.encode()).hexdigest()


AnyItem = ExtendItem | ChainItem | EvaluateItem | CampaignItem


def dependencies(item: AnyItem) -> list[int]:
    """Indices of the items this one waits for."""
    return sorted(set(_references(item)))


def _references(item: AnyItem) -> list[int]:
    if isinstance(item, EvaluateItem):
        return list(item.items or [])
    if isinstance(item, CampaignItem):
        return []
    return [] if item.after is None else [item.after]


def parse_batch(document: Any) -> Batch:
    """A batch from parsed JSON or YAML; InvalidInput names the bad field."""
    try:
        return Batch.model_validate(document)
    except ValidationError as error:
        problems = "; ".join(
            f"{'.'.join(str(p) for p in e['loc']) or 'batch'}: "
            f"{e['msg'].removeprefix('Value error, ')}"
            for e in error.errors()
        )
        raise InvalidInput(f"invalid batch: {problems}") from None
