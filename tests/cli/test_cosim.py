"""Co-simulation over TraCI (issue 46): `scengen cosim` and a bundle's `run.py --cosim`
driven by a separate process written only against SUMO's own traci package
(examples/cosim_client.py), on level-1 test-cases of a stop-sign, an uncontrolled and a
signalized junction; real SUMO, generator and checker throughout."""

from __future__ import annotations

import json
import os
import re
import socket
import struct
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
import traci.constants as tc

from service import cli
from service.core.generator.extension import extend_testcase
from service.core.sim.cosim import cosimulate_testcase
from service.core.sim.replay import evaluate
from service.core.sumo.cosim import CloseWatch
from service.core.testcase import (
    TestCase,
    dump_testcase,
    load_testcase_intersection,
    new_testcase,
)

ROOT = Path(__file__).resolve().parents[2]
CLIENT = ROOT / "examples" / "cosim_client.py"
WAITING = re.compile(r"waiting for a TraCI client with order 2 on 127\.0\.0\.1:(\d+)")
LEVELS = {  # junction: (ego route, the route added at level 1, duration)
    "4way-stop": ("S2C_0:C2N_0", "E2C_0:C2W_0", 25.0),
    "y-uncontrolled": ("N2C_0:C2SE_0", "SW2C_0:C2N_0", 25.0),
    "4way-signal": ("S2C_1:C2W_1", "N2C_1:C2S_1", 45.0),
}


@pytest.fixture(scope="module")
def levels(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[TestCase, Path]]:
    """Level 1 of each junction, and its file (the client reads certificates from it)."""
    folder = tmp_path_factory.mktemp("cosim")
    found = {}
    for junction, (ego, added, duration) in LEVELS.items():
        start = new_testcase(junction, ego, duration=duration)
        level = extend_testcase(start, [added], seed=0, budget=120).testcase
        path = folder / f"{junction}-1.json"
        path.write_text(dump_testcase(level))
        found[junction] = (level, path)
    return found


def _client(port: int, *arguments: str) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, str(CLIENT), str(port), *arguments],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
    )  # fmt: skip


def _cosim_in_process(testcase: TestCase, *arguments: str) -> tuple[dict[str, Any], str]:
    """The verdict of `cosimulate_testcase` with the example client, started as soon as
    scengen says where it waits, and what the client printed."""
    clients: list[subprocess.Popen[str]] = []

    def say(line: str) -> None:
        port = WAITING.search(line)
        assert port is not None, line
        clients.append(_client(int(port.group(1)), *arguments))

    intersection = load_testcase_intersection(testcase)
    evaluation = cosimulate_testcase(testcase, intersection, port=0, say=say)
    printed, _ = clients[0].communicate(timeout=60)
    assert clients[0].returncode == 0, printed
    return _comparable(json.loads(evaluation.verdict.to_json())), printed


def _comparable(verdict: dict[str, Any]) -> dict[str, Any]:
    """A verdict without the name of what drove the ego."""
    return {key: value for key, value in verdict.items() if key not in ("controller", "file")}


@pytest.mark.parametrize("junction", list(LEVELS))
def test_a_client_gets_the_verdict_evaluate_gives(
    junction: str, levels: dict[str, tuple[TestCase, Path]]
) -> None:
    """A client that only steps: SUMO's driver drives the ego, as `evaluate --controller
    sumo`; one that places the ego on a certificate with moveToXY: that certificate's
    verdict (the solvability certificate passes, the complexity certificate fails by the
    same rule)."""
    testcase, path = levels[junction]
    stepped, printed = _cosim_in_process(testcase)
    assert "SUMO closed the connection" in printed
    assert stepped == _comparable(json.loads(evaluate(testcase, "sumo").verdict.to_json()))
    for certificate in ("solvability", "complexity"):
        replayed, _ = _cosim_in_process(testcase, str(path), certificate)
        expected = json.loads(evaluate(testcase, f"certificate:{certificate}").verdict.to_json())
        assert replayed["passed"] == (certificate == "solvability") == expected["passed"]
        assert [v["rule"] for v in replayed["violations"]] == [
            v["rule"] for v in expected["violations"]
        ]
        assert replayed["goal"]["reached"] and not replayed["collisions"]


def _scengen(*arguments: str, env: dict[str, str]) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "service", *arguments],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT, env=env,
    )  # fmt: skip


def _port_of(server: subprocess.Popen[str]) -> int:
    """The port the server says it waits on (its first line on stderr)."""
    assert server.stderr is not None
    line = server.stderr.readline()
    found = WAITING.search(line)
    assert found is not None, line
    return int(found.group(1))


def _private_tmp(tmp_path: Path) -> dict[str, str]:
    """An environment whose temporary files (the run's folder, which SUMO's command line
    names) are under ``tmp_path``: the processes of this run alone can be found by it."""
    return {**os.environ, "TMPDIR": str(tmp_path), "PYTHONPATH": str(ROOT)}


def _left_behind(tmp_path: Path) -> list[str]:
    found = subprocess.run(["pgrep", "-af", str(tmp_path)], capture_output=True, text=True)
    return [line for line in found.stdout.splitlines() if "pgrep" not in line]


def test_the_clients_faults_end_with_their_own_exit_code(
    levels: dict[str, tuple[TestCase, Path]], tmp_path: Path
) -> None:
    """A client that never comes, one that closes its connection at 2 s, and one that moves
    the ego onto a road off its route: exit 4 with one line saying so, no verdict, and
    neither SUMO nor any other process left behind."""
    _, path = levels["4way-stop"]
    env = _private_tmp(tmp_path)
    server = _scengen("cosim", str(path), "--port", "0", "--wait", "1", env=env)
    _port_of(server)
    out, err = server.communicate(timeout=60)
    assert server.returncode == 4 and out == ""
    [line] = err.strip().splitlines()
    assert re.fullmatch(
        r"scengen: failed: no TraCI client came to 127\.0\.0\.1:\d+ within 1 s \(--wait\); "
        "nothing was judged",
        line,
    ), line
    server = _scengen("cosim", str(path), "--port", "0", "--json", env=env)
    client = _client(_port_of(server), "--leave-at", "2.0")
    out, err = server.communicate(timeout=60)
    client.communicate(timeout=60)
    assert server.returncode == 4 and out == "", (out, err)
    assert "the TraCI client closed its connection" in err and len(err.strip().splitlines()) == 1
    off_route = tmp_path / "off_route.py"
    off_route.write_text(OFF_ROUTE)
    server = _scengen("cosim", str(path), "--port", "0", env=env)
    client = subprocess.Popen([sys.executable, str(off_route), str(_port_of(server))])
    out, err = server.communicate(timeout=60)
    client.communicate(timeout=60)
    assert server.returncode == 4 and out == "", (out, err)
    assert "the ego left its route at 1.00 s: it is on road 'W2C', its route is S2C C2N" in err
    assert _left_behind(tmp_path) == []


OFF_ROUTE = """import sys, traci
traci.init(int(sys.argv[1]))
traci.setOrder(2)
for step in range(100):
    if step == 10:  # onto the road from the west, off the ego's route
        x, y = traci.lane.getShape("W2C_0")[0]
        traci.vehicle.moveToXY("ego", "W2C", 0, x + 5, y, 90, keepRoute=2)
    try:
        traci.simulationStep()
    except traci.exceptions.FatalTraCIError:
        break
"""


def test_a_bundle_runs_the_same_cosimulation(
    levels: dict[str, tuple[TestCase, Path]], tmp_path: Path
) -> None:
    """`run.py --cosim` of an exported bundle, driven by the same client, writes the ego's
    FCD; `scengen check` of it gives the verdict `scengen cosim` gives."""
    testcase, path = levels["4way-stop"]
    env = _private_tmp(tmp_path)
    bundle = tmp_path / "bundle"
    exported = subprocess.run(
        [sys.executable, "-m", "service", "export", str(path), "-o", str(bundle)],
        capture_output=True, text=True, cwd=ROOT, env=env,
    )  # fmt: skip
    assert exported.returncode == 0, exported.stderr
    fcd = tmp_path / "cosim.fcd.xml"
    runner = subprocess.Popen(
        [sys.executable, "run.py", "--cosim", "0", "--fcd-output", str(fcd)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=bundle, env=env,
    )  # fmt: skip
    client = _client(_port_of(runner), str(path), "complexity")
    _, err = runner.communicate(timeout=60)
    client.communicate(timeout=60)
    assert runner.returncode == 0, err
    checked = subprocess.run(
        [sys.executable, "-m", "service", "check", str(bundle / "testcase.json"),
         "--ego", str(fcd), "--controller", "cosim", "--json"],
        capture_output=True, text=True, cwd=ROOT, env=env,
    )  # fmt: skip
    assert checked.returncode == 1, checked.stderr
    verdict = json.loads(checked.stdout)
    replayed, _ = _cosim_in_process(testcase, str(path), "complexity")
    assert [v["rule"] for v in verdict["violations"]] == [v["rule"] for v in replayed["violations"]]
    assert verdict["goal"] == replayed["goal"]
    assert _left_behind(tmp_path) == []


def test_bad_ports_and_limits_are_refused_in_one_line(
    levels: dict[str, tuple[TestCase, Path]], capsys: pytest.CaptureFixture[str]
) -> None:
    _, path = levels["4way-stop"]
    with socket.create_server(("127.0.0.1", 0)) as taken:
        port = str(taken.getsockname()[1])
        for flags, said in [
            (["--port", "70000"], "--port 70000 is not a port: give 1 to 65535, or 0"),
            (["--port", port], f"cannot listen on 127.0.0.1:{port}: Address already in use"),
            (["--port", "0", "--wait", "0"], "--wait must be a number of seconds above 0"),
            (["--port", "0", "--budget", "nan"], "--budget must be a number of seconds above 0"),
        ]:
            assert cli.main(["cosim", str(path), *flags]) == 2
            [line] = capsys.readouterr().err.strip().splitlines()
            assert line.startswith("scengen: error: ") and said in line, line


def test_a_close_command_is_seen_before_sumo_gets_it() -> None:
    """The relay reads the stack's TraCI messages, split anywhere, long commands among
    them, and tells the close command (so scengen's next step knows the stack left, however
    the threads are scheduled)."""

    def command(cid: int, payload: bytes = b"") -> bytes:
        size = len(payload) + 2
        if size <= 255:
            return struct.pack("!BB", size, cid) + payload
        return struct.pack("!BiB", 0, size + 4, cid) + payload

    def message(*commands: bytes) -> bytes:
        body = b"".join(commands)
        return struct.pack("!i", len(body) + 4) + body

    step = message(command(tc.CMD_SIMSTEP, struct.pack("!d", 0.0)))
    close = message(command(tc.CMD_SET_VEHICLE_VARIABLE, b"x" * 300), command(tc.CMD_CLOSE))
    watch = CloseWatch()
    assert not watch.seen_in(step) and not watch.seen_in(close[:7])
    assert watch.seen_in(close[7:])
    assert CloseWatch().seen_in(step + close) and not CloseWatch().seen_in(step + step)
