"""/healthz, /metrics (Prometheus text format) and /problems (the error catalogue)."""

from __future__ import annotations

import asyncio
import time

from fastapi import APIRouter
from fastapi.responses import PlainTextResponse

from service.api.problems import ALL_TYPES, Problem
from service.api.schemas import Health
from service.api.state import State

router = APIRouter(tags=["service"])


@router.get("/healthz", operation_id="get_health")
async def get_health(state: State) -> Health:
    """Liveness and readiness: the database answers; the pool's load."""
    state.store.ping()
    stats = state.executor.stats
    return Health(
        status="ok",
        database=state.store.engine.dialect.name,
        workers=stats.workers,
        running=stats.running,
        waiting=stats.waiting,
    )


@router.get("/metrics", operation_id="get_metrics", response_class=PlainTextResponse)
async def get_metrics(state: State) -> PlainTextResponse:
    """Counters and gauges in the Prometheus text exposition format."""
    metrics, stats = state.metrics, state.executor.stats
    testcases, evaluations = await asyncio.to_thread(
        lambda: (
            state.store.list_testcases(limit=1).total,
            state.store.list_evaluations(limit=1).total,
        )
    )
    lines = [
        "# HELP scengen_up_seconds Seconds since the server started.",
        "# TYPE scengen_up_seconds gauge",
        f"scengen_up_seconds {time.time() - metrics.started:.3f}",
        "# HELP scengen_http_requests_total HTTP requests by method, route and status.",
        "# TYPE scengen_http_requests_total counter",
    ]
    for (method, route, code), count in sorted(metrics.requests.items()):
        lines.append(
            f'scengen_http_requests_total{{method="{method}",route="{route}",status="{code}"}} '
            f"{count}"
        )
    lines += [
        "# HELP scengen_http_request_seconds_total Summed request durations.",
        "# TYPE scengen_http_request_seconds_total counter",
    ]
    for (method, route), seconds in sorted(metrics.seconds.items()):
        lines.append(
            f'scengen_http_request_seconds_total{{method="{method}",route="{route}"}} {seconds:.6f}'
        )
    lines += [
        "# HELP scengen_work_total Worker calls by kind of work and outcome.",
        "# TYPE scengen_work_total counter",
    ]
    for (work, outcome), count in sorted(metrics.outcomes.items()):
        lines.append(f'scengen_work_total{{work="{work}",outcome="{outcome}"}} {count}')
    lines += [
        "# HELP scengen_workers Worker processes that may run at once.",
        "# TYPE scengen_workers gauge",
        f"scengen_workers {stats.workers}",
        "# HELP scengen_workers_busy Worker processes running now.",
        "# TYPE scengen_workers_busy gauge",
        f"scengen_workers_busy {stats.running}",
        "# HELP scengen_work_waiting Calls waiting for a free worker.",
        "# TYPE scengen_work_waiting gauge",
        f"scengen_work_waiting {stats.waiting}",
        "# HELP scengen_work_seconds_total Summed wall time of finished worker calls.",
        "# TYPE scengen_work_seconds_total counter",
        f"scengen_work_seconds_total {stats.seconds:.3f}",
        "# HELP scengen_event_loop_lag_max_seconds The event loop's worst late wake-up.",
        "# TYPE scengen_event_loop_lag_max_seconds gauge",
        f"scengen_event_loop_lag_max_seconds {metrics.lag_max:.6f}",
        "# HELP scengen_event_loop_late_total Wake-ups (every 50 ms) later than a threshold.",
        "# TYPE scengen_event_loop_late_total counter",
        *(
            f'scengen_event_loop_late_total{{over="{bucket:g}"}} {count}'
            for bucket, count in sorted(metrics.lag_over.items())
        ),
        "# HELP scengen_job_items_running Job items this server runs now (local executor).",
        "# TYPE scengen_job_items_running gauge",
        f"scengen_job_items_running {len(getattr(state.dispatcher, 'running', ()))}",
        "# HELP scengen_testcases Stored test-cases.",
        "# TYPE scengen_testcases gauge",
        f"scengen_testcases {testcases}",
        "# HELP scengen_evaluations Stored evaluations.",
        "# TYPE scengen_evaluations gauge",
        f"scengen_evaluations {evaluations}",
    ]
    return PlainTextResponse("\n".join(lines) + "\n", media_type="text/plain; version=0.0.4")


@router.get("/problems", operation_id="list_problems")
async def list_problems() -> dict[str, dict[str, object]]:
    """Every problem type the API answers with (the `type` of problem+json bodies)."""
    return {
        t.uri: {"title": t.title, "status": t.status, "description": t.description}
        for t in ALL_TYPES.values()
    }


@router.get("/problems/{slug}", operation_id="get_problem")
async def get_problem(slug: str) -> dict[str, object]:
    """What one problem type means."""
    if slug not in ALL_TYPES:
        raise Problem(404, f"no problem type {slug!r}; GET /problems lists them")
    kind = ALL_TYPES[slug]
    return {
        "type": kind.uri,
        "title": kind.title,
        "status": kind.status,
        "description": kind.description,
    }
