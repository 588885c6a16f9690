"""Where SUMO's programs are: the installed eclipse-sumo wheel first, else the PATH."""

from __future__ import annotations

import shutil
from pathlib import Path

from service.core.errors import ScengenError


def sumo_binary(name: str) -> str:
    """The path of a SUMO program (``sumo``, ``netconvert``, ...)."""
    try:
        import sumo  # the eclipse-sumo wheel

        candidate = Path(sumo.SUMO_HOME) / "bin" / name
        if candidate.exists():
            return str(candidate)
    except ImportError:
        pass
    found = shutil.which(name)
    if found is None:
        raise ScengenError(f"{name} not found: install eclipse-sumo (pip install eclipse-sumo)")
    return found
