"""A campaign's steps as the Celery executor hands them out: one row per step, in the
service's database beside the job items (service.jobs.store).

A step (a junction read, a root, a level grown, a verdict) moves queued -> running -> done
or failed. The campaign's coordinator posts it once (its id is a digest of its memo key, so
a coordinator that posts it again, after a server restart, finds the same row), sends it to
Celery, and waits for it. One worker claims it with a conditional UPDATE (a message
delivered twice runs once) under a lease it renews while it works, and finishes it with its
result (JSON) or its error, kept as soon as it exists. A step whose lease ran out (its
worker was killed) goes back to queued and is sent again, until it has been started
``attempts`` times; then it fails, and its campaign with it.
"""

from __future__ import annotations

import hashlib
import json
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import sqlalchemy as sa

from service.jobs.store import FINISHED, items
from service.store import Store, metadata

steps = sa.Table(
    "job_steps",
    metadata,
    sa.Column("job", sa.String(32), primary_key=True),
    sa.Column("position", sa.Integer, primary_key=True),
    sa.Column("step", sa.String(32), primary_key=True),  # step_id(key)
    sa.Column("key", sa.Text, nullable=False),  # the campaign's memo key of the step
    sa.Column("request", sa.Text, nullable=False),  # JSON: what to do
    sa.Column("state", sa.String(16), nullable=False),
    sa.Column("attempts", sa.Integer, nullable=False),
    sa.Column("owner", sa.String(255), nullable=True),
    sa.Column("lease_until", sa.Float, nullable=True),  # unix time
    sa.Column("sent_at", sa.Float, nullable=True),  # unix time its message was last sent or seen
    sa.Column("posted_at", sa.Float, nullable=False),  # unix time
    sa.Column("finished_at", sa.Float, nullable=True),  # unix time
    sa.Column("seconds", sa.Float, nullable=True),  # how long its last worker worked on it
    sa.Column("result", sa.Text, nullable=True),  # JSON
    sa.Column("error", sa.Text, nullable=True),  # why it failed, in plain words
    sa.Column("error_kind", sa.String(64), nullable=True),  # service.core.errors class
)

STEP_STATES = ("queued", "running", "done", "failed")
WORKER_LOST = "WorkerLost"  # error_kind of a step failed because its workers kept dying


def step_id(key: str) -> str:
    """A step's id: a digest of its key (a memo key may hold slashes and run long)."""
    return hashlib.sha256(key.encode()).hexdigest()[:32]


@dataclass(frozen=True)
class StepRecord:
    job: str
    position: int
    step: str
    key: str
    request: dict[str, Any]
    state: str
    attempts: int
    owner: str | None
    lease_until: float | None
    sent_at: float | None
    posted_at: float
    finished_at: float | None
    seconds: float | None
    result: Any
    error: str | None
    error_kind: str | None


class StepStore:
    """The steps of campaign items, over the service's ``Store``."""

    def __init__(self, store: Store) -> None:
        self.engine = store.engine
        steps.create(self.engine, checkfirst=True)  # however early the store was opened

    def post(self, job: str, position: int, key: str, request: dict[str, Any]) -> StepRecord:
        """The step of ``key``: new and queued, or as an earlier post left it."""
        ident = step_id(key)
        row = {"job": job, "position": position, "step": ident, "key": key,
               "request": json.dumps(request), "state": "queued", "attempts": 0,
               "posted_at": time.time()}  # fmt: skip
        if self.get(job, position, ident) is None:
            try:
                with self.engine.begin() as connection:
                    connection.execute(steps.insert().values(**row))
            except sa.exc.IntegrityError:
                pass  # posted at the same moment by another coordinator: the same step
        found = self.get(job, position, ident)
        assert found is not None
        return found

    def get(self, job: str, position: int, step: str) -> StepRecord | None:
        with self.engine.connect() as connection:
            row = connection.execute(sa.select(steps).where(*_the(job, position, step))).first()
        return None if row is None else _record(row._mapping)

    def of(self, job: str, position: int, wanted: Sequence[str] = ()) -> list[StepRecord]:
        """An item's steps (only those of ``wanted``, when given), in the order posted."""
        query = sa.select(steps).where(steps.c.job == job, steps.c.position == position)
        if wanted:
            query = query.where(steps.c.step.in_(list(wanted)))
        with self.engine.connect() as connection:
            rows = connection.execute(query.order_by(steps.c.posted_at, steps.c.step))
            return [_record(r._mapping) for r in rows]

    # the worker side

    def claim(self, job: str, position: int, step: str, owner: str, lease: float) -> bool:
        """Take a queued step of an unfinished item (of two claims, one wins)."""
        with self.engine.begin() as connection:
            claimed = connection.execute(
                steps.update()
                .where(*_the(job, position, step), steps.c.state == "queued", _item_unfinished())
                .values(state="running", owner=owner, lease_until=time.time() + lease,
                        attempts=steps.c.attempts + 1)
            ).rowcount  # fmt: skip
        return bool(claimed)

    def renew(self, job: str, position: int, step: str, owner: str, lease: float) -> bool:
        """Extend the lease; False when the step is no longer this owner's (its lease ran
        out and it went to another worker) or its item finished (cancelled, failed)."""
        with self.engine.begin() as connection:
            renewed = connection.execute(
                steps.update()
                .where(*_owned(job, position, step, owner), _item_unfinished())
                .values(lease_until=time.time() + lease)
            ).rowcount
        return bool(renewed)

    def finish(
        self, job: str, position: int, step: str, owner: str, seconds: float,
        result: Any = None, error: str | None = None, error_kind: str | None = None,
    ) -> bool:  # fmt: skip
        """Keep a step's result (or, with ``error``, why it failed), while it is this
        owner's; False when it is not (another worker has it now)."""
        with self.engine.begin() as connection:
            finished = connection.execute(
                steps.update()
                .where(*_owned(job, position, step, owner))
                .values(
                    state="failed" if error is not None else "done",
                    result=None if error is not None else json.dumps(result),
                    error=error, error_kind=error_kind, seconds=seconds,
                    finished_at=time.time(), lease_until=None,
                )
            ).rowcount  # fmt: skip
        return bool(finished)

    # the coordinator side

    def mark_sent(self, job: str, position: int, wanted: Sequence[str]) -> None:
        """These queued steps' messages were sent, or seen in the broker, just now."""
        if not wanted:
            return
        with self.engine.begin() as connection:
            connection.execute(
                steps.update()
                .where(steps.c.job == job, steps.c.position == position,
                       steps.c.step.in_(list(wanted)), steps.c.state == "queued")
                .values(sent_at=time.time())
            )  # fmt: skip

    def reclaim(self, job: str, position: int, step: str, attempts: int) -> None:
        """A running step whose lease ran out: back to queued (to be sent again), or
        failed once it has been started ``attempts`` times. The update re-checks the lease,
        so a worker that renews meanwhile keeps its step."""
        cutoff = time.time()
        found = self.get(job, position, step)
        if found is None or found.state != "running" or (found.lease_until or 0) >= cutoff:
            return
        values: dict[str, Any] = {"state": "queued", "owner": None, "sent_at": None}
        if found.attempts >= attempts:
            values = {"state": "failed", "finished_at": cutoff, "error_kind": WORKER_LOST,
                      "error": f"its worker stopped answering {found.attempts} times (killed "
                               f"or out of memory?); last owner {found.owner}"}  # fmt: skip
        with self.engine.begin() as connection:
            connection.execute(
                steps.update()
                .where(*_owned(job, position, step, str(found.owner)),
                       steps.c.lease_until < cutoff)
                .values(lease_until=None, **values)
            )  # fmt: skip


def _the(job: str, position: int, step: str) -> list[sa.ColumnElement[bool]]:
    return [steps.c.job == job, steps.c.position == position, steps.c.step == step]


def _owned(job: str, position: int, step: str, owner: str) -> list[sa.ColumnElement[bool]]:
    return [*_the(job, position, step), steps.c.owner == owner, steps.c.state == "running"]


def _item_unfinished() -> sa.ColumnElement[bool]:
    """The step's item is not finished (a cancelled job's steps stop)."""
    return (
        sa.select(items.c.state)
        .where(items.c.job == steps.c.job, items.c.position == steps.c.position)
        .scalar_subquery()
        .not_in(FINISHED)
    )


def _record(row: Any) -> StepRecord:
    return StepRecord(
        job=row["job"], position=row["position"], step=row["step"], key=row["key"],
        request=json.loads(row["request"]), state=row["state"], attempts=row["attempts"],
        owner=row["owner"], lease_until=row["lease_until"], sent_at=row["sent_at"],
        posted_at=row["posted_at"], finished_at=row["finished_at"], seconds=row["seconds"],
        result=None if row["result"] is None else json.loads(row["result"]),
        error=row["error"], error_kind=row["error_kind"],
    )  # fmt: skip
