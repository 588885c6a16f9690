"""Traffic lights in the pictures, read back from what was drawn: each head's fill in the
SVG at t = 0, each car's signal in the strip under the time-distance panel, the GIF's
pixel at each head in two frames of other phases; and the results browser's colours
equal to the pictures' (ui.js, read as text)."""

from __future__ import annotations

import json
import re
import xml.etree.ElementTree as ElementTree
from collections.abc import Iterator
from pathlib import Path

import matplotlib
import matplotlib.pyplot as plt
import pytest
from matplotlib.collections import PolyCollection
from matplotlib.colors import to_hex, to_rgb
from PIL import Image

import service.pictures
from service.core.generator.extension import extend_testcase
from service.core.network import Intersection
from service.core.network.signals import make_program
from service.core.testcase import TestCase, load_testcase_intersection, new_testcase
from service.pictures.animation import animate_testcase, draw_animation
from service.pictures.plot import draw_testcase, plot_testcase
from service.pictures.signals import MARK, SIGNAL_COLOURS

SVG = "{http://www.w3.org/2000/svg}"
# t-signal's own program with an offset: t = 0 is 31 s into its 38 s cycle
PROGRAM = make_program(
    "C", "offset", 7.0,
    [(18, "GgsrGG"), (3, "yysrGy"), (1, "rrsrGr"), (12, "rrGGGr"), (3, "rryyGr"),
     (1, "rrsrGr")],
)  # fmt: skip


@pytest.fixture(scope="module")
def right_on_red() -> tuple[TestCase, Intersection]:
    """t-signal under PROGRAM, 30 s: the ego turns right from the south (on red after a
    stop, then green), car1 comes straight from the west."""
    start = new_testcase("t-signal", "S2C_0:C2E_0", duration=30.0, signals=PROGRAM)
    testcase = extend_testcase(start, ["W2C_0:C2E_0"], seed=0).testcase
    return testcase, load_testcase_intersection(testcase)


@pytest.fixture(autouse=True)
def text_as_text() -> Iterator[None]:
    with matplotlib.rc_context({"svg.fonttype": "none"}):
        yield


def _fills(svg: Path, prefix: str) -> dict[str, str]:
    """The fill of each group whose id starts with ``prefix``, by the rest of its id."""
    found = {}
    for group in ElementTree.parse(svg).iter(f"{SVG}g"):
        ident = group.get("id", "")
        if ident.startswith(prefix):
            style = next(group.iter(f"{SVG}path")).get("style", "")
            fill = re.search(r"fill:\s*(#[0-9a-f]{6})", style)
            assert fill, style
            found[ident.removeprefix(prefix)] = fill.group(1)
    return found


def _links(intersection: Intersection) -> dict[str, int]:
    """Each signal head's name (FORK-LINK) and its link."""
    return {
        f"{route.fork}-{route.link_index}": route.link_index
        for route in intersection.routes.values()
        if route.link_index >= 0
    }


def test_the_picture_draws_each_head_in_its_colour_at_the_start(
    right_on_red: tuple[TestCase, Intersection], tmp_path: Path
) -> None:
    """In the SVG: a head per link, each filled with its colour at t = 0 (the map's title
    says so), the right-on-red head with its dot; the same bytes a second time."""
    testcase, intersection = right_on_red
    picture = tmp_path / "signals.svg"
    plot_testcase(testcase, intersection, picture)
    links = _links(intersection)
    assert len(links) == 6 == intersection.tls_links
    heads = _fills(picture, "signal-head-")
    assert heads == {
        name: SIGNAL_COLOURS[PROGRAM.colour(link, 0.0)] for name, link in links.items()
    }
    assert {PROGRAM.colour(link, 0.0) for link in links.values()} == {"r", "G"}  # rrGGGr
    assert set(_fills(picture, "signal-dot-")) == set()  # no s at t = 0
    text = picture.read_text()
    assert "signals at t = 0 s" in text and "s right on red after a stop" in text
    again = tmp_path / "again.svg"
    plot_testcase(testcase, intersection, again)
    assert again.read_bytes() == picture.read_bytes()


def _runs(strip: plt.Axes) -> dict[int, list[tuple[float, float, str]]]:
    """The strip's bars by row (y) as (start, end, colour), in time order."""
    rows: dict[int, list[tuple[float, float, str]]] = {}
    for bars in strip.collections:
        if isinstance(bars, PolyCollection):
            (x0, y0), (x1, _) = (
                bars.get_paths()[0].vertices.min(0),
                bars.get_paths()[0].vertices.max(0),
            )
            colour = to_hex(bars.get_facecolor()[0])
            rows.setdefault(round(y0 + 0.35), []).append((float(x0), float(x1), colour))
    return {y: sorted(runs) for y, runs in rows.items()}


def test_the_strip_shows_each_cars_signal_over_the_testcase(
    right_on_red: tuple[TestCase, Intersection],
) -> None:
    """Under the time-distance panel, on its time axis: the ego's row, then car1's, each
    its route's colours from 0 to the duration (SignalProgram.timeline), a triangle where
    the car entered the junction."""
    testcase, intersection = right_on_red
    figure = draw_testcase(testcase, intersection)
    try:
        strip = figure.axes[2]
        assert [t.get_text() for t in strip.get_yticklabels()] == ["car1", "ego"]  # bottom up
        ego_link = intersection.route(testcase.ego.route.id).link_index
        car_link = intersection.route(testcase.nonegos[0].route.id).link_index
        for y, link in ((1, ego_link), (0, car_link)):
            expected = [(a, b, SIGNAL_COLOURS[c]) for a, b, c in PROGRAM.timeline(link, 30.0)]
            drawn = [(round(a, 9), round(b, 9), c) for a, b, c in _runs(strip)[y]]
            assert drawn == expected, link
        assert {c for _, _, c in PROGRAM.timeline(ego_link, 30.0)} == {"s", "G", "y"}
        entered = [e.t for e in testcase.nonegos[0].events if e.kind.value == "entered"]
        triangles = [(line.get_xdata()[0], line.get_ydata()[0]) for line in strip.get_lines()
                     if line.get_marker() == "^"]  # fmt: skip
        assert (pytest.approx(entered[0]), 0) in triangles
        assert sum(1 for _, y in triangles if y == 1) == 2  # both certificates entered
        assert strip.get_shared_x_axes().joined(strip, figure.axes[1])
    finally:
        plt.close(figure)


def test_the_gif_draws_each_head_in_its_colour_in_each_frame(
    right_on_red: tuple[TestCase, Intersection], tmp_path: Path
) -> None:
    """Frames at 0 s (rrGGGr) and 14 s (GgsrGG): the pixel at each head's centre is its
    colour then, white at the right-on-red head (its dot)."""
    testcase, intersection = right_on_red
    gif = tmp_path / "signals.gif"
    animate_testcase(testcase, intersection, gif, every=7.0)  # frames at 0, 7, 14, 21, 28 s
    figure, _ = draw_animation(testcase, intersection)  # the GIF's figure: where heads are
    try:
        figure.canvas.draw()  # the map's box takes its equal aspect when drawn
        axes = figure.axes[0]
        height = figure.bbox.height
        centres = {}
        for patch in axes.patches:
            gid = patch.get_gid() or ""
            if gid.startswith("signal-head-"):
                x, y = axes.transData.transform(patch.get_xy()[:4].mean(0))
                centres[gid.removeprefix("signal-head-")] = (int(x), int(height - y))
    finally:
        plt.close(figure)
    links = _links(intersection)
    assert set(centres) == set(links)
    seen = set()
    with Image.open(gif) as image:
        for frame, t in ((0, 0.0), (2, 14.0)):
            image.seek(frame)
            rgb = image.convert("RGB")
            for name, link in links.items():
                colour = PROGRAM.colour(link, t)
                painted = MARK if colour == "s" else SIGNAL_COLOURS[colour]
                wanted = tuple(round(255 * v) for v in to_rgb(painted))
                assert rgb.getpixel(centres[name]) == wanted, (t, name, colour)
                seen.add(colour)
    assert seen == {"r", "G", "g", "s"}


def test_the_browser_draws_the_pictures_colours() -> None:
    """ui.js's SIGNAL_COLOURS is the pictures' table (the browser test reads its pixels)."""
    script = (Path(service.pictures.__file__).parent / "ui" / "ui.js").read_text()
    table = re.search(r"const SIGNAL_COLOURS = (\{[^}]*\});", script)
    assert table
    colours = json.loads(re.sub(r"(\w+):", r'"\1":', table.group(1)))
    assert colours == SIGNAL_COLOURS
