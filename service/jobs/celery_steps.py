"""A campaign's steps on Celery workers: the coordinator's side.

With the Celery executor, a campaign item is coordinated by the server (the dispatcher runs
it in a thread of its own, service.jobs.dispatch) and its steps run on the workers: each
step is posted in the database (service.jobs.steps) and sent as a ``scengen.run_step``
message; whichever worker is free claims it, does it (service.jobs.step_runner), keeps its
result in the database as soon as it exists and tells the coordinator so
(service.jobs.step_news). One poller per campaign looks at all the steps it waits for in
one query when such news comes (and every ``LOOK_EVERY`` seconds without news) and wakes
their threads. It also sends a step again whose message the broker lost (Redis restarted
empty: not in the broker a lease after it was sent) and one whose worker died (its lease
ran out), so that every step is done, once. A coordinator that restarts (the server did)
posts the same steps again and finds them as they are: done, running or in the broker.
"""

from __future__ import annotations

import sys
import threading
import time
from typing import TYPE_CHECKING, Any, Protocol

import redis

from service.core import errors
from service.jobs.calls import Stopped
from service.jobs.step_news import is_redis, wait_for_news
from service.jobs.steps import WORKER_LOST, StepRecord, StepStore, step_id

if TYPE_CHECKING:
    from service.jobs.campaign_steps import ItemWork

# Steps a campaign on Celery keeps sent at once: its waves' steps wait in the broker's queue
# for whichever worker is free, so every worker of the deployment has one to take
STEPS_SENT = 64
POLL = 0.1  # seconds between the poller's looks when the broker brings no news (not Redis)
LOOK_EVERY = 1.0  # seconds between its looks at the database without news


class StepBroker(Protocol):
    """How steps reach the workers (service.jobs.celery_app.CeleryStepBroker)."""

    def send(self, job: str, position: int, step: str) -> None:
        """Send the step's message."""
        ...

    def held(self, fresh: float) -> set[str] | None:
        """The steps whose message the broker holds (in its queue, or delivered less than
        ``fresh`` seconds ago); None when it cannot tell."""
        ...


class StepFailed(Exception):
    """A step failed on its worker with an error that is not one of service.core.errors
    (a bug there: its log has the details)."""


class CelerySteps:
    """Runs a campaign's steps (``StepRunner``) on Celery workers; ``run`` blocks until the
    step is done and answers its result, or raises its error."""

    def __init__(self, work: ItemWork, broker: StepBroker) -> None:
        self.work, self.broker = work, broker
        self.at_once = STEPS_SENT
        self.steps = StepStore(work.store)
        self.job, self.position = work.item.job, work.item.position
        self.settings = work.settings
        self.stop = work.stop
        self.lock = threading.Lock()
        self.waiting: dict[str, threading.Event] = {}  # step id -> set when it finished
        self.answers: dict[str, StepRecord] = {}
        self.poller: threading.Thread | None = None

    def run(self, key: str, request: dict[str, Any]) -> Any:
        record = self.steps.post(self.job, self.position, key, request)
        if record.state == "queued" and record.sent_at is None:
            try:
                self._send(record.step)
            except Exception as error:  # the broker is away: the poller sends it later
                print(f"scengen: job {self.job} item {self.position}: step {key} not sent yet: "
                      f"{type(error).__name__}: {error}", file=sys.stderr)  # fmt: skip
        if record.state not in ("done", "failed"):
            finished = threading.Event()
            with self.lock:
                self.waiting[record.step] = finished
                if self.poller is None:
                    self.poller = threading.Thread(target=self._poll, daemon=True,
                                                   name=f"scengen-steps-{self.job}")  # fmt: skip
                    self.poller.start()
            while not finished.wait(0.5):
                if self.stop.is_set():
                    raise Stopped(f"campaign step {key}")
            with self.lock:
                record = self.answers.pop(record.step)
        return step_answer(record)

    def unfinished(self, key: str) -> bool:
        record = self.steps.get(self.job, self.position, step_id(key))
        return record is not None and record.state in ("queued", "running")

    def _poll(self) -> None:
        news = (
            redis.Redis.from_url(self.settings.broker_url)
            if is_redis(self.settings.broker_url)
            else None
        )
        try:
            while not self.stop.is_set():
                with self.lock:
                    wanted = list(self.waiting)
                try:
                    if wanted:
                        self._look(wanted)
                    if news is None:
                        self.stop.wait(POLL)
                    else:
                        wait_for_news(news, self.job, self.position, LOOK_EVERY)
                except Exception as error:  # the database or the broker is away: look again
                    print(f"scengen: job {self.job} item {self.position}: waiting for its "
                          f"steps: {type(error).__name__}: {error}", file=sys.stderr)  # fmt: skip
                    self.stop.wait(LOOK_EVERY)
        finally:
            if news is not None:
                news.close()

    def _look(self, wanted: list[str]) -> None:
        """Wake the threads of finished steps; send the others that need it."""
        records = self.steps.of(self.job, self.position, wanted)
        with self.lock:
            for record in records:
                if record.state in ("done", "failed"):
                    self.answers[record.step] = record
                    self.waiting.pop(record.step).set()
        now, lease = time.time(), self.settings.lease_seconds
        for record in records:
            if record.state == "running" and (record.lease_until or now) < now:
                # its worker died: back to queued, sent again at the next look
                self.steps.reclaim(self.job, self.position, record.step,
                                   self.settings.item_attempts)  # fmt: skip
        queued = [r for r in records if r.state == "queued"]
        unsent = [r.step for r in queued if r.sent_at is None]
        stale = [r for r in queued if r.sent_at is not None and r.sent_at < now - lease]
        if stale:
            held = self.broker.held(lease)
            seen = [r.step for r in stale if held is not None and r.step in held]
            self.steps.mark_sent(self.job, self.position, seen)
            for record in stale:
                if record.step not in seen:
                    print(f"scengen: job {self.job} item {self.position}: step {record.key}: "
                          f"its message is not in the broker {now - (record.sent_at or now):.0f}"
                          " s after it was sent (lost?): sent again", file=sys.stderr)  # fmt: skip
                    unsent.append(record.step)
        for step in unsent:
            self._send(step)

    def _send(self, step: str) -> None:
        self.broker.send(self.job, self.position, step)
        self.steps.mark_sent(self.job, self.position, [step])


def step_answer(record: StepRecord) -> Any:
    """A finished step's result, or its error raised as the class it had on the worker."""
    if record.state == "done":
        return record.result
    kind = getattr(errors, record.error_kind or "", None)
    message = f"{record.error}"
    if isinstance(kind, type) and issubclass(kind, errors.ScengenError):
        raise kind(message)
    if record.error_kind == WORKER_LOST:  # not a bug: the machine killed it, again and again
        raise errors.ScengenError(f"campaign step {record.key}: {record.error}")
    raise StepFailed(f"campaign step {record.key}: {record.error}")
