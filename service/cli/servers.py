"""The service: ``serve`` (the HTTP API), ``worker`` (a Celery worker) and ``submit`` (a
batch sent to a server, for CI)."""

from __future__ import annotations

import argparse
import errno
import os
import socket
import sys
from pathlib import Path
from typing import Any

from service.cli.arguments import TOKEN
from service.cli.output import EXIT_FAILED, EXIT_OK
from service.cli.table import arg, command
from service.core.errors import InvalidInput, ScengenError


@command(
    "serve",
    "run the HTTP API (OpenAPI UI at /docs); settings from SCENGEN_* variables",
    arg("--host", default="127.0.0.1", help="address to bind (default 127.0.0.1)"),
    arg("--port", type=int, default=8000, help="port (default 8000)"),
    arg("--data-dir", type=Path, metavar="DIR", writes="folder", help="sets SCENGEN_DATA_DIR"),
    arg("--workers", type=int, metavar="N", help="sets SCENGEN_WORKERS"),
    description="Runs the HTTP API with uvicorn. With no settings it keeps its state in "
    "./scengen-data (SQLite) and runs work in local worker processes; see the README for "
    "SCENGEN_DATA_DIR, SCENGEN_DATABASE_URL, SCENGEN_WORKERS, SCENGEN_API_TOKEN and more.",
)
def serve(args: argparse.Namespace) -> int:
    import uvicorn
    from pydantic import ValidationError

    from service.api import create_app
    from service.settings import Settings

    overrides: dict[str, Any] = {}
    if args.data_dir is not None:
        overrides["data_dir"] = args.data_dir
    if args.workers is not None:
        overrides["workers"] = args.workers
    try:
        settings = Settings(**overrides)
    except ValidationError as error:
        raise InvalidInput(
            f"settings: {error.errors()[0]['loc']}: {error.errors()[0]['msg']}"
        ) from None
    listening = listen(args.host, args.port)  # a port in use is refused before anything starts
    config = uvicorn.Config(create_app(settings), log_level="info")
    base = f"http://{args.host}:{args.port}"
    print(
        f"scengen: serving on {base} (API docs at {base}/docs, results browser at {base}/ui/), "
        f"data in {settings.data_dir.resolve()}, {settings.workers} worker(s)",
        file=sys.stderr,
    )
    uvicorn.Server(config).run(sockets=[listening])
    return EXIT_OK


def listen(host: str, port: int) -> socket.socket:
    """A socket bound to ``host``:``port`` for the server; InvalidInput when the address
    is taken or is not this machine's."""
    try:
        family, kind, proto, _, address = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)[0]
    except socket.gaierror as error:
        raise InvalidInput(f"cannot serve on {host}: {error.strerror}") from None
    listening = socket.socket(family, kind, proto)
    listening.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # as uvicorn does
    try:
        listening.bind(address)
    except OSError as error:
        listening.close()
        hint = " (another program listens there: choose another --port)"
        raise InvalidInput(
            f"cannot serve on {host}:{port}: {error.strerror}"
            + (hint if error.errno == errno.EADDRINUSE else "")
        ) from None
    return listening


@command(
    "worker",
    "run a Celery worker for batch jobs (SCENGEN_EXECUTOR=celery on the server)",
    arg("--concurrency", type=int, default=1, metavar="N", help="tasks at once (default 1)"),
    arg("--name", metavar="NAME", help="worker name (default: host and pid)"),
    description="Runs job items and campaign steps sent by a server whose SCENGEN_EXECUTOR "
    "is celery. It reads SCENGEN_BROKER_URL and SCENGEN_DATABASE_URL (the server's "
    "database). Every solver or SUMO call runs in a fresh child process; a killed "
    "worker's items and steps are retried elsewhere.",
)
def worker(args: argparse.Namespace) -> int:
    import socket

    from service.jobs.celery_app import start_worker
    from service.settings import get_settings

    settings = get_settings()
    name = args.name or f"scengen-{socket.gethostname()}-{os.getpid()}"
    if settings.database.startswith("sqlite"):
        print(
            f"scengen: warning: the worker uses the SQLite file {settings.database}; it must be "
            "the server's own file (same machine and SCENGEN_DATA_DIR), or set "
            "SCENGEN_DATABASE_URL to the server's PostgreSQL",
            file=sys.stderr,
        )
    print(
        f"scengen: worker {name} on {settings.broker_url}, database {settings.database}",
        file=sys.stderr,
    )
    start_worker(settings, args.concurrency, name)
    return EXIT_OK


@command(
    "submit",
    "submit a batch job to a server; with --wait follow it and fetch the results",
    arg("batch", type=Path, metavar="BATCH", help="a .json or .yaml batch file"),
    arg("--server", required=True, metavar="URL", help="e.g. http://127.0.0.1:8000"),
    TOKEN,
    arg("--wait", action="store_true", help="follow the job until it finishes"),
    arg(
        "--junit",
        type=Path,
        metavar="FILE",
        writes="file",
        help="write the JUnit report (waits)",
    ),
    arg(
        "--out",
        type=Path,
        metavar="DIR",
        writes="folder",
        help="download every result into DIR (waits)",
    ),
    arg("--idempotency-key", metavar="KEY", help="resubmitting with the same key is safe"),
    description="Exit codes: 0 every evaluation passed, 1 some evaluation failed, 2 bad "
    "input, 3 the job failed or was cancelled (or the server could not be reached).",
)
def submit(args: argparse.Namespace) -> int:
    from service.cli import submit as client_side

    batch = client_side.read_batch(args.batch)
    client = client_side.Client(args.server, args.token or os.environ.get("SCENGEN_TOKEN"))
    try:
        job = client_side.submit(client, batch, args.idempotency_key)
        print(f"scengen: job {job['id']}: {args.server.rstrip('/')}/jobs/{job['id']}",
              file=sys.stderr)  # fmt: skip
        if not (args.wait or args.junit or args.out):
            return EXIT_OK
        job = client_side.follow(client, job, sys.stderr)
    except client_side.ServerUnreachable as error:
        print(f"scengen: failed: {error}", file=sys.stderr)
        return EXIT_FAILED
    client_side.print_failures(job)
    code = client_side.outcome(job)  # decided before the downloads, which cannot change it
    try:
        client_side.download(client, job, args.junit, args.out)
    except (ScengenError, OSError) as error:
        print(f"scengen: failed: the job {job['state']}, but its results could not be "
              f"fetched: {error}", file=sys.stderr)  # fmt: skip
        return EXIT_FAILED
    return code
