"""Schemathesis against a real server: every operation, a fixed seed, a bounded number of
cases, and strict checks (no server error, only documented statuses, responses that match
their schemas, schema-violating requests refused, and /healthz answering after every request).

``tests/api/fuzz/schemathesis.toml`` names the checks and says which are relaxed where and why;
``tests/api/fuzz/hooks.py`` adds the /healthz check. The command the test runs is printed on
failure, to be run again by hand (docs/reliability.md).
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.servers import Server

pytestmark = pytest.mark.slow  # 14 s of work or more: `make test-fast` leaves it out

FUZZ = Path(__file__).parent / "fuzz"
TOKEN = "fuzz-token"
SEED = 1
CASES_PER_OPERATION = 3


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Server]:
    running = Server(
        tmp_path_factory.mktemp("fuzz"),
        api_token=TOKEN,
        workers="2",
        # bounded work: a fuzzed budget is refused over 5 s, a search stops after 3 s
        max_budget="5",
        extend_budget="3",
        evaluate_budget="5",
        work_budget="30",
    )
    yield running
    running.stop()


def st_command(url: str) -> list[str]:
    return [
        str(Path(sys.executable).with_name("st")),
        "--config-file",
        str(FUZZ / "schemathesis.toml"),
        "run",
        f"{url}/openapi.json",
        "--max-examples",
        str(CASES_PER_OPERATION),
        "--seed",
        str(SEED),
        "--workers",
        "2",
        "--no-shrink",
        "--request-timeout",
        "120",
        "--header",
        f"Authorization: Bearer {TOKEN}",
    ]


def test_the_fuzzer_finds_nothing(server: Server, tmp_path: Path) -> None:
    command = st_command(server.url)
    environment = {
        **os.environ,
        "SCENGEN_FUZZ_URL": server.url,
        "SCHEMATHESIS_HOOKS": "hooks",
        "PYTHONPATH": str(FUZZ),
        "NO_COLOR": "1",
    }
    finished = subprocess.run(
        command, cwd=tmp_path, env=environment, capture_output=True, text=True, timeout=900
    )
    output = finished.stdout + finished.stderr
    report = f"{' '.join(command)}\n{output[-6000:]}"
    assert finished.returncode == 0, report
    paths = json.loads(server.client.get("/openapi.json").text)["paths"]
    operations = sum(len(methods) for methods in paths.values())
    tested = re.search(r"Tested:\s+(\d+)", output)
    generated = re.search(r"(\d+) generated", output)
    assert tested and generated, report
    assert int(tested.group(1)) == operations, report  # every operation, not only some
    assert int(generated.group(1)) >= CASES_PER_OPERATION * operations, report
    assert server.client.get("/healthz").status_code == 200


CHECKS = {
    "not_a_server_error", "status_code_conformance", "content_type_conformance",
    "response_headers_conformance", "response_schema_conformance", "negative_data_rejection",
    "missing_required_header", "unsupported_method", "allow_header_conformance",
    "use_after_free", "ensure_resource_availability", "ignored_auth", "server_stays_healthy",
    "positive_data_acceptance", "schema_as_strict_as_the_server",
}  # fmt: skip
# operations whose schema-valid requests may be refused with 422 (or an upload with 400),
# each for a reason written in schemathesis.toml
RELAXED = {
    ("/testcases", "POST"): {422}, ("/extend", "POST"): {422},
    ("/evaluations", "POST"): {422}, ("/jobs", "POST"): {422},
    ("/networks", "POST"): {400, 422}, ("/testcases/{testcase}/plot", "GET"): {422},
    ("/networks/{network}/junctions/{junction}", "GET"): {422},
    ("/networks/{network}/junctions/{junction}/plot", "GET"): {422},
    ("/networks/{network}/junctions/{junction}/geometry", "GET"): {422},
}  # fmt: skip


def test_the_fuzzer_runs_the_named_checks_and_exempts_a_cancelled_job() -> None:
    """The checks the configuration turns on, for an operation and for the paths below a
    job (DELETE cancels a job and keeps it: 'deleted resource still available' is off);
    schema-valid requests refused only where the configuration says why."""
    from schemathesis import openapi
    from schemathesis.checks import CHECKS as REGISTRY
    from schemathesis.config import SchemathesisConfig

    from service.api.openapi import openapi_document

    sys.path.insert(0, str(FUZZ))
    try:
        import hooks  # noqa: F401 (registers server_stays_healthy)
    finally:
        sys.path.remove(str(FUZZ))
    config = SchemathesisConfig.from_path(str(FUZZ / "schemathesis.toml"))
    schema = openapi.from_dict(json.loads(openapi_document()), config=config)

    def enabled(path: str, method: str) -> set[str]:
        found = schema.config.checks_config_for(operation=schema[path][method], phase="stateful")
        return {n for n in REGISTRY.get_all_names() if found.get_by_name(name=n).enabled}

    assert enabled("/testcases/{testcase}", "GET") == CHECKS
    for path in ("/jobs/{job}", "/jobs/{job}/bundles", "/jobs/{job}/campaign/report"):
        assert enabled(path, "GET") == CHECKS - {"use_after_free"}, path
    for path, methods in schema.raw_schema["paths"].items():
        for method in methods:
            found = schema.config.checks_config_for(
                operation=schema[path][method.upper()], phase="fuzzing"
            )
            statuses = set(found.positive_data_acceptance.expected_statuses)
            refusals = {int(s) for s in statuses if s.isdigit() and s.startswith(("4", "5"))}
            assert refusals - {401, 403, 404, 409, 429} == RELAXED.get(
                (path, method.upper()), set()
            ), (path, method)
