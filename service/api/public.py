"""What a stored record looks like to a client: the public records the routes answer with,
and the same answers read from the store without a server (``store_fetch``, for the paths
a campaign's report embeds)."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any
from urllib.parse import unquote

from service.api.schemas import (
    EvaluationPublic,
    JobItemPublic,
    JobPublic,
    Links,
    NetworkPublic,
    TestCasePublic,
    TestCaseSummary,
)
from service.core.checker.verdict import Verdict
from service.jobs.store import FINISHED, JobRecord, JobStore
from service.pictures.report import Fetch
from service.store import DRIVE_COLUMNS, EvaluationRecord, NetworkRecord, Store, TestCaseRecord


def testcase_links(record: TestCaseRecord) -> Links:
    base = f"/testcases/{record.id}"
    extra = {"parent": f"/testcases/{record.parent}"} if record.parent else {}
    return Links(
        self=base,
        document=f"{base}/document",
        bundle=f"{base}/bundle",
        openscenario=f"{base}/openscenario",
        plot=f"{base}/plot",
        lineage=f"{base}/lineage",
        evaluations=f"/evaluations?testcase={record.id}",
        **extra,
    )


def testcase_summary(record: TestCaseRecord) -> TestCaseSummary:
    return TestCaseSummary(
        id=record.id,
        name=record.name,
        network=record.network,
        junction=record.junction,
        parent=record.parent,
        nonegos=record.nonegos,
        level=record.level,
        duration=record.duration,
        created_at=record.created_at,
        links=testcase_links(record),
    )


def testcase_public(record: TestCaseRecord) -> TestCasePublic:
    return TestCasePublic(
        **testcase_summary(record).model_dump(), testcase=json.loads(record.document)
    )


def network_public(record: NetworkRecord) -> NetworkPublic:
    return NetworkPublic(
        id=record.id,
        filename=record.filename,
        sha256=record.sha256,
        size=record.size,
        bundled=record.bundled,
        controls=record.controls,
        created_at=record.created_at,
        source=record.source,
        links=Links(
            self=f"/networks/{record.id}",
            file=f"/networks/{record.id}/file",
            junctions=f"/networks/{record.id}/junctions",
            **({"source": f"/networks/{record.id}/source"} if record.source else {}),
        ),
    )


def evaluation_public(record: EvaluationRecord) -> EvaluationPublic:
    verdict = Verdict.from_dict(record.verdict)
    return EvaluationPublic(
        id=record.id,
        testcase=record.testcase,
        controller=record.controller,
        passed=record.passed,
        reasons=verdict.reasons,
        information=verdict.information,
        verdict=record.verdict,
        seconds=round(record.seconds, 3),
        created_at=record.created_at,
        links=Links(
            self=f"/evaluations/{record.id}",
            junit=f"/evaluations/{record.id}?format=junit",
            testcase=f"/testcases/{record.testcase}",
            plot=f"/testcases/{record.testcase}/plot?controller={record.controller}",
        ),
    )


def job_public(store: Store, job: JobRecord) -> JobPublic:
    verdicts = list(store.evaluations_passed([e for item in job.items for e in item.evaluations]))
    base = f"/jobs/{job.id}"
    return JobPublic(
        id=job.id,
        name=job.name,
        state=job.state,
        created_at=job.created_at,
        started_at=job.started_at,
        finished_at=job.finished_at,
        done=sum(1 for item in job.items if item.state in FINISHED),
        total=len(job.items),
        evaluations={"passed": sum(verdicts), "failed": len(verdicts) - sum(verdicts)},
        items=[
            JobItemPublic(
                position=i.position,
                kind=i.kind,
                state=i.state,
                attempts=i.attempts,
                progress=i.progress,
                needs=i.needs,
                testcases=i.testcases,
                evaluations=i.evaluations,
                error=i.error,
                started_at=i.started_at,
                finished_at=i.finished_at,
                links=[f"/testcases/{t}" for t in i.testcases]
                + [f"/evaluations/{e}" for e in i.evaluations],
            )
            for i in job.items
        ],
        links=Links(
            self=base,
            junit=f"{base}/junit",
            bundles=f"{base}/bundles",
            openscenario=f"{base}/openscenario",
        ),
    )


Shapes = Callable[[Path, str, str], dict[str, Any]]  # network file, junction, control


def store_fetch(store: Store, shapes: Shapes) -> Fetch:
    """The answers a server on ``store`` gives (its own response models), for the paths a
    report needs; ``shapes`` draws a junction (``tasks.junction_geometry``)."""
    jobs = JobStore(store)

    def fetch(path: str) -> Any:
        where, _, query = path.partition("?")
        parts = [unquote(part) for part in where.strip("/").split("/")]
        asked = dict(pair.split("=", 1) for pair in query.split("&") if pair)
        answer: Any
        if parts[0] == "jobs":
            answer = job_public(store, _found(jobs.job(parts[1]), path))
        elif parts[0] == "testcases":
            answer = testcase_public(_found(store.testcase(parts[1]), path))
        elif parts[0] == "networks":
            return shapes(store.network_file(parts[1]), parts[3], asked["control"])
        elif parts == ["evaluations"]:
            found = store.list_evaluations(asked["testcase"], int(asked.get("limit", 50)))
            return {
                "items": [evaluation_public(e).model_dump(mode="json") for e in found.items],
                "total": found.total,
            }
        elif parts[0] == "evaluations" and parts[2:] == ["drive"]:
            return {"evaluation": parts[1], "columns": DRIVE_COLUMNS,
                    "trajectory": store.drive(parts[1]) or []}  # fmt: skip
        else:
            raise KeyError(path)
        return answer.model_dump(mode="json")

    return fetch


def _found(record: Any, path: str) -> Any:
    if record is None:
        raise KeyError(f"nothing stored at {path}")
    return record
