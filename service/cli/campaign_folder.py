"""``scengen campaign``: a campaign on this machine, its state and results in one folder.

The command runs the very job item a server runs (``service.jobs.runner``, each solver and
SUMO call in a killable child process) against a SQLite store inside the folder. Run the
same command again after a crash or Ctrl-C and it goes on where it stopped; a different
campaign in the same folder is refused. When it ends, the folder holds:

    campaign.json        the outcome (service.core.campaign, schema scengen/campaign/2)
    junit.xml            one test case per chain, level and controller
    report.html          the self-contained report (the results browser, offline)
    testcases/           every test-case as JSON, named chain by chain, with the network
    campaign.sqlite3     the state (a resumed run reads it)
"""

from __future__ import annotations

import fcntl
import json
import os
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any

from service.cli.output import make_folder
from service.core import errors
from service.core.campaign.outcome import campaign_junit
from service.core.errors import InvalidInput, ScengenError
from service.core.files import write_atomically
from service.core.network import bundled_networks, resolve_network
from service.core.network.convert import source_format
from service.core.testcase import dump_testcase, local_network_name, with_network_path
from service.jobs import tasks
from service.jobs.batch import parse_batch
from service.jobs.campaign_steps import outcome_of
from service.jobs.runner import run_item
from service.jobs.store import JobStore
from service.pictures.report import campaign_paths, campaign_title, report_html
from service.settings import Settings
from service.store import Store

STATE_FILE = "campaign.sqlite3"
LOCK_FILE = ".campaign.lock"  # held while a run works in the folder
OWNER = "scengen-campaign"  # the only worker of a folder's store


def open_store(folder: Path, workers: int | None = None) -> tuple[Store, Settings]:
    """The folder's store, and the settings of a run in it (``workers``: steps at once;
    None: the environment's SCENGEN_WORKERS, else the machine's cores)."""
    database = f"sqlite:///{folder.resolve()}/{STATE_FILE}"
    settings = Settings(data_dir=folder, database_url=database)
    if workers is not None:
        settings = settings.model_copy(update={"workers": workers})
    return Store(settings.database, settings.cache_dir), settings


def network_id(store: Store, network: str) -> str:
    """The store's id of ``network``: a bundled name, or a file (a map is converted)."""
    if network in bundled_networks():
        return network
    path = Path(network)
    if not path.is_file():
        resolve_network(network)  # the error names the bundled networks
    content = resolve_network(path).read_bytes()  # a map: the network it converts to
    kind = source_format(path)
    source = (kind, path.name, path.read_bytes()) if kind else None
    name = f"{path.name}.net.xml" if kind else path.name
    return store.add_network(name, content, {}, source).id


def run_folder_campaign(
    spec: dict[str, Any], folder: Path, say: Callable[[str], None], workers: int | None = None
) -> dict[str, Any]:
    """Run (or resume) the campaign ``spec`` (a campaign item with ``network`` a bundled name
    or a file) in ``folder`` with ``workers`` steps at once (None: SCENGEN_WORKERS, else
    the machine's cores) and write its results there; its outcome (the same for any
    ``workers``)."""
    parse_batch({"items": [{"kind": "campaign", **spec}]})  # bad input makes no folder
    make_folder(folder)
    lock = hold_lock(folder / LOCK_FILE)
    store, settings = open_store(folder, workers)
    try:
        spec = {**spec, "network": network_id(store, spec["network"])}
        batch = parse_batch({"name": "scengen campaign", "items": [{"kind": "campaign", **spec}]})
        jobs = JobStore(store)
        existing = jobs.list_jobs(limit=2).items
        if existing and existing[0].fingerprint != batch.fingerprint():
            raise InvalidInput(
                f"{folder} holds another campaign ({json.dumps(existing[0].items[0].spec)}); "
                "give a new folder with -o, or the same options to resume it"
            )
        job = existing[0] if existing else jobs.create(batch)[0]
        if existing and jobs.reopen(job.id):  # stopped, killed or failed: it goes on here
            say(f"resuming the campaign in {folder}")
        _run(store, settings, job.id, say)
        item = jobs.item(job.id, 0)
        assert item is not None
        if item.state != "succeeded":
            _raise_failure(item.error or f"the campaign's item ended {item.state}",
                           item.error_kind)  # fmt: skip
        return write_results(store, settings, job.id, folder)
    finally:
        store.close()
        (folder / LOCK_FILE).unlink(missing_ok=True)  # while it is ours: nothing left behind
        lock.close()  # and with it the lock


def hold_lock(path: Path) -> IO[str]:
    """The folder's lock file, held (InvalidInput when another run holds it). A run that
    ends removes the file while it holds it; one that opened it just before and locks it
    after finds it gone and takes the new one."""
    while True:
        lock = path.open("w")
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            lock.close()
            raise InvalidInput(f"another scengen campaign is running in {path.parent}") from None
        try:
            if path.stat().st_ino == os.fstat(lock.fileno()).st_ino:
                return lock
        except FileNotFoundError:
            pass
        lock.close()  # removed by the run before, as it ended: lock the new one


def _raise_failure(error: str, kind: str | None) -> None:
    """The item's error raised again as the error of the core it was (``kind``); an
    internal fault as a plain ScengenError (exit 3), never as the user's bad input."""
    found = getattr(errors, kind or "", None)
    if not (isinstance(found, type) and issubclass(found, ScengenError)):
        found = ScengenError
    raise found(f"the campaign stopped: {error}; run the same command to resume")


def _run(store: Store, settings: Settings, job: str, say: Callable[[str], None]) -> None:
    """The item in a thread; its progress told as it changes. Ctrl-C stops it (resumable)."""
    shutdown = threading.Event()
    worker = threading.Thread(
        target=run_item, args=(store, settings, job, 0, OWNER, shutdown), daemon=True
    )
    jobs = JobStore(store)
    before = jobs.item(job, 0)
    told = before.progress if before is not None else ""  # a stopped run's, not this one's
    worker.start()
    try:
        while worker.is_alive():
            worker.join(0.5)
            item = jobs.item(job, 0)
            if item is not None and item.progress != told:
                told = item.progress
                say(told)
    except KeyboardInterrupt:
        shutdown.set()
        worker.join(10)
        jobs.release(OWNER)
        raise


def report_of(store: Store, settings: Settings, job: str) -> tuple[dict[str, Any], str]:
    """The outcome of the campaign ``job`` and its self-contained report."""
    from service.api.public import store_fetch  # the API's own answers (FastAPI: 0.5 s)

    outcome = outcome_of(store, job)

    def shapes(network: Path, junction: str, control: str) -> dict[str, Any]:
        return tasks.junction_geometry(network, junction, control, settings.cache_dir)

    data = campaign_paths(job, outcome, store_fetch(store, shapes))
    return outcome, report_html(job, data, campaign_title(outcome))


def folder_report(folder: Path) -> str:
    """The report of the campaign in ``folder`` (as far as it got)."""
    if not (folder / STATE_FILE).is_file():
        raise InvalidInput(
            f"{folder} is not a campaign folder (no {STATE_FILE}); give a folder "
            "`scengen campaign -o` wrote, or a job id with --server URL"
        )
    store, settings = open_store(folder)
    try:
        found = JobStore(store).list_jobs(limit=1).items
        if not found:
            raise InvalidInput(f"{folder} holds no campaign yet")
        return report_of(store, settings, found[0].id)[1]
    finally:
        store.close()


def write_results(store: Store, settings: Settings, job: str, folder: Path) -> dict[str, Any]:
    """campaign.json, junit.xml, report.html and testcases/ of the campaign ``job``."""
    outcome, report = report_of(store, settings, job)
    write_atomically(folder / "campaign.json", json.dumps(outcome, indent=1) + "\n")
    write_atomically(folder / "junit.xml", campaign_junit(outcome))
    write_atomically(folder / "report.html", report)
    cases = folder / "testcases"
    cases.mkdir(exist_ok=True)
    network = outcome["plan"]["network"]
    local = None  # the network's file beside the test-cases, which they name as their path
    if network not in bundled_networks():
        local = cases / local_network_name(network)
        if not local.exists():
            write_atomically(local, store.network_file(network).read_bytes())
    for chain in outcome["chains"]:
        for level in chain["levels"]:
            record = store.testcase(level["testcase"])
            assert record is not None
            name = testcase_file_name(chain["ego"], chain["chain"] + 1, level["level"])
            placed = with_network_path(record.testcase, local, cases)
            write_atomically(cases / name, dump_testcase(placed))
    return outcome


def testcase_file_name(ego: str, chain: int, level: int) -> str:
    """``EGO.chainC.levelL.json``, the ego's route with ``-`` for ``:`` (a file name
    without a colon works on every file system): ``S2C_0-C2N_0.chain1.level2.json``."""
    return f"{ego.replace(':', '-')}.chain{chain}.level{level}.json"


def elapsed_printer(started: float) -> Callable[[str], None]:
    def say(message: str) -> None:
        print(f"[{time.monotonic() - started:7.1f} s] {message}", file=sys.stderr, flush=True)

    return say
