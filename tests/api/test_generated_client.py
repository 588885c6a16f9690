"""A client generated from the served /openapi.json with a standard generator
(openapi-python-client, with openapi/openapi-python-client.yml) drives the main flow against
a real server with a token, in strict mode (an undocumented status raises): upload a
network, create a test-case, extend it, evaluate it, download its bundle and a picture."""

from __future__ import annotations

import importlib
import io
import json
import subprocess
import sys
import zipfile
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest

from service.api.openapi import COMMITTED
from service.api.schemas import EXAMPLE_EGO, EXAMPLE_NEW_ROUTE
from service.core.network import bundled_networks
from tests.servers import Server

TOKEN = "client-token"
CONFIG = COMMITTED.with_name("openapi-python-client.yml")
PACKAGE = "scengen_client"


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Server]:
    running = Server(tmp_path_factory.mktemp("client-server"), api_token=TOKEN, workers="2")
    yield running
    running.stop()


@pytest.fixture(scope="module")
def generated(server: Server, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Any]:
    """``load(name)``: a module of the client generated from the server's document."""
    folder = tmp_path_factory.mktemp("client")
    document = folder / "openapi.json"
    document.write_text(server.client.get("/openapi.json").text)
    generator = Path(sys.executable).with_name("openapi-python-client")
    made = subprocess.run(
        [str(generator), "generate", "--path", str(document), "--meta", "none",
         "--output-path", str(folder / PACKAGE), "--config", str(CONFIG)],
        capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert made.returncode == 0, made.stdout + made.stderr
    # every operation's answers are in the client: none was dropped as unreadable
    assert "response will be omitted" not in made.stdout + made.stderr, made.stdout
    assert "Unable to process schema" not in made.stdout + made.stderr, made.stdout
    sys.path.insert(0, str(folder))
    try:
        yield lambda name: importlib.import_module(f"{PACKAGE}.{name}")
    finally:
        sys.path.remove(str(folder))
        for name in [m for m in sys.modules if m == PACKAGE or m.startswith(f"{PACKAGE}.")]:
            del sys.modules[name]


def test_a_generated_client_drives_the_main_flow(server: Server, generated: Any) -> None:
    models: ModuleType = generated("models")
    types: ModuleType = generated("types")
    client = generated("client").AuthenticatedClient(
        base_url=server.url, token=TOKEN, raise_on_unexpected_status=True, timeout=300.0
    )
    content = bundled_networks()["4way-stop"].read_bytes()
    upload = models.BodyUploadNetwork(
        file=types.File(payload=io.BytesIO(content), file_name="crossing.net.xml"),
        controls=json.dumps({"C": "allway_stop"}),
    )
    network = generated("api.networks.upload_network").sync(client=client, body=upload)
    assert isinstance(network, models.NetworkPublic), network
    assert network.filename == "crossing.net.xml" and network.controls.to_dict() == {
        "C": "allway_stop"
    }
    stored = generated("api.networks.get_network_file").sync(network.id, client=client)
    assert isinstance(stored, types.File) and stored.payload.read() == content

    root = generated("api.testcases.create_testcase").sync(
        client=client, body=models.TestCaseCreate(network=network.id, ego_route=EXAMPLE_EGO)
    )
    assert isinstance(root, models.TestCasePublic), root
    assert root.network == network.id and root.level == 0

    extension = generated("api.extend.extend_testcase").sync(
        client=client,
        body=models.ExtendRequestById(
            testcase_id=root.id, routes=[EXAMPLE_NEW_ROUTE], seed=1, budget=120.0
        ),
    )
    assert isinstance(extension, models.ExtensionPublic), extension
    assert extension.parent == root.id and len(extension.new_cars) == 1

    evaluation = generated("api.evaluations.create_evaluation").sync(
        client=client,
        body=models.EvaluationCreateById(
            testcase_id=extension.id, controller=models.EvaluationCreateByIdController.SUMO
        ),
    )
    assert isinstance(evaluation, models.EvaluationPublic), evaluation
    assert evaluation.testcase == extension.id and isinstance(evaluation.passed, bool)

    bundle = generated("api.testcases.get_bundle").sync(extension.id, client=client)
    assert isinstance(bundle, types.File)
    with zipfile.ZipFile(bundle.payload) as archive:
        assert any(name.endswith(".sumocfg") for name in archive.namelist())
    picture = generated("api.testcases.plot_testcase").sync(
        extension.id, client=client, format_=models.PlotTestcaseFormat.PNG
    )
    assert isinstance(picture, types.File)
    assert picture.payload.read().startswith(b"\x89PNG\r\n\x1a\n")
    drawing = generated("api.networks.plot_junction").sync(
        network.id, "C", client=client, format_=models.PlotJunctionFormat.SVG
    )
    assert isinstance(drawing, types.File) and b"<svg" in drawing.payload.read()


def test_a_generated_client_needs_the_token_where_the_server_does(
    server: Server, generated: Any
) -> None:
    """Writes take an AuthenticatedClient (the document lists the token as required, with
    no anonymous alternative); reads take either."""
    import inspect

    create = generated("api.testcases.create_testcase").sync
    listing = generated("api.testcases.list_testcases").sync
    authenticated = generated("client").AuthenticatedClient
    assert inspect.signature(create).parameters["client"].annotation in (
        "AuthenticatedClient",
        authenticated,
    )
    anonymous = generated("client").Client(base_url=server.url, raise_on_unexpected_status=True)
    page = listing(client=anonymous)
    assert page is not None and page.total >= 0
