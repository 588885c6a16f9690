"""Where SUMO's programs are: the installed eclipse-sumo wheel first, then $SUMO_HOME/bin,
else the PATH (the lookup of the standalone runner, service.core.sumo.run)."""

from __future__ import annotations

from service.core.errors import ScengenError
from service.core.sumo.run import RunFailed, find_program


def sumo_binary(name: str) -> str:
    """The path of a SUMO program (``sumo``, ``netconvert``, ...)."""
    try:
        return find_program(name)
    except RunFailed as exc:
        raise ScengenError(str(exc)) from None
