"""A campaign as a batch job: the same outcome on the embedded executor and on Celery, whose
workers run its steps while the server coordinates it; a worker and the server killed with
kill -9 and a Redis restarted empty in the middle of it lose nothing and repeat nothing: the
lost steps are sent again, every step is done once."""

from __future__ import annotations

import copy
from hashlib import sha256
from pathlib import Path
from typing import Any

import pytest

from service.jobs.steps import StepStore
from service.store import Store
from tests.jobs.conftest import PrivateRedis
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
    "duration": 20.0,  # not the default 45 s: the suite's time
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


def test_campaign_steps_on_celery_survive_kill_9_and_redis_and_match_local(
    tmp_path: Path, celery_settings: dict[str, str], private_redis: PrivateRedis
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

    # on Celery: one worker, killed with -9 in the middle of a step, with the server and
    # Redis (restarted empty); the restarted server and two new workers finish the
    # campaign, its steps spread over them
    settings = {**celery_settings, "broker_url": private_redis.url}
    server = Server(tmp_path / "celery", **settings)
    workers = [Worker(tmp_path / "w1", "w1", **settings)]
    try:
        job = server.client.post("/jobs", json={"items": [CAMPAIGN]}).json()["id"]
        steps = StepStore(Store(settings["database_url"], tmp_path / "cache"))
        running = lambda: any(s.state == "running" for s in steps.of(job, 0))  # noqa: E731
        before = wait_until(lambda: halfway(server, job) if running() else None, timeout=300)
        workers[0].kill()  # in the middle of a step
        server.kill()  # and the campaign's coordinator with it
        private_redis.kill()
        private_redis.start()  # empty: every message it held is gone
        server.start()
        workers = [Worker(tmp_path / f"w{n}", f"w{n}", **settings) for n in (2, 3)]
        after = server.wait_for_job(job)
        assert after["state"] == "succeeded", after["items"][0]["error"]
        item = after["items"][0]
        assert item["attempts"] == 2  # the restarted server coordinated it again
        assert "resuming after" in server.log.read_text()
        assert item["testcases"][:3] == before["items"][0]["testcases"][:3]  # kept, not remade
        assert len(item["testcases"]) == len(set(item["testcases"])) == 5  # root + 2 x 2
        assert len(item["evaluations"]) == len(set(item["evaluations"])) == 5 * 2
        assert outcome(server, job) == on_local
        done = steps.of(job, 0)
        # a junction, a rule set, a root, 4 levels, 10 verdicts: each done once, on a worker;
        # only the step w1 was doing when it was killed was started twice
        assert [s.state for s in done] == ["done"] * 17
        assert len({s.key for s in done}) == 17
        assert sum(s.attempts for s in done) <= 17 + 1
        logs = "".join(w.log.read_text() for w in workers)
        assert "scengen.run_step" in logs
        resent = server.log.read_text().count("(lost?): sent again")
        print(
            f"steps: {len(done)}, started {sum(s.attempts for s in done)} times; "
            f"{resent} message(s) lost with Redis sent again"
        )
    finally:
        for worker in workers:
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
