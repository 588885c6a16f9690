"""The test-case as JSON text: parsed with errors that name the bad fields, read from a
file, written as stable bytes, and the names a test-case goes by from level to level."""

from __future__ import annotations

import json
import re
from pathlib import Path, PurePosixPath
from typing import Any

from pydantic import ValidationError

from service.core.errors import InvalidTestCase
from service.core.motion.plausibility import first_jump
from service.core.testcase.model import MAX_NAME_LENGTH, TestCase


def _describe(error: ValidationError) -> str:
    parts = []
    for item in first_errors(error, 5):
        where = ".".join(str(p) for p in item["loc"]) or "document"
        message = re.sub(r"^Value error, ", "", item["msg"])
        parts.append(f"{where}: {message}")
    more = error.error_count() - len(parts)
    return "; ".join(parts) + (f" (and {more} more)" if more > 0 else "")


def first_errors(error: ValidationError, count: int) -> list[dict[str, Any]]:
    """The first ``count`` errors of ``error``. ``errors()`` builds a dict for every error
    (3.4 s for a million); pydantic writes them all as JSON ten times faster, and only the
    first few are decoded from that."""
    text = error.json(include_url=False, include_context=False, include_input=False)
    decoder = json.JSONDecoder()
    found: list[dict[str, Any]] = []
    position = 1  # after "["
    while len(found) < count and text[position] != "]":
        item, position = decoder.raw_decode(text, position)
        found.append(item)
        position += 1 if text[position] == "," else 0
    return found


def parse_testcase(document: str | bytes | dict[str, Any]) -> TestCase:
    """A validated test-case; InvalidTestCase naming the first bad fields otherwise."""
    try:
        if isinstance(document, dict):
            return TestCase.model_validate(document)
        return TestCase.model_validate_json(document)
    except ValidationError as exc:
        raise InvalidTestCase(f"invalid test-case: {_describe(exc)}") from None


def read_testcase(path: Path) -> TestCase:
    try:
        text = path.read_text()
    except OSError as exc:
        raise InvalidTestCase(f"cannot read test-case {path}: {exc.strerror}") from None
    try:
        json.loads(text)
    except json.JSONDecodeError as exc:
        raise InvalidTestCase(f"{path} is not JSON: {exc}") from None
    return parse_testcase(text)


def implausible_trajectories(testcase: TestCase) -> list[str]:
    """Each stored trajectory that jumps further between two samples than any car can
    drive (service.core.motion.plausibility), in words: a warning, not an error, since the
    checker judges a document as it is written."""
    found = [(f"{car.id}'s trajectory", first_jump(car.trajectory)) for car in testcase.road_users]
    if testcase.certificates is not None:
        found += [
            ("the complexity certificate", first_jump(testcase.certificates.complexity)),
            ("the solvability certificate", first_jump(testcase.certificates.solvability)),
        ]
    return [f"{what} {jump}: no car can" for what, jump in found if jump is not None]


def dump_testcase(testcase: TestCase) -> str:
    """The JSON text of a test-case (stable key order, two-space indent, newline at end)."""
    return (
        json.dumps(testcase.model_dump(mode="json", by_alias=True, exclude_none=True), indent=2)
        + "\n"
    )


def testcase_level(testcase: TestCase) -> int:
    """0 for an ego-only test-case, else the level of the extension that added its last cars."""
    return max((n.added_in for n in testcase.road_users), default=0)


def readable_name(testcase: TestCase, stem: str = "", network: str = "") -> str:
    """A name a test engineer reads at a glance: ``STEM level N``, or without a stem the
    network's short name (a bundled name, or the file name without ``.net.xml``), the
    junction, the ego's route and the level: ``Town05 396 -44_1:-9_1 level 2``. ``network``
    names the network's file where the reference does not say it (a server's network id):
    the short name is then made from it."""
    if not stem:
        short = PurePosixPath(network or testcase.network.ref).name.removesuffix(".xml")
        stem = f"{short.removesuffix('.net')} {testcase.junction} {testcase.ego.route.id}"
    suffix = f" level {testcase_level(testcase)}"
    return stem[: MAX_NAME_LENGTH - len(suffix)] + suffix


def renamed(testcase: TestCase, name: str) -> TestCase:
    """``testcase`` named ``name``, validated like any document (InvalidTestCase names a
    name that is too long or holds control characters)."""
    document = testcase.model_dump(mode="json", by_alias=True, exclude_none=True)
    return parse_testcase({**document, "name": name})


def name_stem(name: str) -> str:
    """``name`` without a trailing ``level N`` (so the next level renames it, not nests)."""
    return re.sub(r" level \d+$", "", name)
