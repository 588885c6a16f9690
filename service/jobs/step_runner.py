"""A campaign step on a Celery worker (``scengen.run_step``): claimed, done, kept.

The step's row (service.jobs.steps) says what to do; the worker claims it (a message
delivered twice, or sent again while the first is still running, does nothing), renews its
lease while it works, does it as the coordinator would (``JobCampaign.perform``: the
network read by its id from the database, the work in a killable child process, what it
makes stored), keeps the result or the error in the row and tells the coordinator
(service.jobs.step_news). The step stops when its lease is lost or its job
is cancelled.
"""

from __future__ import annotations

import threading
import time
import traceback
from typing import Any

from service.core.errors import ScengenError
from service.jobs.batch import CampaignItem
from service.jobs.calls import Stopped, heartbeat
from service.jobs.campaign_steps import JobCampaign
from service.jobs.runner import Work
from service.jobs.step_news import tell_step_done
from service.jobs.steps import StepStore
from service.jobs.store import JobStore
from service.settings import Settings
from service.store import Store


def run_step(
    store: Store, settings: Settings, job: str, position: int, step: str, owner: str
) -> None:
    """Claim and do one campaign step; return quietly if someone else has it, it is done
    or its job is finished."""
    steps, jobs = StepStore(store), JobStore(store)
    lease = settings.lease_seconds
    if not steps.claim(job, position, step, owner, lease):
        return
    record, item = steps.get(job, position, step), jobs.item(job, position)
    assert record is not None and item is not None
    stop = threading.Event()
    beating = threading.Thread(
        target=heartbeat,
        args=(lambda: steps.renew(job, position, step, owner, lease), lease, stop,
              threading.Event()),
        daemon=True,
    )  # fmt: skip
    beating.start()
    clock = time.monotonic()

    def finish(**outcome: Any) -> None:
        if steps.finish(job, position, step, owner, time.monotonic() - clock, **outcome):
            tell_step_done(settings.broker_url, job, position, step)

    try:
        work = Work(store, jobs, settings, item, owner, stop)
        result = JobCampaign(work, CampaignItem.model_validate(item.spec)).perform(record.request)
    except Stopped:
        return  # its job was cancelled, or its lease ran out and another worker has it
    except ScengenError as error:
        finish(error=error.message, error_kind=type(error).__name__)
    except Exception as error:  # a bug must not leave the step running forever
        traceback.print_exc()  # for the worker's log
        finish(error=f"internal error (a bug; the worker's log has the details): {error!r}")
    else:
        finish(result=result)
    finally:
        stop.set()
        beating.join()
