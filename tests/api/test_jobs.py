"""Batch jobs on the embedded executor, through a real server and through `scengen submit`."""

from __future__ import annotations

import io
import json
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path
from typing import Any

import httpx2 as httpx
import pytest
import yaml

from service.core.testcase import dump_testcase, new_testcase
from tests.jobs.batches import regression_batch
from tests.servers import Server

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def finished(server: Server) -> dict[str, Any]:
    reply = server.client.post("/jobs", json=regression_batch())
    assert reply.status_code == 202, reply.text
    assert reply.headers["location"] == f"/jobs/{reply.json()['id']}"
    return server.wait_for_job(reply.json()["id"])


def test_the_job_makes_every_result(api: httpx.Client, finished: dict[str, Any]) -> None:
    assert finished["state"] == "succeeded", [i["error"] for i in finished["items"]]
    extend, chain, evaluate = finished["items"]
    assert len(extend["testcases"]) == 1 and len(chain["testcases"]) == 2
    assert chain["progress"] == "level 2/2" and evaluate["needs"] == [0, 1]
    assert len(evaluate["evaluations"]) == 6
    leaf = api.get(f"/testcases/{chain['testcases'][1]}").json()
    assert leaf["parent"] == chain["testcases"][0] and leaf["nonegos"] == 2
    assert finished["evaluations"]["passed"] + finished["evaluations"]["failed"] == 6
    assert all(i["started_at"] and i["finished_at"] for i in finished["items"])


def test_junit_and_bundles(api: httpx.Client, finished: dict[str, Any]) -> None:
    suite = ET.fromstring(api.get(finished["links"]["junit"]).text).find("testsuite")
    assert suite is not None and suite.get("tests") == "6"
    assert int(suite.get("failures") or 0) == finished["evaluations"]["failed"]
    # named by the test-case's name, which says the level, the id beside it
    levels = {t: lv for item in finished["items"][:2] for lv, t in enumerate(item["testcases"], 1)}
    names = sorted(case.get("name", "") for case in suite.findall("testcase"))
    assert names == sorted(
        f"4way-stop C E2C_1:C2S_1 level {level} ({ident}) / {controller}"
        for ident, level in levels.items()
        for controller in ("sumo", "certificate:solvability")
    )
    archive = zipfile.ZipFile(io.BytesIO(api.get(finished["links"]["bundles"]).content))
    made = [t for item in finished["items"] for t in item["testcases"]]
    assert {name.split("/")[0] for name in archive.namelist()} == set(made)
    assert f"{made[0]}/testcase.sumocfg" in archive.namelist()
    scenarios = zipfile.ZipFile(io.BytesIO(api.get(finished["links"]["openscenario"]).content))
    assert {name.split("/")[0] for name in scenarios.namelist()} == set(made)
    assert {f"{made[0]}/testcase.xosc", f"{made[0]}/testcase.xodr"} <= set(scenarios.namelist())


def test_the_same_idempotency_key_gives_the_same_job(
    api: httpx.Client, finished: dict[str, Any]
) -> None:
    root = finished["items"][0]["testcases"][0]
    batch = {"items": [{"kind": "evaluate", "testcase_id": root, "controllers": ["sumo"]}]}
    first = api.post("/jobs", json=batch, headers={"Idempotency-Key": "ci-run-7"})
    again = api.post("/jobs", json=batch, headers={"Idempotency-Key": "ci-run-7"})
    assert first.status_code == 202 and again.status_code == 200
    assert again.json()["id"] == first.json()["id"]
    other = {"items": [{"kind": "evaluate", "testcase_id": root, "controllers": ["sumo-cautious"]}]}
    clash = api.post("/jobs", json=other, headers={"Idempotency-Key": "ci-run-7"})
    assert clash.status_code == 409 and "another batch" in clash.json()["detail"]


def test_a_batch_naming_unknown_things_is_refused(api: httpx.Client) -> None:
    """Every unknown test-case id, network and controller is named, with the valid choices,
    and no job is made (they used to be accepted, then fail with an internal class name)."""
    before = api.get("/jobs").json()["total"]
    batch = {"items": [
        {"kind": "evaluate", "testcase_id": "nope", "controllers": ["sumo", "autopilot"]},
        {"kind": "extend", "testcase_id": "gone", "routes": ["a:b"]},
        {"kind": "campaign", "network": "nowhere", "egos": ["a:b"], "depth": 1, "chains": 1,
         "controllers": ["sumo"]},
    ]}  # fmt: skip
    reply = api.post("/jobs", json=batch)
    assert reply.status_code == 422 and reply.headers["content-type"] == "application/problem+json"
    problem = reply.json()
    assert problem["type"] == "/problems/invalid-input"
    assert [line.split(":")[0] for line in problem["errors"]] == [
        "items[0].testcase_id", "items[0].controllers", "items[1].testcase_id", "items[2].network"
    ]  # fmt: skip
    detail = problem["detail"]
    assert "no stored test-case 'nope'" in detail and "no stored test-case 'gone'" in detail
    assert "'autopilot' is not a controller installed here" in detail and "sumo-cautious" in detail
    assert "no network 'nowhere' (known networks: 4way-signal, 4way-stop" in detail
    assert api.get("/jobs").json()["total"] == before


def test_the_docs_batch_on_a_fresh_server_is_refused(tmp_path: Path) -> None:
    """examples/regression.yaml names the first test-case of the HTTP examples
    (docs/http-api.md, docs/jobs.md): a server that has not made it refuses the batch at
    once, naming the id (twice: two items name it)."""
    from fastapi.testclient import TestClient

    from service.api import create_app
    from service.cli.submit import read_batch
    from service.settings import Settings

    batch = read_batch(Path(__file__).parents[2] / "examples" / "regression.yaml")
    with TestClient(create_app(Settings(data_dir=tmp_path))) as fresh:
        reply = fresh.post("/jobs", json=batch.model_dump(mode="json"))
    assert reply.status_code == 422
    assert reply.json()["errors"] == [
        f"items[{i}].testcase_id: no stored test-case 'c2de5a280aab66bd' (POST /testcases "
        "makes one, GET /testcases lists them)"
        for i in (0, 1)
    ]


def test_a_campaign_job_over_the_cap_is_refused_with_its_count(tmp_path: Path) -> None:
    """Issue 50: one campaign over every route of the signalized four-way (16), 100 chains
    of 10 levels, 8 controllers was accepted as 144,128 steps (days of work). It is 422
    naming the count and the cap (SCENGEN_MAX_JOB_STEPS), and no job is made; a smaller
    cap refuses a small campaign, counted over its junction's routes too."""
    from fastapi.testclient import TestClient

    from service.api import create_app
    from service.settings import Settings

    big = {"kind": "campaign", "network": "4way-signal", "all_egos": True, "depth": 10,
           "chains": 100, "controllers": ["sumo"] * 8}  # fmt: skip
    small = {**big, "depth": 1, "chains": 1, "controllers": ["sumo"]}  # 16 * (1 + 2)
    with TestClient(create_app(Settings(data_dir=tmp_path, workers=1))) as fresh:
        reply = fresh.post("/jobs", json={"items": [big]})
        assert reply.status_code == 422, reply.text
        assert reply.json()["type"] == "/problems/invalid-input"
        assert "144,128 steps" in reply.json()["detail"]
        assert "limit of 2,000 (SCENGEN_MAX_JOB_STEPS)" in reply.json()["detail"]
        assert fresh.get("/jobs").json()["total"] == 0
    with TestClient(create_app(Settings(data_dir=tmp_path, workers=1, max_job_steps=47))) as low:
        reply = low.post("/jobs", json={"items": [small]})
        assert reply.status_code == 422 and "up to 48 steps" in reply.json()["detail"]


def test_a_failing_item_is_an_error_in_the_junit(server: Server) -> None:
    """The second car, on the ego's fork, would start behind the ego: the item's error says
    so in plain words, naming that car (so the list reached the generator in the order of
    the routes); the item that needs it fails too; the JUnit has an error for each."""
    item = {"kind": "extend", "testcase": regression_batch()["items"][0]["testcase"],
            "routes": ["S2C_1:C2N_1", "E2C_1:C2W_1"], "start_distance": [None, 40]}  # fmt: skip
    after = {"kind": "chain", "after": 0, "levels": 1}
    batch = {"name": "all fail", "items": [item, after]}
    job = server.wait_for_job(server.client.post("/jobs", json=batch).json()["id"])
    assert job["state"] == "failed"
    error = job["items"][0]["error"]
    assert (
        error.startswith("new car 2 (E2C_1:C2W_1) would start 40 m") and "behind the ego" in error
    )
    assert job["items"][1]["error"] == "item 0 it depends on did not succeed"
    suite = ET.fromstring(server.client.get(job["links"]["junit"]).text).find("testsuite")
    assert suite is not None and (suite.get("tests"), suite.get("errors")) == ("2", "2")
    errors = [(case.get("name"), case.find("error")) for case in suite.findall("testcase")]
    assert [name for name, _ in errors] == ["item 0 (extend)", "item 1 (chain)"]
    messages = [found.get("message") for _, found in errors if found is not None]
    assert messages == [error, job["items"][1]["error"]]


def test_an_evaluation_budget_too_small_fails_the_item_without_a_verdict(server: Server) -> None:
    """The budget is the server's limit: the item fails with the budget error, and no
    evaluation (no FAIL of the controller) is stored."""
    root = regression_batch()["items"][0]["testcase"]
    batch = {"items": [{"kind": "evaluate", "testcase": root, "controllers": ["sumo"],
                        "budget": 0.01}]}  # fmt: skip
    job = server.wait_for_job(server.client.post("/jobs", json=batch).json()["id"])
    item = job["items"][0]
    assert job["state"] == "failed" and item["evaluations"] == []
    assert "budget of 0.01 s" in item["error"] and "no verdict on sumo" in item["error"]


def test_a_bad_start_distance_list_is_refused_before_the_job(api: httpx.Client) -> None:
    batch = {"items": [{"kind": "extend", "testcase_id": "x", "routes": ["a:b"],
                        "start_distance": [1, 2]}]}  # fmt: skip
    reply = api.post("/jobs", json=batch)
    assert reply.status_code == 422
    assert "1 route, 2 start distances" in reply.json()["detail"]


def test_cancelling_stops_a_running_job(server: Server, api: httpx.Client) -> None:
    batch = {"items": [{"kind": "chain", "testcase": regression_batch()["items"][0]["testcase"],
                        "levels": 3, "budget": 120}]}  # fmt: skip
    job = api.post("/jobs", json=batch).json()
    while api.get(f"/jobs/{job['id']}").json()["items"][0]["state"] != "running":
        time.sleep(0.2)
    time.sleep(1.0)  # let it start a solver child
    cancelled = api.delete(f"/jobs/{job['id']}")
    assert cancelled.status_code == 202 and cancelled.json()["state"] == "cancelled"
    assert server.wait_for_job(job["id"])["items"][0]["state"] == "cancelled"

    def items_running() -> int:
        lines = api.get("/metrics").text.splitlines()
        return int(next(x for x in lines if x.startswith("scengen_job_items_running ")).split()[1])

    deadline = time.monotonic() + 15
    while items_running() and time.monotonic() < deadline:
        time.sleep(0.2)
    assert items_running() == 0  # the worker saw the cancellation and killed its child


def test_item_budgets_are_capped(api: httpx.Client) -> None:
    batch = {"items": [{"kind": "evaluate", "testcase_id": "x", "controllers": ["sumo"],
                        "budget": 100000}]}  # fmt: skip
    reply = api.post("/jobs", json=batch)
    assert reply.status_code == 422 and "items[0].budget" in reply.json()["detail"]


def test_listing_jobs(api: httpx.Client, finished: dict[str, Any]) -> None:
    page = api.get("/jobs", params={"state": "succeeded"}).json()
    assert finished["id"] in [j["id"] for j in page["items"]]
    assert api.get("/jobs", params={"state": "bogus"}).status_code == 422
    assert api.get("/jobs/nope").status_code == 404


def scengen(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "service", *args], cwd=cwd,
                          capture_output=True, text=True, timeout=600)  # fmt: skip


def test_submit_waits_and_downloads(server: Server, tmp_path: Path) -> None:
    batch = regression_batch()
    batch["items"][2]["controllers"] = ["certificate:solvability"]
    (tmp_path / "batch.yaml").write_text(yaml.safe_dump(batch))
    done = scengen("submit", "batch.yaml", "--server", server.url, "--junit", "report.xml",
                   "--out", "results", cwd=tmp_path)  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert "succeeded: 3/3 items, evaluations 3 passed 0 failed" in done.stderr
    job = json.loads((tmp_path / "results" / "job.json").read_text())
    made = [t for item in job["items"] for t in item["testcases"]]
    assert sorted(p.stem for p in (tmp_path / "results" / "testcases").iterdir()) == sorted(made)
    assert (tmp_path / "results" / "bundles.zip").stat().st_size > 10_000
    assert (tmp_path / "results" / "openscenario.zip").stat().st_size > 10_000
    assert ET.parse(tmp_path / "report.xml").getroot().tag == "testsuites"


def test_submit_gives_a_campaign_its_own_junit_and_report(server: Server, tmp_path: Path) -> None:
    """A campaign job's JUnit names each case by chain and level; --out also holds the
    campaign's outcome and its self-contained report."""
    campaign = {"kind": "campaign", "network": "t-stop", "egos": ["S2C_0:C2E_0"], "depth": 1,
                "chains": 1, "controllers": ["sumo"], "seed": 0, "duration": 20.0}  # fmt: skip
    (tmp_path / "campaign.json").write_text(json.dumps({"items": [campaign]}))
    done = scengen("submit", "campaign.json", "--server", server.url, "--junit", "report.xml",
                   "--out", "results", cwd=tmp_path)  # fmt: skip
    assert done.returncode == 0, done.stderr
    outcome = json.loads((tmp_path / "results" / "campaign.json").read_text())
    assert outcome["schema"] == "scengen/campaign/2" and outcome["finished"]
    levels = outcome["chains"][0]["levels"]
    suite = ET.parse(tmp_path / "report.xml").getroot().find("testsuite")
    assert suite is not None
    assert [case.get("name") for case in suite.findall("testcase")] == [
        f"t-stop C S2C_0:C2E_0 chain 1 level {lv} ({levels[lv]['testcase']}) / sumo"
        for lv in (0, 1)
    ]
    assert [level["name"] for level in levels] == [
        "t-stop C S2C_0:C2E_0 level 0", "t-stop C S2C_0:C2E_0 chain 1 level 1"
    ]  # fmt: skip
    assert (tmp_path / "results" / "junit.xml").read_bytes() == (
        tmp_path / "report.xml"
    ).read_bytes()
    assert "window.SCENGEN_REPORT" in (tmp_path / "results" / "report.html").read_text()


def test_submit_exit_codes(server: Server, tmp_path: Path) -> None:
    failing = regression_batch()
    judge = {"kind": "evaluate", "items": [0], "controllers": ["sumo-aggressive"]}
    failing["items"] = [failing["items"][0], judge]
    (tmp_path / "failing.json").write_text(json.dumps(failing))
    assert scengen("submit", "failing.json", "--server", server.url, "--wait",
                   cwd=tmp_path).returncode == 1  # fmt: skip
    (tmp_path / "broken.json").write_text('{"items": [{"kind": "grow"}]}')
    bad = scengen("submit", "broken.json", "--server", server.url, cwd=tmp_path)
    assert bad.returncode == 2 and "invalid batch" in bad.stderr
    unknown = {"items": [{"kind": "extend", "testcase_id": "nope", "routes": ["a:b"]}]}
    (tmp_path / "nope.json").write_text(json.dumps(unknown))
    refused = scengen("submit", "nope.json", "--server", server.url, "--wait", cwd=tmp_path)
    assert refused.returncode == 2 and "no stored test-case 'nope'" in refused.stderr
    assert "ScengenError" not in refused.stderr and "Traceback" not in refused.stderr
    item = {"kind": "extend", "testcase": regression_batch()["items"][0]["testcase"],
            "routes": ["S2C_1:C2N_1", "E2C_1:C2W_1"], "start_distance": [None, 40]}  # fmt: skip
    (tmp_path / "fails.json").write_text(json.dumps({"items": [item]}))
    failed = scengen("submit", "fails.json", "--server", server.url, "--junit", "fails.xml",
                     cwd=tmp_path)  # fmt: skip
    assert failed.returncode == 3
    assert "item 0 (extend) failed: new car 2 (E2C_1:C2W_1) would start 40 m" in failed.stderr
    suite = ET.parse(tmp_path / "fails.xml").getroot().find("testsuite")
    assert suite is not None and (suite.get("tests"), suite.get("errors")) == ("1", "1")
    away = scengen("submit", "nope.json", "--server", "http://127.0.0.1:9", cwd=tmp_path)
    assert away.returncode == 3 and "cannot reach" in away.stderr


def test_a_chain_by_levels_joins_a_queue_once_the_forks_are_taken(
    server: Server, api: httpx.Client
) -> None:
    """On the T-junction only two forks besides the ego's are free: the service picks
    them first, and a third level exists only on a fork in use (before queues, a chain of
    levels stopped at two with "none left")."""
    root = json.loads(dump_testcase(new_testcase("t-stop", "E2C_0:C2S_0", duration=45.0)))
    batch = {"items": [{"kind": "chain", "testcase": root, "levels": 3, "budget": 120}]}
    job = server.wait_for_job(api.post("/jobs", json=batch).json()["id"])
    assert job["state"] == "succeeded", job["items"][0]["error"]
    made = job["items"][0]["testcases"]
    assert len(made) == 3
    last = api.get(f"/testcases/{made[-1]}/document").json()
    by_level = {car["added_in"]: car["route"]["fork"] for car in last["nonegos"]}
    assert {by_level[1], by_level[2]} == {"W2C_0", "S2C_0"}  # the free forks first
    assert by_level[3] in {"W2C_0", "S2C_0", "E2C_0"}


def test_a_batch_on_a_signalized_junction_carries_its_program(
    server: Server, api: httpx.Client
) -> None:
    """Extend, chain, evaluate and campaign items on the bundled signalized four-way: the
    job succeeds, every test-case the extensions make carries the root's program, and the
    campaign's test-cases the program it was given."""
    root = api.post("/testcases", json={"network": "4way-signal", "ego_route": "S2C_1:C2W_1",
                                        "duration": 45})  # fmt: skip
    assert root.status_code == 201, root.text
    program = root.json()["testcase"]["signals"]
    given = {**program, "program": "campaign", "offset": 10.0}
    batch = {"name": "signals", "items": [
        {"kind": "extend", "testcase_id": root.json()["id"], "routes": ["N2C_0:C2S_0"]},
        {"kind": "chain", "after": 0, "levels": 1, "seed": 0},
        {"kind": "evaluate", "items": [0, 1], "controllers": ["sumo", "certificate:complexity"]},
        {"kind": "campaign", "network": "4way-signal", "control": "traffic_light",
         "signals": given, "egos": ["S2C_1:C2W_1"], "depth": 1, "chains": 1,
         "controllers": ["sumo"], "duration": 45},
    ]}  # fmt: skip
    reply = api.post("/jobs", json=batch)
    assert reply.status_code == 202, reply.text
    finished = server.wait_for_job(reply.json()["id"])
    assert finished["state"] == "succeeded", [i["error"] for i in finished["items"]]
    extend, chain, evaluate, campaign = finished["items"]
    assert len(evaluate["evaluations"]) == 4 and len(campaign["testcases"]) == 2
    for ident in extend["testcases"] + chain["testcases"]:
        assert api.get(f"/testcases/{ident}").json()["testcase"]["signals"] == program
    for ident in campaign["testcases"]:
        assert api.get(f"/testcases/{ident}").json()["testcase"]["signals"] == given
    verdicts = [api.get(f"/evaluations/{e}").json()["verdict"] for e in evaluate["evaluations"]]
    judged = {(v["controller"], v["passed"]) for v in verdicts}
    assert ("certificate:complexity", False) in judged and not any(v["errors"] for v in verdicts)
    outcome = api.get(f"/jobs/{finished['id']}/campaign").json()
    assert outcome["plan"]["control"] == "traffic_light" and outcome["finished"]
