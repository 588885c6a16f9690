"""The OpenSCENARIO and OpenDRIVE export: the ASAM Quality Checker bundles find no issue in
any exported file, the non-egos' polylines give back their trajectories, the conventions
(heading, reference point, bounding box) hold, and the OpenDRIVE network read back by
netconvert is the same junction (real netconvert, real checkers, no mocks)."""

from __future__ import annotations

import itertools
import math
import subprocess
import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
from shapely.geometry import Point

from service.core.checker.check import check_testcase
from service.core.export.openscenario import angle_of, export_openscenario, heading_of
from service.core.motion.poses import PoseSample, interpolate_heading
from service.core.network import Intersection, load_intersection
from service.core.sumo.binaries import sumo_binary
from service.core.testcase import Sample, TestCase, load_testcase_intersection

pytestmark = pytest.mark.slow  # 14 s of work or more: `make test-fast` leaves it out

CENTIMETRE = 0.01


@pytest.mark.parametrize(
    ("angle", "heading"),
    [
        (0.0, math.pi / 2),
        (90.0, 0.0),
        (180.0, 3 * math.pi / 2),
        (270.0, math.pi),
        (45.0, math.pi / 4),
    ],
)
def test_headings_turn_from_sumo_to_openscenario_and_back(angle: float, heading: float) -> None:
    # SUMO: degrees clockwise from north; OpenSCENARIO: radians counter-clockwise from x
    assert heading_of(angle) == pytest.approx(heading)
    assert angle_of(heading) == pytest.approx(angle)
    assert 0 <= heading_of(359.9999) < 2 * math.pi


@pytest.fixture(scope="module")
def exported(
    tmp_path_factory: pytest.TempPathFactory, exported_cases: list[TestCase]
) -> list[tuple[TestCase, Path, Path]]:
    """Every example level, a queue, Town05 396 and Town07 358: each exported in the ASAM
    flavour and in the CARLA one."""
    out = []
    for k, case in enumerate(exported_cases):
        asam = tmp_path_factory.mktemp(f"osc{k}")
        carla = tmp_path_factory.mktemp(f"carla{k}")
        export_openscenario(case, asam)
        export_openscenario(case, carla, flavour="carla")
        out.append((case, asam, carla))
    return out


QC_BIN = Path(__file__).resolve().parents[3] / ".venv-qc" / "bin"
BUNDLES = {"xosc": ("qc_openscenario", "xoscBundle"), "xodr": ("qc_opendrive", "xodrBundle")}
QC_CONFIG = """<?xml version="1.0" encoding="UTF-8"?>
<Config>
  <Param name="InputFile" value="{file}"/>
  <CheckerBundle application="{bundle}">
    <Param name="resultFile" value="result.xqar"/>
  </CheckerBundle>
</Config>
"""


def _issues(kind: str, path: Path) -> list[str]:
    """The issues the ASAM Quality Checker bundle finds in ``path`` (run as a command, as
    docs/export.md shows, from the venv `make test` installs it into), and every checker that
    ended in an error; the schema check must have run."""
    program, bundle = BUNDLES[kind]
    command = QC_BIN / program
    assert command.exists(), f"{command} is missing: `make test` installs the ASAM checkers"
    with tempfile.TemporaryDirectory() as work:  # the config and the result, not the export
        config = Path(work) / "config.xml"
        config.write_text(QC_CONFIG.format(file=path.resolve(), bundle=bundle))
        subprocess.run([str(command), "-c", str(config)], cwd=work, check=True,
                       capture_output=True, timeout=300)  # fmt: skip
        checkers = list(ET.parse(Path(work) / "result.xqar").getroot().iter("Checker"))
    found = []
    for checker in checkers:
        name, status = checker.get("checkerId", "?"), checker.get("status")
        if status not in ("completed", "skipped") or (
            name.endswith("xml_valid_schema") and status != "completed"
        ):
            found.append(f"{path.name}: {name} {status}: {checker.get('summary')}")
        found += [f"{path.name}: {name}: {i.get('description')}" for i in checker.iter("Issue")]
    return found


def test_every_export_passes_the_asam_quality_checkers(
    exported: list[tuple[TestCase, Path, Path]],
) -> None:
    issues = []
    networks = set()
    for _, asam, _ in exported:
        network = (asam / "testcase.xodr").read_bytes()  # one per junction: checked once
        if network not in networks:
            networks.add(network)
            issues += _issues("xodr", asam / "testcase.xodr")
        issues += _issues("xosc", asam / "testcase.xosc")
    # the certificates' files and the CARLA flavour differ in the ego's part, the version and
    # the vertices: checked on a bundled junction and on a CARLA map
    for _, asam, carla in (exported[3], exported[-1]):
        scenarios = [*sorted(asam.glob("testcase.*.xosc")), carla / "testcase.xosc"]
        issues += [issue for scenario in scenarios for issue in _issues("xosc", scenario)]
    # the five bundled junctions (the signal examples' two among them), the crosswalk
    # example's, Town05 396, Town07 358
    assert len(networks) == 8
    assert issues == []
    rules = (exported[3][1] / "verdict-rules.md").read_text()  # four-way-3, an all-way stop
    assert "`stopAtSign`: CVC 22450(a)" in rules and "`yieldToRightAtAllWayStop`" in rules
    names = {p.name for p in exported[-1][1].iterdir()}
    assert names == {"testcase.xodr", "testcase.xosc", "testcase.solvability.xosc",
                     "testcase.complexity.xosc", "verdict-rules.md"}  # fmt: skip


def _vertices(root: ET.Element, actor: str) -> list[tuple[float, float, float, float]]:
    """(time, x, y, h) of every vertex of ``actor``'s polyline."""
    for group in root.iter("ManeuverGroup"):
        refs = [e.get("entityRef") for e in group.iter("EntityRef")]
        if refs == [actor]:
            return [
                (float(v.get("time", "nan")), *(float(w.get(k, "0")) for k in ("x", "y", "h")))
                for v in group.iter("Vertex")
                for w in v.iter("WorldPosition")
            ]
    raise AssertionError(f"no trajectory for {actor}")


def _at(vertices: list[tuple[float, float, float, float]], t: float) -> tuple[float, float, float]:
    """The polyline at time ``t``: linear between vertices, headings the short way round."""
    for a, b in itertools.pairwise(vertices):
        if a[0] <= t + 1e-9 <= b[0] + 1e-9:
            share = 0.0 if b[0] == a[0] else min(1.0, (t - a[0]) / (b[0] - a[0]))
            angle = interpolate_heading(angle_of(a[3]), angle_of(b[3]), share)
            return a[1] + share * (b[1] - a[1]), a[2] + share * (b[2] - a[2]), angle
    raise AssertionError(f"t = {t} outside the polyline")


def _off(sample: Sample, pose: tuple[float, float, float]) -> tuple[float, float]:
    turn = abs((sample.heading - pose[2] + 180.0) % 360.0 - 180.0)
    return math.hypot(sample.x - pose[0], sample.y - pose[1]), turn


def test_every_polyline_gives_back_its_trajectory(
    exported: list[tuple[TestCase, Path, Path]],
) -> None:
    """Read back as plain XML and sampled at every time step of the test-case: within 1 cm
    and one degree, in both flavours (CARLA's 20 Hz polyline interpolated)."""
    worst = (0.0, 0.0)
    checked = 0
    for case, asam, carla in exported:
        for folder, scenario in ((asam, "testcase.xosc"), (carla, "testcase.xosc"),
                                 (asam, "testcase.solvability.xosc")):  # fmt: skip
            if not (folder / scenario).exists():
                continue
            root = ET.parse(folder / scenario).getroot()
            cars = [(c.id, c.trajectory) for c in case.nonegos]
            if "solvability" in scenario:
                assert case.certificates is not None
                cars = [("ego", case.certificates.solvability)]
            for name, trajectory in cars:
                vertices = _vertices(root, name)
                for sample in trajectory:
                    metres, degrees = _off(sample, _at(vertices, sample.t))
                    assert metres <= CENTIMETRE and degrees <= 1.0, (scenario, name, sample.t)
                    worst = max(worst, (metres, degrees))
                    checked += 1
    assert checked > 5000  # every car of every case, not a few


def test_the_ego_is_the_system_under_test_at_its_start(
    exported: list[tuple[TestCase, Path, Path]],
) -> None:
    for case, asam, _ in exported:
        root = ET.parse(asam / "testcase.xosc").getroot()
        ego = next(o for o in root.iter("ScenarioObject") if o.get("name") == "ego")
        properties = {p.get("name"): p.get("value") for p in ego.iter("Property")}
        assert properties == {"type": "ego_vehicle"}
        box = ego.find("Vehicle/BoundingBox")
        assert box is not None
        dims, centre = box.find("Dimensions"), box.find("Center")
        assert dims is not None and centre is not None
        assert float(dims.get("length", 0)) == case.ego.length
        assert float(dims.get("width", 0)) == case.ego.width
        assert (float(centre.get("x", 1)), float(centre.get("y", 1))) == (0.0, 0.0)
        private = next(p for p in root.iter("Private") if p.get("entityRef") == "ego")
        start = private.find("PrivateAction/TeleportAction/Position/WorldPosition")
        speed = private.find(".//AbsoluteTargetSpeed")
        assert start is not None and speed is not None
        assert float(speed.get("value", -1)) == case.ego.start.speed
        assert ego.find(".//FollowTrajectoryAction") is None
        story = root.find("Storyboard/Story")
        assert story is None or story.find(".//EntityRef[@entityRef='ego']") is None
        # the ego is named once: by the condition that stops the run at its goal
        refs = root.iterfind("Storyboard/StopTrigger/ConditionGroup/Condition//EntityRef")
        assert [r.get("entityRef") for r in refs] == ["ego"]
        # where a certificate starts is where the ego starts (front bumper at its distance)
        if case.certificates is not None:
            first = case.certificates.solvability[0]
            x, y, h = (float(start.get(k, 0)) for k in ("x", "y", "h"))
            metres, degrees = _off(first, (x, y, angle_of(h)))
            assert metres < 0.05 and degrees < 1.0, case.name
        route = private.findall(".//AssignRouteAction/Route/Waypoint")
        assert len(route) == 2


def _goal_condition(root: ET.Element) -> tuple[float, float, float]:
    """(x, y, tolerance) of the stop trigger's condition on the ego's goal: ASAM 1.2's
    DistanceCondition or CARLA's 1.0 ReachPositionCondition."""
    groups = root.findall("Storyboard/StopTrigger/ConditionGroup")
    names = [[c.get("name") for c in g.iter("Condition")] for g in groups]
    assert names == [["ego_reached_its_goal"], ["duration_reached"]]  # either stops it
    condition = groups[0].find(".//DistanceCondition")
    if condition is not None:
        assert condition.get("rule") == "lessOrEqual" and condition.get("freespace") == "false"
        assert condition.get("relativeDistanceType") == "euclidianDistance"
        tolerance = float(condition.get("value", "nan"))
    else:
        condition = groups[0].find(".//ReachPositionCondition")
        assert condition is not None
        tolerance = float(condition.get("tolerance", "nan"))
    position = condition.find("Position/WorldPosition")
    assert position is not None
    return float(position.get("x", "nan")), float(position.get("y", "nan")), tolerance


def test_the_run_stops_when_the_ego_has_reached_its_goal(
    exported: list[tuple[TestCase, Path, Path]],
) -> None:
    """The storyboard stops when the ego reaches its goal, where scengen's judgement ends
    (or at the duration): driven as its solvability certificate, in both flavours, the ego
    first meets the condition just after the checker's goal (its rear a metre out of the
    junction), never before it."""
    checked = 0
    for case, asam, carla in exported:
        if case.certificates is None:
            continue
        certificate = [PoseSample(**s.model_dump()) for s in case.certificates.solvability]
        goal = check_testcase(case, certificate, "solvability", criticality=False).goal_time
        assert goal is not None
        for folder in (asam, carla):
            x, y, tolerance = _goal_condition(ET.parse(folder / "testcase.xosc").getroot())
            met = next(s.t for s in certificate if math.hypot(s.x - x, s.y - y) <= tolerance)
            assert goal < met < goal + 1.0, (case.name, folder.name, goal, met)
            checked += 1
    assert checked >= 2 * 10


def _fork_at(intersection: Intersection, point: Point) -> str:
    lane, distance = min(
        ((f.lane, Point(f.stop_line).distance(point)) for f in intersection.forks.values()),
        key=lambda pair: pair[1],
    )
    assert distance < 0.5, f"no fork within 0.5 m of {point}"
    return lane


def _exit_at(intersection: Intersection, point: Point) -> str:
    lane, distance = min(
        ((e.lane, Point(e.departure.coords[0]).distance(point))
         for e in intersection.exits.values()),
        key=lambda pair: pair[1],
    )  # fmt: skip
    assert distance < 0.5, f"no exit within 0.5 m of {point}"
    return lane


@pytest.mark.parametrize("which", ["4way-stop", "t-stop", "y-uncontrolled", "Town05 396"])
def test_opendrive_read_back_is_the_same_junction(
    which: str, exported: list[tuple[TestCase, Path, Path]], tmp_path: Path
) -> None:
    """netconvert --opendrive-files on the export: the same forks, exits, routes and
    conflicts, lanes matched by where they meet the junction (netconvert renames them)."""
    case, asam, _ = next(
        (c, a, k) for c, a, k in exported
        if (c.network.ref.startswith("Town05") and which == "Town05 396")
        or c.network.ref == which
    )  # fmt: skip
    original = load_testcase_intersection(case)
    back = tmp_path / "back.net.xml"
    subprocess.run(
        [sumo_binary("netconvert"), "--opendrive-files", str(asam / "testcase.xodr"),
         "-o", str(back), "--no-warnings"],
        check=True, capture_output=True, timeout=120,
    )  # fmt: skip
    centre = original.polygon.centroid
    nearest = min(
        (j for j in ET.parse(back).getroot().iter("junction")
         if j.get("type") not in ("internal", "dead_end")),
        key=lambda j: centre.distance(Point(float(j.get("x", 0)), float(j.get("y", 0)))),
    )  # fmt: skip
    read = load_intersection(back, nearest.get("id"), case.control, cache_dir=tmp_path)
    assert read.polygon.centroid.distance(centre) < 1.0
    assert len(read.forks) == len(original.forks)
    forks = {f.lane: _fork_at(read, Point(f.stop_line)) for f in original.forks.values()}
    exits = {e.lane: _exit_at(read, Point(e.departure.coords[0])) for e in original.exits.values()}
    assert len(set(forks.values())) == len(forks) and len(set(exits.values())) == len(exits)
    mapped = {r.id: f"{forks[r.fork]}:{exits[r.exit]}" for r in original.routes.values()}
    assert set(mapped.values()) == set(read.routes)
    for route, conflicts in original.conflicts.items():
        assert {mapped[c] for c in conflicts} == set(read.conflicts[mapped[route]]), route


def test_stop_signs_stand_on_the_roads_into_the_junction(
    exported: list[tuple[TestCase, Path, Path]],
) -> None:
    """One stop sign (OpenDRIVE signal 206, as CARLA reads it) per incoming road with a stop
    line: every arm of an all-way stop, the minor arms of a two-way stop, none where the
    junction is uncontrolled; each at the end of a road that leads into the junction."""
    seen = set()
    for case, asam, _ in exported:
        if case.network.ref in seen:
            continue
        seen.add(case.network.ref)
        junction = load_testcase_intersection(case)
        edges = {f.edge for f in junction.forks.values() if f.stop_sign}
        root = ET.parse(asam / "testcase.xodr").getroot()
        signed = [r for r in root.iter("road") for g in r.iter("signal") if g.get("type") == "206"]
        assert len(signed) == len(edges), case.network.ref
        for road in signed:
            successor = road.find("link/successor")
            assert successor is not None and successor.get("elementType") == "junction"
            signal = road.find("signals/signal")
            assert signal is not None
            before_end = float(road.get("length", 0)) - float(signal.get("s", 0))
            assert before_end == pytest.approx(1.0, abs=1e-3)
    assert len(seen) == 8  # at the two signalized ones: none


def test_yield_signs_stand_on_the_minor_roads_of_a_priority_junction(tmp_path: Path) -> None:
    """A priority junction's minor road gets a yield sign (OpenDRIVE signal 205) on each of
    its roads into the junction, at the road's end, and no stop sign."""
    from service.core.testcase import new_testcase
    from tests.conftest import DATA

    case = new_testcase(DATA / "junctions" / "skewed-yield.net.xml", "S2C_0:C2N_0")
    assert case.control == "priority" and case.rules == "priority"
    export_openscenario(case, tmp_path)
    root = ET.parse(tmp_path / "testcase.xodr").getroot()
    signs = [(g.get("type"), g.get("name")) for g in root.iter("signal")]
    assert sorted(signs) == [("205", "yield N2C"), ("205", "yield S2C")]
    for road in root.iter("road"):
        signal = road.find("signals/signal")
        if signal is not None:
            successor = road.find("link/successor")
            assert successor is not None and successor.get("elementType") == "junction"
            before_end = float(road.get("length", 0)) - float(signal.get("s", 0))
            assert before_end == pytest.approx(1.0, abs=1e-3)
