"""The units of work an executor runs in a worker process: plain functions over core.

Each worker is a fresh process that imports only what its call needs: the generator, the
replay and the exporter (z3, clingo, the checker) are imported inside the calls that use
them, so that a description or a new test-case does not pay for them.

Arguments and results are JSON documents, paths and bytes, so that a call pickles small and
the same function can run in the local pool or on a remote worker. Every function loads the
network itself: the caller hands over the file (materialised from the store) and checks
nothing that a worker would have to repeat.
"""

from __future__ import annotations

import io
import tempfile
import time
import zipfile
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

from service.core.errors import NoneFound
from service.core.network import load_intersection
from service.core.network.describe import describe_intersection
from service.core.network.load import SUPPORTED, junction_arms, read_network
from service.core.testcase import (
    NetworkRef,
    Params,
    Signals,
    TestCase,
    dump_testcase,
    load_testcase_intersection,
    name_stem,
    new_testcase,
    parse_testcase,
    readable_name,
    renamed,
)

if TYPE_CHECKING:
    from service.core.generator.extension import Extension

T = TypeVar("T")


def list_junctions(network_file: Path) -> list[dict[str, Any]]:
    """Every junction with three or more approaches: id, control type, approaches."""
    net = read_network(network_file)
    found = []
    for node in net.getNodes():
        approaches = junction_arms(node)
        if node.getType() != "internal" and approaches >= 3:
            found.append(
                {
                    "id": str(node.getID()),
                    "type": str(node.getType()),
                    "supported": node.getType() in SUPPORTED,
                    "approaches": approaches,
                }
            )
    return sorted(found, key=lambda item: item["id"])


def check_controls(network_file: Path, controls: dict[str, str], cache_dir: Path) -> None:
    """Build every overridden junction once: an unknown junction or a control type
    netconvert cannot apply fails here, at upload, not at the first test-case."""
    read_network(network_file)
    for junction, control in sorted(controls.items()):
        load_intersection(network_file, junction, control, cache_dir)


def convert_upload(source: Path, controls: dict[str, str], cache_dir: Path) -> bytes:
    """The SUMO network of an uploaded .xodr or .osm file, after ``check_controls`` on it."""
    from service.core.network.convert import convert_network

    converted = convert_network(source, cache_dir)
    check_controls(converted, controls, cache_dir)
    return converted.read_bytes()


def describe_junction(
    network_file: Path,
    junction: str | None,
    control: str | None,
    cache_dir: Path,
    guess_crossings: bool = False,
) -> dict[str, Any]:
    """``scengen intersection --json`` of one junction."""
    description = describe_intersection(
        load_intersection(
            network_file, junction, control, cache_dir, guess_crossings=guess_crossings
        )
    )
    description.pop("network", None)  # a server-side path means nothing to a client
    return description


def junction_geometry(
    network_file: Path,
    junction: str | None,
    control: str | None,
    cache_dir: Path,
    guess_crossings: bool = False,
) -> dict[str, Any]:
    """The junction's shapes for the results browser (service.core.network.geometry)."""
    from service.core.network.geometry import junction_geometry as shapes

    return shapes(
        load_intersection(
            network_file, junction, control, cache_dir, guess_crossings=guess_crossings
        )
    )


def rule_set_laws(control: str, crosswalks: bool = True) -> list[tuple[str, str]]:
    """The rules of a control type's rule set with their CVC sections, sorted; without
    ``crosswalks``, not those about people on foot (``peopleLaw``: no test-case of a
    junction without crosswalks can test them)."""
    from service.core.checker.rules import people_laws, solve_rules
    from service.core.network import ControlType

    atoms = solve_rules(ControlType(control), [], shown=[("law", 2)])
    people = people_laws(ControlType(control))
    found = ((str(a.arguments[0]), a.arguments[1].string) for a in atoms)
    return sorted(law for law in found if crosswalks or law[0] not in people)


def plot_junction(
    network_file: Path,
    junction: str | None,
    control: str | None,
    cache_dir: Path,
    routes: list[str],
    suffix: str,
) -> bytes:
    """The junction's picture (PNG or SVG) with the given routes highlighted."""
    from service.pictures.junction import plot_intersection

    intersection = load_intersection(network_file, junction, control, cache_dir)
    for route in routes:
        intersection.route(route)  # an unknown route is an error, not an unlit line
    with tempfile.TemporaryDirectory(prefix="scengen-plot-") as folder:
        path = Path(folder) / f"junction.{suffix}"
        plot_intersection(intersection, path, highlight=routes)
        return path.read_bytes()


def create_testcase(
    network_file: Path,
    network: NetworkRef,
    cache_dir: Path,
    request: dict[str, Any],
) -> str:
    """A new ego-only test-case on a stored network; its JSON document. Without a name in
    ``request`` it gets the readable default (the network's short name from its file's)."""
    params = request.pop("params", None)
    signals = request.pop("signals", None)
    testcase = new_testcase(
        network_file,
        cache_dir=cache_dir,
        params=None if params is None else Params.model_validate(params),
        signals=None if signals is None else Signals.model_validate(signals).to_program(),
        **request,
    )
    if not testcase.name:
        testcase = renamed(testcase, readable_name(testcase, network=network_file.name))
    return dump_testcase(testcase.model_copy(update={"network": network}))


def named_extension(new: TestCase, old: TestCase, network_file: Path, stem: str | None) -> str:
    """The document of an extension of ``old``, named ``STEM level N``: by default the old
    name without its level (``... level 1`` after ``... level 0``), or for an old test-case
    without a name, the readable default."""
    return dump_testcase(renamed(new, extension_name(new, old, network_file, stem)))


def extension_name(new: TestCase, old: TestCase, network_file: Path, stem: str | None) -> str:
    """The name ``named_extension`` gives ``new``."""
    chosen = name_stem(old.name) if stem is None else stem
    return readable_name(new, chosen, network=network_file.name)


def _search_record(extension: Extension) -> dict[str, Any]:
    """What an extension's search did: its answer sets (numbered from 1) and step timings."""
    return {
        "attempts": [{"index": a.index + 1, "outcome": a.outcome} for a in extension.attempts],
        "seconds": {step: round(value, 3) for step, value in extension.seconds.items()},
    }


def extend(
    document: str,
    network_file: Path,
    cache_dir: Path,
    routes: list[str],
    seed: int,
    budget: float,
    start_distance: float | list[float | None] | None,
    deadline: float | None = None,
    walks: Sequence[str] = (),
) -> dict[str, Any]:
    """The extension of a test-case: the new document (named as ``named_extension`` says),
    the attempts and the step timings. ``start_distance`` is one for all new cars, one (or
    None) per route, or None: automatic. With ``deadline`` (a Unix time), the generator gets
    only what is left of ``budget``. ``walks``: new pedestrians, one on each."""
    from service.core.generator.extension import extend_testcase

    old = parse_testcase(document)
    intersection = load_testcase_intersection(old, cache_dir, network_file)
    extension = _within(
        budget,
        deadline,
        lambda left: extend_testcase(
            old, routes, seed, left, start_distance, intersection=intersection, walks=walks
        ),
    )
    return {
        "document": named_extension(extension.testcase, old, network_file, None),
        **_search_record(extension),
    }


def extend_variants(
    document: str,
    network_file: Path,
    cache_dir: Path,
    routes: list[str],
    count: int,
    seed: int,
    budget: float,
    start_distance: float | list[float | None] | None,
    deadline: float | None = None,
    walks: Sequence[str] = (),
) -> dict[str, Any]:
    """Up to ``count`` distinct extensions of a test-case (as ``extend`` makes one), each
    named as variant K (``variety.variant_name``): ``extensions``, each with its document,
    attempts, step timings and what tells it from the others (``difference``); and
    ``shortfall``, why fewer than ``count`` came back (None when that many did)."""
    from service.core.generator.extension import extend_testcases
    from service.core.generator.variety import describe_variants, variant_name

    old = parse_testcase(document)
    intersection = load_testcase_intersection(old, cache_dir, network_file)
    extensions = _within(
        budget,
        deadline,
        lambda left: extend_testcases(
            old,
            routes,
            count,
            seed,
            left,
            start_distance,
            intersection=intersection,
            walks=walks,
        ),
    )
    found = extensions.found
    differences = describe_variants([e.testcase for e in found])
    variants = []
    for number, (extension, difference) in enumerate(zip(found, differences, strict=True), 1):
        name = extension_name(extension.testcase, old, network_file, None)
        variant = renamed(extension.testcase, variant_name(name, number))
        variants.append(
            {"document": dump_testcase(variant), **_search_record(extension),
             "difference": difference}
        )  # fmt: skip
    return {"extensions": variants, "shortfall": extensions.shortfall(count)}


def _within(budget: float, deadline: float | None, generate: Callable[[float], T]) -> T:
    """``generate(seconds)`` with what is left of ``budget`` at ``deadline`` (a Unix time;
    None: all of it); a budget that runs out is reported as the request's whole budget."""
    left = budget if deadline is None else min(budget, deadline - time.time())
    try:
        return generate(max(0.1, left))
    except NoneFound as error:
        if left == budget or not error.context.get("budget_exhausted"):
            raise
        message = error.message.replace(f"{max(0.1, left):g} s", f"{budget:g} s", 1)
        raise NoneFound(message, **error.context) from None


def evaluate_controller(
    document: str, network_file: Path, cache_dir: Path, controller: str, budget: float
) -> dict[str, Any]:
    """A controller's verdict on a test-case (``Verdict.to_dict``), the seconds it took and
    the ego's drive (rows of t, x, y, heading, speed, distance)."""
    from service.core.sim.replay import evaluate

    testcase = parse_testcase(document)
    intersection = load_testcase_intersection(testcase, cache_dir, network_file)
    clock = time.monotonic()
    evaluation = evaluate(testcase, controller, intersection, budget)
    drive = [
        [round(value, 3) for value in (s.t, s.x, s.y, s.heading, s.speed, s.distance)]
        for s in evaluation.trajectory
    ]
    return {
        "verdict": evaluation.verdict.to_dict(),
        "seconds": time.monotonic() - clock,
        "drive": drive,
    }


def bundle(document: str, network_file: Path, cache_dir: Path) -> bytes:
    """The SUMO export of a test-case as a zip archive (one folder named after it)."""
    from service.core.export.bundle import export_bundle

    testcase = parse_testcase(document)
    intersection = load_testcase_intersection(testcase, cache_dir, network_file)
    memory = io.BytesIO()
    with tempfile.TemporaryDirectory(prefix="scengen-bundle-") as folder:
        written = export_bundle(testcase, Path(folder), intersection)
        with zipfile.ZipFile(memory, "w", zipfile.ZIP_DEFLATED) as archive:
            for path in sorted(written):
                archive.write(path, path.name)
    return memory.getvalue()


def openscenario(document: str, network_file: Path, cache_dir: Path, flavour: str) -> bytes:
    """The OpenSCENARIO export of a test-case as a zip archive: the .xodr, the .xosc files
    and the verdict rules."""
    from service.core.export.openscenario import export_openscenario

    testcase = parse_testcase(document)
    intersection = load_testcase_intersection(testcase, cache_dir, network_file)
    memory = io.BytesIO()
    with tempfile.TemporaryDirectory(prefix="scengen-openscenario-") as folder:
        written = export_openscenario(testcase, Path(folder), intersection, flavour)
        with zipfile.ZipFile(memory, "w", zipfile.ZIP_DEFLATED) as archive:
            for path in sorted(written):
                archive.write(path, path.name)
    return memory.getvalue()


def plot_testcase(
    document: str,
    network_file: Path,
    cache_dir: Path,
    suffix: str,
    controller: str | None,
    budget: float,
) -> bytes:
    """The test-case's picture; with a controller, that controller's replay and verdict."""
    from service.core.sim.replay import evaluate
    from service.pictures.plot import plot_testcase as draw

    testcase = parse_testcase(document)
    intersection = load_testcase_intersection(testcase, cache_dir, network_file)
    with tempfile.TemporaryDirectory(prefix="scengen-plot-") as folder:
        path = Path(folder) / f"testcase.{suffix}"
        if controller is None:
            draw(testcase, intersection, path)
        else:
            evaluation = evaluate(testcase, controller, intersection, budget)
            draw(
                testcase,
                intersection,
                path,
                ego=evaluation.trajectory,
                ego_label=controller,
                verdict=evaluation.verdict,
            )
        return path.read_bytes()


def extend_any(
    document: str,
    network_file: Path,
    cache_dir: Path,
    seed: int,
    budget: float,
    last: tuple[str, ...] = (),
    stem: str | None = None,
    avoid: tuple[str, ...] = (),
) -> dict[str, Any]:
    """An extension by one car on a route the service chooses (service.core.generator.chain.grow):
    the routes that conflict with the ego's or start ahead of it, from forks no car uses
    first, then from forks in use (the new car joins the queue), in an order drawn from
    ``seed`` (routes in ``last`` after the others), that differs from every test-case of
    ``avoid`` (documents); the budget only stops the call. The new test-case is named
    ``STEM level N`` (default: as ``named_extension`` says)."""
    from service.core.generator.chain import grow

    old = parse_testcase(document)
    intersection = load_testcase_intersection(old, cache_dir, network_file)
    others = [parse_testcase(other) for other in avoid]
    growth = grow(old, seed, budget, intersection, last=last, avoid=others)
    extension = growth.extension
    return {
        "document": named_extension(extension.testcase, old, network_file, stem),
        "route": growth.route,
        "attempts": [{"index": a.index + 1, "outcome": a.outcome} for a in extension.attempts],
        "seconds": {step: round(value, 3) for step, value in extension.seconds.items()},
    }


def bundles(
    sources: list[tuple[str, str, Path]], cache_dir: Path, flavour: str | None = None
) -> bytes:
    """The SUMO bundles of several test-cases in one zip, a folder per test-case id; with
    ``flavour``, their OpenSCENARIO exports in that flavour instead."""
    memory = io.BytesIO()
    with zipfile.ZipFile(memory, "w", zipfile.ZIP_DEFLATED) as archive:
        for ident, document, network_file in sources:
            content = (
                bundle(document, network_file, cache_dir)
                if flavour is None
                else openscenario(document, network_file, cache_dir, flavour)
            )
            with zipfile.ZipFile(io.BytesIO(content)) as one:
                for name in one.namelist():
                    archive.writestr(f"{ident}/{name}", one.read(name))
    return memory.getvalue()
