"""``scengen submit``: send a batch to a server, follow it, fetch its results (for CI).

Exit codes: 0 every evaluation passed, 1 some evaluation failed, 2 bad input (the batch
file, or the server refused it), 3 the job failed or was cancelled, or the server could
not be reached.
"""

from __future__ import annotations

import json
import re
import sys
import time
import urllib.error
import urllib.request
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TextIO

import yaml

from service.cli.output import make_folder, write_output
from service.core.errors import InvalidInput, ScengenError
from service.jobs.batch import Batch, parse_batch

FINISHED = ("succeeded", "failed", "cancelled")


class ServerRefused(InvalidInput):
    """The server answered a 4xx: the problem's detail says why."""


class ServerUnreachable(ScengenError):
    """The server could not be reached or answered with a 5xx."""


class Yaml12Floats(yaml.SafeLoader):
    """YAML 1.1's SafeLoader, reading floats as YAML 1.2 (and JSON) write them: PyYAML takes
    ``1e-06``, which json.dumps writes, for a string, and numbers are strict."""


Yaml12Floats.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(
        r"""^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
        |[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)
        |\.[0-9_]+(?:[eE][-+]?[0-9]+)?
        |[-+]?\.(?:inf|Inf|INF)
        |\.(?:nan|NaN|NAN))$""",
        re.VERBOSE,
    ),
    list("-+0123456789."),
)


def read_batch(path: Path) -> Batch:
    """A batch file: JSON, or YAML by its suffix."""
    try:
        text = path.read_text()
    except OSError as error:
        raise InvalidInput(f"cannot read {path}: {error.strerror}") from None
    try:
        if path.suffix.lower() in (".yaml", ".yml"):
            document = yaml.load(text, Loader=Yaml12Floats)
        elif path.suffix.lower() == ".json":
            document = json.loads(text)
        else:
            raise InvalidInput(f"{path}: a batch file ends in .json, .yaml or .yml")
    except (json.JSONDecodeError, yaml.YAMLError) as error:
        kind = path.suffix[1:].upper()
        raise InvalidInput(f"{path} is not valid {kind}: {_one_line(error)}") from None
    return parse_batch(document)


def _one_line(error: json.JSONDecodeError | yaml.YAMLError) -> str:
    """A parser's error as one line: what is wrong, and where (line and column from 1)."""
    if isinstance(error, json.JSONDecodeError):
        return f"{error.msg} at line {error.lineno} column {error.colno}"
    if isinstance(error, yaml.MarkedYAMLError) and error.problem_mark is not None:
        mark = error.problem_mark
        what = ": ".join(part for part in (error.context, error.problem) if part)
        return f"{what} at line {mark.line + 1} column {mark.column + 1}"
    return " ".join(str(error).split())


@dataclass
class Client:
    """The few HTTP calls ``submit`` needs (standard library only)."""

    server: str
    token: str | None = None
    timeout: float = 60.0

    def call(
        self, method: str, path: str, body: Any = None, headers: dict[str, str] | None = None
    ) -> tuple[int, dict[str, str], bytes]:
        request = urllib.request.Request(
            self.server.rstrip("/") + path,
            method=method,
            data=None if body is None else json.dumps(body).encode(),
            headers={"Content-Type": "application/json", **(headers or {})},
        )
        if self.token:
            request.add_header("Authorization", f"Bearer {self.token}")
        try:
            with urllib.request.urlopen(request, timeout=self.timeout) as reply:
                return reply.status, dict(reply.headers), reply.read()
        except urllib.error.HTTPError as error:
            content = error.read()
            detail = _detail(content) or error.reason
            if 400 <= error.code < 500:
                raise ServerRefused(
                    f"the server refused {method} {path} ({error.code}): {detail}"
                ) from None
            raise ServerUnreachable(f"{method} {path} failed ({error.code}): {detail}") from None
        except (urllib.error.URLError, OSError) as error:
            reason = getattr(error, "reason", error)
            raise ServerUnreachable(f"cannot reach {self.server}: {reason}") from None

    def json(self, method: str, path: str, body: Any = None, **headers: str) -> Any:
        content = self.call(method, path, body, headers)[2]
        try:
            return json.loads(content)
        except ValueError:
            raise ServerUnreachable(
                f"{method} {path}: the answer is not JSON (a proxy page?): "
                f"{content[:80].decode(errors='replace')!r}"
            ) from None


def _detail(content: bytes) -> str:
    try:
        return str(json.loads(content).get("detail", ""))
    except (ValueError, AttributeError):
        return content.decode(errors="replace")[:200]


def submit(client: Client, batch: Batch, key: str | None) -> dict[str, Any]:
    headers = {"Idempotency-Key": key} if key else {}
    job: dict[str, Any] = client.json("POST", "/jobs", batch.model_dump(mode="json"), **headers)
    return job


def follow(
    client: Client,
    job: dict[str, Any],
    out: TextIO,
    poll: float = 1.0,
    patience: float = 600.0,
) -> dict[str, Any]:
    """Poll until the job finishes; a progress bar on a terminal, plain lines otherwise.
    A server that is away (restarting, database down) is retried for ``patience`` seconds:
    the job goes on without it."""
    terminal = out.isatty()
    last = ""
    while True:
        line = _summary(job)
        if terminal:
            finished = job["state"] in FINISHED
            shown = line if finished else line[:80].ljust(80)
            out.write("\r" + _bar(job) + " " + shown)
            out.flush()
        elif line != last:
            out.write(f"[{time.strftime('%H:%M:%S')}] {line}\n")
            out.flush()
        last = line
        if job["state"] in FINISHED:
            if terminal:
                out.write("\n")
            return job
        time.sleep(poll)
        job = _poll(client, job, out, patience)


def _poll(client: Client, job: dict[str, Any], out: TextIO, patience: float) -> dict[str, Any]:
    deadline, wait = time.monotonic() + patience, 1.0
    while True:
        try:
            found: dict[str, Any] = client.json("GET", f"/jobs/{job['id']}")
            return found
        except ServerUnreachable as error:
            if time.monotonic() + wait > deadline:
                raise
            out.write(f"\nscengen: {error}; retrying in {wait:g} s\n")
            time.sleep(wait)
            wait = min(wait * 2, 15.0)


def _bar(job: dict[str, Any], width: int = 24) -> str:
    filled: int = round(width * int(job["done"]) / max(int(job["total"]), 1))
    return "[" + "#" * filled + "." * (width - filled) + "]"


def _summary(job: dict[str, Any]) -> str:
    running = [f"item {i['position']} {i['progress']}".strip() for i in job["items"]
               if i["state"] == "running"]  # fmt: skip
    ev = job["evaluations"]
    text = f"job {job['id']} {job['state']}: {job['done']}/{job['total']} items"
    if ev["passed"] or ev["failed"]:
        text += f", evaluations {ev['passed']} passed {ev['failed']} failed"
    return text + (f" ({'; '.join(running)})" if running else "")


def download(client: Client, job: dict[str, Any], junit: Path | None, folder: Path | None) -> None:
    """The JUnit report (a campaign's cases in it, named by chain and level), and with
    ``folder`` every result: job.json, junit.xml, the test-case documents, a zip of all
    SUMO bundles and one of all OpenSCENARIO exports; for a campaign also campaign.json
    and report.html."""
    report = client.call("GET", f"/jobs/{job['id']}/junit")[2]
    if junit is not None:
        write_output(junit, report)
    if folder is None:
        return
    make_folder(folder)
    write_output(folder / "job.json", json.dumps(job, indent=2) + "\n")
    write_output(folder / "junit.xml", report)
    if any(item["kind"] == "campaign" for item in job["items"]):
        _download_campaign(client, job, folder)
    documents = folder / "testcases"
    made = [ident for item in job["items"] for ident in item["testcases"]]
    for ident in made:
        content = client.call("GET", f"/testcases/{ident}/document")[2]
        write_output(documents / f"{ident}.json", content)
    if made:
        client.timeout = max(client.timeout, 300.0)
        write_output(folder / "bundles.zip", client.call("GET", f"/jobs/{job['id']}/bundles")[2])
        scenarios = client.call("GET", f"/jobs/{job['id']}/openscenario")[2]
        write_output(folder / "openscenario.zip", scenarios)


def _download_campaign(client: Client, job: dict[str, Any], folder: Path) -> None:
    """campaign.json and report.html of the job's campaign; a campaign that stopped before
    its first level has neither (said on stderr)."""
    try:
        outcome = client.json("GET", f"/jobs/{job['id']}/campaign")
    except ServerRefused:  # 404: no level finished
        print(f"scengen: job {job['id']} has no campaign outcome: no campaign.json or "
              "report.html", file=sys.stderr)  # fmt: skip
        return
    write_output(folder / "campaign.json", json.dumps(outcome, indent=1) + "\n")  # as campaign -o
    client.timeout = max(client.timeout, 300.0)
    report = client.call("GET", f"/jobs/{job['id']}/campaign/report")[2]
    write_output(folder / "report.html", report)


def outcome(job: dict[str, Any]) -> int:
    if job["state"] != "succeeded":
        return 3
    return 1 if job["evaluations"]["failed"] else 0


def print_failures(job: dict[str, Any], out: TextIO = sys.stderr) -> None:
    for item in job["items"]:
        if item["state"] in ("failed", "cancelled"):
            out.write(
                f"item {item['position']} ({item['kind']}) {item['state']}: {item['error']}\n"
            )
