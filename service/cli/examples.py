"""The paper's experiments as runnable examples: chains of extensions.

Each example starts from an ego-only test-case on a bundled intersection and extends it
step by step; every step's result is verified by the checker before it is kept. Then every
level is evaluated with each controller (by default the paper's pair, SUMO's driver and the
same driver guarded by RSS) into the paper's table.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from service.cli.output import write_output
from service.core.campaign.paper_table import PAPER_CONTROLLERS, PaperTable, paper_table
from service.core.errors import ScengenError

if TYPE_CHECKING:  # the generator, the replay and the test-case's models load when one runs
    from service.core.testcase import TestCase

WORKER_SLACK = 30.0  # seconds the worker may take beyond a replay's own budget (its start)


@dataclass(frozen=True)
class Example:
    name: str
    network: str
    ego: str
    steps: tuple[tuple[str, ...], ...]  # each level's new routes and walks (a walk has no ':')
    duration: float
    about: str
    controllers: tuple[str, ...] = PAPER_CONTROLLERS  # the table's rows by default


EXAMPLES = {
    example.name: example
    for example in (
        Example(
            "four-way",
            "4way-stop",
            "E2C_1:C2S_1",
            (("S2C_1:C2N_1",), ("W2C_1:C2E_1",), ("S2C_0:C2N_0",)),
            30.0,
            "left turn at the all-way stop; three successive extensions: a car from the left "
            "going straight, a car from the opposite side going straight, a car from the left "
            "on the other lane going straight",
        ),
        Example(
            "t-junction",
            "t-stop",
            "E2C_0:C2S_0",
            (("W2C_0:C2E_0", "S2C_0:C2W_0"),),
            25.0,
            "left turn from the continuing road into the terminating one; two cars added at "
            "once, one straight across from the left, one turning out of the terminating road",
        ),
        Example(
            "y-junction",
            "y-uncontrolled",
            "N2C_0:C2SE_0",
            (("SW2C_0:C2N_0", "SE2C_0:C2N_0"),),
            25.0,
            "left turn at the uncontrolled Y; a conflicting car and a car whose route does "
            "not meet the ego's added together",
        ),
        Example(
            "signal",
            "4way-signal",
            "N2C_1:C2E_1",
            (("S2C_0:C2N_0",), ("S2C_1:C2N_1",), ("S2C_0:C2N_0",)),
            30.0,
            "left turn on a permissive green at the signalized four-way (21451 (a) with 21801 "
            "(a)); three successive extensions: oncoming cars going straight on either lane, "
            "then a second one queued on the first lane",
        ),
        Example(
            "crosswalk",
            "crosswalk-stop",
            "E2C_1:C2N_1",
            (("C_c0-",), ("C_c1+",), ("S2C_1:C2N_1",)),
            40.0,
            "right turn at the all-way stop with crosswalks (its east arm 25 degrees off) while "
            "people cross: a pedestrian over the ego's exit, walking towards its lane (21950 "
            "(a)), then one over the road it comes from, then a car straight on from the left",
            ("sumo", "sumo+rss", "sumo-aggressive"),
        ),
        Example(
            "right-on-red",
            "t-signal",
            "S2C_0:C2E_0",
            (("W2C_0:C2E_0",),),
            30.0,
            "right turn on red after a full stop out of the signalized T (21453 (b)); a car "
            "on the through road, on green, into the ego's exit lane",
        ),
    )
}


def run_example(
    example: Example,
    seed: int = 0,
    budget: float = 120.0,
    progress: Callable[[str], None] | None = None,
    on_level: Callable[[TestCase], None] | None = None,
) -> list[TestCase]:
    """The chain of test-cases: the ego-only start, then one per step, named after the
    example and the level (``four-way level 2``). ``on_level`` hears of each level as soon
    as it is verified; a level that fails names itself in its error."""
    from service.core.generator.extension import extend_testcase
    from service.core.testcase import new_testcase, readable_name, renamed

    start = new_testcase(example.network, example.ego, duration=example.duration)
    chain = [renamed(start, readable_name(start, example.name))]
    if on_level is not None:
        on_level(chain[0])
    for level, step in enumerate(example.steps, start=1):
        routes = [item for item in step if ":" in item]
        walks = [item for item in step if ":" not in item]
        try:
            extension = extend_testcase(
                chain[-1], routes, seed, budget, progress=progress, walks=walks
            )
        except ScengenError as error:
            message = f"{example.name} level {level}: {error.message}"
            raise type(error)(message, **error.context) from error
        document = renamed(extension.testcase, readable_name(extension.testcase, example.name))
        chain.append(document)
        if on_level is not None:
            on_level(document)
    return chain


def write_testcase(testcase: TestCase, folder: Path) -> Path:
    """``folder/EXAMPLE-LEVEL.json`` (``four-way-2.json`` for ``four-way level 2``), the
    folder made when missing."""
    from service.core.testcase import dump_testcase, name_stem, testcase_level

    path = folder / f"{name_stem(testcase.name)}-{testcase_level(testcase)}.json"
    write_output(path, dump_testcase(testcase))
    return path


def evaluate_levels(
    chain: Sequence[TestCase],
    controllers: Sequence[str],
    budget: float | None = None,
    on_verdict: Callable[[str], None] | None = None,
) -> PaperTable:
    """Every level of ``chain`` replayed with each controller, as the paper's table. The
    replays run one after another in one warm child process (its imports paid once), each
    under ``budget`` (None: the replay's own, REPLAY_BUDGET). A certificate controller on
    the ego-only level (which has no certificates) leaves its cell empty; ``on_verdict``
    hears ``NAME / CONTROLLER: pass`` (``FAIL``, ``(none)``) after each."""
    from service.core.budget import WarmWorker
    from service.core.names import REPLAY_BUDGET
    from service.core.sim.controllers import CertificateDriver, resolve_driver
    from service.core.testcase import testcase_level

    drivers = [resolve_driver(name) for name in controllers]  # bad names fail first
    budget = REPLAY_BUDGET if budget is None else budget
    levels: dict[int, dict[str, list[dict[str, Any]]]] = {}
    worker = WarmWorker()
    try:
        for testcase in chain:
            found = levels.setdefault(testcase_level(testcase), {})
            for name, driver in zip(controllers, drivers, strict=True):
                said = f"{testcase.name} / {name}"
                if isinstance(driver, CertificateDriver) and testcase.certificates is None:
                    if on_verdict is not None:
                        on_verdict(f"{said}: (none)")
                    continue
                call = (testcase, name, budget)
                try:
                    verdict = worker.call(replay_verdict, call, budget + WORKER_SLACK, said)
                except ScengenError as error:
                    raise type(error)(f"{said}: {error.message}", **error.context) from error
                found[name] = [verdict]
                if on_verdict is not None:
                    on_verdict(f"{said}: {'pass' if verdict['passed'] else 'FAIL'}")
    finally:
        worker.close()
    return paper_table(levels, controllers)


def replay_verdict(testcase: TestCase, controller: str, budget: float) -> dict[str, Any]:
    """The controller's verdict on ``testcase`` (``Verdict.to_dict``), in the worker."""
    from service.core.sim.replay import evaluate

    return evaluate(testcase, controller, budget=budget).verdict.to_dict()
