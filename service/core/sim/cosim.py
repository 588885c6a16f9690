"""``scengen cosim``: a test-case as a co-simulation over TraCI, judged by the checker.

The runner's files are written as for a replay (service.core.sim.replay), SUMO runs them as
a TraCI server for two clients (service.core.sumo.cosim: scengen scripts every other road
user, the driving stack under test drives ``ego``), and the ego's recorded trajectory is
judged exactly as ``evaluate`` judges a controller's. The stack's faults (it never came,
left before the end, took the ego off its route) are ClientFault, a run past its budget is
BudgetExceeded: neither gives a verdict.
"""

from __future__ import annotations

import tempfile
from collections.abc import Callable
from pathlib import Path

from service.core.checker.check import check_testcase
from service.core.errors import BudgetExceeded, ClientFault, InvalidInput, SimulationFailed
from service.core.names import COSIM_BUDGET as COSIM_BUDGET  # the waits, light for the CLI
from service.core.names import COSIM_WAIT as COSIM_WAIT
from service.core.network import Intersection
from service.core.sim.replay import Evaluation, departures, row_sample, write_run_files
from service.core.sumo import cosim
from service.core.sumo import run as sumo_run
from service.core.testcase import TestCase

CONTROLLER = "cosim"  # how the verdict names what drove the ego


def cosimulate_testcase(
    testcase: TestCase,
    intersection: Intersection,
    port: int,
    host: str = "127.0.0.1",
    wait: float = COSIM_WAIT,
    budget: float = COSIM_BUDGET,
    say: Callable[[str], None] = print,
) -> Evaluation:
    """Run ``testcase`` as a co-simulation on ``host``:``port`` (``say`` tells where it
    waits) and judge the ego the driving stack drove."""
    import traci  # SUMO's own client: the co-simulation speaks TraCI over sockets

    for name, value in (("--wait", wait), ("--budget", budget)):
        if not value > 0:
            raise InvalidInput(f"{name} must be a number of seconds above 0, got {value:g}")
    with tempfile.TemporaryDirectory(prefix="scengen-cosim-") as folder:
        ego, others = departures(testcase, intersection)
        network = str(intersection.network_file.resolve())
        write_run_files(testcase, ego, others, Path(folder), network, intersection)
        plan_file = Path(folder) / sumo_run.PLAN_FILE
        program = sumo_run.find_program("sumo")
        try:
            rows = cosim.cosimulate(sumo_run, traci, plan_file, program, host, port, wait,
                                    budget, say)  # fmt: skip
        except cosim.ListenFailed as exc:
            raise InvalidInput(str(exc)) from None
        except cosim.ClientFault as exc:
            raise ClientFault(str(exc)) from None
        except cosim.BudgetOver as exc:
            raise BudgetExceeded(str(exc)) from None
        except (sumo_run.RunFailed, traci.TraCIException, traci.FatalTraCIError,
                RuntimeError) as exc:  # fmt: skip
            raise SimulationFailed(f"SUMO broke off the co-simulation: {exc}") from None
    samples = [row_sample(row, testcase.ego.length) for row in rows]
    verdict = check_testcase(testcase, samples, CONTROLLER, intersection)
    return Evaluation(verdict, samples)
