"""Reliability: large stored documents against a real server. The worst /healthz latency
and the server's memory while five 30 MB test-cases are read, exported and plotted at once.

Run with `make bench-reliability` (after the hostile requests). It starts `scengen serve`
(two workers, an API token) on a free port with a fresh data directory, makes the issue's
document: an ego-only test-case of 600 s at 0.01 s (60,000 samples per car), extended once
(one new car and the two certificates: 30 MB of JSON); then sends each scenario's requests
at once while /healthz is polled every 20 ms and the server's resident memory is sampled,
and prints a Markdown table for docs/reliability.md. "after" is the memory 3 s after the
scenario's last answer; "loop late" counts the server's own event-loop wake-ups (every 50 ms)
that came over 100 ms late (`/metrics`), whatever the client saw. ``--source DIR`` serves
another checkout (the same API) to measure a version before a change.
"""

from __future__ import annotations

import argparse
import multiprocessing
import platform
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from datetime import date
from pathlib import Path
from typing import Any

import httpx2 as httpx

from bench.bench_api import serve
from bench.bench_hostile import rss_mb
from service.api.schemas import EXAMPLE_EGO, EXAMPLE_NETWORK, EXAMPLE_NEW_ROUTE

TOKEN = "bench-secret"
AUTH = {"authorization": f"Bearer {TOKEN}"}
ROOT = {
    "network": EXAMPLE_NETWORK,
    "ego_route": EXAMPLE_EGO,
    "duration": 600,
    "timestep": 0.01,
}
AT_ONCE = 5
Request = tuple[str, str, dict[str, object] | None]  # method, path, JSON body
SETTLE = 3.0  # seconds after the last answer before "after" is read


def poll(url: str, pid: int, stop: Any, answers: Any) -> None:
    """/healthz every 20 ms and the server's RSS until ``stop``, in a process of its own (the
    senders' threads, reading 16 MB answers, would delay it); (worst latency, peak RSS)."""
    worst, peak = 0.0, rss_mb(pid)
    with httpx.Client(base_url=url) as client:
        while not stop.is_set():
            clock = time.monotonic()
            client.get("/healthz", timeout=120).raise_for_status()
            worst = max(worst, time.monotonic() - clock)
            peak = max(peak, rss_mb(pid))
            time.sleep(0.02)
    answers.put((worst, peak))


def late_wakeups(url: str) -> int:
    """How often the server's event loop woke up over 100 ms late so far (/metrics)."""
    text = httpx.get(f"{url}/metrics", timeout=60).text
    for line in text.splitlines():
        if line.startswith('scengen_event_loop_late_total{over="0.1"}'):
            return int(line.split()[-1])
    raise RuntimeError("/metrics has no scengen_event_loop_late_total")


def scenario(url: str, pid: int, name: str, requests: list[Request]) -> list[str]:
    """The requests at once (none: the server idle for as long as SETTLE); a table row."""

    def send(request: Request) -> tuple[int, int]:
        method, path, body = request
        with httpx.Client(base_url=url, timeout=900, headers=AUTH) as client:
            reply = client.request(method, path, json=body)
            return reply.status_code, len(reply.content)

    context = multiprocessing.get_context("spawn")
    stop, answers = context.Event(), context.Queue()
    poller = context.Process(target=poll, args=(url, pid, stop, answers))
    before, late = rss_mb(pid), late_wakeups(url)
    poller.start()
    time.sleep(1.0)  # the poller is up
    clock = time.monotonic()
    with ThreadPoolExecutor(max(1, len(requests))) as pool:
        replies = list(pool.map(send, requests))
    seconds = time.monotonic() - clock
    time.sleep(SETTLE)
    stop.set()
    worst, peak = answers.get()
    poller.join()
    statuses = sorted({status for status, _ in replies})
    largest = max((size for _, size in replies), default=0) / 1e6
    return [
        name,
        "/".join(map(str, statuses)) or "-",
        f"{largest:.1f}",
        f"{seconds:.1f}",
        f"{worst * 1000:.0f}",
        str(late_wakeups(url) - late),
        f"{before:.0f} / {peak:.0f} / {rss_mb(pid):.0f}",
    ]


def _at_once(path: str) -> list[Request]:
    return [("GET", path, None)] * AT_ONCE


def rows(url: str, pid: int) -> list[list[str]]:
    with httpx.Client(base_url=url, timeout=900, headers=AUTH) as client:
        root = client.post("/testcases", json=ROOT)
        root.raise_for_status()
    extend = {"testcase_id": root.json()["id"], "routes": [EXAMPLE_NEW_ROUTE], "budget": 300}
    found = [
        scenario(url, pid, "none (the server idle)", []),
        scenario(
            url, pid, "POST /extend making the 30 MB test-case", [("POST", "/extend", extend)]
        ),
    ]
    with httpx.Client(base_url=url, timeout=60) as client:
        children = client.get("/testcases", params={"parent": root.json()["id"]}).json()
    leaf = f"/testcases/{children['items'][0]['id']}"
    found += [
        scenario(url, pid, f"{AT_ONCE} x GET {{id}}", _at_once(leaf)),
        scenario(url, pid, f"{AT_ONCE} x GET {{id}}/document", _at_once(f"{leaf}/document")),
        scenario(
            url, pid, f"{AT_ONCE} x GET {{id}}/bundle (made once)", _at_once(f"{leaf}/bundle")
        ),
        scenario(url, pid, f"{AT_ONCE} x GET {{id}}/bundle (cached)", _at_once(f"{leaf}/bundle")),
        scenario(
            url,
            pid,
            f"{AT_ONCE} x (GET {{id}}, bundle, OpenSCENARIO, plot) at once",
            _at_once(leaf)
            + _at_once(f"{leaf}/bundle")
            + _at_once(f"{leaf}/openscenario")
            + _at_once(f"{leaf}/plot?format=png"),
        ),
        scenario(url, pid, f"{AT_ONCE} x GET {{id}}/lineage", _at_once(f"{leaf}/lineage")),
    ]
    return found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--source", type=Path, help="serve this checkout instead")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="scengen-large-") as folder:
        server, url = serve(Path(folder), 2, cwd=args.source, api_token=TOKEN)
        try:
            table = rows(url, server.pid)
        finally:
            server.terminate()
            server.wait(10)
    print(f"{platform.node()}, {multiprocessing.cpu_count()} cores, {date.today()}\n")
    print(
        "| requests at once | answers | largest answer (MB) | seconds | worst /healthz (ms) "
        "| loop late > 100 ms | server RSS before / peak / after (MB) |"
    )
    print("|---|---|---|---|---|---|---|")
    for row in table:
        print("| " + " | ".join(row) + " |")


if __name__ == "__main__":
    main()
