"""A real uvicorn server on a free local port, with its own data directory."""

from __future__ import annotations

from collections.abc import Iterator

import httpx2 as httpx
import pytest

from tests.servers import Server


@pytest.fixture(scope="session")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Server]:
    running = Server(tmp_path_factory.mktemp("server"), workers="2")
    yield running
    running.stop()


@pytest.fixture(scope="session")
def api(server: Server) -> httpx.Client:
    return server.client
