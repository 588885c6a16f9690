"""The exported SUMO bundle: its run.py reproduces the in-service evaluation, and its
.sumocfg runs with the plain `sumo` binary (real SUMO, no mocks)."""

from __future__ import annotations

import json
import math
import subprocess
import sys
import xml.etree.ElementTree as ET
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

from service.core.checker.check import check_testcase
from service.core.checker.check import testcase_label as label_of
from service.core.checker.verdict import Verdict
from service.core.export.bundle import export_bundle
from service.core.generator.extension import extend_testcase
from service.core.motion.poses import centre_to_front, generate_poses
from service.core.motion.trajectory import read_trajectory
from service.core.network import Intersection, bundled_networks, parsed_network
from service.core.sim.controllers import BUILT_IN
from service.core.sim.replay import Evaluation, evaluate
from service.core.sumo.binaries import sumo_binary
from service.core.testcase import TestCase, load_testcase_intersection, new_testcase, read_testcase
from tests.helpers import next_junction_network, retime, with_nonegos
from tests.walkers import crosswalk_scene, in_path_times, on_crossing_times

pytestmark = pytest.mark.slow  # 14 s of work or more: `make test-fast` leaves it out


@pytest.fixture(scope="module")
def four_way() -> TestCase:
    start = new_testcase("4way-stop", "E2C_1:C2S_1", duration=25.0, name="left")
    return extend_testcase(start, ["S2C_1:C2N_1", "W2C_1:C2E_1"], seed=0, budget=120).testcase


@pytest.fixture(scope="module")
def bundle_run(four_way: TestCase, tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("bundle")
    export_bundle(four_way, folder)
    subprocess.run(
        [sumo_binary("sumo"), "-c", "testcase.sumocfg", "--fcd-output", "run.fcd.xml"],
        cwd=folder, check=True, capture_output=True, timeout=120,
    )  # fmt: skip
    return folder


def test_the_bundle_is_self_contained(bundle_run: Path, four_way: TestCase) -> None:
    names = {p.name for p in bundle_run.iterdir()}
    assert {"testcase.json", "testcase.rou.xml", "testcase.types.xml", "testcase.fcd.xml",
            "testcase.sumocfg", "README.md", "4way-stop.net.xml",
            "testcase.all.rou.xml"} <= names  # fmt: skip
    everyone = ET.parse(bundle_run / "testcase.all.rou.xml").getroot()
    assert [v.get("id") for v in everyone.iter("vehicle")] == ["ego", "car1", "car2"]
    assert read_testcase(bundle_run / "testcase.json") == four_way
    assert "sumo -c testcase.sumocfg" in (bundle_run / "README.md").read_text()


def test_sumo_replays_the_nonegos_within_centimetres(bundle_run: Path, four_way: TestCase) -> None:
    """SUMO's fcd-replay device puts each non-ego on its recorded front bumper; at a rare
    step (about one per car per run, near a lane boundary) it is off by up to a step's
    travel, about 10 cm at walking pace."""
    recorded = {n.id: n for n in four_way.nonegos}
    misses = []
    for step in ET.parse(bundle_run / "run.fcd.xml").getroot().iter("timestep"):
        t = float(step.get("time", "nan"))
        for car in step.iter("vehicle"):
            name = car.get("id", "")
            if name == "ego":
                continue
            nonego = recorded[name]
            sample = nonego.trajectory[round(t / four_way.timestep)]
            assert sample.t == pytest.approx(t)
            expected = centre_to_front(sample.x, sample.y, sample.heading, nonego.length)
            actual = (float(car.get("x", "nan")), float(car.get("y", "nan")))
            misses.append(math.dist(expected, actual))
    assert len(misses) >= len(recorded) * 200
    assert max(misses) < 0.15
    assert sum(1 for m in misses if m < 0.02) >= 0.99 * len(misses)


def test_the_bundle_run_gets_the_in_service_verdict(bundle_run: Path, four_way: TestCase) -> None:
    ego = read_trajectory(bundle_run / "run.fcd.xml", "ego", four_way.ego.length)
    from_bundle = check_testcase(four_way, ego, "sumo")
    in_service = evaluate(four_way, "sumo").verdict
    assert from_bundle.passed == in_service.passed
    assert {v.rule for v in from_bundle.violations} == {v.rule for v in in_service.violations}
    assert from_bundle.goal_reached == in_service.goal_reached


RUN_EVERY_CONTROLLER = """
import sys
import run
for controller in sys.argv[1:]:
    code = run.main(["--controller", controller, "--fcd-output", controller + ".fcd.xml"])
    assert code == 0, (controller, code)
"""


def test_the_bundle_runner_reproduces_the_evaluation(
    exported_cases: list[TestCase], tmp_path: Path
) -> None:
    """For every built-in controller on every case, `python run.py` in the exported bundle
    drives the ego along the trajectory of `scengen evaluate` (to a micrometre), so the
    checker's verdict is the same: pass or fail, the rules broken against whom, the
    collisions, the goal time and the ego's event times."""
    jobs = []
    for k, testcase in enumerate(exported_cases):
        intersection = load_testcase_intersection(testcase)
        folder = tmp_path / f"case{k}"
        export_bundle(testcase, folder, intersection)
        controllers = [
            name for name in BUILT_IN
            if testcase.certificates is not None or not name.startswith("certificate:")
        ]  # fmt: skip
        subprocess.run(
            [sys.executable, "-c", RUN_EVERY_CONTROLLER, *controllers],
            cwd=folder, check=True, capture_output=True, timeout=300,
        )  # fmt: skip
        jobs += [(testcase, intersection, folder, name) for name in controllers]
    assert len(jobs) == 4 * len(exported_cases) + 2 * (len(exported_cases) - 8)  # 8 ego-only cases

    def evaluated(job: tuple[TestCase, Intersection, Path, str]) -> Evaluation:
        testcase, intersection, _, controller = job
        return evaluate(testcase, controller, intersection)

    with ThreadPoolExecutor(max_workers=2) as pool:  # each evaluation is its own process
        evaluations = list(pool.map(evaluated, jobs))
    outcomes = set()
    for (testcase, intersection, folder, controller), evaluation in zip(
        jobs, evaluations, strict=True
    ):
        case = f"{label_of(testcase)} / {controller}"
        ego = read_trajectory(folder / f"{controller}.fcd.xml", "ego", testcase.ego.length)
        assert len(ego) == len(evaluation.trajectory), case
        for ours, theirs in zip(ego, evaluation.trajectory, strict=True):
            assert ours.t == theirs.t, case
            assert math.dist((ours.x, ours.y), (theirs.x, theirs.y)) < 1e-6, case
            assert abs(ours.distance - theirs.distance) < 1e-6, case
        bundle = check_testcase(testcase, ego, controller, intersection)
        service = evaluation.verdict
        assert bundle.passed == service.passed, case
        assert _offences(bundle) == _offences(service), case
        assert bundle.goal_reached == service.goal_reached, case
        if service.goal_time is not None:
            assert bundle.goal_time == pytest.approx(service.goal_time, abs=testcase.timestep)
        assert [(e.car, e.kind, e.lane) for e in bundle.ego_events] == [
            (e.car, e.kind, e.lane) for e in service.ego_events
        ], case
        for ours, theirs in zip(bundle.ego_events, service.ego_events, strict=True):
            assert ours.t == pytest.approx(theirs.t, abs=testcase.timestep), case
        outcomes.add((controller, service.passed))
        if controller == "sumo" and testcase.network.ref not in bundled_networks():
            # a new shell in the bundle finds the network the test-case names, next to it
            judged = subprocess.run(
                [sys.executable, "-m", "service", "check", "testcase.json",
                 "--ego", "sumo.fcd.xml", "--controller", "sumo"],
                cwd=folder, capture_output=True, text=True, timeout=120,
            )  # fmt: skip
            assert judged.returncode == (0 if service.passed else 1), judged.stderr
            assert "(its path from the test-case)" in judged.stderr
    # the comparison covers passes and failures of SUMO's drivers and of the certificates
    assert {("sumo", True), ("sumo-rolling-stop", False), ("certificate:complexity", False)} <= (
        outcomes
    )


def _offences(verdict: Verdict) -> set[tuple[str, str | None]]:
    return {(v.rule, v.other) for v in verdict.violations} | {
        ("collision", c.other) for c in verdict.collisions
    }


def test_run_py_runs_with_traci_and_the_sumo_binary(bundle_run: Path, four_way: TestCase) -> None:
    """Without libsumo (`--traci`): the same trajectory as the in-process run."""
    for flag, output in (([], "libsumo.fcd.xml"), (["--traci"], "traci.fcd.xml")):
        result = subprocess.run(
            [sys.executable, "run.py", "--controller", "sumo", "--fcd-output", output, *flag],
            cwd=bundle_run, capture_output=True, text=True, timeout=120,
        )  # fmt: skip
        assert result.returncode == 0, result.stderr
        assert "scengen check testcase.json --ego" in result.stdout
    a = read_trajectory(bundle_run / "libsumo.fcd.xml", "ego", four_way.ego.length)
    b = read_trajectory(bundle_run / "traci.fcd.xml", "ego", four_way.ego.length)
    assert [(s.t, round(s.x, 6), round(s.y, 6)) for s in a] == [
        (s.t, round(s.x, 6), round(s.y, 6)) for s in b
    ]


def test_a_car_past_the_end_of_its_road_leaves_the_bundle(tmp_path: Path) -> None:
    """A non-ego that drives on past the end of its road (off the map) is in the FCD only
    while it is on its road, and SUMO runs the bundle and the evaluation with it."""
    base = new_testcase("4way-stop", "E2C_0:C2W_0", duration=30.0)
    junction = load_testcase_intersection(base)
    route = junction.route("S2C_0:C2N_0")
    (track,) = generate_poses(junction, [(route, 30.0)], 12.0, 30.0, 0.1)
    fast = retime(track, lambda t: (12.0 * t, 12.0), 30.0, 0.1)  # 360 m: past the road
    assert fast[-1].distance > track.samples[-1].distance + 100.0
    case = with_nonegos(base, [("fast", route.id, fast)])
    export_bundle(case, tmp_path, junction)
    written = [
        float(v.get("speed") or 0)
        for v in ET.parse(tmp_path / "testcase.fcd.xml").getroot().iter("vehicle")
    ]
    assert 0 < len(written) < len(fast)
    assert len(written) * 0.1 * 12.0 <= track.samples[-1].distance + 12.0 * 0.1
    subprocess.run(
        [sumo_binary("sumo"), "-c", "testcase.sumocfg"],
        cwd=tmp_path, check=True, capture_output=True, timeout=120,
    )  # fmt: skip
    assert evaluate(case, "sumo", junction).verdict.goal_reached


def test_run_py_names_the_valid_controllers(bundle_run: Path) -> None:
    result = subprocess.run(
        [sys.executable, "run.py", "--controller", "autopilot"],
        cwd=bundle_run, capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert result.returncode == 2
    assert "unknown controller 'autopilot'" in result.stderr
    assert "sumo-cautious" in result.stderr and "certificate:complexity" in result.stderr


def test_the_bundle_ends_the_ego_with_its_goal(next_junction: TestCase, tmp_path: Path) -> None:
    """On a chain whose car1 drives on through the next junction: `python run.py` drives
    the ego as `scengen evaluate` does, until it leaves just past its goal, and `scengen
    check` on its FCD gives evaluate's verdict; plain `sumo` ends the ego's route there
    too (its arrivalPos). Neither stands at the next junction's red light, where car1
    would run into it."""
    junction = load_testcase_intersection(next_junction)
    export_bundle(next_junction, tmp_path, junction)
    done = subprocess.run(
        [sys.executable, "run.py", "--controller", "sumo", "--fcd-output", "run.fcd.xml"],
        cwd=tmp_path, capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert "until it left at the end of its route, past its goal, at" in done.stdout
    length = next_junction.ego.length
    ego = read_trajectory(tmp_path / "run.fcd.xml", "ego", length)
    evaluation = evaluate(next_junction, "sumo", junction)
    assert [(s.t, round(s.distance, 6)) for s in ego] == [
        (s.t, round(s.distance, 6)) for s in evaluation.trajectory
    ]
    judged = subprocess.run(
        [sys.executable, "-m", "service", "check", "testcase.json", "--ego", "run.fcd.xml",
         "--controller", "sumo", "--json"],
        cwd=tmp_path, capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert judged.returncode == 0, judged.stderr
    verdict = json.loads(judged.stdout)
    service = json.loads(evaluation.verdict.to_json())
    for key in ("passed", "goal", "judged_until", "collisions", "violations", "after_goal"):
        assert verdict[key] == service[key], key
    assert verdict["after_goal"] == {"collisions": [], "violations": []}
    subprocess.run(
        [sumo_binary("sumo"), "-c", "testcase.sumocfg", "--fcd-output", "plain.fcd.xml"],
        cwd=tmp_path, check=True, capture_output=True, timeout=120,
    )  # fmt: skip
    plain = read_trajectory(tmp_path / "plain.fcd.xml", "ego", length)
    on_plain = check_testcase(next_junction, plain, "sumo", junction)
    assert on_plain.goal_time is not None and plain[-1].t < on_plain.goal_time + 1.0
    assert on_plain.passed and on_plain.after_goal_collisions == ()


def test_plain_sumo_inserts_a_car_that_starts_in_a_junction_on_a_network_with_sidewalks(
    tmp_path: Path,
) -> None:
    """Every FCD row of a car names its lane and position: plain `sumo -c` used to fail
    with "Invalid departLane definition" for a car that starts inside a junction on a
    network with sidewalks (its fcd-replay device guessed the junction's internal lane
    and gave its index to the edge after it, where index 0 is the sidewalk). On the
    two-junction network with guessed crossings, car1 starts inside the signalized D and
    drives through the all-way stop C: SUMO runs the bundle and replays car1 within
    centimetres from its first step."""
    network = next_junction_network(tmp_path)
    base = new_testcase(network, "S2C_1:C2D_1", junction="C", duration=20.0,
                        guess_crossings=True)  # fmt: skip
    junction = load_testcase_intersection(base)
    assert junction.crossings  # sidewalks: the car lanes are 1 and up
    route = junction.route("D2C_1:C2S_1")
    into_d = parsed_network(junction.network_file).getEdge("D2C").getLength() + 4.0
    (track,) = generate_poses(junction, [(route, into_d)], 6.0, 20.0, 0.1)
    steps = track.at_time_steps(0.1)
    case = with_nonegos(base, [("car1", route.id, steps)])
    folder = tmp_path / "bundle"
    export_bundle(case, folder, junction)
    rows = list(ET.parse(folder / "testcase.fcd.xml").getroot().iter("vehicle"))
    assert rows[0].get("lane", "").startswith(":D_")  # it starts inside D
    assert all(row.get("lane") and row.get("pos") for row in rows)
    done = subprocess.run(
        [sumo_binary("sumo"), "-c", "testcase.sumocfg", "--fcd-output", "plain.fcd.xml"],
        cwd=folder, capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    misses = []
    for step in ET.parse(folder / "plain.fcd.xml").getroot().iter("timestep"):
        for car in step.iter("vehicle"):
            if car.get("id") == "car1":
                sample = steps[round(float(step.get("time", "nan")) / 0.1)]
                expected = centre_to_front(sample.x, sample.y, sample.heading, 5.0)
                misses.append(math.dist(expected, (float(car.get("x", "nan")),
                                                   float(car.get("y", "nan")))))  # fmt: skip
    assert len(misses) > 150 and max(misses) < 0.02


def test_a_bundle_replays_its_pedestrians(tmp_path: Path) -> None:
    """A pedestrian on the crosswalk of the ego's skewed arm: `python run.py` gives the
    ego's trajectory of `scengen evaluate` (to a micrometre) for `sumo` and `sumo+rss`;
    plain `sumo -c` runs the bundle, replays her at her poses (within a centimetre but for
    a step or two at a curb, from its first step: SUMO has no place for a replayed person
    at t = 0) until she leaves the map, and its `sumo` waits for her too (she walks the
    crosswalk along its lane: README.md says why that matters)."""
    _, testcase, junction = crosswalk_scene("E2C_1:C2W_1", "C_c1+", lead=2.0, wait=0.0)
    export_bundle(testcase, tmp_path, junction)
    plan = json.loads((tmp_path / "testcase.run.json").read_text())
    assert [p["id"] for p in plan["pedestrians"]] == ["ped1"]
    assert "rss_world.py" in {p.name for p in tmp_path.iterdir()}
    assert "pedestrian" in (tmp_path / "README.md").read_text()
    subprocess.run(
        [sys.executable, "-c", RUN_EVERY_CONTROLLER, "sumo", "sumo+rss"],
        cwd=tmp_path, check=True, capture_output=True, timeout=300,
    )  # fmt: skip
    in_path = in_path_times(testcase, junction)
    for controller in ("sumo", "sumo+rss"):
        ego = read_trajectory(tmp_path / f"{controller}.fcd.xml", "ego", testcase.ego.length)
        service = evaluate(testcase, controller, junction).trajectory
        assert [(s.t, round(s.x, 6), round(s.y, 6)) for s in ego] == [
            (s.t, round(s.x, 6), round(s.y, 6)) for s in service
        ]
        entered = on_crossing_times(testcase, junction, ego)
        assert entered[0] > in_path[-1]  # it waited for her
    done = subprocess.run(
        [sumo_binary("sumo"), "-c", "testcase.sumocfg", "--fcd-output", "plain.fcd.xml"],
        cwd=tmp_path, capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    person = testcase.pedestrians[0]
    poses = plan["pedestrians"][0]["poses"]
    seen = {}
    for step in ET.parse(tmp_path / "plain.fcd.xml").getroot().iter("timestep"):
        for row in step.iter("person"):
            seen[round(float(step.get("time", "nan")) / 0.1)] = (
                float(row.get("x", "nan")), float(row.get("y", "nan")))  # fmt: skip
    assert sorted(seen) == list(range(len(poses)))  # on the map, and only then
    misses = [math.dist(place, poses[k][:2]) for k, place in seen.items() if k > 0]
    assert max(misses) < 0.15  # at a step near a curb SUMO has her at the crosswalk's end
    assert sum(1 for miss in misses if miss >= 0.01) <= 2
    assert len(poses) < len(person.trajectory)  # she walked off her walk's sidewalk
    plain = read_trajectory(tmp_path / "plain.fcd.xml", "ego", testcase.ego.length)
    assert on_crossing_times(testcase, junction, plain)[0] > in_path[-1]
