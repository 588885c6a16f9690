"""New cars' start distances as the API and batch jobs take them, checked at the edge.

A body gives one number for every new car, null (automatic for all), or a list with one
number or null (automatic for that car) per route, in the order of the routes: what
``service.core.generator.additions.StartDistances`` takes. A wrong value gets one message that says
what is allowed, not pydantic's one error per member of the union.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Annotated, Any

from pydantic import Field, ValidationError, ValidatorFunctionWrapHandler, WrapValidator
from pydantic_core import PydanticCustomError

DESCRIPTION = (
    "metres from each new car's front to its stop line at t = 0: one number for every new "
    "car, or a list with one number or null per route (in the order of `routes`); null "
    "means automatic: behind the last car on its fork, ahead of the ego on the ego's fork, "
    "where the ego starts on a free fork; never further back than the road before the fork "
    "goes (a number given must fit on that road)"
)


def _one_problem(value: Any, handler: ValidatorFunctionWrapHandler) -> Any:
    try:
        return handler(value)
    except ValidationError:
        raise PydanticCustomError("start_distance", _problem(value)) from None


def _is_distance(value: Any) -> bool:
    return (
        isinstance(value, int | float)
        and not isinstance(value, bool)
        and math.isfinite(value)
        and value >= 0
    )


def _problem(value: Any) -> str:
    if isinstance(value, list):
        for k, entry in enumerate(value):
            if entry is not None and not _is_distance(entry):
                return (
                    f"entry {k} (for routes[{k}]) is {_shown(entry)}: each entry is a number >= 0 "
                    "(m) or null (automatic)"
                )
    if isinstance(value, int | float) and not isinstance(value, bool):
        return f"a start distance must be a finite number >= 0 m, got {_shown(value)}"
    return (
        "give a number >= 0 (m), null (automatic), or a list with one number or null per "
        f"route, not {_shown(value)}"
    )


def _shown(value: Any) -> str:
    """The value as the client sent it, cut short: an answer never echoes a huge body."""
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


StartDistance = Annotated[float, Field(ge=0)]
StartDistancesField = Annotated[
    StartDistance | list[StartDistance | None] | None, WrapValidator(_one_problem)
]


def check_start_count(routes: Sequence[str], start: float | Sequence[Any] | None) -> None:
    """ValueError unless ``start`` is one value for all or a list with one per route."""
    if isinstance(start, list) and len(start) != len(routes):
        raise ValueError(
            "start_distance: give one number for every new car or one entry per route: "
            f"{_count(len(routes), 'route')}, {_count(len(start), 'start distance')}"
        )


def _count(n: int, what: str) -> str:
    return f"{n} {what}" if n == 1 else f"{n} {what}s"


def check_new_road_users(routes: Sequence[str], walks: Sequence[str], most: int = 6) -> None:
    """ValueError unless an extension adds at least one road user, and at most ``most``:
    a car per route, a pedestrian per walk."""
    if not routes and not walks:
        raise ValueError("name at least one new car (routes) or pedestrian (pedestrians)")
    if len(routes) + len(walks) > most:
        raise ValueError(
            f"at most {most} new road users in one extension: {_count(len(routes), 'route')} "
            f"and {_count(len(walks), 'pedestrian')}"
        )
