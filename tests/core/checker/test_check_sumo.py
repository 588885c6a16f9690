"""The checker on SUMO's own FCD output, with SUMO's default driver as the ego.

These run the plain ``sumo`` binary, the way a user's pipeline would, and feed its
``--fcd-output`` to the checker.
"""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest
import sumolib

from service.core.checker.check import check_testcase
from service.core.errors import InvalidTrajectory
from service.core.motion.trajectory import read_fcd, read_trajectory
from service.core.network import bundled_networks
from service.core.sumo.binaries import sumo_binary
from service.core.testcase import new_testcase
from tests.helpers import with_nonegos

START = 40.0


def run_sumo(tmp_path: Path, network: str, vehicles: dict[str, tuple[str, str, int]]) -> Path:
    """Drive ``vehicles`` (id -> from edge, to edge, lane) with SUMO's default driver, each
    departing at t = 0 with its front START metres before the stop line at 8 m/s."""
    net_file = bundled_networks()[network]
    net = sumolib.net.readNet(str(net_file))
    lines = ["<routes>", '  <vType id="car" length="5" width="1.8" sigma="0"/>']
    for car, (source, target, lane) in vehicles.items():
        position = net.getEdge(source).getLanes()[lane].getLength() - START
        lines += [
            f'  <vehicle id="{car}" type="car" depart="0" departLane="{lane}" '
            f'departPos="{position:.2f}" departSpeed="8">',
            f'    <route edges="{source} {target}"/>',
            "  </vehicle>",
        ]
    routes = tmp_path / "cars.rou.xml"
    routes.write_text("\n".join([*lines, "</routes>"]) + "\n")
    fcd = tmp_path / "fcd.xml"
    subprocess.run(
        [sumo_binary("sumo"), "-n", str(net_file), "-r", str(routes), "--fcd-output", str(fcd),
         "--step-length", "0.1", "--collision.check-junctions", "true", "--end", "25",
         "--no-step-log", "true"],
        check=True, capture_output=True, timeout=60,
    )  # fmt: skip
    return fcd


def test_sumo_driver_alone_at_an_all_way_stop_passes(tmp_path: Path) -> None:
    # SUMO's driver halts at an all-way stop (for at least one step) and then turns; with
    # nobody else there, it stops at the sign, reaches its exit and passes.
    fcd = run_sumo(tmp_path, "4way-stop", {"ego": ("S2C", "C2W", 1)})
    testcase = new_testcase("4way-stop", "S2C_1:C2W_1", start_distance=START)
    verdict = check_testcase(testcase, read_trajectory(fcd), "sumo")
    assert verdict.passed, verdict.reasons
    kinds = [e.kind for e in verdict.ego_events]
    assert kinds.index("stopped") < kinds.index("entered")
    assert verdict.goal_time is not None and verdict.goal_time < 15.0


def test_sumo_left_turn_yields_to_oncoming_traffic(tmp_path: Path) -> None:
    # On the through road of the T both cars arrive together; SUMO's left turn is a minor
    # link ('m') that waits inside the junction for the oncoming car, as 21801 (a) asks,
    # so the ego passes: no collision, and it enters car1's lane only once car1 has left.
    fcd = run_sumo(tmp_path, "t-stop", {"ego": ("E2C", "C2S", 0), "car1": ("W2C", "C2E", 0)})
    car1 = read_fcd(fcd.read_text(), "car1", 5.0, "fcd")
    testcase = with_nonegos(
        new_testcase("t-stop", "E2C_0:C2S_0", start_distance=START),
        [("car1", "W2C_0:C2E_0", car1)],
        duration=25.0,
    )
    verdict = check_testcase(testcase, read_trajectory(fcd), "sumo")
    assert verdict.passed, verdict.reasons


def test_sumo_driver_on_the_minor_road_stops(tmp_path: Path) -> None:
    fcd = run_sumo(tmp_path, "t-stop", {"ego": ("S2C", "C2E", 0)})
    testcase = new_testcase("t-stop", "S2C_0:C2E_0", start_distance=START)
    verdict = check_testcase(testcase, read_trajectory(fcd), "sumo")
    assert verdict.passed, verdict.reasons
    assert "stopped" in [e.kind for e in verdict.ego_events]


def test_fcd_without_the_vehicle_names_the_ones_present(tmp_path: Path) -> None:
    fcd = run_sumo(tmp_path, "t-stop", {"car7": ("S2C", "C2E", 0)})
    with pytest.raises(InvalidTrajectory, match="vehicles in the file: car7"):
        read_trajectory(fcd, "ego")
