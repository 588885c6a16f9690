"""A failed artifact is remembered (service.api.media, issue 50): a picture of a stored
test-case that fails answers the same problem at once on the next read, without a worker
call, rather than holding a worker for the whole budget on every read (88 s each time).
The failure here is real: the picture's work run under a work budget far too small for it
(SCENGEN_WORK_BUDGET 0.01 s), by a second server on the same data directory."""

from __future__ import annotations

import json
import re
from pathlib import Path

from fastapi.testclient import TestClient

from service.api import create_app
from service.api.media import FAILURE_SECONDS, failure_file
from service.settings import Settings


def plot_calls(client: TestClient) -> int:
    """Worker calls for test-case pictures so far (any outcome)."""
    text = client.get("/metrics").text
    return sum(int(n) for n in re.findall(r'scengen_work_total\{work="plot",[^}]*\} (\d+)', text))


def test_a_failed_picture_answers_its_problem_at_once(tmp_path: Path) -> None:
    with TestClient(create_app(Settings(data_dir=tmp_path, workers=1))) as server:
        made = server.post("/testcases", json={"network": "4way-stop", "ego_route": "S2C_0:C2N_0"})
        assert made.status_code == 201, made.text
    ident = made.json()["id"]
    tight = Settings(data_dir=tmp_path, workers=1, work_budget=0.01)
    with TestClient(create_app(tight)) as server:
        first = server.get(f"/testcases/{ident}/plot?format=svg")
        assert first.status_code == 504, first.text
        assert first.json()["type"] == "/problems/budget-exceeded"
        calls = plot_calls(server)
        again = server.get(f"/testcases/{ident}/plot?format=svg")
        assert (again.status_code, again.json()["type"]) == (504, "/problems/budget-exceeded")
        assert again.json()["detail"].startswith(first.json()["detail"])
        assert "remembered: this request failed" in again.json()["detail"]
        assert plot_calls(server) == calls  # no new work
        other = server.get(f"/testcases/{ident}/plot?format=png")  # another artifact: tried
        assert other.status_code == 504 and plot_calls(server) == calls + 1
    # forgotten after FAILURE_SECONDS: a server with room for the work draws it
    remembered = next((tmp_path / "cache" / "artifacts").rglob("plot-testcase.svg.failed.json"))
    failure = json.loads(remembered.read_text())
    assert failure["error"] == "BudgetExceeded"
    failure["at"] -= FAILURE_SECONDS
    remembered.write_text(json.dumps(failure))
    with TestClient(create_app(Settings(data_dir=tmp_path, workers=1))) as server:
        drawn = server.get(f"/testcases/{ident}/plot?format=svg")
        assert drawn.status_code == 200 and b"<svg" in drawn.content
    assert failure_file(remembered.with_name("plot-testcase.svg")) == remembered
    assert not remembered.exists()  # made now: the failure is gone
