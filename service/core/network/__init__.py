"""The intersection model: load a SUMO network and describe one junction of it."""

from service.core.network.load import (
    bundled_networks,
    load_intersection,
    parsed_network,
    read_network,
    resolve_network,
    with_signals,
)
from service.core.network.model import (
    ConnectingLane,
    ControlType,
    Crossing,
    Exit,
    Fork,
    Intersection,
    Route,
    Turn,
    Walk,
    route_id,
    walk_id,
)
from service.core.network.override import file_sha256
from service.core.network.signals import SignalPhase, SignalProgram

__all__ = [
    "ConnectingLane",
    "ControlType",
    "Crossing",
    "Exit",
    "Fork",
    "Intersection",
    "Route",
    "SignalPhase",
    "SignalProgram",
    "Turn",
    "Walk",
    "bundled_networks",
    "file_sha256",
    "load_intersection",
    "parsed_network",
    "read_network",
    "resolve_network",
    "route_id",
    "walk_id",
    "with_signals",
]
