"""Benchmark: ten concurrent POST /extend against a real server while /healthz is polled,
and small requests one after another.

Run with `make bench-api` (part of `make bench`). For each pool size it starts
`scengen serve` on a free port with a fresh data directory, sends ten /extend requests at
once (the four-way example, seeds 0-9, each with the same budget) and polls /healthz every
20 ms until all have answered. It prints, per pool size: each request's status and wall
time against its budget, and the /healthz latency (p50, p95, max). Then, on a server of
two workers, the latency of small requests that each still need a worker (a new test-case,
one naming a junction the network lacks, a junction's description), one at a time: what
a worker call costs beyond its work. `--checkout PATH` serves another checkout of the
project for the small requests as well (the same run, to compare two versions). The
figures go into docs/benchmarks.md with the machine and the date.
"""

from __future__ import annotations

import multiprocessing
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from datetime import date
from pathlib import Path
from typing import Any

import httpx2 as httpx

from service.api.schemas import EXAMPLE_NEW_ROUTE, example_testcase

REQUESTS = 10
BUDGET = 30.0
POOLS = (2, 10)


def serve(
    data_dir: Path, workers: int, cwd: Path | None = None, **settings: str
) -> tuple[subprocess.Popen[bytes], str]:
    """``scengen serve`` on a free port; ``settings`` as SCENGEN_* variables (api_token=...);
    ``cwd``: serve the checkout there (its ``service`` package comes first on the path)."""
    import socket

    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    env = {**os.environ, "SCENGEN_DATA_DIR": str(data_dir), "SCENGEN_WORKERS": str(workers)}
    env.update({f"SCENGEN_{name.upper()}": value for name, value in settings.items()})
    process = subprocess.Popen(
        [sys.executable, "-m", "service", "serve", "--port", str(port)],
        env=env,
        cwd=cwd,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    url = f"http://127.0.0.1:{port}"
    for _ in range(150):
        try:
            if httpx.get(f"{url}/healthz").status_code == 200:
                return process, url
        except httpx.TransportError:
            time.sleep(0.2)
    raise RuntimeError("the server did not come up")


def run(workers: int) -> dict[str, object]:
    with tempfile.TemporaryDirectory(prefix="scengen-bench-") as folder:
        process, url = serve(Path(folder), workers)
        try:
            return measure(url)
        finally:
            process.terminate()
            process.wait(10)


def poll(url: str, stop: Any, answers: Any) -> None:
    """/healthz every 20 ms until ``stop``; the latencies go back through ``answers``."""
    latencies = []
    with httpx.Client(base_url=url) as client:
        while not stop.is_set():
            clock = time.monotonic()
            client.get("/healthz").raise_for_status()
            latencies.append(time.monotonic() - clock)
            time.sleep(0.02)
    answers.put(sorted(latencies))


def measure(url: str) -> dict[str, object]:
    results: list[tuple[int, float]] = []

    def extend(seed: int) -> None:
        body = {"testcase": example_testcase(), "routes": [EXAMPLE_NEW_ROUTE], "seed": seed,
                "budget": BUDGET}  # fmt: skip
        clock = time.monotonic()
        reply = httpx.post(f"{url}/extend", json=body, timeout=BUDGET + 60)
        results.append((reply.status_code, time.monotonic() - clock))

    # The poller is a process of its own, so that the senders' threads (and their GIL) do
    # not delay its measurements.
    context = multiprocessing.get_context("spawn")
    stop, answers = context.Event(), context.Queue()
    poller = context.Process(target=poll, args=(url, stop, answers))
    poller.start()
    clock = time.monotonic()
    senders = [threading.Thread(target=extend, args=(seed,)) for seed in range(REQUESTS)]
    for sender in senders:
        sender.start()
    for sender in senders:
        sender.join()
    wall = time.monotonic() - clock
    stop.set()
    latencies = answers.get(timeout=30)
    poller.join()
    metrics = httpx.get(f"{url}/metrics").text
    lag = [line for line in metrics.splitlines() if line.startswith("scengen_event_loop")]
    return {
        "statuses": sorted(status for status, _ in results),
        "slowest": max(seconds for _, seconds in results),
        "median": statistics.median(seconds for _, seconds in results),
        "wall": wall,
        "polls": len(latencies),
        "p50_ms": 1000 * latencies[len(latencies) // 2],
        "p95_ms": 1000 * latencies[int(len(latencies) * 0.95)],
        "max_ms": 1000 * latencies[-1],
        "lag": lag,
    }


SMALL = 20  # small requests of each kind, one after another


def small_requests(url: str) -> dict[str, float]:
    """Median wall time of each kind of small request (after one unmeasured request of
    each, which starts the workers)."""
    new = {"network": "4way-stop", "ego_route": "E2C_1:C2S_1"}
    kinds: dict[str, tuple[str, str, dict[str, Any] | None, int]] = {
        "POST /testcases (201)": ("POST", "/testcases", new, 201),
        "POST /testcases, unknown junction (422)": (
            "POST", "/testcases", {**new, "junction": "nowhere"}, 422),
        "GET a junction (200)": ("GET", "/networks/4way-stop/junctions/C", None, 200),
    }  # fmt: skip
    medians = {}
    with httpx.Client(base_url=url, timeout=60) as client:
        for kind, (method, path, body, expected) in kinds.items():
            seconds = []
            for attempt in range(SMALL + 1):
                clock = time.monotonic()
                reply = client.request(method, path, json=body)
                if reply.status_code != expected:
                    raise RuntimeError(f"{kind}: {reply.status_code} {reply.text[:300]}")
                if attempt:
                    seconds.append(time.monotonic() - clock)
            medians[kind] = statistics.median(seconds)
    return medians


def print_small_requests(checkouts: list[Path | None]) -> None:
    print(f"\n# small requests, one at a time, 2 workers: median of {SMALL} each")
    rows: dict[str, list[str]] = {}
    for checkout in checkouts:
        with tempfile.TemporaryDirectory(prefix="scengen-bench-") as folder:
            process, url = serve(Path(folder), 2, cwd=checkout)
            try:
                for kind, median in small_requests(url).items():
                    rows.setdefault(kind, []).append(f"{1000 * median:.0f} ms")
            finally:
                process.terminate()
                process.wait(10)
    names = ["this checkout" if c is None else str(c) for c in checkouts]
    print(f"| request | {' | '.join(names)} |")
    print(f"|---|{'---|' * len(names)}")
    for kind, cells in rows.items():
        print(f"| {kind} | {' | '.join(cells)} |")


def main() -> None:
    print(f"# bench_api {date.today()} on {platform.node()} ({os.cpu_count()} cores), "
          f"{REQUESTS} concurrent /extend, budget {BUDGET:g} s each")  # fmt: skip
    print("| workers | statuses | request median | slowest | all done | /healthz p50 | p95 | max |")
    print("|---|---|---|---|---|---|---|---|")
    for workers in POOLS:
        r = run(workers)
        statuses = ", ".join(f"{s}" for s in sorted(set(r["statuses"])))  # type: ignore[call-overload]
        print(
            f"| {workers} | {statuses} x{len(r['statuses'])} | {r['median']:.1f} s | "  # type: ignore[arg-type]
            f"{r['slowest']:.1f} s | {r['wall']:.1f} s | {r['p50_ms']:.1f} ms | "
            f"{r['p95_ms']:.1f} ms | {r['max_ms']:.1f} ms |"
        )
        print("  server side:", "; ".join(r["lag"]))  # type: ignore[arg-type]
    others = [Path(a) for a in sys.argv[sys.argv.index("--checkout") + 1 :][:1]] if (
        "--checkout" in sys.argv) else []  # fmt: skip
    print_small_requests([None, *others])


if __name__ == "__main__":
    main()
