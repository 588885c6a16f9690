"""Architecture rules: the layers of docs/architecture.md, no import circles, a core free of web,
queue and settings code, public surfaces."""

from __future__ import annotations

import ast
import graphlib
import importlib
import subprocess
import sys
from collections.abc import Collection, Sequence
from pathlib import Path

import pytest

import service.core.network as network
import service.core.testcase as testcase

ROOT = Path(__file__).parents[1]
PACKAGE = ROOT / "service"
ARCHITECTURE = ROOT / "docs" / "architecture.md"
LAYERS_MARK = "<!-- layers: read by tests/test_boundaries.py"


def layers() -> list[list[str]]:
    """The units of each floor, bottom first, from docs/architecture.md's layer list."""
    text = ARCHITECTURE.read_text()
    block = text[text.index(LAYERS_MARK) :].split("```")[1]
    floors = [line.split() for line in block.splitlines()[1:] if line.strip()]
    assert [int(floor[0]) for floor in floors] == list(range(1, len(floors) + 1))
    return [floor[1:] for floor in floors]


def modules() -> dict[str, Path]:
    """Every module of the package by its dotted name (a package by its ``__init__``)."""
    found = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = path.relative_to(ROOT).with_suffix("").parts
        found[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return found


def imports_of(path: Path, known: Collection[str]) -> set[str]:
    """The modules of ours that a file imports, wherever the import statement stands."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found |= {alias.name for alias in node.names if alias.name.startswith("service")}
        elif isinstance(node, ast.ImportFrom) and (node.module or "").startswith("service"):
            assert node.level == 0, f"{path}: a relative import"
            for alias in node.names:  # `from package import module` names the module
                name = f"{node.module}.{alias.name}"
                found.add(name if name in known else str(node.module))
    unknown = found - set(known)
    assert not unknown, f"{path} imports what is not a module of ours: {sorted(unknown)}"
    return found


def unit_of(module: str, floors: Sequence[Sequence[str]]) -> tuple[int, str] | None:
    for floor, units in enumerate(floors):
        for unit in units:
            if module == unit or module.startswith(unit + "."):
                return floor, unit
    return None


def import_graph() -> dict[str, set[str]]:
    known = modules()
    return {module: imports_of(path, known) for module, path in known.items()}


def fresh_interpreter(code: str) -> str:
    """What ``code`` prints in a new Python process (none of this one's imports)."""
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    )
    return result.stdout.strip()


FORBIDDEN = (
    "fastapi", "uvicorn", "starlette", "celery", "redis", "pydantic_settings", "sqlalchemy",
)  # fmt: skip


def test_core_imports_no_adapter_libraries() -> None:
    """Every module of the core, imported in a fresh interpreter, loads no web, queue or
    settings library (directly or through anything it imports)."""
    core = [module for module in modules() if module.startswith("service.core")]
    code = (
        f"import importlib, sys; [importlib.import_module(m) for m in {core!r}]; "
        f"print([m for m in {FORBIDDEN!r} if m in sys.modules])"
    )
    assert fresh_interpreter(code) == "[]"


def test_worker_tasks_import_no_web_code() -> None:
    """A worker process (local pool or remote) loads the core, not the web stack."""
    code = (
        "import sys, service.jobs.tasks, service.jobs.executor; "
        "print([m for m in ('fastapi', 'uvicorn', 'starlette') if m in sys.modules])"
    )
    assert fresh_interpreter(code) == "[]"


def test_core_does_not_import_libsumo_outside_a_drive() -> None:
    code = (
        "import sys, service.core.motion.poses, service.core.motion.events; "
        "print('libsumo' in sys.modules)"
    )
    assert fresh_interpreter(code) == "False"


def test_network_public_surface_is_complete() -> None:
    public = {name for name in vars(network) if not name.startswith("_")}
    # its modules, which become attributes once anything imports them
    submodules = {path.stem for path in Path(network.__file__).parent.glob("*.py")}
    assert set(network.__all__) == public - submodules


def test_testcase_public_surface_is_complete() -> None:
    """The test-case package re-exports every public name its modules define (not those
    they import), so that callers import from ``service.core.testcase`` whichever module
    holds a name."""
    submodules = {"model", "document", "network_path", "make"}
    public = {name for name in vars(testcase) if not name.startswith("_")}
    assert set(testcase.__all__) == public - submodules
    defined = set()
    for name in submodules:
        path = PACKAGE / "core" / "testcase" / f"{name}.py"
        body = ast.parse(path.read_text()).body
        imported = {
            (alias.asname or alias.name).split(".")[0]
            for node in body
            if isinstance(node, ast.Import | ast.ImportFrom)
            for alias in node.names
        }
        module = importlib.import_module(f"service.core.testcase.{name}")
        defined |= {n for n in vars(module) if not n.startswith("_") and n not in imported}
    assert defined == set(testcase.__all__)


ROOTS = {"service", "service.core"}  # namespaces: docstrings only, no floor of their own


def test_every_module_has_a_floor() -> None:
    floors = layers()
    placed = {module: unit_of(module, floors) for module in modules()}
    assert [m for m, unit in placed.items() if unit is None] == sorted(ROOTS)
    units = {unit for floor in floors for unit in floor}
    used = {unit[1] for unit in placed.values() if unit is not None}
    assert units == used, f"docs/architecture.md names units that are gone: {units - used}"


def test_no_import_runs_up_a_layer_or_across_a_floor() -> None:
    floors = layers()
    wrong = []
    for module, imported in import_graph().items():
        if module in ROOTS:
            assert not imported, f"{module} is a namespace and imports {imported}"
            continue
        here = unit_of(module, floors)
        assert here is not None
        for other in sorted(imported):
            there = unit_of(other, floors)
            assert there is not None, f"{module} imports the namespace {other}"
            if there[1] != here[1] and there[0] >= here[0]:
                way = "up" if there[0] > here[0] else "across"
                wrong.append(f"{module} (floor {here[0] + 1}) imports {other} "
                             f"(floor {there[0] + 1}): {way}")  # fmt: skip
    assert not wrong, "imports against docs/architecture.md's layers:\n" + "\n".join(wrong)


def test_no_import_runs_in_a_circle() -> None:
    try:
        graphlib.TopologicalSorter(import_graph()).prepare()
    except graphlib.CycleError as circle:
        chain = " -> ".join(reversed(circle.args[1]))
        pytest.fail(f"modules that import each other (each imports the next): {chain}")
