"""A campaign as a batch job: the same outcome on the embedded executor and on Celery, and
a Celery worker killed with kill -9 in the middle of it loses nothing: the retried item
answers every step it took from memory and goes on."""

from __future__ import annotations

import copy
from hashlib import sha256
from pathlib import Path
from typing import Any

import pytest

from tests.jobs.test_durability import wait_until
from tests.servers import Server, Worker

pytestmark = pytest.mark.slow

CAMPAIGN = {
    "kind": "campaign",
    "network": "4way-stop",
    "egos": ["S2C_0:C2N_0"],
    "depth": 2,
    "chains": 2,
    "controllers": ["sumo", "sumo-rolling-stop"],
    "seed": 3,
}


def outcome(server: Server, job: str) -> dict[str, Any]:
    """The campaign's outcome without the evaluations' ids (they name their job)."""
    found: dict[str, Any] = copy.deepcopy(server.client.get(f"/jobs/{job}/campaign").json())
    for chain in found["chains"]:
        for level in chain["levels"]:
            for verdict in level["verdicts"].values():
                assert len(verdict.pop("evaluation")) == 16
    return found


def halfway(server: Server, job: str) -> dict[str, Any] | None:
    """The job once its campaign has grown its first chain and works on the second."""
    found: dict[str, Any] = server.client.get(f"/jobs/{job}").json()
    item = found["items"][0]
    return found if item["state"] == "running" and len(item["testcases"]) >= 3 else None


def test_campaign_resumes_after_kill_and_matches_the_local_executor(
    tmp_path: Path, celery_settings: dict[str, str]
) -> None:
    local = Server(tmp_path / "local", workers="2")
    try:
        job = local.client.post("/jobs", json={"items": [CAMPAIGN]}).json()["id"]
        finished = local.wait_for_job(job)
        assert finished["state"] == "succeeded", finished["items"][0]["error"]
        on_local = outcome(local, job)
        junit = local.client.get(f"/jobs/{job}/campaign/junit").text
    finally:
        local.stop()
    assert on_local["finished"]
    assert [c["reached"] for c in on_local["chains"]] == [2, 2]
    assert [lv["testcases"] for lv in on_local["levels"]] == [1, 2, 2]
    # rolling through the stop sign fails every level; SUMO's own driver passes level 0
    rolling = [lv["controllers"]["sumo-rolling-stop"] for lv in on_local["levels"]]
    assert all(s["share"] == 1.0 and s["rules"].get("stopAtSign") for s in rolling)
    assert on_local["levels"][0]["controllers"]["sumo"]["failed"] == 0
    assert junit.count("<testcase ") == 2 * 3 * 2  # chains x levels (0 to 2) x controllers
    covered = [c for c in on_local["coverage"] if c["covered"]]
    assert covered and all(c["testcases"] for c in covered)

    server = Server(tmp_path / "celery", **celery_settings)
    worker = Worker(tmp_path / "w1", "w1", **celery_settings)
    try:
        job = server.client.post("/jobs", json={"items": [CAMPAIGN]}).json()["id"]
        before = wait_until(lambda: halfway(server, job), timeout=300)
        worker.kill()
        worker = Worker(tmp_path / "w2", "w2", **celery_settings)
        after = server.wait_for_job(job)
        assert after["state"] == "succeeded", after["items"][0]["error"]
        item = after["items"][0]
        assert item["attempts"] >= 2  # interrupted and resumed
        assert item["testcases"][:3] == before["items"][0]["testcases"][:3]  # kept, not remade
        assert len(item["testcases"]) == len(set(item["testcases"])) == 5  # root + 2 x 2
        assert len(item["evaluations"]) == len(set(item["evaluations"])) == 5 * 2
        assert "resuming after" in worker.log.read_text()
        assert outcome(server, job) == on_local
    finally:
        worker.stop()
        server.stop()


def test_all_egos_at_a_light_leaves_out_the_routes_that_stay_red(tmp_path: Path) -> None:
    """Town05 1126 (42 s green, 3 s yellow each way): in 45 s the routes from -46 and 47
    never get a colour to go, so --all-egos takes only the other eight; in 50 s all 16,
    and under a program that is red for everyone none, which is refused with the reason."""
    from service.core.errors import InvalidInput
    from service.core.testcase import Signals
    from service.jobs.campaign_steps import routes_that_can_go
    from service.jobs.tasks import describe_junction
    from tests.conftest import TOWN05

    described = describe_junction(TOWN05, "1126", None, tmp_path)
    every = [r["id"] for r in described["routes"]]
    in_45 = routes_that_can_go(described, None, 45.0)
    assert len(every) == 16 and len(in_45) == 8
    assert {r.split("_")[0] for r in in_45} == {"-6", "7"}
    assert routes_that_can_go(described, None, 50.0) == every
    red = Signals.model_validate({"tls": "1126", "phases": [{"duration": 60, "state": "r" * 16}]})
    with pytest.raises(InvalidInput, match="no route of junction '1126' gets a colour to go"):
        routes_that_can_go(described, red, 45.0)


def test_a_campaigns_level_differs_from_what_it_avoids(tmp_path: Path) -> None:
    """extend_any, as a campaign's step calls it in a child process: with the same seed
    and parent, a level told to avoid another chain's level is another test-case, and
    its memo key names what it avoided (a level that avoids nothing keeps the key it had
    before campaigns avoided)."""
    from service.core.generator.variety import signature
    from service.core.network import resolve_network
    from service.core.testcase import dump_testcase, new_testcase, parse_testcase
    from service.jobs.campaign_steps import grow_key
    from service.jobs.tasks import extend_any

    root = dump_testcase(new_testcase("4way-stop", "S2C_0:C2N_0"))
    network = resolve_network("4way-stop")
    first = extend_any(root, network, tmp_path, 0, 120.0)
    second = extend_any(root, network, tmp_path, 0, 120.0, avoid=(first["document"],))
    a, b = parse_testcase(first["document"]), parse_testcase(second["document"])
    assert not signature(b).same_as(signature(a))
    assert grow_key("p", 3, ("r1",), []) == "grow/p/3/" + sha256(b"r1").hexdigest()[:16]
    keys = {grow_key("p", 3, ("r1",), avoid) for avoid in ([], ["a"], ["b"], ["a", "b"])}
    assert len(keys) == 4
