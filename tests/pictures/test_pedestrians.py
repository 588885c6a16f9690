"""People on foot and crosswalks in the pictures, read back from what was drawn: the SVG's
zebras (a group of bars per crossing), the pedestrian's id, disc and dotted path in her
colour and her curve on the time-distance panel, labels apart; at a signal her crossing's
heads in their colour and her row in the strip; the GIF's frames with her disc where she
is, and none once her trajectory has ended; the browser's colours equal to the
pictures'."""

from __future__ import annotations

import itertools
import json
import re
import xml.etree.ElementTree as ElementTree
from collections.abc import Iterator
from pathlib import Path

import matplotlib
import matplotlib.pyplot as plt
import numpy as np
import pytest
from matplotlib.colors import to_hex, to_rgb
from PIL import Image

import service.pictures
from service.core.generator.extension import extend_testcase
from service.core.network import Intersection
from service.core.network.geometry import zebra_stripes
from service.core.testcase import TestCase, load_testcase_intersection, new_testcase
from service.pictures.animation import animate_testcase, draw_animation
from service.pictures.pedestrians import CROSSWALK, PEDESTRIAN_COLOURS, STRIPE
from service.pictures.plot import CAR_COLOURS, CERTIFICATE_COLOURS, draw_testcase, plot_testcase
from service.pictures.signals import SIGNAL_COLOURS
from tests.pictures.crossings import PACE, straight_walk, with_pedestrians
from tests.pictures.test_plot import _apart_and_inside, _labels

SVG = "{http://www.w3.org/2000/svg}"


@pytest.fixture(autouse=True)
def text_as_text() -> Iterator[None]:
    with matplotlib.rc_context({"svg.fonttype": "none"}):
        yield


@pytest.fixture(scope="module")
def walking() -> tuple[TestCase, Intersection]:
    """crosswalk-stop, 20 s: the ego turns left from the south, car1 comes from the east
    (level 1), and ped1 (level 2) walks over the south crosswalk (C_c2+, west to east),
    from 3 m before the curb to 3 m past the far one at 1.3 m/s (18.8 m: her trajectory
    ends at 14.5 s)."""
    start = new_testcase("crosswalk-stop", "S2C_2:C2W_2", duration=20.0)
    testcase = extend_testcase(start, ["E2C_2:C2S_2"], seed=0).testcase
    intersection = load_testcase_intersection(testcase)
    person = straight_walk(intersection, "C_c2+", testcase, added_in=2)
    return with_pedestrians(testcase, [person]), intersection


def _groups(svg: Path, prefix: str) -> dict[str, ElementTree.Element]:
    """The SVG's groups whose id starts with ``prefix``, by the rest of the id."""
    return {
        group.get("id", "").removeprefix(prefix): group
        for group in ElementTree.parse(svg).iter(f"{SVG}g")
        if group.get("id", "").startswith(prefix)
    }


def _fill(group: ElementTree.Element) -> str:
    style = next(group.iter(f"{SVG}path")).get("style", "")
    found = re.search(r"fill:\s*(#[0-9a-f]{6})", style)
    assert found, style
    return found.group(1)


def test_the_svg_draws_each_crosswalk_as_a_zebra_and_the_pedestrian_with_her_id(
    walking: tuple[TestCase, Intersection], tmp_path: Path
) -> None:
    testcase, intersection = walking
    picture = tmp_path / "walking.svg"
    plot_testcase(testcase, intersection, picture)
    strips = _groups(picture, "crosswalk-")
    bars = {name.removeprefix("stripes-"): group for name, group in strips.items()
            if name.startswith("stripes-")}  # fmt: skip
    assert set(bars) == {c.lstrip(":") for c in intersection.crossings} == {
        "C_c0", "C_c1", "C_c2", "C_c3"
    }  # fmt: skip
    for name, group in bars.items():  # white bars over each dark strip
        crossing = intersection.crossings[f":{name}"]
        assert len(list(group.iter(f"{SVG}path"))) == len(zebra_stripes(crossing)) >= 8
        assert _fill(group) == STRIPE
        assert _fill(strips[name]) == CROSSWALK
    assert "pavement" in _groups(picture, "")  # sidewalks and walking areas
    text = picture.read_text()
    for words in (">ped1<", "ped1 (pedestrian, C_c2+, level 2)", ">crosswalk<",
                  ">sidewalk, walking area<", "distance travelled or walked (m)",
                  "arrived (in the road user's colour)"):  # fmt: skip
        assert words in text, words
    again = tmp_path / "again.svg"
    plot_testcase(testcase, intersection, again)
    assert again.read_bytes() == picture.read_bytes()
    plot_testcase(testcase, intersection, tmp_path / "walking.png")
    assert (tmp_path / "walking.png").read_bytes()[:4] == b"\x89PNG"


def test_the_pedestrian_is_a_dotted_path_of_discs_in_her_colour_and_a_curve_on_the_panel(
    walking: tuple[TestCase, Intersection],
) -> None:
    """On the map: her path dotted along her trajectory, a disc every 2 s (none a car's
    rectangle), her id beside her start, labels apart and inside the map; on the panel her
    distance walked over time, dotted, and her events in her colour."""
    testcase, intersection = walking
    person = testcase.pedestrians[0]
    colour = PEDESTRIAN_COLOURS[0]
    figure = draw_testcase(testcase, intersection)
    try:
        axes, panel = figure.axes[0], figure.axes[1]
        mine = [line for line in axes.get_lines() if to_hex(line.get_color()) == colour]
        (path,) = [line for line in mine if len(line.get_xdata()) == len(person.trajectory)]
        assert path.get_linestyle() == ":"  # dotted
        assert list(path.get_xdata()) == [s.x for s in person.trajectory]
        assert list(path.get_ydata()) == [s.y for s in person.trajectory]
        every = person.trajectory[::20]  # a disc every 2 s, the start a hollow one
        discs = [line for line in mine if line.get_marker() == "o" and len(line.get_xdata())]
        assert sorted(x for d in discs for x in d.get_xdata()) == sorted(s.x for s in every)
        assert sorted(len(line.get_xdata()) for line in mine) == sorted(
            [0, 1, len(every) - 1, len(person.trajectory)]
        )  # the legend's entry, her start, her discs, her path: no car's rectangle
        labels = _labels(axes)
        _apart_and_inside(figure, axes, labels)
        (name,) = [t for t in labels if t.get_text() == "ped1"]
        assert name.xy == (person.trajectory[0].x, person.trajectory[0].y)
        assert to_hex(name.get_color()) == colour
        times = [t.get_text() for t in labels if to_hex(t.get_color()) == colour][1:]
        assert "4s" in times and "8s" in times  # walking, not standing: one label each
        (curve,) = [line for line in panel.get_lines()
                    if line.get_label() == "ped1 (pedestrian, C_c2+, level 2)"]  # fmt: skip
        assert curve.get_linestyle() == ":"
        assert list(curve.get_ydata()) == [s.distance for s in person.trajectory]
        assert curve.get_ydata()[-1] == pytest.approx(PACE * curve.get_xdata()[-1], abs=0.2)
        events = [line for line in panel.get_lines() if len(line.get_xdata()) == 1]
        markers = {(line.get_marker(), round(float(line.get_xdata()[0]), 3))
                   for line in events if to_hex(line.get_color()) == colour}  # fmt: skip
        kinds = {"arrived": "o", "entered": "^", "exited": "s"}
        assert markers == {(kinds[e.kind.value], round(e.t, 3)) for e in person.events
                           if e.kind.value in kinds}  # fmt: skip
        assert len(markers) == 3
    finally:
        plt.close(figure)


@pytest.fixture(scope="module")
def signalized() -> tuple[TestCase, Intersection]:
    """crosswalk-signal, 30 s: the ego turns left from the south, car1 comes from the
    north; ped1 walks over the east crosswalk (C_c1-, its walk from 0 s to 15 s)."""
    start = new_testcase("crosswalk-signal", "S2C_2:C2W_2", duration=30.0)
    testcase = extend_testcase(start, ["N2C_1:C2S_1"], seed=0).testcase
    intersection = load_testcase_intersection(testcase)
    person = straight_walk(intersection, "C_c1-", testcase, wait=1.0, added_in=2)
    return with_pedestrians(testcase, [person]), intersection


def test_at_a_signal_each_crosswalk_shows_its_walk_signal_and_the_strip_her_row(
    signalized: tuple[TestCase, Intersection], tmp_path: Path
) -> None:
    """Each crossing's two heads filled with its link's colour at t = 0 (C_c1 and C_c3
    walk, C_c0 and C_c2 don't), like the cars' heads; her row in the strip under the panel
    with her crossing's colours over the test-case and a triangle where she stepped on."""
    testcase, intersection = signalized
    program = intersection.signals
    assert program is not None
    picture = tmp_path / "signals.svg"
    plot_testcase(testcase, intersection, picture)
    fills = {name: _fill(group) for name, group in _groups(picture, "pedestrian-head-").items()}
    expected = {}
    for crossing in intersection.crossings.values():
        for sign in ("plus", "minus"):
            colour = program.colour(crossing.link_index, 0.0)
            expected[f"{crossing.id[1:]}-{sign}"] = SIGNAL_COLOURS[colour]
    assert fills == expected
    assert set(fills.values()) == {SIGNAL_COLOURS["G"], SIGNAL_COLOURS["r"]}
    figure = draw_testcase(testcase, intersection)
    try:
        strip = figure.axes[2]
        rows = [t.get_text() for t in strip.get_yticklabels()]
        assert rows == ["ped1", "car1", "ego"]  # bottom up
        link = intersection.crossings[":C_c1"].link_index
        bars = sorted(
            (round(float(b.get_paths()[0].vertices[:, 0].min()), 6), to_hex(b.get_facecolor()[0]))
            for b in strip.collections
            if round(float(b.get_paths()[0].vertices[:, 1].min()) + 0.35) == 0
        )  # fmt: skip
        assert bars == [(a, SIGNAL_COLOURS[c]) for a, _, c in program.timeline(link, 30.0)]
        entered = next(e.t for e in testcase.pedestrians[0].events if e.kind.value == "entered")
        triangles = [(line.get_xdata()[0], line.get_ydata()[0]) for line in strip.get_lines()
                     if line.get_marker() == "^"]  # fmt: skip
        assert (pytest.approx(entered), 0) in triangles
        assert "stepped onto the crossing" in strip.get_title(loc="left")
    finally:
        plt.close(figure)


def _pixel(figure: plt.Figure, x: float, y: float) -> tuple[int, int]:
    """Where the map's point (x, y) is in the GIF's frames (pixels from the top left)."""
    px, py = figure.axes[0].transData.transform((x, y))
    return int(px), int(figure.bbox.height - py)


def _near(rgb: Image.Image, colour: str, at: tuple[int, int], reach: int = 2) -> bool:
    """``colour`` (within a palette's error) at ``at`` or a pixel or two around it."""
    wanted = np.array([round(255 * v) for v in to_rgb(colour)])
    x, y = at
    pixels = np.asarray(rgb)[y - reach : y + reach + 1, x - reach : x + reach + 1].reshape(-1, 3)
    return bool((np.abs(pixels - wanted).max(axis=1) <= 12).any())


def _count(rgb: Image.Image, colour: str) -> int:
    wanted = np.array([round(255 * v) for v in to_rgb(colour)])
    return int((np.abs(np.asarray(rgb).reshape(-1, 3) - wanted).max(axis=1) <= 12).sum())


def test_the_gif_moves_the_pedestrian_over_the_zebra_and_drops_her_when_her_walk_ends(
    walking: tuple[TestCase, Intersection], tmp_path: Path
) -> None:
    """Frames at 4 s and 8 s: her disc where her trajectory puts her then (not where she
    was), the crosswalk's bars drawn; at 16 s her trajectory has ended (14.5 s): her
    colour is nowhere in the frame, disc and id gone."""
    testcase, intersection = walking
    person = testcase.pedestrians[0]
    assert 8.0 < person.trajectory[-1].t < 16.0
    gif = tmp_path / "walking.gif"
    animate_testcase(testcase, intersection, gif, every=4.0)  # frames at 0, 4, ..., 20 s
    figure, draw = draw_animation(testcase, intersection)
    try:
        figure.canvas.draw()
        x0, y0, x1, y1 = figure.axes[0].get_window_extent().extents
        inside = (int(x0) + 1, int(figure.bbox.height - y1) + 1, int(x1) - 1,
                  int(figure.bbox.height - y0) - 1)  # fmt: skip  # the map, not its legend
        at = {t: _pixel(figure, person.trajectory[t * 10].x, person.trajectory[t * 10].y)
              for t in (4, 8)}  # fmt: skip
        bars = [np.array(b).mean(axis=0) for b in zebra_stripes(intersection.crossings[":C_c0"])]
        stripe, gap = _pixel(figure, *bars[3]), _pixel(figure, *(bars[3] + bars[4]) / 2.0)
        disc = next(a for a in draw(40) if a.get_label() == "ped1 (pedestrian)")
        assert list(disc.get_xdata()) == [person.trajectory[40].x]
        assert "ped1" in {text.get_text() for text in _labels(figure.axes[0])}
        draw(160)
        assert list(disc.get_xdata()) == []
        assert "ped1" not in {text.get_text() for text in _labels(figure.axes[0])}
    finally:
        plt.close(figure)
    colour = PEDESTRIAN_COLOURS[0]
    with Image.open(gif) as image:
        frames = {}
        for k, t in ((1, 4), (2, 8), (4, 16)):
            image.seek(k)
            frames[t] = image.convert("RGB")
    assert at[4] != at[8]
    assert _near(frames[4], colour, at[4]) and not _near(frames[4], colour, at[8])
    assert _near(frames[8], colour, at[8]) and not _near(frames[8], colour, at[4])
    assert _near(frames[4], STRIPE, stripe, reach=0)  # a white bar of the north zebra
    assert _near(frames[4], CROSSWALK, gap, reach=0)  # and the dark strip between two bars
    assert _count(frames[4].crop(inside), colour) > 20  # her disc and her id
    assert _count(frames[16].crop(inside), colour) == 0  # gone


def _table(script: str, name: str) -> list[str]:
    """A list of colours in ui.js, ``const NAME = [...]``."""
    table = re.search(rf"const {name} = (\[[^\]]*\]);", script)
    assert table, name
    found: list[str] = json.loads(table.group(1))
    return found


def _lab(colour: str) -> np.ndarray:
    """CIELAB (D65) of a matplotlib colour."""
    rgb = np.array(to_rgb(colour))
    linear = np.where(rgb > 0.04045, ((rgb + 0.055) / 1.055) ** 2.4, rgb / 12.92)
    matrix = np.array([[0.4124, 0.3576, 0.1805], [0.2126, 0.7152, 0.0722],
                       [0.0193, 0.1192, 0.9505]])  # fmt: skip
    xyz = matrix @ linear / np.array([0.95047, 1.0, 1.08883])
    f = np.where(xyz > 0.008856, np.cbrt(xyz), 7.787 * xyz + 16.0 / 116.0)
    return np.array([116.0 * f[1] - 16.0, 500.0 * (f[0] - f[1]), 200.0 * (f[1] - f[2])])


def test_the_browser_draws_the_pedestrians_colours_which_no_car_has() -> None:
    """ui.js's PEDESTRIAN_COLOURS is the pictures' table, and each is at least 30 apart
    (CIELAB delta E: told apart at a glance) from every car's colour in the pictures and in
    the browser, the ego's, the certificates', the roads' and the crosswalks', and from the
    other pedestrians'."""
    script = (Path(service.pictures.__file__).parent / "ui" / "ui.js").read_text()
    assert _table(script, "PEDESTRIAN_COLOURS") == PEDESTRIAN_COLOURS
    pictures = [*CAR_COLOURS, *CERTIFICATE_COLOURS.values(), "black", "0.85", "0.9", CROSSWALK]
    browser = [*_table(script, "CAR_COLOURS"), "#111827", "#dc2626", "#c8cace", "#d4d6da"]
    others = pictures + browser  # the browser's ego and complexity certificate, its roads
    for colour in PEDESTRIAN_COLOURS:
        nearest = min(float(np.linalg.norm(_lab(colour) - _lab(o))) for o in others)
        assert nearest >= 30.0, (colour, nearest)
    for a, b in itertools.combinations(PEDESTRIAN_COLOURS, 2):
        assert np.linalg.norm(_lab(a) - _lab(b)) >= 30.0, (a, b)
