"""Replays under the RSS guard (``NAME+rss``): real libsumo, real ad-rss."""

from __future__ import annotations

import itertools
import os
import subprocess
import sys
from pathlib import Path

import pytest

from service.core.checker.verdict import Verdict
from service.core.errors import InvalidInput
from service.core.export.bundle import export_bundle
from service.core.motion.poses import generate_poses
from service.core.sim.controllers import GuardedDriver, UserDriver, controller_names, resolve_driver
from service.core.sim.replay import evaluate
from service.core.testcase import TestCase, load_testcase_intersection, new_testcase
from tests.helpers import retime, with_nonegos

EGO_ROUTE, CROSSING_ROUTE = "E2C_1:C2W_1", "N2C_1:C2S_1"


@pytest.fixture(scope="module")
def empty() -> TestCase:
    return new_testcase("4way-stop", EGO_ROUTE, duration=20.0, name="empty")


def _crossing(empty: TestCase, start: float) -> TestCase:
    """A car from the north runs the all-way stop at 8 m/s from ``start`` metres out."""
    junction = load_testcase_intersection(empty)
    (track,) = generate_poses(junction, [(junction.route(CROSSING_ROUTE), start)], 8.0, 20.0, 0.1)
    samples = retime(track, lambda t: (8.0 * t, 8.0), 20.0, 0.1)
    return with_nonegos(empty, [("cross", CROSSING_ROUTE, samples)], name="crossing")


@pytest.fixture(scope="module")
def crossing(empty: TestCase) -> TestCase:
    """From 50 m out the car is in the junction just when SUMO's ego, having stopped,
    drives off: unguarded, they collide."""
    return _crossing(empty, 50.0)


def test_a_car_crossing_ahead_forces_braking_and_averts_the_collision(
    crossing: TestCase,
) -> None:
    unguarded = evaluate(crossing, "sumo").verdict
    assert [c.other for c in unguarded.collisions] == ["cross"]
    assert unguarded.guard is None
    guarded = evaluate(crossing, "sumo+rss").verdict
    assert guarded.passed, guarded.reasons
    guard = guarded.guard
    assert guard is not None and guard["fallback"] is None
    assert guard["braking"] == guard["interventions"] > 0
    assert guard["by_car"] == {"cross": guard["interventions"]}
    assert "IntersectionSamePriority with cross: brake" in guard["first"]["why"]


def test_an_empty_junction_changes_nothing(empty: TestCase) -> None:
    plain = evaluate(empty, "sumo")
    guarded = evaluate(empty, "sumo+rss")
    assert guarded.trajectory == plain.trajectory
    assert guarded.verdict.guard is not None
    assert guarded.verdict.guard["steps"] > 0 and guarded.verdict.guard["interventions"] == 0


def test_a_user_controller_flooring_the_accelerator_is_restricted(
    empty: TestCase, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """From 20 m out the crossing car meets a floored ego in the junction (unguarded they
    collide at 3.5 s); the guard brakes it in time."""
    crossing = _crossing(empty, 20.0)
    (tmp_path / "floored.py").write_text(
        "class Floored:\n    def step(self, observation):\n        return 100.0\n"
    )
    monkeypatch.chdir(tmp_path)
    monkeypatch.syspath_prepend(str(tmp_path))
    assert isinstance(resolve_driver("floored:Floored+rss"), GuardedDriver)
    evaluation = evaluate(crossing, "floored:Floored+rss")
    guard = evaluation.verdict.guard
    assert evaluation.error is None and guard is not None
    assert guard["interventions"] > 0 and set(guard["by_car"]) == {"cross"}
    assert not evaluation.verdict.collisions
    # braked: somewhere its speed drops, which a floored accelerator never does by itself
    speeds = [s.speed for s in evaluation.trajectory]
    assert any(b < a - 0.1 for a, b in itertools.pairwise(speeds))


def test_guarded_names_cover_the_drivers_and_not_the_certificates(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from importlib.metadata import EntryPoint

    import service.core.sim.controllers as controllers

    registered = [EntryPoint("steady", "steady:Steady", controllers.ENTRY_POINT_GROUP)]
    monkeypatch.setattr(controllers, "entry_points", lambda group: registered)
    assert resolve_driver("steady+rss") == GuardedDriver(
        "steady+rss", UserDriver("steady", "steady:Steady")
    )
    names = controller_names()
    assert "steady+rss" in names
    assert {"sumo+rss", "sumo-cautious+rss", "sumo-aggressive+rss"} <= set(names)
    assert not any(n.startswith("certificate:") and n.endswith("+rss") for n in names)
    guarded = resolve_driver("my.module:Driver+rss")
    assert isinstance(guarded, GuardedDriver) and guarded.inner == UserDriver(
        "my.module:Driver", "my.module:Driver"
    )
    with pytest.raises(InvalidInput, match=r"certificate is a replay.*sumo\+rss"):
        resolve_driver("certificate:solvability+rss")
    with pytest.raises(InvalidInput, match="twice"):
        resolve_driver("sumo+rss+rss")


def test_the_verdict_keeps_the_guard_through_json() -> None:
    verdict = Verdict("t", "sumo+rss", True, 1.0, guard={"kind": "rss", "interventions": 3})
    assert Verdict.from_dict(verdict.to_dict()) == verdict
    assert verdict.to_dict()["guard"]["interventions"] == 3
    assert Verdict.from_dict(Verdict("t", "sumo", True, 1.0).to_dict()).guard is None


def test_the_bundle_runs_the_guard_and_falls_back_without_ad_rss(
    crossing: TestCase, tmp_path: Path
) -> None:
    """run.py loads rss_guard.py from its own folder; where ad-rss cannot be imported the
    guard says so and uses its time-gap rule, which also averts the collision."""
    export_bundle(crossing, tmp_path / "bundle")
    blocker = tmp_path / "blocked"
    blocker.mkdir()
    (blocker / "ad_rss.py").write_text("raise ImportError('blocked for the test')\n")
    env = {**os.environ, "PYTHONPATH": str(blocker)}
    done = subprocess.run(
        [sys.executable, "run.py", "--controller", "sumo+rss"],
        cwd=tmp_path / "bundle", env=env, capture_output=True, text=True, check=True,
    )  # fmt: skip
    assert "fell back on the time-gap rule: ad-rss is not installed" in done.stdout
    assert "intervened at 0 of" not in done.stdout
    assert (tmp_path / "bundle" / "run.fcd.xml").exists()
