"""The paper's experiments as runnable examples: chains of extensions.

Each example starts from an ego-only test-case on a bundled intersection and extends it
step by step; every step's result is verified by the checker before it is kept.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from service.cli.output import write_output
from service.core.errors import ScengenError
from service.core.generator.extension import extend_testcase
from service.core.testcase import (
    TestCase,
    dump_testcase,
    name_stem,
    new_testcase,
    readable_name,
    renamed,
    testcase_level,
)


@dataclass(frozen=True)
class Example:
    name: str
    network: str
    ego: str
    steps: tuple[tuple[str, ...], ...]
    duration: float
    about: str


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
    start = new_testcase(example.network, example.ego, duration=example.duration)
    chain = [renamed(start, readable_name(start, example.name))]
    if on_level is not None:
        on_level(chain[0])
    for level, routes in enumerate(example.steps, start=1):
        try:
            extension = extend_testcase(chain[-1], list(routes), seed, budget, progress=progress)
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
    path = folder / f"{name_stem(testcase.name)}-{testcase_level(testcase)}.json"
    write_output(path, dump_testcase(testcase))
    return path
