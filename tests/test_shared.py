"""tests.shared.made_once: the first worker makes, the others read what it made."""

from __future__ import annotations

import pytest

from tests.shared import made_once


def test_made_once_per_run_whichever_worker_asks(tmp_path_factory: pytest.TempPathFactory) -> None:
    calls: list[str] = []

    def make() -> dict[str, list[int]]:
        calls.append("made")
        return {"levels": [0, 1, 2]}

    name = f"probe-{tmp_path_factory.getbasetemp().name}"  # this run's, this worker's
    first = made_once(name, make, tmp_path_factory, worker_id="gw0")
    second = made_once(name, make, tmp_path_factory, worker_id="gw1")
    assert first == second == {"levels": [0, 1, 2]} and calls == ["made"]
    assert made_once(name, make, tmp_path_factory, worker_id="master") == first
    assert calls == ["made", "made"]  # without xdist: a plain call
