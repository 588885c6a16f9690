"""The artifact cache on a real server: an artifact asked for by several requests at once is
produced by one worker call, and every request gets it."""

from __future__ import annotations

import re
from concurrent.futures import ThreadPoolExecutor

import httpx2 as httpx

from tests.servers import Server


def junction_work(api: httpx.Client) -> int:
    """Worker calls for junction pictures and shapes so far (any outcome)."""
    text = api.get("/metrics").text
    return sum(
        int(n) for n in re.findall(r'scengen_work_total\{work="junction",[^}]*\} (\d+)', text)
    )


def test_an_artifact_asked_for_at_once_is_made_once(server: Server) -> None:
    # a highlight no other test asks for: not yet in this server's cache
    path = "/networks/t-stop/junctions/C/plot?format=svg&route=W2C_0:C2S_0&route=E2C_0:C2W_0"
    before = junction_work(server.client)
    with ThreadPoolExecutor(3) as pool, httpx.Client(base_url=server.url, timeout=120) as api:
        answers = list(pool.map(lambda _: api.get(path), range(3)))
    assert [answer.status_code for answer in answers] == [200, 200, 200]
    assert answers[0].content == answers[1].content == answers[2].content
    assert b"<svg" in answers[0].content
    assert junction_work(server.client) == before + 1
    assert server.client.get(path).content == answers[0].content  # from the cache now
    assert junction_work(server.client) == before + 1
