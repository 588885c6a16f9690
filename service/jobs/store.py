"""The authoritative state of batch jobs, in the service's database (not in the queue).

An item moves queued -> running -> succeeded | failed | cancelled. A worker claims an item
with one conditional UPDATE (so a message delivered twice runs once) and holds a lease it
renews while it works; an item whose lease ran out (its worker was killed) goes back to
queued until it has been started ``attempts`` times, then fails with the reason. Results are
written as they are made (a chain's test-cases level by level), so a retry resumes.
"""

from __future__ import annotations

import hashlib
import json
import re
import secrets
import time
from dataclasses import dataclass
from datetime import datetime
from typing import Any

import sqlalchemy as sa

from service.core import errors
from service.jobs.batch import Batch, dependencies
from service.store import Page, Store, metadata, now, utc

jobs = sa.Table(
    "jobs",
    metadata,
    sa.Column("id", sa.String(32), primary_key=True),
    sa.Column("name", sa.Text, nullable=False),
    sa.Column("state", sa.String(16), nullable=False, index=True),
    sa.Column("batch", sa.Text, nullable=False),
    sa.Column("fingerprint", sa.String(64), nullable=False),
    sa.Column("idempotency_key", sa.String(255), nullable=True, unique=True),
    sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
    sa.Column("started_at", sa.DateTime(timezone=True), nullable=True),
    sa.Column("finished_at", sa.DateTime(timezone=True), nullable=True),
)

items = sa.Table(
    "job_items",
    metadata,
    sa.Column("job", sa.String(32), primary_key=True),
    sa.Column("position", sa.Integer, primary_key=True),
    sa.Column("kind", sa.String(16), nullable=False),
    sa.Column("spec", sa.Text, nullable=False),
    sa.Column("needs", sa.Text, nullable=False),  # JSON list of positions
    sa.Column("state", sa.String(16), nullable=False, index=True),
    sa.Column("attempts", sa.Integer, nullable=False),
    sa.Column("owner", sa.String(255), nullable=True),
    sa.Column("lease_until", sa.Float, nullable=True),  # unix time
    sa.Column("sent_at", sa.Float, nullable=True),  # unix time the item was queued to Celery
    sa.Column("progress", sa.Text, nullable=False),
    sa.Column("testcases", sa.Text, nullable=False),  # JSON list of ids, in order made
    sa.Column("evaluations", sa.Text, nullable=False),  # JSON list of ids
    sa.Column("error", sa.Text, nullable=True),  # why it failed, in plain words
    sa.Column("started_at", sa.DateTime(timezone=True), nullable=True),
    sa.Column("finished_at", sa.DateTime(timezone=True), nullable=True),
    # added later: the class of service.core.errors that failed it (None: none of them)
    sa.Column("error_kind", sa.String(64), nullable=True),
)

# What an item remembers of its steps beyond test-cases and evaluations (a campaign's
# chain ends and its outcome so far), so that a retry answers them from memory
memos = sa.Table(
    "job_item_memos",
    metadata,
    sa.Column("job", sa.String(32), primary_key=True),
    sa.Column("position", sa.Integer, primary_key=True),
    sa.Column("key", sa.String(255), primary_key=True),
    sa.Column("value", sa.Text, nullable=False),  # JSON
)

FINISHED = ("succeeded", "failed", "cancelled")
ERROR_KINDS = frozenset(
    name
    for name, value in vars(errors).items()
    if isinstance(value, type) and issubclass(value, errors.ScengenError)
)
SWEEP_PERIOD = 10.0  # seconds between looks for jobs left unfinished with finished items


@dataclass(frozen=True)
class ItemRecord:
    job: str
    position: int
    kind: str
    spec: dict[str, Any]
    needs: list[int]
    state: str
    attempts: int
    owner: str | None
    progress: str
    testcases: list[str]
    evaluations: list[str]
    error: str | None
    started_at: datetime | None
    finished_at: datetime | None
    error_kind: str | None = None  # the class of service.core.errors behind ``error``
    sent_at: float | None = None  # unix time its message was sent or last seen in the broker

    def evaluation_id(self, testcase: str, controller: str) -> str:
        """The same item, test-case and controller: the same stored evaluation, once."""
        key = f"{self.job}/{self.position}/{testcase}/{controller}"
        return hashlib.sha256(key.encode()).hexdigest()[:16]


@dataclass(frozen=True)
class JobRecord:
    id: str
    name: str
    state: str
    fingerprint: str
    idempotency_key: str | None
    created_at: datetime
    started_at: datetime | None
    finished_at: datetime | None
    items: list[ItemRecord]


class IdempotencyConflict(Exception):
    """The Idempotency-Key was used before with another batch."""


class JobStore:
    """Jobs and their items, over the service's ``Store``."""

    def __init__(self, store: Store) -> None:
        self.store = store
        self.engine = store.engine
        self._swept = -SWEEP_PERIOD

    def create(self, batch: Batch, key: str | None = None) -> tuple[JobRecord, bool]:
        """The new job (True), or the job an earlier request with ``key`` made (False)."""
        fingerprint = batch.fingerprint()
        if key is not None:
            existing = self.by_key(key)
            if existing is not None:
                if existing.fingerprint != fingerprint:
                    raise IdempotencyConflict(key)
                return existing, False
        ident = secrets.token_hex(8)
        try:
            self._insert(ident, batch, fingerprint, key)
        except sa.exc.IntegrityError:
            if key is None:
                raise
            return self.create(batch, key)  # the same key, submitted at the same moment
        job = self.job(ident)
        assert job is not None
        return job, True

    def _insert(self, ident: str, batch: Batch, fingerprint: str, key: str | None) -> None:
        with self.engine.begin() as connection:
            connection.execute(
                jobs.insert().values(
                    id=ident,
                    name=batch.name,
                    state="queued",
                    batch=json.dumps(batch.model_dump(mode="json")),
                    fingerprint=fingerprint,
                    idempotency_key=key,
                    created_at=now(),
                )
            )
            for position, item in enumerate(batch.items):
                connection.execute(
                    items.insert().values(
                        job=ident,
                        position=position,
                        kind=item.kind,
                        spec=json.dumps(item.model_dump(mode="json")),
                        needs=json.dumps(dependencies(item)),
                        state="queued",
                        attempts=0,
                        progress="",
                        testcases="[]",
                        evaluations="[]",
                    )
                )

    def by_key(self, key: str) -> JobRecord | None:
        """The job an earlier request with this Idempotency-Key made, or None."""
        with self.engine.connect() as connection:
            ident = connection.execute(
                sa.select(jobs.c.id).where(jobs.c.idempotency_key == key)
            ).scalar()
        return None if ident is None else self.job(ident)

    def job(self, ident: str) -> JobRecord | None:
        with self.engine.connect() as connection:
            row = connection.execute(sa.select(jobs).where(jobs.c.id == ident)).first()
            if row is None:
                return None
            rows = connection.execute(
                sa.select(items).where(items.c.job == ident).order_by(items.c.position)
            )
            found = [_item(r._mapping) for r in rows]
        return _job(row._mapping, found)

    def list_jobs(
        self, state: str | None = None, limit: int = 50, offset: int = 0
    ) -> Page[JobRecord]:
        query = sa.select(jobs.c.id)
        if state is not None:
            query = query.where(jobs.c.state == state)
        counted = sa.select(sa.func.count()).select_from(query.subquery())
        ordered = query.order_by(jobs.c.created_at.desc(), jobs.c.id).limit(limit).offset(offset)
        with self.engine.connect() as connection:
            total = connection.execute(counted).scalar_one()
            idents = list(connection.execute(ordered).scalars())
        return Page([j for j in (self.job(i) for i in idents) if j is not None], total)

    def item(self, job: str, position: int) -> ItemRecord | None:
        with self.engine.connect() as connection:
            row = connection.execute(
                sa.select(items).where(items.c.job == job, items.c.position == position)
            ).first()
        return None if row is None else _item(row._mapping)

    # the worker side

    def claim(self, job: str, position: int, owner: str, lease: float) -> bool:
        """Take a queued item (atomically: of two claims, one wins)."""
        with self.engine.begin() as connection:
            claimed = connection.execute(
                items.update()
                .where(items.c.job == job, items.c.position == position, items.c.state == "queued")
                .values(
                    state="running",
                    owner=owner,
                    lease_until=time.time() + lease,
                    attempts=items.c.attempts + 1,
                    started_at=sa.func.coalesce(items.c.started_at, now()),
                )
            ).rowcount
            if claimed:
                connection.execute(
                    jobs.update()
                    .where(jobs.c.id == job, jobs.c.state == "queued")
                    .values(state="running", started_at=now())
                )
        return bool(claimed)

    def renew(self, job: str, position: int, owner: str, lease: float) -> bool:
        """Extend the lease; False when the item is no longer this owner's (cancelled,
        or given to another worker after the lease ran out)."""
        with self.engine.begin() as connection:
            renewed = connection.execute(
                items.update()
                .where(*_owned(job, position, owner))
                .values(lease_until=time.time() + lease)
            ).rowcount
        return bool(renewed)

    def record(
        self, job: str, position: int, owner: str, progress: str,
        testcases: list[str] | None = None, evaluations: list[str] | None = None,
    ) -> None:  # fmt: skip
        """Results so far of a running item (kept even if its worker dies next)."""
        values: dict[str, Any] = {"progress": progress}
        if testcases is not None:
            values["testcases"] = json.dumps(testcases)
        if evaluations is not None:
            values["evaluations"] = json.dumps(evaluations)
        with self.engine.begin() as connection:
            connection.execute(items.update().where(*_owned(job, position, owner)).values(**values))

    def memo(self, job: str, position: int, key: str) -> Any:
        """What the item remembered under ``key``, or None."""
        with self.engine.connect() as connection:
            found = connection.execute(
                sa.select(memos.c.value).where(
                    memos.c.job == job, memos.c.position == position, memos.c.key == key
                )
            ).scalar()
        return None if found is None else json.loads(found)

    def remember(self, job: str, position: int, owner: str, key: str, value: Any) -> None:
        """Keep ``value`` under ``key`` (replacing it), while the item is this owner's."""
        where = [memos.c.job == job, memos.c.position == position, memos.c.key == key]
        with self.engine.begin() as connection:
            owned = connection.execute(
                sa.select(items.c.position).where(*_owned(job, position, owner))
            ).first()
            if owned is None:
                return  # cancelled or taken over: the new owner writes its own
            connection.execute(memos.delete().where(*where))
            connection.execute(
                memos.insert().values(job=job, position=position, key=key, value=json.dumps(value))
            )

    def finish(
        self,
        job: str,
        position: int,
        owner: str | None,
        state: str,
        error: str | None = None,
        expired_before: float | None = None,
        error_kind: str | None = None,
    ) -> None:
        """Finish an item (only its owner's, and only while unfinished) and, in the same
        transaction, its job when this was the last item. ``error`` says why it failed in
        plain words; ``error_kind`` names the class of service.core.errors behind it."""
        where = [items.c.job == job, items.c.position == position, items.c.state.not_in(FINISHED)]
        if owner is not None:
            where.append(items.c.owner == owner)
        if expired_before is not None:
            where.append(items.c.lease_until < expired_before)
        with self.engine.begin() as connection:
            connection.execute(
                items.update()
                .where(*where)
                .values(state=state, error=error, error_kind=error_kind)
                .values(finished_at=now(), lease_until=None)
            )
            _refresh(connection, job)

    def refresh(self, job: str) -> None:
        """The job's state from its items' states."""
        with self.engine.begin() as connection:
            _refresh(connection, job)

    def unfinished_jobs(self) -> list[str]:
        with self.engine.connect() as connection:
            return list(
                connection.execute(
                    sa.select(jobs.c.id).where(jobs.c.state.not_in(FINISHED))
                ).scalars()
            )

    def release(self, owner: str) -> int:
        """Give this owner's running items back, undoing their attempt (a clean shutdown)."""
        with self.engine.begin() as connection:
            return int(
                connection.execute(
                    items.update()
                    .where(items.c.owner == owner, items.c.state == "running")
                    .values(
                        state="queued",
                        owner=None,
                        lease_until=None,
                        sent_at=None,
                        attempts=items.c.attempts - 1,
                    )
                ).rowcount
            )

    def reopen(self, job: str) -> int:
        """Queue a job's failed, cancelled or abandoned items again, their results and memos
        kept (``scengen campaign`` run again on its folder: it is the only worker there)."""
        with self.engine.begin() as connection:
            count = connection.execute(
                items.update()
                .where(items.c.job == job, items.c.state != "succeeded")
                .values(
                    state="queued",
                    owner=None,
                    lease_until=None,
                    sent_at=None,
                    error=None,
                    error_kind=None,
                    attempts=0,
                    finished_at=None,
                )
            ).rowcount
            if count:
                connection.execute(
                    jobs.update().where(jobs.c.id == job).values(state="queued", finished_at=None)
                )
        return int(count)

    def cancel(self, job: str) -> None:
        """Cancel every unfinished item; running ones stop at their next lease renewal."""
        with self.engine.begin() as connection:
            connection.execute(
                items.update()
                .where(items.c.job == job, items.c.state.not_in(FINISHED))
                .values(state="cancelled", error="cancelled", finished_at=now())
            )
            _refresh(connection, job)

    # the dispatcher side

    def runnable(
        self, limit: int, unsent_only: bool = False, resend_after: float = 0.0
    ) -> list[ItemRecord]:
        """Queued items whose dependencies succeeded (failing those whose dependencies
        failed); oldest jobs first. ``unsent_only``: only those never sent to the broker, or
        sent (or last seen there, ``mark_sent``) more than ``resend_after`` seconds ago.
        Two light queries, whatever the number of items; only the chosen items are read in
        full."""
        queued = (
            sa.select(items.c.job, items.c.position, items.c.needs)
            .join(jobs, jobs.c.id == items.c.job)
            .where(items.c.state == "queued")
        )
        if unsent_only:
            queued = queued.where(
                sa.or_(items.c.sent_at.is_(None), items.c.sent_at < time.time() - resend_after)
            )
        with self.engine.connect() as connection:
            waiting = list(
                connection.execute(
                    queued.order_by(jobs.c.created_at, items.c.job, items.c.position)
                )
            )
            active = sorted({row.job for row in waiting})
            states = {
                (row.job, row.position): row.state
                for row in connection.execute(
                    sa.select(items.c.job, items.c.position, items.c.state).where(
                        items.c.job.in_(active)
                    )
                )
            } if active else {}  # fmt: skip
        chosen: list[tuple[str, int]] = []
        for row in waiting:
            needs = json.loads(row.needs)
            needed = [states.get((row.job, n), "failed") for n in needs]
            broken = [n for n, state in zip(needs, needed, strict=True)
                      if state in ("failed", "cancelled")]  # fmt: skip
            if broken:
                self.finish(row.job, row.position, None, "failed",
                            f"item {broken[0]} it depends on did not succeed")  # fmt: skip
            elif all(state == "succeeded" for state in needed) and len(chosen) < limit:
                chosen.append((row.job, row.position))
        return [found for found in (self.item(j, p) for j, p in chosen) if found is not None]

    def mark_sent(self, keys: list[tuple[str, int]]) -> None:
        """These queued items' messages were sent, or were seen in the broker, just now."""
        with self.engine.begin() as connection:
            for job, position in keys:
                connection.execute(
                    items.update()
                    .where(
                        items.c.job == job, items.c.position == position,
                        items.c.state == "queued",
                    )
                    .values(sent_at=time.time())
                )  # fmt: skip

    def reclaim_expired(self, attempts: int) -> list[tuple[str, int]]:
        """Running items whose lease ran out: back to queued, or failed after ``attempts``.
        Every update re-checks the lease, so a worker that renews meanwhile keeps its item."""
        cutoff = time.time()
        if time.monotonic() - self._swept > SWEEP_PERIOD:
            self._swept = time.monotonic()
            for job in self.unfinished_jobs():
                self.refresh(job)  # a job whose last item finished as its worker died
        with self.engine.connect() as connection:
            rows = [
                _item(r._mapping)
                for r in connection.execute(
                    sa.select(items).where(items.c.state == "running", items.c.lease_until < cutoff)
                )
            ]
        moved = []
        for item in rows:
            if item.attempts >= attempts:
                self.finish(
                    item.job, item.position, item.owner, "failed",
                    f"its worker stopped answering {item.attempts} times (killed or out of "
                    f"memory?); last owner {item.owner}",
                    expired_before=cutoff,
                )  # fmt: skip
            else:
                with self.engine.begin() as connection:
                    connection.execute(
                        items.update()
                        .where(
                            items.c.job == item.job,
                            items.c.position == item.position,
                            items.c.owner == item.owner,
                            items.c.state == "running",
                            items.c.lease_until < cutoff,
                        )
                        .values(state="queued", owner=None, lease_until=None, sent_at=None)
                    )
            moved.append((item.job, item.position))
        return moved


def _item(row: Any) -> ItemRecord:
    error, kind = row["error"], row["error_kind"]
    legacy = re.match(r"([A-Z][A-Za-z]+): (.*)", error or "", re.S)
    if kind is None and legacy and legacy[1] in ERROR_KINDS:  # "Class: message", stored before
        kind, error = legacy[1], legacy[2]
    return ItemRecord(
        job=row["job"], position=row["position"], kind=row["kind"],
        spec=json.loads(row["spec"]), needs=json.loads(row["needs"]), state=row["state"],
        attempts=row["attempts"], owner=row["owner"], progress=row["progress"],
        testcases=json.loads(row["testcases"]), evaluations=json.loads(row["evaluations"]),
        error=error, error_kind=kind, sent_at=row["sent_at"],
        started_at=utc(row["started_at"]) if row["started_at"] else None,
        finished_at=utc(row["finished_at"]) if row["finished_at"] else None,
    )  # fmt: skip


def _job(row: Any, found: list[ItemRecord]) -> JobRecord:
    return JobRecord(
        id=row["id"], name=row["name"], state=row["state"], fingerprint=row["fingerprint"],
        idempotency_key=row["idempotency_key"], created_at=utc(row["created_at"]),
        started_at=utc(row["started_at"]) if row["started_at"] else None,
        finished_at=utc(row["finished_at"]) if row["finished_at"] else None,
        items=found,
    )  # fmt: skip


def _owned(job: str, position: int, owner: str) -> list[sa.ColumnElement[bool]]:
    """The item, while it runs under this owner."""
    return [
        items.c.job == job,
        items.c.position == position,
        items.c.owner == owner,
        items.c.state == "running",
    ]


def _refresh(connection: sa.Connection, job: str) -> None:
    """Set a job's final state once all its items are finished."""
    states = list(connection.execute(sa.select(items.c.state).where(items.c.job == job)).scalars())
    if not states or not all(s in FINISHED for s in states):
        return
    final = "succeeded" if all(s == "succeeded" for s in states) else "failed"
    if "cancelled" in states and "failed" not in states:
        final = "cancelled"
    connection.execute(
        jobs.update()
        .where(jobs.c.id == job, jobs.c.state.not_in(FINISHED))
        .values(state=final, finished_at=now())
    )
