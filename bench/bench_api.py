"""Benchmark: ten concurrent POST /extend against a real server while /healthz is polled.

Run with `make bench-api` (part of `make bench`). For each pool size it starts
`scengen serve` on a free port with a fresh data directory, sends ten /extend requests at
once (the four-way example, seeds 0-9, each with the same budget) and polls /healthz every
20 ms until all have answered. It prints, per pool size: each request's status and wall
time against its budget, and the /healthz latency (p50, p95, max). The figures go into
docs/benchmarks.md with the machine and the date.
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


if __name__ == "__main__":
    main()
