"""The results browser (/ui) in headless Chromium on a real server with generated data: a
small campaign run as a job (the server has an API token: pages read without it), then
every page: networks with their junctions drawn (and what the first load waits for), the
lineage tree and its filter, a test-case's animation (the cars move: frames differ when
played, scrubbed or with the certificates off) and its time-distance panel (axis numbers,
curve names whole and apart, measured on the drawn SVG), the campaign with its
failure-rate plot, and the verdict matrix whose cells open the replay of that very
evaluation. The report `scengen report JOB --server` writes works from a file, offline.
A campaign whose verdicts carry criticality (hand-made ones: the measures are tested
where they are computed) plots each measure by level beside the failure rate.
On a server of its own, a signalized test-case's animation draws each signal head in the
colour its program shows at the moment on the slider; on another, a test-case with a
pedestrian lists her, draws the crosswalks and moves her over one; a network's page
lists its walks under each junction drawn with its zebras.
Screenshots go to build/screenshots/ui-*.png (look at them)."""

from __future__ import annotations

import itertools
import json
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from matplotlib.colors import to_rgb
from playwright.sync_api import Page

from service.core.campaign.growing import run_campaign
from service.core.checker.check import until_goal
from service.core.generator.extension import extend_testcase
from service.core.motion.poses import PoseSample
from service.core.testcase import (
    Signals,
    TestCase,
    load_testcase_intersection,
    new_testcase,
    parse_testcase,
)
from service.pictures.pedestrians import CROSSWALK, PEDESTRIAN_COLOURS
from service.pictures.report import report_html
from service.pictures.signals import SIGNAL_COLOURS
from service.store import Store
from tests.api.test_docs_browser import SCREENSHOTS, external, opened_page
from tests.core.campaign.test_campaign import RULES, FakeSteps, plan
from tests.pictures.crossings import straight_walk, with_pedestrians
from tests.servers import Server

pytestmark = pytest.mark.slow

TOKEN = "ui-test-token"
CAMPAIGN = {
    "kind": "campaign",
    "network": "t-stop",
    "egos": ["S2C_0:C2E_0"],
    "depth": 2,
    "chains": 1,
    "controllers": ["sumo", "sumo-rolling-stop"],
    "duration": 20.0,  # not the default 45 s: the suite's time
}


@pytest.fixture(scope="module")
def served(
    tmp_path_factory: pytest.TempPathFactory,
) -> Iterator[tuple[Server, str, dict[str, Any]]]:
    server = Server(tmp_path_factory.mktemp("ui"), workers="2", api_token=TOKEN)
    try:
        refused = server.client.post("/jobs", json={"items": [CAMPAIGN]})
        assert refused.status_code == 401  # writes need the token; the pages below do not
        job = server.client.post(
            "/jobs", json={"name": "ui campaign", "items": [CAMPAIGN]},
            headers={"Authorization": f"Bearer {TOKEN}"},
        ).json()["id"]  # fmt: skip
        finished = server.wait_for_job(job)
        assert finished["state"] == "succeeded", finished["items"][0]["error"]
        outcome = server.client.get(f"/jobs/{job}/campaign").json()
        longer = server.client.post(  # a second root on the campaign's route: 30 s, not 20
            "/testcases", json={"network": "t-stop", "ego_route": "S2C_0:C2E_0", "duration": 30},
            headers={"Authorization": f"Bearer {TOKEN}"},
        )  # fmt: skip
        assert longer.status_code == 201, longer.text
        yield server, job, outcome
    finally:
        server.stop()


@pytest.fixture(scope="module")
def browser_page(served: tuple[Server, str, dict[str, Any]]) -> Iterator[tuple[Page, list[str]]]:
    with opened_page() as (opened, requested, errors):
        yield opened, requested
    assert errors == []  # no script error on any page


def canvas_frame(page: Page) -> bytes:
    return page.locator("#animation").screenshot()


def test_networks_show_their_junctions_drawn_and_say_what_they_wait_for(
    served: tuple[Server, str, dict[str, Any]], browser_page: tuple[Page, list[str]]
) -> None:
    """The first visit waits for workers: the page says so (a held request shows it), then
    draws each junction from its shapes (connecting lanes by turn, stop lines), with a link
    to the server's picture."""
    server, _, _ = served
    page, requested = browser_page
    held: list[Any] = []
    page.route("**/networks/t-stop/junctions", lambda route: held.append(route))  # held
    page.goto(f"{server.url}/ui/")
    page.wait_for_selector("text=Reading the junctions of t-stop…")
    page.wait_for_function("() => document.querySelectorAll('svg.junction-drawing').length == 6")
    assert len(held) == 1  # t-stop's junctions are still on their way
    held[0].continue_()
    page.unroute("**/networks/t-stop/junctions")
    page.wait_for_function("() => document.querySelectorAll('svg.junction-drawing').length == 7")
    assert page.locator("text=Reading the junctions").count() == 0
    drawn = (("4way-stop", 16, 0), ("t-stop", 6, 0), ("y-uncontrolled", 6, 0),
             ("4way-signal", 16, 16), ("t-signal", 6, 6), ("crosswalk-stop", 16, 0),
             ("crosswalk-signal", 16, 16))  # fmt: skip
    for network, routes, heads in drawn:
        drawing = page.locator(f".card:has(a[href='#/networks/{network}']) svg.junction-drawing")
        assert drawing.get_attribute("data-junction") == "C"
        assert drawing.locator("polyline.route").count() == routes  # one per connecting lane
        assert drawing.locator("polygon.signal-head").count() == heads  # one per signal link
        assert drawing.locator("polyline.stop-line").count() >= 3
        box = drawing.bounding_box()
        assert box is not None and box["width"] > 200 and abs(box["width"] - box["height"]) < 2
    picture = page.locator("a:text-is('picture')").first.get_attribute("href")
    assert picture and server.client.get(picture).headers["content-type"] == "image/png"
    page.screenshot(path=str(SCREENSHOTS / "ui-networks.png"))
    assert external(server, requested) == []


def test_lineage_tree_filters_by_ego_and_level(
    served: tuple[Server, str, dict[str, Any]], browser_page: tuple[Page, list[str]]
) -> None:
    server, _, outcome = served
    page, _ = browser_page
    page.goto(f"{server.url}/ui/#/testcases?ego=S2C_0:C2E_0")
    page.wait_for_selector("#lineage")
    made = [level["testcase"] for level in outcome["chains"][0]["levels"]]
    for ident in made:  # root, level 1 and level 2, nested
        assert page.locator(f"#lineage a[href='#/testcases/{ident}']").count() == 1
    nested = page.locator(
        f"#lineage li:has(a[href='#/testcases/{made[0]}']) ul a[href='#/testcases/{made[2]}']"
    )
    assert nested.count() == 1
    page.screenshot(path=str(SCREENSHOTS / "ui-lineage.png"))
    page.goto(f"{server.url}/ui/#/testcases?level=2")
    page.wait_for_selector("table")
    assert page.locator(f"a[href='#/testcases/{made[2]}']").count() == 1
    assert page.locator(f"a[href='#/testcases/{made[1]}']").count() == 0


def test_variants_are_listed_in_their_order_not_newest_first(
    browser_page: tuple[Page, list[str]], tmp_path: Path
) -> None:
    """Three variants of one test-case (POST /extend, count 3) sit under it by name:
    variant 1, 2, 3 (the API lists the newest first)."""
    server = Server(tmp_path, workers="2")
    try:
        root = server.client.post(
            "/testcases", json={"network": "t-stop", "ego_route": "S2C_0:C2E_0"}
        ).json()["id"]
        made = server.client.post(
            "/extend", json={"testcase_id": root, "routes": ["W2C_0:C2E_0"], "count": 3}
        )
        assert made.status_code == 201, made.text
        page, requested = browser_page  # the module's page, on a server of this test's own
        before = len(requested)
        page.goto(f"{server.url}/ui/#/testcases")
        page.wait_for_selector(f"#lineage li[data-testcase='{root}'] > ul > li")
        names = page.locator(f"#lineage li[data-testcase='{root}'] > ul > li > a").all_inner_texts()
        del requested[before:]  # this server's pages are not the module server's requests
    finally:
        server.stop()
    assert len(names) == len(made.json()["extensions"]) >= 2
    assert [n.split(" variant ")[1] for n in names] == [
        f"{k} level 1" for k in range(1, len(names) + 1)
    ]


def test_roots_on_one_route_are_told_apart_and_names_say_the_level(
    served: tuple[Server, str, dict[str, Any]], browser_page: tuple[Page, list[str]]
) -> None:
    """Two ego-only roots on the same route (20 s and 30 s): their headings differ; every
    entry of the tree, the level listing, the evaluation matrix and the campaign's matrix
    names its test-case with the level, its duration beside it."""
    server, job, outcome = served
    page, _ = browser_page
    page.goto(f"{server.url}/ui/#/testcases?ego=S2C_0:C2E_0")
    page.wait_for_selector("#lineage")
    headings = page.locator("#lineage strong.root").all_inner_texts()
    assert len(headings) == 2 and len(set(headings)) == 2
    assert sorted(h.split(" · ")[3] for h in headings) == ["20 s", "30 s"]
    entries = page.locator("#lineage li[data-testcase]")
    assert entries.count() == 4  # the campaign's root and its two levels, the longer root
    made = [level["testcase"] for level in outcome["chains"][0]["levels"]]
    for level, ident in enumerate(made):
        link = page.locator(f"#lineage li[data-testcase='{ident}'] > a")
        assert link.inner_text() == outcome["chains"][0]["levels"][level]["name"]
    names = page.locator("#lineage li[data-testcase] > a").all_inner_texts()
    assert sorted(names) == sorted(
        ["t-stop C S2C_0:C2E_0 level 0", "t-stop C S2C_0:C2E_0 level 0",
         "t-stop C S2C_0:C2E_0 chain 1 level 1", "t-stop C S2C_0:C2E_0 chain 1 level 2"]
    )  # fmt: skip
    page.screenshot(path=str(SCREENSHOTS / "ui-roots.png"), full_page=True)
    page.goto(f"{server.url}/ui/#/testcases?level=0")
    page.wait_for_selector("#listing table")
    rows = [row.split("\t") for row in page.locator("#listing tbody tr").all_inner_texts()]
    assert sorted((r[0], r[1], r[2]) for r in rows) == [
        ("t-stop C S2C_0:C2E_0 level 0", "0", "20 s"), ("t-stop C S2C_0:C2E_0 level 0", "0", "30 s")
    ]  # fmt: skip
    page.goto(f"{server.url}/ui/#/evaluations")
    page.wait_for_selector("#evaluation-matrix td.cell")
    head = page.locator("#evaluation-matrix th").all_inner_texts()
    assert head[:3] == ["test-case", "level", "duration"]
    for level, ident in enumerate(made):
        cells = page.locator(f"#evaluation-matrix tr[data-testcase='{ident}'] td").all_inner_texts()
        name = outcome["chains"][0]["levels"][level]["name"]
        assert cells[:3] == [f"{name} {ident[:8]}", str(level), "20 s"]
    page.goto(f"{server.url}/ui/#/jobs/{job}")
    page.wait_for_selector("#verdict-matrix td.cell")
    first = page.locator(f"#verdict-matrix tr[data-testcase='{made[2]}'] td").all_inner_texts()
    assert first[:3] == [f"t-stop C S2C_0:C2E_0 chain 1 level 2 {made[2][:8]}", "2", "20 s"]


def test_the_animation_moves_the_cars(
    served: tuple[Server, str, dict[str, Any]], browser_page: tuple[Page, list[str]]
) -> None:
    server, _, outcome = served
    page, requested = browser_page
    level2 = outcome["chains"][0]["levels"][2]["testcase"]
    page.goto(f"{server.url}/ui/#/testcases/{level2}")
    page.wait_for_selector("#animation")
    start = canvas_frame(page)
    page.locator("#speed").select_option("4")
    page.locator("#play").click()
    page.wait_for_function("() => Number(document.querySelector('#animation').dataset.time) > 2")
    page.locator("#play").click()  # pause
    played = canvas_frame(page)
    assert played != start
    page.locator("#scrub").fill("12")
    scrubbed = canvas_frame(page)
    assert scrubbed not in (start, played)
    assert page.locator("#animation").get_attribute("data-time") == "12.00"
    page.locator("#certificates").uncheck()
    assert canvas_frame(page) != scrubbed  # the two ego certificates are gone
    page.locator("#certificates").check()
    assert page.locator("#time-distance polyline").count() == 2 + 2  # two cars, two proofs
    body = page.locator("main").inner_text()
    assert "car2 (new)" in body and "complexity certificate breaks" in body
    for download in ("test-case JSON", "SUMO bundle (zip)", "OpenSCENARIO (zip)"):
        href = page.locator(f"a:text-is('{download}')").get_attribute("href")
        assert href and server.client.get(href).status_code == 200
    page.screenshot(path=str(SCREENSHOTS / "ui-testcase.png"), full_page=True)
    assert external(server, requested) == []


def test_the_certificates_leave_the_animation_at_their_goal(
    served: tuple[Server, str, dict[str, Any]], browser_page: tuple[Page, list[str]]
) -> None:
    """The test ends with the goal: a test-case's page draws each certificate until its
    goal, found in the browser from the junction's area as the checker finds it (the same
    sample: the first at or after the goal), and not after it, as the replay's ego leaves
    the simulation there."""
    server, _, outcome = served
    page, _ = browser_page
    level2 = outcome["chains"][0]["levels"][2]["testcase"]
    testcase = parse_testcase(server.client.get(f"/testcases/{level2}").json()["testcase"])
    assert testcase.certificates is not None
    intersection = load_testcase_intersection(testcase)
    area = server.client.get(
        f"/networks/{testcase.network.ref}/junctions/{testcase.junction}/geometry",
        params={"control": testcase.control},
    ).json()["area"]  # fmt: skip
    page.goto(f"{server.url}/ui/#/testcases/{level2}")
    page.wait_for_selector("#animation")
    ends = []
    for kind in ("solvability", "complexity"):
        samples = [PoseSample(**s.model_dump()) for s in getattr(testcase.certificates, kind)]
        kept = until_goal(testcase, samples, intersection)
        assert len(kept) < len(samples)  # both reach their goal before the duration
        rows = [[s.t, s.x, s.y, s.heading, s.speed, s.distance] for s in samples]
        drawn = page.evaluate(
            "([rows, area, length, width]) => untilOut(rows, area, length, width).length",
            [rows, area, testcase.ego.length, testcase.ego.width],
        )  # fmt: skip
        assert drawn == len(kept), kind
        ends.append(kept[-1].t)
    page.locator("#scrub").fill(f"{max(ends) + 0.5:g}")  # both gone: no certificate drawn
    with_them = canvas_frame(page)
    page.locator("#certificates").uncheck()
    assert canvas_frame(page) == with_them
    page.locator("#certificates").check()
    page.locator("#scrub").fill(f"{min(ends) - 0.5:g}")  # both still there
    with_them = canvas_frame(page)
    page.locator("#certificates").uncheck()
    assert canvas_frame(page) != with_them
    page.locator("#certificates").check()


TEXT_BOXES = """() => {
  const panel = document.querySelector('#time-distance');
  const frame = panel.getBoundingClientRect();
  const texts = [...panel.querySelectorAll('text')].map((t) => {
    const b = t.getBoundingClientRect();
    return { text: t.textContent, kind: t.getAttribute('class') || '',
             x0: b.left - frame.left, x1: b.right - frame.left,
             y0: b.top - frame.top, y1: b.bottom - frame.top };
  });
  return { width: frame.width, height: frame.height, texts };
}"""


def test_the_time_distance_panel_numbers_its_axes_and_names_every_curve_whole(
    served: tuple[Server, str, dict[str, Any]], browser_page: tuple[Page, list[str]]
) -> None:
    """Measured on the drawn SVG: metres on the y axis, every word inside the panel (no name
    cut off at its edge), and no two curve names over each other."""
    server, _, outcome = served
    page, _ = browser_page
    level2 = outcome["chains"][0]["levels"][2]["testcase"]
    page.goto(f"{server.url}/ui/#/testcases/{level2}")
    page.wait_for_selector("#time-distance polyline")
    drawn = page.evaluate(TEXT_BOXES)
    ticks = [float(t["text"]) for t in drawn["texts"] if t["kind"] == "y-tick"]
    assert len(ticks) >= 3 and ticks[0] == 0 and ticks == sorted(ticks)
    assert ticks[1] > 0  # metres, increasing up the axis
    names = [t for t in drawn["texts"] if t["kind"] == "curve-name"]
    assert sorted(t["text"] for t in names) == sorted(
        ["car1", "car2", "ego (solvability)", "ego (complexity)"]
    )
    assert len(names) == page.locator("#time-distance polyline").count()
    for text in drawn["texts"]:  # inside the panel: nothing clipped
        assert text["x0"] >= 0 and text["x1"] <= drawn["width"], text
        assert text["y0"] >= 0 and text["y1"] <= drawn["height"], text
    for a, b in itertools.combinations(names, 2):
        side_by_side = a["x1"] <= b["x0"] or b["x1"] <= a["x0"]
        assert side_by_side or a["y1"] <= b["y0"] or b["y1"] <= a["y0"], (a["text"], b["text"])
    page.locator("#time-distance").screenshot(path=str(SCREENSHOTS / "ui-time-distance.png"))


def test_campaign_matrix_opens_the_replay_of_that_evaluation(
    served: tuple[Server, str, dict[str, Any]], browser_page: tuple[Page, list[str]]
) -> None:
    server, job, outcome = served
    page, requested = browser_page
    page.goto(f"{server.url}/ui/#/jobs/{job}")
    page.wait_for_selector("#failure-plot polyline")
    assert page.locator("#failure-plot polyline").count() == 2  # one line per controller
    # lines of equal shares stay apart: each its own dashes, a few pixels beside the other
    lines = page.locator("#failure-plot polyline.failure-line")
    dashes = [lines.nth(k).get_attribute("stroke-dasharray") for k in range(2)]
    assert dashes[0] != dashes[1]
    assert lines.nth(0).get_attribute("points") != lines.nth(1).get_attribute("points")
    page.screenshot(path=str(SCREENSHOTS / "ui-campaign.png"), full_page=True)
    state = page.locator("#job-state").inner_text()
    assert state.startswith("job succeeded · 1/1 items ran · the controllers' verdicts below")
    level = outcome["chains"][0]["levels"][2]
    verdict = level["verdicts"]["sumo-rolling-stop"]
    cell = page.locator(
        f"#verdict-matrix a[data-testcase='{level['testcase']}']"
        "[data-controller='sumo-rolling-stop']"
    ).first
    # a failed cell says every reason of the verdict, as the campaign's JUnit does
    assert cell.inner_text() == ("pass" if verdict["passed"] else "; ".join(verdict["reasons"]))
    for chain in outcome["chains"]:
        for each in chain["levels"]:
            for controller, judged in each["verdicts"].items():
                shown = page.locator(
                    f"#verdict-matrix a[data-testcase='{each['testcase']}']"
                    f"[data-controller='{controller}']"
                ).first.inner_text()
                assert all(reason in shown for reason in judged["reasons"]), (shown, judged)
    cell.click()
    page.wait_for_selector("#verdict")
    assert page.url.endswith(f"#/replay/{verdict['evaluation']}")
    assert "sumo-rolling-stop" in page.locator("h1").inner_text()
    assert ("pass" if verdict["passed"] else "FAIL") in page.locator("#verdict").inner_text()
    measured = server.client.get(f"/evaluations/{verdict['evaluation']}").json()
    others = measured["verdict"]["criticality"]["others"]
    rows = page.locator("#criticality tbody tr").all_inner_texts()
    assert [row.split("\t")[0] for row in rows] == ["overall", *others]
    distance = measured["verdict"]["criticality"]["overall"]["distance"]
    assert f"{distance['value']:.2f} m at {distance['t']:.2f} s, {distance['car']}" in rows[0]
    start = canvas_frame(page)
    page.locator("#scrub").fill("6")
    assert canvas_frame(page) != start
    page.screenshot(path=str(SCREENSHOTS / "ui-replay.png"), full_page=True)
    page.goto(f"{server.url}/ui/#/evaluations")
    page.wait_for_selector("td.cell a")
    assert page.locator("td.cell a").count() == 3 * 2  # three test-cases, two controllers
    guarded = server.client.post(  # the RSS guard's record beside the measures
        "/evaluations", json={"testcase_id": level["testcase"], "controller": "sumo+rss"},
        headers={"Authorization": f"Bearer {TOKEN}"},
    ).json()  # fmt: skip
    page.goto(f"{server.url}/ui/#/replay/{guarded['id']}")
    page.wait_for_selector("#guard")
    guard = guarded["verdict"]["guard"]
    said = page.locator("#guard").inner_text()
    assert f"Intervened at {guard['interventions']} of {guard['steps']} steps" in said
    assert external(server, requested) == []


def test_the_report_works_from_a_file_offline(
    served: tuple[Server, str, dict[str, Any]], browser_page: tuple[Page, list[str]],
    tmp_path: Path,
) -> None:  # fmt: skip
    server, job, outcome = served
    page, _ = browser_page
    report = tmp_path / "report.html"
    written = subprocess.run(
        [sys.executable, "-m", "service", "report", job, "--server", server.url, "-o", str(report)],
        capture_output=True, text=True, check=False,
    )  # fmt: skip
    assert written.returncode == 0, written.stderr
    assert report.read_text() == server.client.get(f"/jobs/{job}/campaign/report").text
    loaded: list[str] = []
    page.on("request", lambda request: loaded.append(request.url))
    page.goto(report.as_uri())
    page.wait_for_selector("#verdict-matrix")
    level = outcome["chains"][0]["levels"][1]
    page.locator(
        f"#verdict-matrix a[data-testcase='{level['testcase']}'][data-controller='sumo']"
    ).first.click()
    page.wait_for_selector("#animation")
    assert "sumo on" in page.locator("h1").inner_text()
    page.locator("a:text-is('" + page.locator("#verdict a").inner_text() + "')").click()
    page.wait_for_selector("#time-distance")
    page.screenshot(path=str(SCREENSHOTS / "ui-report.png"))
    assert [url for url in loaded if not url.startswith(("file:", "data:", "blob:"))] == []


def test_the_served_report_runs_under_its_content_security_policy(
    served: tuple[Server, str, dict[str, Any]], browser_page: tuple[Page, list[str]]
) -> None:
    """Served, the report's inline script and data run by their hashes and nothing else
    would (a violation is a script error of the page: browser_page fails on it)."""
    server, job, _ = served
    page, _ = browser_page
    answer = server.client.get(f"/jobs/{job}/campaign/report")
    policy = answer.headers["content-security-policy"]
    scripts = next(d for d in policy.split(";") if d.strip().startswith("script-src"))
    assert scripts.count("'sha256-") == 2 and "unsafe" not in scripts, policy
    assert answer.headers["x-frame-options"] == "DENY"
    page.goto(f"{server.url}/jobs/{job}/campaign/report")
    page.wait_for_selector("#verdict-matrix")
    assert page.locator("#verdict-matrix a").count() > 0


def test_the_campaign_plots_each_criticality_measure_by_level_beside_the_failure_rate(
    browser_page: tuple[Page, list[str]], tmp_path: Path
) -> None:
    page, _ = browser_page
    outcome = run_campaign(plan(), FakeSteps(measured=True), RULES)
    job = "c" * 32
    record = {"id": job, "name": "fake", "state": "succeeded", "done": 1, "total": 1,
              "items": [{"position": 0, "kind": "campaign", "state": "succeeded",
                         "progress": "", "error": None}]}  # fmt: skip
    report = tmp_path / "report.html"
    answers = {f"/jobs/{job}": record, f"/jobs/{job}/campaign": outcome}
    report.write_text(report_html(job, answers, "criticality"))
    page.goto(report.as_uri())
    page.wait_for_selector("#criticality")
    weak = page.locator(".criticality-card[data-controller='weak']")
    assert weak.locator(".failure-rate").inner_text() == (
        "failed: level 0 0/1 0% (0–79%) · level 1 0/2 0% (0–66%) · level 2 2/2 100% (34–100%)"
        " · level 3 2/2 100% (34–100%)"
    )
    assert (
        weak.locator(".trend")
        .inner_text()
        .startswith("criticality grows: median TTC 3.25 → 2.25 → 1.25 s (levels 1–3)")
    )
    ttc = weak.locator(".criticality-plot[data-measure='ttc']")
    assert ttc.locator(".level-tick").all_text_contents() == ["0", "1", "2", "3"]
    values = "circles => circles.map((c) => c.getAttribute('data-value'))"
    dots = {
        level: ttc.locator(f"g.level[data-level='{level}'] circle").evaluate_all(values)
        for level in (0, 1, 2, 3)
    }
    assert dots == {0: [], 1: ["3", "3.5"], 2: ["2", "2.5"], 3: ["1", "1.5"]}
    # the median of a more critical level is drawn lower: TTC falls from level to level
    heights = [
        float(ttc.locator(f"g.level[data-level='{level}'] .median").get_attribute("y1") or 0)
        for level in (1, 2, 3)
    ]
    assert heights == sorted(heights) and heights[0] < heights[2]
    strong = page.locator(".criticality-plot[data-controller='strong'][data-measure='ttc']")
    assert "never arose" in (strong.text_content() or "")  # strong never was on a collision course
    page.locator("#criticality").screenshot(path=str(SCREENSHOTS / "ui-criticality.png"))


def test_the_campaign_shows_each_share_with_its_interval_and_each_levels_diversity(
    browser_page: tuple[Page, list[str]], tmp_path: Path
) -> None:
    """Over hand-made verdicts (tests/core/campaign/test_campaign.py's fake): the level
    table and the plot carry each share's Wilson interval, the diversity table each
    level's measures, and an outcome stored before campaigns kept them still shows its
    shares."""
    page, _ = browser_page
    outcome = run_campaign(plan(), FakeSteps(), RULES)
    job = "d" * 32
    record = {"id": job, "name": "fake", "state": "succeeded", "done": 1, "total": 1,
              "items": [{"position": 0, "kind": "campaign", "state": "succeeded",
                         "progress": "", "error": None}]}  # fmt: skip
    old = json.loads(json.dumps(outcome))
    for level in old["levels"]:
        del level["diversity"], level["grown"]
        for share in level["controllers"].values():
            del share["interval"]
    for name, shown in (("new", outcome), ("old", old)):
        report = tmp_path / f"{name}.html"
        answers = {f"/jobs/{job}": record, f"/jobs/{job}/campaign": shown}
        report.write_text(report_html(job, answers, "diversity"))
        page.goto(report.as_uri())
        page.wait_for_selector("#failure-shares")
        level_two = page.locator("#failure-shares tbody tr").nth(2)
        cells = level_two.locator("td").all_inner_texts()
        if name == "old":
            assert cells[3].startswith("2/2") and "%" not in cells[3]
            assert page.locator("#failure-plot line.interval").count() == 0
            assert page.locator("#diversity-none").count() == 1
            continue
        assert cells[:2] == ["2", "2"] and cells[3].startswith("2/2 100% (34–100%)")
        bars = page.locator("#failure-plot line.interval[data-controller='weak']")
        assert bars.count() == 4  # one per level
        assert bars.nth(2).locator("title").text_content() == "weak, level 2: 2/2 100% (34–100%)"
        rows = page.locator("#diversity tbody tr").all_inner_texts()
        assert rows[3].split("\t") == ["3", "2", "1", "1", "1: yieldToInside", "—", "—"]


# t-signal's own program with an offset: at t = 0 the light is 31 s into its 38 s cycle
SIGNAL_PROGRAM = {
    "tls": "C",
    "program": "offset",
    "offset": 7.0,
    "phases": [
        {"duration": 18, "state": "GgsrGG"}, {"duration": 3, "state": "yysrGy"},
        {"duration": 1, "state": "rrsrGr"}, {"duration": 12, "state": "rrGGGr"},
        {"duration": 3, "state": "rryyGr"}, {"duration": 1, "state": "rrsrGr"},
    ],
}  # fmt: skip


@pytest.fixture(scope="module")
def signalized(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Server, str, str]]:
    """A server of its own (the campaign's pages count their test-cases) with a level-1
    test-case on t-signal under SIGNAL_PROGRAM (the ego turns right, on red after a stop;
    a car comes straight from the west) and SUMO's driver evaluated on it."""
    server = Server(tmp_path_factory.mktemp("ui-signals"), workers="1")
    try:
        root = server.client.post("/testcases", json={
            "network": "t-signal", "ego_route": "S2C_0:C2E_0", "duration": 30,
            "signals": SIGNAL_PROGRAM,
        })  # fmt: skip
        assert root.status_code == 201, root.text
        extended = server.client.post(
            "/extend", json={"testcase_id": root.json()["id"], "routes": ["W2C_0:C2E_0"]}
        )
        assert extended.status_code == 201, extended.text
        ident = extended.json()["id"]
        evaluated = server.client.post("/evaluations", json={"testcase_id": ident})
        assert evaluated.status_code == 201, evaluated.text
        yield server, ident, evaluated.json()["id"]
    finally:
        server.stop()


SIGNALS_SHOWN = """() => {
  const canvas = document.querySelector('#animation');
  const heads = JSON.parse(canvas.dataset.signals || '[]');
  const context = canvas.getContext('2d');
  return heads.map((head) => ({...head,
    pixel: [...context.getImageData(Math.floor(head.x), Math.floor(head.y), 1, 1).data]}));
}"""


def test_the_animation_draws_each_signal_head_in_its_colour_at_that_moment(
    signalized: tuple[Server, str, str], browser_page: tuple[Page, list[str]]
) -> None:
    """At four moments, each in another phase (25 s just where its phase begins), every
    head of the junction is drawn in the colour SignalProgram.colour gives its link then:
    the colour the page says (the canvas's data-signals) and the pixel at the head (white
    at an ``s`` head: its dot). The replay of SUMO's drive draws them too."""
    server, ident, evaluation = signalized
    program = Signals.model_validate(SIGNAL_PROGRAM).to_program()
    geometry = server.client.get("/networks/t-signal/junctions/C/geometry").json()
    heads = {f"{h['fork']}-{h['link_index']}": h["link_index"] for h in geometry["signal_heads"]}
    assert len(heads) == 6  # one per link of the traffic light
    page, requested = browser_page
    before = len(requested)
    page.goto(f"{server.url}/ui/#/testcases/{ident}")
    page.wait_for_selector("#animation[data-signals]")
    seen = set()
    for moment in ("0", "13", "25", "28.5"):
        page.locator("#scrub").fill(moment)
        assert page.locator("#animation").get_attribute("data-time") == f"{float(moment):.2f}"
        shown = page.evaluate(SIGNALS_SHOWN)
        assert {s["head"] for s in shown} == set(heads)
        for head in shown:
            colour = program.colour(heads[head["head"]], float(moment))
            assert head["colour"] == colour, (moment, head)
            painted = "#ffffff" if colour == "s" else SIGNAL_COLOURS[colour]
            assert head["pixel"] == [*(round(255 * v) for v in to_rgb(painted)), 255], head
            seen.add(colour)
    assert seen == {"G", "g", "y", "r", "s"}
    page.locator("#scrub").fill("7")  # the ego waits on s (red, turn after a stop), car1 on G
    legend = page.locator("#signal-legend").inner_text()
    assert "s right on red after a stop" in legend and "y yellow" in legend
    page.screenshot(path=str(SCREENSHOTS / "ui-testcase-signals.png"), full_page=True)
    page.goto(f"{server.url}/ui/#/replay/{evaluation}")
    page.wait_for_selector("#animation[data-signals]")
    page.locator("#scrub").fill("13")
    shown = {s["head"]: s["colour"] for s in page.evaluate(SIGNALS_SHOWN)}
    assert shown == {head: program.colour(link, 13.0) for head, link in heads.items()}
    assert page.locator("#signal-legend").count() == 1
    assert external(server, requested[before:]) == []


def test_a_network_page_lists_the_walks_and_draws_the_crosswalks(
    served: tuple[Server, str, dict[str, Any]], browser_page: tuple[Page, list[str]]
) -> None:
    """A network with crosswalks: each junction drawn with its zebras (the bars the API's
    geometry gives) and, under it, its walks as `scengen intersection` describes them; at a
    signal, a walk signal at each curb."""
    server, _, _ = served
    page, requested = browser_page
    before = len(requested)
    for network, heads in (("crosswalk-stop", 0), ("crosswalk-signal", 8)):
        geometry = server.client.get(f"/networks/{network}/junctions/C/geometry").json()
        walks = server.client.get(f"/networks/{network}/junctions/C").json()["walks"]
        assert len(walks) == 8 and len(geometry["crossings"]) == 4
        page.goto(f"{server.url}/ui/#/networks/{network}")
        page.wait_for_selector("details.walks li", state="attached")
        drawing = page.locator("svg.junction-drawing[data-junction='C']")
        assert drawing.locator("g.crosswalk").count() == 4
        stripes = sum(len(crossing["stripes"]) for crossing in geometry["crossings"])
        assert drawing.locator("polygon.stripe").count() == stripes >= 4 * 8
        assert drawing.locator("polygon.pedestrian-head").count() == heads
        assert drawing.locator("polygon.walking-area").count() == 4
        listed = page.locator("details.walks li")
        assert [listed.nth(k).get_attribute("data-walk") for k in range(listed.count())] == [
            w["id"] for w in walks
        ]  # fmt: skip
        page.locator("details.walks summary").click()  # open: the walks shown
        first = listed.first.inner_text()
        assert first.startswith(f"{walks[0]['id']} · {walks[0]['from']} → {walks[0]['to']}")
        assert f"{len(walks[0]['conflicts'])} conflicting routes" in first
        page.screenshot(path=str(SCREENSHOTS / f"ui-walks-{network}.png"), full_page=True)
    assert external(server, requested[before:]) == []


Walking = tuple[Server, dict[str, str], dict[str, TestCase]]


@pytest.fixture(scope="module")
def walking(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Walking]:
    """A server of its own holding two test-cases with a pedestrian, by name: "stop", on
    crosswalk-stop, the ego turns left from the south, car1 (level 1) comes from the east,
    and ped1 (level 2) walks over the south crosswalk from west to east (C_c2+, 1.3 m/s,
    from 3 m before the curb to 3 m past the far one: her trajectory ends at 14.5 s);
    "guessed", on 4way-stop with guessed crosswalks, ped1 alone over the north one."""
    folder = tmp_path_factory.mktemp("ui-walking")
    start = new_testcase("crosswalk-stop", "S2C_2:C2W_2", duration=20.0)
    testcase = extend_testcase(start, ["E2C_2:C2S_2"], seed=0).testcase
    intersection = load_testcase_intersection(testcase)
    person = straight_walk(intersection, "C_c2+", testcase, added_in=2)
    cases = {"stop": with_pedestrians(testcase, [person])}
    guessed = new_testcase("4way-stop", "S2C_2:C2N_2", duration=20.0, guess_crossings=True)
    person = straight_walk(load_testcase_intersection(guessed), "C_c0+", guessed)
    cases["guessed"] = with_pedestrians(guessed, [person])
    server = Server(folder, workers="1")
    try:
        store = Store(f"sqlite:///{folder.resolve()}/scengen.sqlite3", folder / "cache")
        idents = {name: store.add_testcase(case).id for name, case in cases.items()}
        store.close()
        yield server, idents, cases
    finally:
        server.stop()


def canvas_view(page: Page, geometry: dict[str, Any]) -> tuple[float, Any]:
    """The animation's scale (pixels a metre) and where a point of the map is on its
    canvas, as Player.view puts it: the junction's area centred, 40 m around it."""
    canvas = page.locator("#animation")
    width, height = (
        int(canvas.get_attribute("width") or 0),
        int(canvas.get_attribute("height") or 0),
    )
    xs = [p[0] for ring in geometry["area"] for p in ring]
    ys = [p[1] for ring in geometry["area"] for p in ring]
    half = max(max(xs) - min(xs), max(ys) - min(ys)) / 2 + 40
    scale = min(width, height) / (2 * half)

    def screen(x: float, y: float) -> list[float]:
        return [width / 2 + (x - (min(xs) + max(xs)) / 2) * scale,
                height / 2 - (y - (min(ys) + max(ys)) / 2) * scale]  # fmt: skip

    return scale, screen


def bar_centre(bar: list[list[float]]) -> tuple[float, float]:
    return sum(p[0] for p in bar[:4]) / 4, sum(p[1] for p in bar[:4]) / 4


WALKERS_SHOWN = """() => {
  const canvas = document.querySelector('#animation');
  const context = canvas.getContext('2d');
  const pixel = (x, y) => [...context.getImageData(Math.floor(x), Math.floor(y), 1, 1).data];
  return JSON.parse(canvas.dataset.walkers).map((w) => ({...w, pixel: pixel(w.x, w.y)}));
}"""
CANVAS_PIXEL = """([x, y]) => [...document.querySelector('#animation').getContext('2d')
  .getImageData(Math.floor(x), Math.floor(y), 1, 1).data]"""


def test_a_testcase_with_a_pedestrian_shows_her_walking_over_the_crosswalk(
    walking: Walking, browser_page: tuple[Page, list[str]]
) -> None:
    """The test-case's page lists her (id, walk, level, when she is on the crosswalk), the
    animation draws the zebras and moves her disc along her trajectory (where the page's
    view puts her: canvas pixels of her colour), she is gone once her trajectory ends, and
    the time-distance panel has her dotted curve named as a pedestrian's."""
    server, idents, cases = walking
    ident, testcase = idents["stop"], cases["stop"]
    person = testcase.pedestrians[0]
    page, requested = browser_page
    before = len(requested)
    geometry = server.client.get("/networks/crosswalk-stop/junctions/C/geometry").json()
    page.goto(f"{server.url}/ui/#/testcases/{ident}")
    page.wait_for_selector("#animation[data-walkers]")
    assert not any("guess_crossings" in url for url in requested[before:])  # bundled crosswalks
    row = page.locator("#pedestrians tbody tr").first.locator("td").all_inner_texts()
    on = {e.kind.value: e.t for e in person.events}
    assert row[:6] == ["ped1", "C_c2+", "2", f"{on['arrived']:.1f} s", f"{on['entered']:.1f} s",
                       f"{on['exited']:.1f} s"]  # fmt: skip
    assert " · 1 pedestrian · " in page.locator("main p.muted").first.inner_text()
    scale, screen = canvas_view(page, geometry)
    colour = [*(round(255 * v) for v in to_rgb(PEDESTRIAN_COLOURS[0])), 255]
    places = []
    for moment in ("4", "8"):
        page.locator("#scrub").fill(moment)
        (shown,) = page.evaluate(WALKERS_SHOWN)
        sample = person.trajectory[int(moment) * 10]
        assert shown["id"] == "ped1"
        assert (shown["x"], shown["y"]) == pytest.approx(screen(sample.x, sample.y), abs=0.1)
        assert shown["pixel"] == colour, moment
        places.append((shown["x"], shown["y"]))
    assert places[1][0] - places[0][0] == pytest.approx(4 * 1.3 * scale, abs=0.2)  # east
    bars = [bar_centre(bar) for bar in geometry["crossings"][0]["stripes"]]  # the north
    assert page.evaluate(CANVAS_PIXEL, screen(*bars[3])) == [255, 255, 255, 255]  # nobody there
    gap = [(a + b) / 2 for a, b in zip(bars[3], bars[4], strict=True)]
    strip = [round(255 * v) for v in to_rgb(CROSSWALK)]  # 3 px between bars: blended a little
    dark = page.evaluate(CANVAS_PIXEL, list(screen(*gap)))[:3]
    assert max(abs(a - b) for a, b in zip(dark, strip, strict=True)) <= 30, dark
    page.screenshot(path=str(SCREENSHOTS / "ui-pedestrian.png"), full_page=True)
    page.locator("#scrub").fill("16")  # her trajectory ended at 14.5 s
    assert page.evaluate(WALKERS_SHOWN) == []
    curve = page.locator("#time-distance polyline.walker-curve[data-track='ped1']")
    assert curve.count() == 1 and curve.get_attribute("stroke-dasharray") != "none"
    names = page.locator("#time-distance text.curve-name").all_text_contents()
    assert "ped1 (pedestrian)" in names and "car1" in names
    assert "distance driven or walked (m)" in (page.locator("#time-distance").text_content() or "")
    page.locator("details summary:has-text('Events')").click()
    events = page.locator("details table tbody tr").all_inner_texts()
    entered = next(e for e in person.events if e.kind.value == "entered")
    assert f"{entered.t:.2f}\tped1\tentered\t{entered.lane}" in events
    assert sum(row.split("\t")[1] == "ped1" for row in events) == len(person.events)
    page.goto(f"{server.url}/ui/#/testcases/{idents['guessed']}")  # 4way-stop, crosswalks guessed
    page.wait_for_selector("#animation[data-walkers]")
    asked = [url for url in requested[before:] if "/geometry" in url]
    assert asked[-1].endswith("/networks/4way-stop/junctions/C/geometry?control=allway_stop"
                              "&guess_crossings=true")  # fmt: skip
    guessed = server.client.get(asked[-1].removeprefix(server.url)).json()
    assert len(guessed["crossings"]) == 4
    _, screen = canvas_view(page, guessed)
    south = next(c for c in guessed["crossings"] if c["id"] == ":C_c2")  # nobody on it
    assert page.evaluate(CANVAS_PIXEL, screen(*bar_centre(south["stripes"][3]))) == [255] * 4
    assert page.locator("#pedestrians tbody td").first.inner_text() == "ped1"
    assert external(server, requested[before:]) == []
