"""Reliability: hostile requests against a real server, each with its answer, its time, the
server's memory after it and the worst /healthz latency while it ran.

Run with `make bench-reliability` (part of `make bench`). It starts `scengen serve` (two
workers, an API token) on a free port with a fresh data directory, sends each request of
issue 15's list (and what the fuzzer found since) one after another while /healthz is
polled every 20 ms, and prints a Markdown table for docs/reliability.md with the machine and
the date. Each row's request is the curl command that reproduces it.
"""

from __future__ import annotations

import json
import multiprocessing
import platform
import tempfile
import threading
import time
from dataclasses import dataclass, field
from datetime import date
from pathlib import Path
from typing import Any

import httpx2 as httpx

from bench.bench_api import serve
from service.api.schemas import EXAMPLE_EGO, EXAMPLE_NETWORK, EXAMPLE_NEW_ROUTE, example_testcase
from service.core.network import bundled_networks

TOKEN = "bench-secret"
AUTH = {"authorization": f"Bearer {TOKEN}"}
CREATE = {"network": EXAMPLE_NETWORK, "ego_route": EXAMPLE_EGO}


@dataclass
class Hostile:
    name: str
    method: str
    path: str
    json_body: Any = None
    content: bytes | None = None
    files: dict[str, Any] | None = None
    data: dict[str, str] | None = None
    headers: dict[str, str] = field(default_factory=lambda: dict(AUTH))
    curl: str = ""

    def __post_init__(self) -> None:
        if self.content is not None:  # raw JSON (NaN, Infinity): json= would refuse it
            self.headers.setdefault("content-type", "application/json")


def hostile_requests() -> list[Hostile]:
    flood = json.dumps({**CREATE, "params": {f"k{i}": 1 for i in range(1_000_000)}}).encode()
    network = bundled_networks()[EXAMPLE_NETWORK].read_bytes()
    nested = "[" * 100_000 + "]" * 100_000
    return [
        Hostile(
            "600 million samples",
            "POST",
            "/testcases",
            {**CREATE, "timestep": 1e-6, "duration": 600},
            curl='-d \'{"network":"4way-stop","ego_route":"E2C_1:C2S_1","timestep":1e-6,'
            '"duration":600}\' /testcases',
        ),
        Hostile(
            "timestep 5e-324",
            "POST",
            "/testcases",
            {**CREATE, "timestep": 5e-324},
            curl="-d '{... \"timestep\": 5e-324}' /testcases",
        ),
        Hostile(
            "inline duration Infinity",
            "POST",
            "/extend",
            content=json.dumps(
                {
                    "testcase": {**example_testcase(), "duration": float("inf")},
                    "routes": [EXAMPLE_NEW_ROUTE],
                }
            ).encode(),
            curl='-d \'{"testcase": {... "duration": Infinity}, ...}\' /extend',
        ),
        Hostile(
            "params.v_max Infinity",
            "POST",
            "/testcases",
            content=b'{"network":"4way-stop","ego_route":"E2C_1:C2S_1",'
            b'"params":{"v_max":Infinity}}',
            curl='-d \'{... "params": {"v_max": Infinity}}\' /testcases',
        ),
        *(
            Hostile(
                f"params.{key} {value!r}",
                "POST",
                "/testcases",
                {**CREATE, "params": {key: value}},
                curl=f'-d \'{{... "params": {{"{key}": {value!r}}}}}\' /testcases',
            )
            for key, value in (("v_max", 1e308), ("m", 1e308), ("a_min", -5e-324))
        ),
        Hostile(
            "duration NaN",
            "POST",
            "/testcases",
            content=b'{"network":"4way-stop","ego_route":"E2C_1:C2S_1","duration":NaN}',
            curl="-d '{... \"duration\": NaN}' /testcases",
        ),
        Hostile(
            "a million unknown keys (14 MB)",
            "POST",
            "/testcases",
            content=flood,
            curl="-d @million-keys.json /testcases",
        ),
        Hostile(
            "offset 10^20",
            "GET",
            "/testcases?offset=99999999999999999999",
            curl="'/testcases?offset=99999999999999999999' (and /evaluations, /jobs)",
        ),
        Hostile(
            "junction id with a NUL",
            "GET",
            "/networks/4way-stop/junctions/a%00b",
            curl="/networks/4way-stop/junctions/a%00b",
        ),
        Hostile(
            "junction id of 10,000 characters",
            "GET",
            "/networks/4way-stop/junctions/" + "j" * 10_000 + "/plot",
            curl="/networks/4way-stop/junctions/jjj...j/plot",
        ),
        Hostile(
            "controls nested 100,000 deep",
            "POST",
            "/networks",
            files={"file": ("n.net.xml", network)},
            data={"controls": nested},
            curl="-F file=@4way-stop.net.xml -F controls='[[[[...]]]]' /networks",
        ),
        Hostile(
            "a 15 MB XML attribute in an upload",
            "POST",
            "/networks",
            files={
                "file": (
                    "n.net.xml",
                    network.replace(b"<net ", b'<net junk="' + b"a" * 15_000_000 + b'" ', 1),
                )
            },
            curl="-F file=@net-with-a-15-MB-attribute.net.xml /networks",
        ),
        Hostile(
            "name with a NUL",
            "POST",
            "/testcases",
            {**CREATE, "name": "a\u0000b"},
            curl='-d \'{... "name": "a\\u0000b"}\' /testcases',
        ),
        Hostile(
            "token after two spaces",
            "DELETE",
            "/testcases/0000000000000000",
            headers={"authorization": f"Bearer  {TOKEN}"},
            curl=f"-X DELETE -H 'Authorization: Bearer  {TOKEN}' /testcases/ID",
        ),
        Hostile(
            "PUT on a test-case",
            "PUT",
            "/testcases/0000000000000000",
            curl="-X PUT /testcases/ID",
        ),
        Hostile(
            "network '../../etc'",
            "POST",
            "/testcases",
            {**CREATE, "network": "../../etc"},
            curl='-d \'{"network": "../../etc", ...}\' /testcases',
        ),
        Hostile(
            "start_distance false",
            "POST",
            "/testcases",
            {**CREATE, "start_distance": False},
            curl="-d '{... \"start_distance\": false}' /testcases",
        ),
        Hostile(
            "extend an unknown testcase_id",
            "POST",
            "/extend",
            {"testcase_id": "nope", "routes": [EXAMPLE_NEW_ROUTE]},
            curl='-d \'{"testcase_id": "nope", "routes": [...]}\' /extend',
        ),
        Hostile(
            "extend with budget 5",
            "POST",
            "/extend",
            {
                "testcase": example_testcase(),
                "routes": [EXAMPLE_NEW_ROUTE, "W2C_1:C2E_1"],
                "budget": 5,
            },
            curl='-d \'{"testcase": ..., "routes": [2 routes], "budget": 5}\' /extend',
        ),
    ]


def rss_mb(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return float("nan")


def poll(url: str, stop: threading.Event, worst: list[float]) -> None:
    with httpx.Client(base_url=url) as client:
        while not stop.is_set():
            clock = time.monotonic()
            client.get("/healthz", timeout=60).raise_for_status()
            worst[0] = max(worst[0], time.monotonic() - clock)
            time.sleep(0.02)


def main() -> None:
    with tempfile.TemporaryDirectory(prefix="scengen-hostile-") as folder:
        server, url = serve(Path(folder), 2, api_token=TOKEN)
        try:
            rows = [measure(url, server.pid, hostile) for hostile in hostile_requests()]
        finally:
            server.terminate()
            server.wait(10)
    print(f"{platform.node()}, {multiprocessing.cpu_count()} cores, {date.today()}\n")
    print("| request | answer | seconds | server RSS after (MB) | worst /healthz (ms) |")
    print("|---|---|---|---|---|")
    for row in rows:
        print("| " + " | ".join(row) + " |")


def measure(url: str, pid: int, hostile: Hostile) -> list[str]:
    stop, worst = threading.Event(), [0.0]
    poller = threading.Thread(target=poll, args=(url, stop, worst))
    poller.start()
    clock = time.monotonic()
    with httpx.Client(base_url=url, timeout=120) as client:
        reply = client.request(
            hostile.method,
            hostile.path,
            json=hostile.json_body,
            content=hostile.content,
            files=hostile.files,
            data=hostile.data,
            headers=hostile.headers,
        )
    seconds = time.monotonic() - clock
    time.sleep(0.1)
    stop.set()
    poller.join()
    kind = reply.json().get("type", "") if reply.status_code >= 400 else ""
    answer = f"{reply.status_code} {kind.removeprefix('/problems/')}".strip()
    return [
        f"{hostile.name}: `curl {hostile.curl}`",
        answer,
        f"{seconds:.2f}",
        f"{rss_mb(pid):.0f}",
        f"{worst[0] * 1000:.0f}",
    ]


if __name__ == "__main__":
    main()
