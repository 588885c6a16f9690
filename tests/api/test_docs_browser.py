"""The OpenAPI UI in headless Chromium, offline: /docs and /redoc load only local assets,
the /extend example runs as it stands through "Try it out", and a picture shows inline.
Screenshots go to build/screenshots/ (look at them)."""

from __future__ import annotations

import shutil
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest
from playwright.sync_api import Page, sync_playwright

from service.core.version import package_version
from tests.servers import Server

pytestmark = pytest.mark.slow

SCREENSHOTS = Path(__file__).parents[2] / "build" / "screenshots"
CHROMIUM_FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]


def chromium() -> str:
    found = shutil.which("chromium") or shutil.which("chromium-browser")
    assert found, "Chromium is missing: `make test` installs Debian's chromium package (as root)"
    return found


@contextmanager
def opened_page() -> Iterator[tuple[Page, list[str], list[str]]]:
    """A page in headless Chromium, the URLs it requested and its script errors so far
    (with what the Content-Security-Policy blocked)."""
    SCREENSHOTS.mkdir(parents=True, exist_ok=True)
    requested: list[str] = []
    errors: list[str] = []
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=chromium(), args=CHROMIUM_FLAGS)
        context = browser.new_context(viewport={"width": 1400, "height": 1000})
        opened = context.new_page()
        opened.on("request", lambda request: requested.append(request.url))
        opened.on("pageerror", lambda error: errors.append(str(error)))
        # what the Content-Security-Policy blocked (Chromium says so on the console)
        opened.on(
            "console",
            lambda message: (
                errors.append(message.text) if "Content Security Policy" in message.text else None
            ),
        )
        try:
            yield opened, requested, errors
        finally:
            browser.close()


@pytest.fixture(scope="module")
def page(server: Server) -> Iterator[tuple[Page, list[str]]]:
    with opened_page() as (opened, requested, errors):
        yield opened, requested
    assert [e for e in errors if "Content Security Policy" in e] == []  # the docs run as sent


def external(server: Server, requested: list[str]) -> list[str]:
    """Requests that left this server (blob: and data: URLs stay in the page)."""
    return [url for url in requested if not url.startswith((server.url, "blob:", "data:"))]


def open_operation(page: Page, operation: str) -> Any:
    block = page.locator(f"#{operation}")
    block.locator(".opblock-summary").click()
    block.locator("button.try-out__btn").click()
    return block


def test_extend_example_runs_from_swagger_ui(server: Server, page: tuple[Page, list[str]]) -> None:
    browser, requested = page
    browser.goto(f"{server.url}/docs")
    browser.wait_for_selector("#operations-extend-extend_testcase", timeout=30_000)
    block = open_operation(browser, "operations-extend-extend_testcase")
    block.locator("button.execute").click()
    status = block.locator(".live-responses-table tbody .response-col_status").first
    status.wait_for(timeout=120_000)
    assert status.inner_text().strip() == "201", block.locator(".live-responses-table").inner_text()
    body = block.locator(
        ".live-responses-table tbody .response-col_description pre"
    ).first.inner_text()
    assert '"new_cars"' in body and '"car1"' in body
    status.scroll_into_view_if_needed()
    browser.screenshot(path=str(SCREENSHOTS / "docs-extend.png"))
    assert external(server, requested) == []


def test_picture_shows_inline(server: Server, page: tuple[Page, list[str]]) -> None:
    browser, requested = page
    browser.goto(f"{server.url}/docs")
    browser.wait_for_selector("#operations-networks-plot_junction", timeout=30_000)
    block = open_operation(browser, "operations-networks-plot_junction")
    block.locator("button.execute").click()
    image = block.locator(".live-responses-table img").first
    image.wait_for(timeout=60_000)
    width = image.evaluate("img => img.naturalWidth")
    assert width > 400
    image.scroll_into_view_if_needed()
    browser.screenshot(path=str(SCREENSHOTS / "docs-plot.png"))
    assert external(server, requested) == []


def test_redoc_renders_offline(server: Server, page: tuple[Page, list[str]]) -> None:
    browser, requested = page
    browser.goto(f"{server.url}/redoc")
    browser.wait_for_selector(f"text=scengen ({package_version()})", timeout=30_000)
    browser.wait_for_timeout(1000)  # let it finish rendering and fetching
    browser.screenshot(path=str(SCREENSHOTS / "redoc.png"))
    assert external(server, requested) == []
