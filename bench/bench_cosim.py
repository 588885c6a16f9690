"""Benchmark: what a co-simulation over TraCI costs per step over a plain replay, with six
cars.

The chain of bench_rss (level 5 on the bundled four-way: the ego and five non-egos) is run
REPEATS times each way, alternately: replayed in libsumo in this process with `sumo` (what
`scengen evaluate` runs), and as a co-simulation (`scengen cosim`'s code: SUMO as a TraCI
server for two clients, this process scripting the non-egos, a client process that only
steps, so SUMO's driver drives the ego as in the replay). Both time the runner's loop alone
(from the first step to the ego's goal, SUMO's start and the client's connection left
out), per step, in wall-clock time: a co-simulation's cost is mostly waiting on sockets
and on the other processes, which CPU time of this process would not see. The client's
own time is a bare `simulationStep` per step.

Run with `make bench` (or `python -m bench.bench_cosim`). Target (issue 46): at most 1 ms
per step more than the replay.
"""

from __future__ import annotations

import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
import types
from datetime import date
from pathlib import Path
from typing import Any

import traci

from bench.bench_rss import six_cars
from service.core.network import load_intersection
from service.core.sim.replay import departures, write_run_files
from service.core.sumo import cosim
from service.core.sumo import run as sumo_run

REPEATS = 5
CLIENT = """import sys, traci
traci.init(int(sys.argv[1]))
traci.setOrder(2)
try:
    while True:
        traci.simulationStep()
except traci.exceptions.FatalTraCIError:
    pass
"""


def replay(plan_file: Path) -> float:
    """Wall-clock seconds per step of the runner's loop, libsumo in this process."""
    import libsumo

    plan = sumo_run.load_plan(plan_file)
    controller = plan["controllers"]["sumo"]
    with tempfile.TemporaryDirectory(prefix="bench-cosim-") as scratch:
        types_file = sumo_run.write_types(plan, plan_file.parent, controller,
                                          Path(scratch) / "types.xml")  # fmt: skip
        libsumo.start(["sumo", *sumo_run.sumo_arguments(plan, plan_file.parent, types_file)])
        try:
            start = time.perf_counter()
            rows, _ = sumo_run.drive(libsumo, plan, controller)
            return (time.perf_counter() - start) / len(rows)
        finally:
            libsumo.close()


def cosimulation(plan_file: Path, client_file: Path) -> float:
    """Wall-clock seconds per step of the runner's loop in a co-simulation."""
    timed: dict[str, float] = {}

    def drive(*arguments: Any) -> Any:
        start = time.perf_counter()
        rows, stopped = sumo_run.drive(*arguments)
        timed["per step"] = (time.perf_counter() - start) / len(rows)
        return rows, stopped

    runner = types.SimpleNamespace(**{name: getattr(sumo_run, name) for name in dir(sumo_run)})
    runner.drive = drive
    clients: list[subprocess.Popen[bytes]] = []

    def say(line: str) -> None:
        port = int(line.rsplit(":", 1)[1])
        clients.append(subprocess.Popen([sys.executable, str(client_file), str(port)]))

    program = sumo_run.find_program("sumo")
    cosim.cosimulate(runner, traci, plan_file, program, "127.0.0.1", 0, 60.0, 600.0, say)
    clients[0].wait(timeout=60)
    return timed["per step"]


def main() -> None:
    testcase = six_cars()
    intersection = load_intersection("4way-stop")
    plain: list[float] = []
    cosimulated: list[float] = []
    with tempfile.TemporaryDirectory(prefix="bench-cosim-") as folder:
        ego, others = departures(testcase, intersection)
        network = str(intersection.network_file.resolve())
        write_run_files(testcase, ego, others, Path(folder), network, intersection)
        plan_file = Path(folder) / sumo_run.PLAN_FILE
        client_file = Path(folder) / "client.py"
        client_file.write_text(CLIENT)
        for _ in range(REPEATS):
            plain.append(replay(plan_file))
            cosimulated.append(cosimulation(plan_file, client_file))
    cost = statistics.median(cosimulated) - statistics.median(plain)
    cars = len(testcase.nonegos) + 1
    print(f"co-simulation, {date.today()}, {platform.machine()} {platform.processor() or ''}, "
          f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}, {cars} cars, "
          f"{REPEATS} runs each")  # fmt: skip
    print("| ms per step (wall-clock, median of the runs) | min | median | max |")
    print("|---|---|---|---|")
    for label, times in (("replay (libsumo, in process)", plain),
                         ("co-simulation (TraCI, two clients)", cosimulated)):  # fmt: skip
        print(f"| {label} | {min(times) * 1000:.3f} | {statistics.median(times) * 1000:.3f} | "
              f"{max(times) * 1000:.3f} |")  # fmt: skip
    print(f"| the co-simulation's cost (difference of the medians) | | {cost * 1000:.3f} | |")
    print(f"target <= 1 ms per step: {'met' if cost <= 0.001 else 'NOT met'}")


if __name__ == "__main__":
    main()
