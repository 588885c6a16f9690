"""The child-process side of bench.ssm_compare: a replay with SUMO's SSM device on
(libsumo is a per-process singleton; a module of its own, so that the child finds it by
name when the comparison runs as a script)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from service.core.sumo import run as sumo_run


def ssm_options(path: str) -> tuple[str, ...]:
    """SUMO's options that equip the ego with the SSM device and log every value."""
    return (
        "--device.ssm.explicit", "ego", "--device.ssm.measures", "TTC DRAC PET",
        "--device.ssm.thresholds", "1000 0 1000", "--device.ssm.range", "50",
        "--device.ssm.trajectories", "--device.ssm.file", path,
    )  # fmt: skip


def replay_with_ssm(
    plan_file: str, controller: dict[str, Any], ssm_file: str
) -> list[sumo_run.Row]:
    """The ego's rows of a replay (in this process: a budget child) with SSM on."""
    import libsumo

    rows, _ = sumo_run.run(libsumo, Path(plan_file), controller, extra=ssm_options(ssm_file))
    return rows
