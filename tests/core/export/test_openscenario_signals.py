"""The OpenSCENARIO export at signalized junctions: the TrafficSignalController shows SUMO's
colour of every signalized route at every moment (offsets, cut phases, both flavours), every
signalized fork lane has its heads in the OpenDRIVE network, both ASAM checkers find no
issue, and an export without signals keeps netconvert's bytes (real netconvert, real
checkers, real generated test-cases)."""

from __future__ import annotations

import json
import math
import re
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import pytest

from service.core.export.openscenario import export_openscenario
from service.core.export.openscenario_signals import STATE_WORDS, controller_phases, head_id
from service.core.generator.extension import extend_testcase
from service.core.network import Intersection, parsed_network
from service.core.network.override import run_netconvert
from service.core.network.signals import make_program
from service.core.testcase import (
    TestCase,
    dump_testcase,
    load_testcase_intersection,
    new_testcase,
    parse_testcase,
)
from tests.core.export.test_openscenario import _issues

SKEWED = Path(__file__).parents[2] / "data" / "junctions" / "skewed-signal.net.xml"
# CARLA's SignalType::IsTrafficLight
CARLA_LIGHTS = {"1000001", "1000002", "1000007", "1000008", "1000009", "1000010", "1000011",
                "1000012", "1000013", "1000014", "1000015", "1000016", "1000017", "1000018",
                "1000019", "1000020"}  # fmt: skip


def _index_at(durations: Sequence[float], t: float) -> int:
    """Which phase a controller of ``durations`` shows at ``t``: OpenSCENARIO's reading,
    the first phase from simulation time 0 (no delay: no reference), then cyclic."""
    position = t % sum(durations)
    for k, duration in enumerate(durations):
        if position < duration:
            return k
        position -= duration
    return len(durations) - 1


@pytest.mark.parametrize("offset", [0.0, 7.0, -3.0, 12.0, 25.0, 31.5, 8.25, 1e-7, -1e-7, 1e5])
def test_the_controller_cycle_starts_where_sumo_stands_at_zero(offset: float) -> None:
    """Run from t = 0, the controller's phases give every link SUMO's colour at
    (t - offset) mod cycle, with a phase cut at t = 0 (or none, on a boundary)."""
    program = make_program(
        "C", "p", offset, [(10, "Grsu"), (2, "yrsr"), (0.5, "rrrr"), (12.5, "rGgy")]
    )
    phases = controller_phases(program)
    assert sum(p.duration for p in phases) == pytest.approx(program.cycle, abs=1e-6)
    assert len({p.name for p in phases}) == len(phases)
    assert len(phases) in (len(program.phases), len(program.phases) + 1)
    durations = [p.duration for p in phases]
    for step in range(3 * 25 * 20):  # three cycles, every 0.05 s
        t = step / 20 + 0.013  # off the boundaries, where a microsecond of rounding shows
        state = phases[_index_at(durations, t)].state
        assert [program.colour(k, t) for k in range(program.links)] == list(state), t


@dataclass(frozen=True)
class Export:
    """A signalized test-case exported in one flavour."""

    name: str
    testcase: TestCase
    intersection: Intersection
    flavour: str
    folder: Path


def _red_yellow(testcase: TestCase) -> TestCase:
    """``testcase`` under its program with red-yellow before each green and an offset
    that cuts a phase: every SUMO colour but none of the bundled programs has u."""
    document = json.loads(dump_testcase(testcase))
    signals = document["signals"]
    signals["offset"] = 5.5
    for k, phase in enumerate(signals["phases"]):
        after = signals["phases"][(k + 1) % len(signals["phases"])]["state"]
        if phase["duration"] <= 1:  # the all-red before a green: red-yellow where it comes
            phase["state"] = "".join(
                "u" if c == "r" and n in "Gg" else c
                for c, n in zip(phase["state"], after, strict=True)
            )
    return parse_testcase(json.dumps(document))


@pytest.fixture(scope="module")
def exports(tmp_path_factory: pytest.TempPathFactory) -> list[Export]:
    """4way-signal with a new car and certificates (both flavours), skewed-signal (offset
    10 s, a leading protected left, permissive lefts) with a new car, and an ego-only
    t-signal (right on red) under a program with red-yellow and offset 5.5 s (both
    flavours)."""
    four_way = new_testcase("4way-signal", "S2C_1:C2W_1", duration=45)
    skewed = new_testcase(str(SKEWED), "SSW2C_0:C2N_0", duration=45)
    cases = {
        "4way-signal": extend_testcase(four_way, ["N2C_1:C2S_1"], seed=0, budget=120).testcase,
        "skewed-signal": extend_testcase(skewed, ["N2C_0:C2ENE_0"], seed=0, budget=120).testcase,
        "t-signal": _red_yellow(new_testcase("t-signal", "S2C_0:C2E_0", duration=30)),
    }
    out = []
    for name, case in cases.items():
        intersection = load_testcase_intersection(case)
        for flavour in ("asam", "carla") if name != "skewed-signal" else ("asam",):
            folder = tmp_path_factory.mktemp(f"{name}-{flavour}")
            export_openscenario(case, folder, intersection, flavour)
            out.append(Export(name, case, intersection, flavour, folder))
    return out


def _controller(root: ET.Element) -> ET.Element:
    controllers = root.findall("RoadNetwork/TrafficSignals/TrafficSignalController")
    assert len(controllers) == 1
    return controllers[0]


def test_the_controller_shows_sumo_colours_on_every_signalized_route(
    exports: list[Export],
) -> None:
    """Every scenario file (certificates and CARLA's too): one controller, named after the
    traffic light, without delay or reference, whose phases sum to the cycle and whose
    states, run from t = 0, show each signalized route SUMO's colour (in the flavour's
    words; SignalProgram.colour is SUMO's, tests/core/sim/test_replay_signals.py) over two
    cycles, longer than the test-case, every 0.1 s and either side of every change."""
    checked = 0
    for export in exports:
        program = export.testcase.signals
        assert program is not None
        sumo = program.to_program()
        routes = [r for r in export.intersection.routes.values() if r.link_index >= 0]
        assert len(routes) == export.intersection.tls_links
        assert 2 * sumo.cycle > export.testcase.duration
        changes = [i.start for i in sumo.instances(2 * sumo.cycle)]
        times = [k / 10 + 0.01 for k in range(int(20 * sumo.cycle))]
        times += [t + d for t in changes for d in (-1e-3, 1e-3) if t + d >= 0]
        scenarios = sorted(export.folder.glob("testcase*.xosc"))
        assert len(scenarios) == (3 if export.testcase.certificates is not None else 1)
        for scenario in scenarios:
            controller = _controller(ET.parse(scenario).getroot())
            assert controller.get("name") == sumo.tls
            assert controller.get("delay") is None and controller.get("reference") is None
            phases = controller.findall("Phase")
            durations = [float(p.get("duration", "nan")) for p in phases]
            assert sum(durations) == pytest.approx(sumo.cycle, abs=1e-6)
            states = [
                {s.get("trafficSignalId"): s.get("state") for s in p.iter("TrafficSignalState")}
                for p in phases
            ]
            for t in times:
                shown = states[_index_at(durations, t)]
                for route in routes:
                    word = STATE_WORDS[export.flavour][sumo.colour(route.link_index, t)]
                    assert shown[head_id(sumo.tls, route.link_index)] == word, (export.name, t)
                    checked += 1
    assert checked > 50_000


def test_colour_words_follow_the_flavour(exports: list[Export]) -> None:
    """G and g green, y yellow, r and s red; u red;yellow, and red for CARLA (no
    red-yellow light): in the scenario and in verdict-rules.md."""
    for export in exports:
        root = ET.parse(export.folder / "testcase.xosc").getroot()
        words = {s.get("state") for s in root.iter("TrafficSignalState")}
        rules = (export.folder / "verdict-rules.md").read_text()
        if export.name == "t-signal":  # every colour: G, g, y, r, u, s
            red_yellow = "red" if export.flavour == "carla" else "red;yellow"
            assert words == {"green", "yellow", "red"} | {red_yellow}
            assert f"- `u` red-yellow (red; green follows): `{red_yellow}`" in rules
        assert "- `s` red on which a right turn may go after a full stop: `red`" in rules
        assert "California Vehicle Code 21451 to 21453 (`asp/laws/cvc2145*.lp`)" in rules
        # the rule set's summary without the rest of its three-line title
        assert "`asp/rules/traffic_light.lp`:\n\n    21451 (a)  circular green" in rules
        tls = export.intersection.tls
        for route in export.intersection.routes.values():
            assert f"- `{head_id(str(tls), route.link_index)}`: `{route.id}`" in rules


def test_every_signalized_fork_lane_has_its_heads(exports: list[Export]) -> None:
    """In testcase.xodr, every link of the traffic light is a head (a traffic light to
    CARLA) on the road of its fork, at its end (the stop line), valid on the fork's lane;
    the controller lists the heads, the junction names the controller, and every signal a
    TrafficSignalState names is one of them."""
    for export in exports:
        if export.flavour != "asam":
            continue
        root = ET.parse(export.folder / "testcase.xodr").getroot()
        net = parsed_network(export.intersection.network_file)
        tls = export.intersection.tls
        assert tls is not None
        junction = next(
            j for j in root.iter("junction") if j.get("name") == export.intersection.junction
        )
        assert [c.get("id") for c in junction.findall("controller")] == [tls]
        controller = next(c for c in root.findall("controller") if c.get("id") == tls)
        listed = {c.get("signalId") for c in controller.iter("control")}
        heads = {}
        for road in root.iter("road"):
            for signal in road.iter("signal"):
                heads[signal.get("id")] = (road, signal)
        routes = [r for r in export.intersection.routes.values() if r.link_index >= 0]
        forks = {r.fork for r in routes}
        assert forks == set(export.intersection.forks)  # every fork lane has a signal
        for route in routes:
            name = head_id(tls, route.link_index)
            assert name in listed
            road, signal = heads[name]
            lane = net.getLane(route.fork)
            edge = lane.getEdge()
            successor = road.find("link/successor")
            assert successor is not None and successor.get("elementId") == junction.get("id")
            assert _starts_at_left_border(road, edge)
            assert float(signal.get("s", "nan")) == pytest.approx(float(road.get("length", 0)))
            ids = {(v.get("fromLane"), v.get("toLane")) for v in signal.iter("validity")}
            opendrive_lane = str(lane.getIndex() - edge.getLaneNumber())
            assert (opendrive_lane, opendrive_lane) in ids
            assert signal.get("dynamic") == "yes" and signal.get("type") in CARLA_LIGHTS
        scenario = ET.parse(export.folder / "testcase.xosc").getroot()
        named = {s.get("trafficSignalId") for s in scenario.iter("TrafficSignalState")}
        assert named == listed and named <= set(heads)


def _starts_at_left_border(road: ET.Element, edge: object) -> bool:
    """netconvert's road for a SUMO edge starts at the edge's left border."""
    left = max(edge.getLanes(), key=lambda lane: lane.getIndex())  # type: ignore[attr-defined]
    (x0, y0), (x1, y1) = left.getShape()[:2]
    norm = math.hypot(x1 - x0, y1 - y0)
    half = left.getWidth() / 2
    start = (x0 - (y1 - y0) / norm * half, y0 + (x1 - x0) / norm * half)
    first = road.find("planView/geometry")
    assert first is not None
    return math.dist(start, (float(first.get("x", 0)), float(first.get("y", 0)))) < 0.5


QC_FILES = [
    ("4way-signal", "asam", "testcase.xodr"),
    ("4way-signal", "asam", "testcase.xosc"),
    ("4way-signal", "asam", "testcase.solvability.xosc"),
    ("4way-signal", "carla", "testcase.xosc"),
    ("skewed-signal", "asam", "testcase.xodr"),
    ("skewed-signal", "asam", "testcase.xosc"),
    ("t-signal", "asam", "testcase.xosc"),
    ("t-signal", "carla", "testcase.xosc"),
]


@pytest.mark.parametrize(("name", "flavour", "file"), QC_FILES)
def test_signalized_exports_pass_the_asam_quality_checkers(
    name: str, flavour: str, file: str, exports: list[Export]
) -> None:
    """Both bundles, their XSD schema checks included (OpenSCENARIO 1.2 and CARLA's 1.0):
    no issue. The complexity certificate's file differs from the solvability one only in
    the ego's trajectory."""
    export = next(e for e in exports if (e.name, e.flavour) == (name, flavour))
    assert _issues(file.rpartition(".")[2], export.folder / file) == []


def test_the_same_signalized_test_case_gives_the_same_bytes(
    exports: list[Export], tmp_path: Path
) -> None:
    export = next(e for e in exports if e.name == "4way-signal" and e.flavour == "asam")
    export_openscenario(export.testcase, tmp_path, export.intersection, export.flavour)
    names = sorted(p.name for p in export.folder.iterdir())
    assert names == sorted(p.name for p in tmp_path.iterdir())
    for name in names:
        assert (tmp_path / name).read_bytes() == (export.folder / name).read_bytes(), name


def test_an_export_without_signals_keeps_netconverts_bytes(tmp_path: Path) -> None:
    """Where there is nothing to add (no stop line, no traffic light), testcase.xodr is
    netconvert's file (as scengen runs it) with the two header edits, byte for byte; the
    scenario has no TrafficSignals and the rules no signals section."""
    case = new_testcase("y-uncontrolled", "SW2C_0:C2N_0")
    intersection = load_testcase_intersection(case)
    export_openscenario(case, tmp_path / "osc", intersection)
    plain_file = tmp_path / "plain.xodr"
    arguments = ["--sumo-net-file", str(intersection.network_file), "--opendrive-output"]
    assert run_netconvert([*arguments, str(plain_file)], plain_file, "write OpenDRIVE") is None
    plain = plain_file.read_text()
    plain = plain.replace('<header revMajor="1" revMinor="4"', '<header revMajor="1" revMinor="5"')
    plain = re.sub(r' date="[^"]*"', ' date="2026-01-01T00:00:00"', plain, count=1)
    assert (tmp_path / "osc" / "testcase.xodr").read_text() == plain
    root = ET.parse(tmp_path / "osc" / "testcase.xosc").getroot()
    assert root.find("RoadNetwork/TrafficSignals") is None
    assert "## Signals" not in (tmp_path / "osc" / "verdict-rules.md").read_text()
