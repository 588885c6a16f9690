"""Starting ``scengen`` costs little (issue 49): building the parser, ``--version``,
``--help``, each command's ``--help`` and a usage error load none of the heavy libraries
(SUMO's, numpy, shapely, the solvers, pydantic and the core's models, the web and queue
stacks). Each case runs ``service.cli.main`` in a fresh interpreter, which then says what it
has imported: a check of imports, not of seconds."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from service.cli.commands import COMMANDS

HEAVY = (
    "sumolib", "libsumo", "traci", "numpy", "shapely", "clingo", "z3", "highspy",
    "pydantic", "matplotlib", "fastapi", "starlette", "uvicorn", "celery", "sqlalchemy",
    "yaml", "tqdm", "scenariogeneration",
    "service.core.network", "service.core.testcase", "service.core.generator.extension",
    "service.core.checker.check", "service.core.sim.replay",
    "service.api", "service.jobs", "service.settings", "service.store", "service.pictures",
)  # fmt: skip
MARK = "--imported--"
IN_CHILD = "--as-the-child"  # the probe runs the command as the command's child does
PROBE = f"""
import json, os, sys
from service.cli import main
from service.cli.commands import run_command
try:
    if sys.argv[1:2] == [{IN_CHILD!r}]:
        code, _ = run_command(dict(argv=sys.argv[2:], cwd=os.getcwd(), environ=dict(os.environ),
                                   ttys=(False, False), columns=80))
    else:
        code = main(sys.argv[1:])
except SystemExit as stop:
    code = stop.code
sys.stdout.flush()
print({MARK!r}, json.dumps([code, [m for m in {HEAVY!r} if m in sys.modules]]))
"""


def start(*argv: str) -> tuple[int, list[str], str, str]:
    """``scengen ARGV`` in a fresh interpreter: its exit code, the heavy modules it imported,
    its stdout (without the probe's line; the help unwrapped) and stderr."""
    run = subprocess.run(
        [sys.executable, "-c", PROBE, *argv], capture_output=True, text=True, timeout=120,
        env={**os.environ, "COLUMNS": "10000"},
    )  # fmt: skip
    out, _, said = run.stdout.rpartition(MARK)
    assert said, f"no answer: {run.stderr}"
    code, loaded = json.loads(said)
    return code, loaded, out, run.stderr


def test_version_loads_nothing_heavy() -> None:
    code, loaded, out, _ = start("--version")
    assert code == 0 and loaded == []
    assert out.startswith("scengen ") and "(SUMO " in out


def test_help_loads_nothing_heavy() -> None:
    code, loaded, out, _ = start("--help")
    assert code == 0 and loaded == []
    assert all(entry.name in out for entry in COMMANDS)


@pytest.mark.parametrize("name", [entry.name for entry in COMMANDS])
def test_a_commands_help_loads_nothing_heavy(name: str) -> None:
    code, loaded, out, _ = start(name, "--help")
    assert code == 0 and loaded == []
    assert out.startswith(f"usage: scengen {name}")


def test_the_help_names_what_the_core_offers() -> None:
    """The choices and lists the help shows come from the core's light modules, exact."""
    from service.core.names import ControlType, bundled_networks
    from service.core.sim.controllers import controller_names

    _, _, new, _ = start("new", "--help")
    assert f"bundled network ({', '.join(bundled_networks())})" in new
    assert f"netconvert: {', '.join(c.value for c in ControlType)}" in new
    _, _, _, refused = start("new", "4way-stop", "--ego", "a:b", "--control", "roundabout")
    assert f"(choose from {', '.join(repr(c.value) for c in ControlType)})" in refused
    _, _, evaluate, _ = start("evaluate", "--help")
    assert f"Controllers: {', '.join(controller_names())}, or" in evaluate


@pytest.mark.parametrize(
    "argv, says",
    [
        ((), "the following arguments are required: COMMAND"),
        (("nosuch",), "invalid choice: 'nosuch'"),
        (("new", "4way-stop"), "the following arguments are required: --ego"),
        (("new", "4way-stop", "--ego", "a:b", "--control", "roundabout"), "invalid choice"),
        (("extend", "old.json", "--count", "51"), "a whole number of extensions from 1 to 50"),
        (("example", "nosuch"), "invalid choice: 'nosuch'"),
        (("export", "t.json", "-o", "d", "--flavour", "x"), "invalid choice: 'x'"),
    ],
)
def test_a_usage_error_loads_nothing_heavy(argv: tuple[str, ...], says: str) -> None:
    code, loaded, _, err = start(*argv)
    assert code == 2 and loaded == []
    assert says in err.splitlines()[-1]


def test_a_command_that_works_loads_nothing_heavy_either() -> None:
    """Its work runs in the command's child (service.cli.budgeted)."""
    code, loaded, out, _ = start("intersection", "4way-stop", "--json")
    assert code == 0 and json.loads(out)["junction"] == "C"
    assert loaded == []


def test_the_probe_sees_a_command_that_loads_the_network() -> None:
    """The checks above are not blind: the command's work, run where the child runs it,
    loads what it needs."""
    code, loaded, out, _ = start(IN_CHILD, "intersection", "4way-stop", "--json")
    assert code == 0 and json.loads(out)["junction"] == "C"
    assert {"sumolib", "service.core.network"} <= set(loaded)
