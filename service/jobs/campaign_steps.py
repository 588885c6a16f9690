"""A campaign item's steps (service.core.campaign.CampaignSteps) over the service's state.

``JobCampaign.run`` coordinates the campaign: it asks for each step by a request (plain
JSON: which step, on which stored test-cases) that a ``StepRunner`` carries out wherever
it runs (``JobCampaign.perform``): in the coordinator's own threads (``LocalSteps``: the
local executor and ``scengen campaign``, up to ``Settings.workers`` at once), or on Celery
workers (service.jobs.celery_steps). Every step's work runs in a killable child process
(``ItemWork.call``) and is remembered as soon as it is done: test-cases and evaluations in
the store (and in the item's lists), the end of a chain and the outcome so far in the item's
memos. A retried item runs the campaign again and every step done before answers from
memory, so it goes on where it stopped. What the coordinator's threads share is kept under
a lock.
"""

from __future__ import annotations

import hashlib
import threading
from collections.abc import Callable, Sequence
from typing import Any, Protocol

from service.core.campaign.growing import (
    CHAIN_ENDS,
    run_campaign,
)
from service.core.campaign.outcome import (
    CampaignPlan,
    resummarized,
)
from service.core.errors import InvalidInput, ScengenError, UnknownNetwork, choices
from service.core.network.signals import program_from_document
from service.core.testcase import NetworkRef, Signals, TestCase, dump_testcase, parse_testcase
from service.jobs import tasks
from service.jobs.batch import CampaignItem
from service.jobs.store import ItemRecord, JobStore
from service.settings import Settings
from service.store import Store

OUTCOME = "outcome"  # the memo key of the campaign's outcome (so far)
_ENDS = {error.__name__: error for error in CHAIN_ENDS}


class ItemWork(Protocol):
    """What a campaign's steps work through: the item's state and a killable call
    (service.jobs.runner's Work)."""

    store: Store
    jobs: JobStore
    settings: Settings
    item: ItemRecord
    owner: str
    stop: threading.Event  # set when the item must end (cancelled, lease lost, shutdown)

    def call(
        self, function: Callable[..., Any], args: tuple[Any, ...], budget: float, what: str
    ) -> Any: ...


def routes_that_can_go(
    description: dict[str, Any], signals: Signals | None, duration: float
) -> list[str]:
    """The routes of a described junction (service.jobs.tasks.describe_junction) that an
    ego can take in a test-case of ``duration``: at a light (under ``signals``, or the
    network's program) not those whose signal stays red all along (no ego could pass it:
    ``new`` refuses them). InvalidInput when none is left."""
    document = description.get("signals")
    routes = description["routes"]
    if signals is None and document is None:
        return [r["id"] for r in routes]
    program = signals.to_program() if signals else program_from_document(document)
    egos = [
        r["id"]
        for r in routes
        if r["signal"] is None or program.goes_within(r["signal"]["link_index"], duration)
    ]
    if not egos:
        raise InvalidInput(
            f"no route of junction {description['junction']!r} gets a colour to go within "
            f"{duration:g} s: give a longer duration"
        )
    return egos


class StepRunner(Protocol):
    """Where a campaign's steps run: ``run`` does the step of ``key`` that ``request`` names
    (``JobCampaign.perform``) and answers its result; ``at_once`` steps run at a time."""

    at_once: int

    def run(self, key: str, request: dict[str, Any]) -> Any: ...

    def unfinished(self, key: str) -> bool:
        """Whether the step of ``key`` was started and is not done (its worker may have
        kept what it made and died before saying so)."""
        ...


class LocalSteps:
    """Every step in the coordinator's own thread, its work in a killable child process."""

    def __init__(self, campaign: JobCampaign) -> None:
        self.campaign = campaign
        self.at_once = campaign.work.settings.workers

    def run(self, key: str, request: dict[str, Any]) -> Any:
        return self.campaign.perform(request)

    def unfinished(self, key: str) -> bool:
        return False  # a step here ends with its thread


class JobCampaign:
    """One campaign item: ``run`` coordinates it (the waves, the memos, the progress),
    ``perform`` does one of its steps wherever it runs (the coordinator's thread, or a
    Celery worker: service.jobs.step_runner)."""

    def __init__(self, work: ItemWork, spec: CampaignItem) -> None:
        self.work, self.spec = work, spec
        self.item = work.item
        self.made = list(work.item.testcases)
        self.evaluated = list(work.item.evaluations)
        network = work.store.network(spec.network)
        if network is None:
            known = [n.id for n in work.store.list_networks()]
            raise UnknownNetwork(
                f"unknown network {spec.network!r}; known networks: {choices(known)}"
            )
        self.network = network
        self.network_file = work.store.network_file(network.id)
        self.ref = NetworkRef(ref=network.id, sha256=network.sha256)
        self.budget_per_level = spec.budget_per_level or work.settings.extend_budget
        self.steps: StepRunner = LocalSteps(self)
        self.progress = "starting"
        self.lock = threading.Lock()  # over the lists, the progress and their record
        self.step = threading.local()  # .recalled: the thread's step was answered from
        # memory (a resumed item)

    def run(self, steps: StepRunner | None = None) -> dict[str, Any]:
        """The campaign, its steps run by ``steps`` (default: here, ``LocalSteps``)."""
        self.steps = steps or LocalSteps(self)
        junction, control = self.network.junction_and_control(self.spec.junction,
                                                              self.spec.control)  # fmt: skip
        key = f"junction/{junction}/{control}"
        description = self._remembered(
            key, {"step": "describe", "junction": junction, "control": control}
        )
        routes = [r["id"] for r in description["routes"]]
        egos = (
            routes_that_can_go(description, self.spec.signals, self.spec.duration)
            if self.spec.all_egos
            else list(self.spec.egos or [])
        )
        for ego in egos:
            if ego not in routes:
                raise InvalidInput(
                    f"ego route {ego!r} is not a route of junction {description['junction']!r}; "
                    f"valid routes: {choices(routes)}"
                )
        self.junction, self.control = description["junction"], description["control"]
        crosswalks = bool(description.get("walks"))
        laws = self._remembered(
            f"laws/{self.control}/{'crosswalks' if crosswalks else 'no-crosswalks'}",
            {"step": "laws", "control": self.control, "crosswalks": crosswalks},
        )
        plan = CampaignPlan(
            network=self.network.id,
            junction=self.junction,
            control=self.control,
            egos=tuple(egos),
            depth=self.spec.depth,
            chains=self.spec.chains,
            controllers=tuple(self.spec.controllers),
            seed=self.spec.seed,
            budget_per_level=self.budget_per_level,
        )
        return run_campaign(
            plan, self, [(rule, law) for rule, law in laws], self._progress, self._save,
            self.steps.at_once,
        )  # fmt: skip

    # CampaignSteps

    def root(self, ego: str) -> tuple[str, TestCase]:
        self.step.recalled = False
        request = {"step": "root", "ego": ego, "junction": self.junction, "control": self.control}
        ident = self._remembered(f"root/{ego}", request)
        self._made(ident)
        return ident, self._testcase(ident)

    def grow(
        self,
        parent: str,
        testcase: TestCase,
        seed: int,
        last: tuple[str, ...],
        stem: str,
        avoid: Sequence[tuple[str, TestCase]],
    ) -> tuple[str, TestCase, str]:
        self.step.recalled = False
        avoided = [ident for ident, _ in avoid]
        request = {"step": "grow", "parent": parent, "seed": seed, "last": list(last),
                   "stem": stem, "avoid": avoided}  # fmt: skip
        found = self._remembered(grow_key(parent, seed, last, avoided), request)
        if "end" in found:
            raise _ENDS[found["end"]](found["message"])
        self._made(found["testcase"])
        return found["testcase"], self._testcase(found["testcase"]), found["route"]

    def evaluate(self, ident: str, testcase: TestCase, controller: str) -> dict[str, Any]:
        key = self.item.evaluation_id(ident, controller)
        stored = self.work.store.evaluation(key)
        self.step.recalled = stored is not None
        # A worker that stored the verdict and died before finishing its step: the step is
        # done again (it finds the verdict stored), so that no step is left running
        if stored is None or self.steps.unfinished(f"evaluate/{key}"):
            request = {"step": "evaluate", "testcase": ident, "controller": controller,
                       "evaluation": key}  # fmt: skip
            verdict = self.steps.run(f"evaluate/{key}", request)
        else:
            verdict = stored.verdict
        with self.lock:
            if key not in self.evaluated:
                self.evaluated.append(key)
                self._record()
        return {**verdict, "evaluation": key}

    # one step, wherever it runs

    def perform(self, request: dict[str, Any]) -> Any:
        """Do the step ``request`` names (its work in a killable child process, what it
        makes stored) and answer what the coordinator remembers of it (JSON)."""
        settings, kind = self.work.settings, request["step"]
        if kind == "describe":
            junction, control = request["junction"], request["control"]
            return self.work.call(
                tasks.describe_junction,
                (self.network_file, junction, control, settings.cache_dir),
                settings.work_budget, f"reading junction {junction}",
            )  # fmt: skip
        if kind == "laws":
            return self.work.call(tasks.rule_set_laws, (request["control"], request["crosswalks"]),
                                  settings.work_budget, "reading the rule set")  # fmt: skip
        if kind == "root":
            return self._make_root(request["ego"], request["junction"], request["control"])
        if kind == "grow":
            return self._grow_level(request)
        if kind == "evaluate":
            return self._judge(request["testcase"], request["controller"], request["evaluation"])
        raise ValueError(f"unknown campaign step {kind!r}")

    def _make_root(self, ego: str, junction: str, control: str) -> str:
        request = {"ego_route": ego, "junction": junction, "control": control,
                   "duration": self.spec.duration}  # fmt: skip
        if self.spec.signals is not None:
            request["signals"] = self.spec.signals.model_dump()
        document = self.work.call(
            tasks.create_testcase,
            (self.network_file, self.ref, self.work.settings.cache_dir, request),
            self.work.settings.work_budget, f"creating the test-case of ego {ego}",
        )  # fmt: skip
        return self.work.store.add_testcase(parse_testcase(document)).id

    def _grow_level(self, request: dict[str, Any]) -> dict[str, str]:
        parent = request["parent"]
        avoided = tuple(dump_testcase(self._testcase(ident)) for ident in request["avoid"])
        args = (dump_testcase(self._testcase(parent)), self.network_file,
                self.work.settings.cache_dir, request["seed"], self.budget_per_level,
                tuple(request["last"]), request["stem"], avoided)  # fmt: skip
        try:
            result = self.work.call(tasks.extend_any, args, self.budget_per_level + 5.0,
                                    f"growing a level on {parent}")  # fmt: skip
        except CHAIN_ENDS as error:  # remembered by its kind (MemoryExceeded too)
            end = next(kind for kind in CHAIN_ENDS if isinstance(error, kind))
            return {"end": end.__name__, "message": error.message}
        record = self.work.store.add_testcase(parse_testcase(result["document"]), parent)
        return {"testcase": record.id, "route": result["route"]}

    def _judge(self, ident: str, controller: str, key: str) -> dict[str, Any]:
        stored = self.work.store.evaluation(key)
        if stored is None:
            budget = self.spec.budget or self.work.settings.evaluate_budget
            result = self.work.call(
                tasks.evaluate_controller,
                (dump_testcase(self._testcase(ident)), self.network_file,
                 self.work.settings.cache_dir, controller, budget),
                budget + self.work.settings.work_budget, f"evaluating {controller} on {ident}",
            )  # fmt: skip
            stored = self.work.store.add_evaluation(
                ident, controller, result["verdict"], result["seconds"], key, result["drive"]
            )
        return dict(stored.verdict)

    # memory

    def _testcase(self, ident: str) -> TestCase:
        record = self.work.store.testcase(ident)
        if record is None:
            raise ScengenError(f"the campaign's test-case {ident} is no longer stored")
        return record.testcase

    def _made(self, ident: str) -> None:
        with self.lock:
            if ident not in self.made:
                self.made.append(ident)
                self._record()

    def _remembered(self, key: str, request: dict[str, Any]) -> Any:
        found = self.work.jobs.memo(self.item.job, self.item.position, key)
        if found is None:
            found = self.steps.run(key, request)
            self._remember(key, found)
        else:
            self.step.recalled = True
        return found

    def _remember(self, key: str, value: Any) -> None:
        self.work.jobs.remember(self.item.job, self.item.position, self.work.owner, key, value)

    def _record(self) -> None:
        self.work.jobs.record(
            self.item.job, self.item.position, self.work.owner, self.progress, self.made,
            self.evaluated,
        )  # fmt: skip

    def _progress(self, message: str, done: int, total: int) -> None:
        # a step answered from memory was done before the restart: say so, not what it did
        recalled = getattr(self.step, "recalled", False)
        said = f"resuming, {done} steps read back" if recalled else message
        with self.lock:
            self.progress = f"{done}/{total}: {said}"
            self._record()

    def _save(self, outcome: dict[str, Any]) -> None:
        self._remember(OUTCOME, outcome)


def grow_key(parent: str, seed: int, last: Sequence[str], avoid: Sequence[str]) -> str:
    """The memo key of a level grown from ``parent``: its seed, the routes held back and the
    test-cases it must differ from (a resumed campaign asks the same, so it reads back
    what it grew). A level that avoids nothing keeps the key campaigns had before they
    avoided, so that their first chains are read back too."""
    key = f"grow/{parent}/{seed}/{_digest(last)}"
    return f"{key}/avoid-{_digest(avoid)}" if avoid else key


def _digest(names: Sequence[str]) -> str:
    return hashlib.sha256(",".join(names).encode()).hexdigest()[:16]


def outcome_of(store: Store, job: str) -> dict[str, Any]:
    """The campaign outcome (so far) of ``job``'s first campaign item; one stored before
    levels kept their signature, summarized anew over its distinct test-cases
    (service.core.campaign.resummarized)."""
    jobs = JobStore(store)
    record = jobs.job(job)
    if record is None:
        raise KeyError(job)
    for item in record.items:
        if item.kind == "campaign":
            found = jobs.memo(job, item.position, OUTCOME)
            if found is not None:
                return resummarized(dict(found), lambda ident: _stored(store, ident))
    raise KeyError(f"job {job} has no campaign outcome yet")


def _stored(store: Store, ident: str) -> TestCase | None:
    record = store.testcase(ident)
    return None if record is None else record.testcase
