"""Ego controllers: who drives the ego in a replay.

Built-in controllers are SUMO's own driver model and variants of it (the ego is then an
ordinary SUMO vehicle that sees the replayed non-egos), and the two certificates (replayed
like a non-ego). User controllers implement a small protocol: every step they get what the
ego can observe and return a longitudinal command (an acceleration); the route is fixed by
the test-case. They are named ``module:attribute`` (a class or a factory called with no
arguments) or registered under the entry-point group ``scengen.controllers``.

``NAME+rss`` guards SUMO's drivers and user controllers with Responsibility-Sensitive
Safety (service.core.sumo.rss_guard): the wrapped driver's acceleration is restricted to
RSS's proper response every step. Certificates are replays, not drivers: they take no guard.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from importlib.metadata import entry_points
from typing import Any, Protocol, runtime_checkable

from service.core.errors import InvalidInput
from service.core.sumo.rss_guard import RSS_SUFFIX

ENTRY_POINT_GROUP = "scengen.controllers"
LEADER_LOOKAHEAD = 100.0  # metres ahead of the ego's front within which a leader is reported


@dataclass(frozen=True)
class SumoDriver:
    """SUMO's driver model with deterministic settings and named variants.

    ``speed_mode``: SUMO's bit set (31: every check; 23: no right-of-way).
    ``stop_sign_wait``: seconds SUMO's driver waits at a stop line (``jmStopSignWait``).
    ``rolling_speed``: when set, the ego never goes below this speed between arriving at
    the fork and entering the junction (it does not come to a full stop)."""

    name: str
    about: str
    speed_mode: int = 31
    stop_sign_wait: float = 1.0
    rolling_speed: float | None = None


@dataclass(frozen=True)
class CertificateDriver:
    """Replays one of the test-case's certificates."""

    name: str
    about: str
    certificate: str  # "solvability" or "complexity"


@dataclass(frozen=True)
class UserDriver:
    """A user controller, loaded in the replay process by its reference."""

    name: str
    reference: str  # module:attribute


@dataclass(frozen=True)
class GuardedDriver:
    """A SUMO driver or a user controller under the RSS guard (``NAME+rss``)."""

    name: str
    inner: SumoDriver | UserDriver


Driver = SumoDriver | CertificateDriver | UserDriver | GuardedDriver

BUILT_IN: dict[str, SumoDriver | CertificateDriver] = {
    driver.name: driver
    for driver in (
        SumoDriver("sumo", "SUMO's default driver model, no randomness"),
        SumoDriver(
            "sumo-cautious",
            "SUMO's driver waiting 3 s at every stop line",
            stop_sign_wait=3.0,
        ),
        SumoDriver(
            "sumo-rolling-stop",
            "SUMO's driver that rolls through stop signs at 3 m/s instead of stopping",
            rolling_speed=3.0,
        ),
        SumoDriver(
            "sumo-aggressive",
            "SUMO's driver keeping safe speeds behind cars ahead but ignoring right-of-way",
            speed_mode=23,
        ),
        CertificateDriver(
            "certificate:solvability", "replays the solvability certificate", "solvability"
        ),
        CertificateDriver(
            "certificate:complexity", "replays the complexity certificate", "complexity"
        ),
    )
}


@dataclass(frozen=True)
class Vehicle:
    """What the ego sees of one car (itself included): centre, heading, speed."""

    id: str
    x: float
    y: float
    heading: float  # degrees clockwise from north
    speed: float
    length: float
    width: float


@dataclass(frozen=True)
class Leader:
    """The nearest car ahead of the ego on the lanes of its route (the lanes SUMO drives
    it on, internal lanes included), front or rear on one of them."""

    id: str
    gap: float  # metres from the ego's front bumper to the leader's rear bumper
    speed: float  # m/s


@dataclass(frozen=True)
class Observation:
    """Everything a user controller is told at one step."""

    t: float  # seconds since the start
    timestep: float
    ego: Vehicle
    distance: float  # metres the ego has travelled along its route
    to_stop_line: float  # metres from the ego's front to its stop line (negative: past it)
    lane: str  # the SUMO lane the ego is on
    others: tuple[Vehicle, ...]  # every non-ego on the map
    a_min: float  # the bounds the command is clipped to (m/s^2)
    a_max: float
    v_max: float
    leader: Leader | None = None  # within LEADER_LOOKAHEAD metres; None: nobody ahead
    signal: str | None = None  # the SUMO colour of the ego's link at a signalized junction
    # (G protected green, g permissive green, y yellow, r red, u red-yellow, s right on red
    # after a stop), as SUMO shows it at this step; None: the ego's route has no signal
    pedestrians: tuple[Vehicle, ...] = ()  # every pedestrian on the map, as ``Vehicle``s:
    # the centre of her rectangle, her walking direction, speed, length and width (last,
    # and empty without pedestrians, so that controllers written before them still work)


@runtime_checkable
class Controller(Protocol):
    """A user controller: ``step`` returns the ego's acceleration for the next step (m/s^2).

    The command is clipped to [a_min, a_max] and the speed to [0, v_max]."""

    def step(self, observation: Observation) -> float: ...


def controller_names() -> list[str]:
    """Every name ``resolve_driver`` accepts besides ``module:attribute`` (and
    ``module:attribute+rss``): the built-in and registered controllers, and each of them
    but the certificates guarded (``NAME+rss``)."""
    plain = sorted(BUILT_IN) + sorted(e.name for e in entry_points(group=ENTRY_POINT_GROUP))
    guarded = [name + RSS_SUFFIX for name in plain if not name.startswith("certificate:")]
    return plain + guarded


def resolve_driver(name: str) -> Driver:
    """The driver called ``name``: built-in, registered entry point, or module:attribute;
    with ``+rss`` the same under the RSS guard (not a certificate)."""
    if name.endswith(RSS_SUFFIX):
        inner = resolve_driver(name.removesuffix(RSS_SUFFIX))
        if isinstance(inner, CertificateDriver | GuardedDriver):
            why = "twice" if isinstance(inner, GuardedDriver) else "(a certificate is a replay)"
            guarded = [n for n in controller_names() if n.endswith(RSS_SUFFIX)]
            raise InvalidInput(
                f"controller {name!r}: {inner.name} cannot be guarded {why}; guarded "
                f"controllers: {', '.join(guarded)}, or module:attribute+rss",
                choices=controller_names(),
            )
        return GuardedDriver(name, inner)
    if name in BUILT_IN:
        return BUILT_IN[name]
    for entry in entry_points(group=ENTRY_POINT_GROUP):
        if entry.name == name:
            return UserDriver(name, entry.value)
    module, colon, attribute = name.partition(":")
    if colon and module and attribute and module != "certificate":
        return UserDriver(name, name)
    raise InvalidInput(
        f"unknown controller {name!r}; valid: {', '.join(controller_names())}, "
        "or a user controller as module:attribute (module:attribute+rss under the RSS guard)",
        choices=controller_names(),
    )


def load_user_controller(reference: str) -> Controller:
    """Import ``module:attribute`` and make the controller (call it when it is a class or
    a factory). Errors name the reference."""
    module_name, _, attribute = reference.partition(":")
    try:
        target: Any = importlib.import_module(module_name)
        for part in attribute.split("."):
            target = getattr(target, part)
    except (ImportError, AttributeError) as exc:
        raise InvalidInput(f"cannot load controller {reference!r}: {exc}") from exc
    if isinstance(target, type) or (callable(target) and not hasattr(target, "step")):
        try:
            controller = target()
        except Exception as exc:
            raise InvalidInput(f"cannot make controller {reference!r}: {exc}") from exc
    else:
        controller = target
    if not isinstance(controller, Controller):
        raise InvalidInput(
            f"controller {reference!r} has no step(observation) method returning an acceleration"
        )
    return controller
