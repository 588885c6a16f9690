"""The exception tree of the core: every error the domain raises, with its context.

    ScengenError                    root; never raised itself
    ├── InvalidInput                the caller's input is wrong; the message names the problem
    │   ├── UnknownNetwork          a network reference is neither bundled nor a readable file
    │   ├── UnknownJunction         a junction id that is not in the network, or none was named
    │   ├── UnknownLane             a lane id that is not a fork or an exit of the intersection
    │   ├── UnknownRoute            a (fork, exit) pair that no connection links
    │   ├── UnknownWalk             a walk (a crossing walked one way) the junction has not,
    │   │                           or a junction without crossings (the message says how
    │   │                           to add them)
    │   ├── InvalidTestCase         a test-case document that fails validation
    │   └── InvalidTrajectory       an ego trajectory (JSON or SUMO FCD) that cannot be used
    ├── UnsupportedIntersection     the junction's control type has no rule set
    ├── NoMoreComplexTestCase       an expected outcome: no extension exists for these routes
    ├── NoneFound                   an expected outcome: orderings existed, none was realised
    ├── NetworkBuildFailed          netconvert could not rebuild a network
    ├── SimulationFailed            SUMO refused or broke off a drive
    ├── ClientFault                 a co-simulated driving stack never came, left before
    │                               the end, or took the ego off its route
    └── BudgetExceeded              a solver or simulator call ran out of its time budget
        └── MemoryExceeded          a call needed more memory than a worker may use

Adapters (CLI, HTTP API, jobs) map these classes once, to exit codes or problem types.
"""

from __future__ import annotations

from collections.abc import Iterable


class ScengenError(Exception):
    """Root of every error raised by ``service.core``."""

    def __init__(self, message: str, **context: object) -> None:
        super().__init__(message)
        self.message = message
        self.context = {key: value for key, value in context.items() if value is not None}

    def __str__(self) -> str:
        return self.message

    def __reduce__(self) -> tuple[object, ...]:
        # Keep the context when an error crosses a process boundary.
        return (_rebuild_error, (type(self), self.message, self.context))


def _rebuild_error(
    cls: type[ScengenError], message: str, context: dict[str, object]
) -> ScengenError:
    return cls(message, **context)


class InvalidInput(ScengenError):
    """Raised when the caller's input is wrong; the message names the bad value."""


class UnknownNetwork(InvalidInput):
    """Raised when a network reference is neither a bundled name nor a readable file."""


class UnknownJunction(InvalidInput):
    """Raised when a junction id is not in the network, or a junction must be named."""


class UnknownLane(InvalidInput):
    """Raised when a lane id is not a fork or an exit of the intersection."""


class UnknownRoute(InvalidInput):
    """Raised when no connection of the junction links the given fork and exit."""


class UnknownWalk(InvalidInput):
    """Raised when a walk id names no crossing of the junction walked in that direction,
    or when the junction has no crossings at all (the message says how to add them)."""


class InvalidTestCase(InvalidInput):
    """Raised when a test-case document fails validation; names the bad field."""


class InvalidTrajectory(InvalidInput):
    """Raised when an ego trajectory file cannot be read or does not fit the test-case."""


class UnsupportedIntersection(ScengenError):
    """Raised when a junction's control type has no traffic-rule set."""


class NoMoreComplexTestCase(ScengenError):
    """Raised when no more complex test-case exists for the new routes (Step 2 is UNSAT or
    no new route meets the ego's); the message says which requirement could not be met."""


class NoneFound(ScengenError):
    """Raised when orderings existed but none became a verified test-case, within the budget
    or at all; the message says how many were tried and how far each got."""


class NetworkBuildFailed(ScengenError):
    """Raised when netconvert fails to rebuild a network (control-type override)."""


class SimulationFailed(ScengenError):
    """Raised when SUMO refuses a drive or the car leaves the planned route."""


class ClientFault(ScengenError):
    """Raised when the driving stack of a co-simulation (``scengen cosim``) never connects,
    leaves before the end, or takes the ego off its route: its fault, no verdict."""


class BudgetExceeded(ScengenError):
    """Raised when a solver or simulator call runs out of its time budget and is killed."""


class MemoryExceeded(BudgetExceeded):
    """Raised when a call in a worker process needs more memory than the worker's limit."""


def choices(values: Iterable[str], limit: int = 30) -> str:
    """A readable, sorted list of valid choices for an error message (long lists are cut)."""
    ordered = sorted(values)
    shown = ", ".join(ordered[:limit])
    if len(ordered) > limit:
        shown += f", ... ({len(ordered) - limit} more)"
    return shown or "(none)"
