"""Runs one job item, wherever it is (a thread of the server, or a Celery worker).

``run_item`` claims the item, renews its lease while it works, runs each solver or SUMO
call in a killable child process (``python -m service.core.budget``), writes every result
as soon as it exists, and resumes from those results when the item is retried. Cancelling
the job, or losing the lease, kills the running child.
"""

from __future__ import annotations

import os
import socket
import sys
import threading
import traceback
from collections.abc import Callable, Sequence
from typing import Any

from service.core.errors import InvalidInput, ScengenError
from service.core.testcase import parse_testcase
from service.jobs import tasks
from service.jobs.batch import CampaignItem, ChainItem, EvaluateItem, ExtendItem
from service.jobs.calls import Stopped, heartbeat, run_stoppable
from service.jobs.campaign_steps import JobCampaign
from service.jobs.celery_steps import CelerySteps, StepBroker
from service.jobs.store import ItemRecord, JobStore
from service.settings import Settings
from service.store import Store, TestCaseRecord


def owner_name(kind: str) -> str:
    return f"{kind}:{socket.gethostname()}:{os.getpid()}:{threading.get_ident()}"


def run_item(
    store: Store,
    settings: Settings,
    job: str,
    position: int,
    owner: str,
    shutdown: threading.Event | None = None,
    step_broker: StepBroker | None = None,
) -> None:
    """Claim and run one item; return quietly if someone else has it or it is finished.
    ``shutdown`` stops it without finishing it (the caller gives the claim back). A
    campaign item with a ``step_broker`` sends its steps to Celery workers through it
    (service.jobs.celery_steps) and waits for them; else it runs them itself."""
    jobs = JobStore(store)
    if not jobs.claim(job, position, owner, settings.lease_seconds):
        return
    item = jobs.item(job, position)
    assert item is not None
    stop = threading.Event()
    beating = threading.Thread(
        target=heartbeat,
        args=(lambda: jobs.renew(job, position, owner, settings.lease_seconds),
              settings.lease_seconds, stop, shutdown or threading.Event()),
        daemon=True,
    )  # fmt: skip
    beating.start()
    if item.testcases or item.evaluations:
        print(
            f"scengen: job {job} item {position}: resuming after {len(item.testcases)} "
            f"test-case(s) and {len(item.evaluations)} evaluation(s) made before",
            file=sys.stderr,
        )
    try:
        _run_unless_shut_down(Work(store, jobs, settings, item, owner, stop, step_broker), shutdown)
    except Stopped:
        return  # cancelled (already marked) or taken over by another worker
    except ScengenError as error:
        kind = type(error).__name__
        jobs.finish(job, position, owner, "failed", error.message, error_kind=kind)
    except Exception as error:  # a bug must not leave the item running forever
        traceback.print_exc()  # for the worker's log
        why = f"internal error (a bug; the worker's log has the details): {error!r}"
        jobs.finish(job, position, owner, "failed", why)
    else:
        jobs.finish(job, position, owner, "succeeded")
    finally:
        stop.set()
        beating.join()


def _run_unless_shut_down(work: Work, shutdown: threading.Event | None) -> None:
    """``work.run()``; whatever ends it once ``shutdown`` is set (Ctrl-C; the executor
    going away, which also stops its thread pools) is Stopped, not a failure: the caller
    gives the claim back and the work resumes later."""
    try:
        work.run()
    except Exception:
        if shutdown is not None and shutdown.is_set():
            raise Stopped("shut down") from None
        raise


class Work:
    """One item's work; ``stop`` is set when it must end."""

    def __init__(
        self, store: Store, jobs: JobStore, settings: Settings, item: ItemRecord, owner: str,
        stop: threading.Event, step_broker: StepBroker | None = None,
    ) -> None:  # fmt: skip
        self.store, self.jobs, self.settings = store, jobs, settings
        self.item, self.owner, self.stop = item, owner, stop
        self.step_broker = step_broker

    def run(self) -> None:
        kind = self.item.kind
        if kind == "extend":
            self._extend(ExtendItem.model_validate(self.item.spec))
        elif kind == "chain":
            self._chain(ChainItem.model_validate(self.item.spec))
        elif kind == "campaign":
            campaign = JobCampaign(self, CampaignItem.model_validate(self.item.spec))
            broker = self.step_broker
            campaign.run(None if broker is None else CelerySteps(self, broker))
        else:
            self._evaluate(EvaluateItem.model_validate(self.item.spec))

    def _source(self, spec: ExtendItem | ChainItem) -> TestCaseRecord:
        if spec.testcase is not None:
            return self.store.keep_inline(spec.testcase)
        if spec.after is not None:
            earlier = self.jobs.item(self.item.job, spec.after)
            assert earlier is not None and earlier.testcases
            ident = earlier.testcases[-1]
        else:
            ident = str(spec.testcase_id)
        record = self.store.testcase(ident)
        if record is None:
            raise _gone(ident)
        return record

    def _extend(self, spec: ExtendItem) -> None:
        if self.item.testcases:
            return  # made before this worker was killed: never recomputed
        old = self._source(spec)
        self.jobs.record(self.item.job, self.item.position, self.owner, "extending")
        if spec.count > 1:
            made, progress = self._variants(old, spec)
        else:
            extension = self._extension(
                old, spec.routes, spec.seed, spec.budget, spec.start_distance, spec.pedestrians
            )
            made, progress = [extension.id], "done"
        self.jobs.record(self.item.job, self.item.position, self.owner, progress, made)

    def _variants(self, old: TestCaseRecord, spec: ExtendItem) -> tuple[list[str], str]:
        """Up to ``spec.count`` distinct extensions of ``old``, every one stored, and the
        item's last progress: how many came back, and why fewer than asked when they did
        (the item succeeds with those found)."""
        budget = spec.budget or self.settings.extend_budget
        result = self.call(
            tasks.extend_variants,
            (old.document, self.store.network_file_for(old.testcase), self.settings.cache_dir,
             spec.routes, spec.count, spec.seed, budget, spec.start_distance, None,
             spec.pedestrians),
            budget + 5.0,
            f"extending {old.id} by {', '.join([*spec.routes, *spec.pedestrians])} "
            f"({spec.count} distinct)",
        )  # fmt: skip
        made = [
            self.store.add_testcase(parse_testcase(variant["document"]), parent=old.id).id
            for variant in result["extensions"]
        ]
        progress = f"done: {len(made)} distinct extensions of {spec.count} asked for"
        shortfall = result["shortfall"]
        return made, progress if shortfall is None else f"{progress}; {shortfall}"

    def _chain(self, spec: ChainItem) -> None:
        made = list(self.item.testcases)
        current = self.store.testcase(made[-1]) if made else self._source(spec)
        assert current is not None
        for level in range(len(made), spec.count):
            progress = f"level {level + 1}/{spec.count}"
            self.jobs.record(self.item.job, self.item.position, self.owner, progress)
            routes = None if spec.steps is None else spec.steps[level]
            try:
                current = self._extension(current, routes, spec.seed, spec.budget)
            except ScengenError as error:  # the levels made so far are kept, and named
                kept = f"; levels 1 to {level} are kept" if level else ""
                message = f"level {level + 1} of {spec.count}: {error.message}{kept}"
                raise type(error)(message, **error.context) from error
            made.append(current.id)
            self.jobs.record(self.item.job, self.item.position, self.owner, progress, made)

    def _evaluate(self, spec: EvaluateItem) -> None:
        targets = self._targets(spec)
        done = list(self.item.evaluations)
        budget = spec.budget or self.settings.evaluate_budget
        pairs = [(t, c) for t in targets for c in spec.controllers]
        for number, (target, controller) in enumerate(pairs, start=1):
            ident = self.item.evaluation_id(target.id, controller)
            progress = f"evaluation {number}/{len(pairs)}"
            if ident not in done and self.store.evaluation(ident) is None:
                self.jobs.record(self.item.job, self.item.position, self.owner, progress)
                result = self.call(
                    tasks.evaluate_controller,
                    (target.document, self.store.network_file_for(target.testcase),
                     self.settings.cache_dir, controller, budget),
                    budget + self.settings.work_budget, f"evaluating {controller}",
                )  # fmt: skip
                self.store.add_evaluation(
                    target.id,
                    controller,
                    result["verdict"],
                    result["seconds"],
                    ident,
                    result["drive"],
                )
            if ident not in done:
                done.append(ident)
            self.jobs.record(self.item.job, self.item.position, self.owner, progress, None, done)

    def _targets(self, spec: EvaluateItem) -> list[TestCaseRecord]:
        if spec.testcase is not None:
            return [self.store.keep_inline(spec.testcase)]
        if spec.testcase_id is not None:
            record = self.store.testcase(spec.testcase_id)
            if record is None:
                raise _gone(spec.testcase_id)
            return [record]
        found = []
        for position in spec.items or []:
            earlier = self.jobs.item(self.item.job, position)
            assert earlier is not None
            found += [r for r in map(self.store.testcase, earlier.testcases) if r is not None]
        return found

    def _extension(
        self, old: TestCaseRecord, routes: list[str] | None, seed: int, budget: float | None,
        start_distance: float | list[float | None] | None = None, walks: Sequence[str] = (),
    ) -> TestCaseRecord:  # fmt: skip
        """``old`` extended by cars on ``routes`` and pedestrians on ``walks``, or on a route
        the service picks (``routes`` None); the new cars start ``start_distance`` before
        their stop lines (None: automatic)."""
        chosen = budget or self.settings.extend_budget
        common = (old.document, self.store.network_file_for(old.testcase), self.settings.cache_dir)
        call: Callable[..., Any]
        args: tuple[Any, ...]
        if routes is None:
            call, args, what = tasks.extend_any, (*common, seed, chosen), f"extending {old.id}"
        else:
            call = tasks.extend
            args = (*common, routes, seed, chosen, start_distance, None, list(walks))
            what = f"extending {old.id} by {', '.join([*routes, *walks])}"
        result = self.call(call, args, chosen + 5.0, what)
        return self.store.add_testcase(parse_testcase(result["document"]), parent=old.id)

    def call(
        self, function: Callable[..., Any], args: tuple[Any, ...], budget: float, what: str
    ) -> Any:
        return run_stoppable(function, args, budget, what, self.stop)


def _gone(ident: str) -> InvalidInput:
    """A test-case the batch names that is not stored (any more: a batch naming one that
    was never stored is refused when it is submitted)."""
    return InvalidInput(
        f"testcase_id: no stored test-case {ident!r} (deleted since the job was submitted?)"
    )
