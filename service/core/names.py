"""Names, defaults and limits that the command line shows before it does any work, each
defined once here, in a module that imports no library (issue 49: every ``scengen`` command
paid a second of sumolib, numpy, shapely, pydantic, clingo and z3 to print its help).

The modules that use them import them from here, and re-export them where callers import
them from (``service.core.network``, ``service.core.testcase``, ...): the bundled networks,
the junction control types, the ego's automatic start, the most extensions one call asks
for and the co-simulation's waits.
"""

from __future__ import annotations

from enum import StrEnum
from pathlib import Path

from service.core.errors import UnknownNetwork

DEFAULT_START_DISTANCE = 30.0  # m: the ego's automatic start, where the road is that long
DEFAULT_START_SPEED = 8.0  # m/s: the ego's automatic start speed, where its lane allows it
MAX_COUNT = 50  # distinct extensions one call (CLI, API, batch item) asks for at most
COSIM_WAIT = 60.0  # seconds the driving stack may take to connect
REPLAY_BUDGET = 60.0  # seconds for one evaluation
COSIM_BUDGET = 600.0  # seconds the run may take once it has connected


class ControlType(StrEnum):
    """Junction control types that have a traffic-rule set (SUMO junction types)."""

    ALLWAY_STOP = "allway_stop"
    PRIORITY = "priority"
    PRIORITY_STOP = "priority_stop"
    RIGHT_BEFORE_LEFT = "right_before_left"
    TRAFFIC_LIGHT = "traffic_light"
    TRAFFIC_LIGHT_RIGHT_ON_RED = "traffic_light_right_on_red"

    @property
    def signalized(self) -> bool:
        """Traffic lights control the junction (its program is part of the test-case)."""
        return self in (ControlType.TRAFFIC_LIGHT, ControlType.TRAFFIC_LIGHT_RIGHT_ON_RED)

    @property
    def rule_set(self) -> str:
        """The name of the rule set (asp/rules/NAME.lp): both signal types share one, the
        program's colours (``s``: right on red) say what each lane may do."""
        return "traffic_light" if self.signalized else self.value


def bundled_networks_dir() -> Path:
    """``sumo_nets/``: inside the installed package, or beside it in a source checkout."""
    package = Path(__file__).resolve().parents[1]
    for candidate in (package / "sumo_nets", package.parent / "sumo_nets"):
        if candidate.is_dir():
            return candidate
    raise UnknownNetwork("the bundled networks (sumo_nets/) are missing from this installation")


def bundled_networks() -> dict[str, Path]:
    """Short name -> path of every bundled network."""
    return {
        path.name.removesuffix(".net.xml"): path
        for path in sorted(bundled_networks_dir().glob("*.net.xml"))
    }
