"""What the pictures say, read from SVG text (matplotlib writes text as text when asked),
and where their words are, measured on the drawn artists (matplotlib's text extents): a
level-6 chain's labels apart and inside the map, times beside their rectangles, the verdict
whole and inside the figure, the title with the level, the GIF's stop lines and ids."""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator, Sequence
from pathlib import Path

import matplotlib
import matplotlib.pyplot as plt
import pytest
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.text import Annotation, Text
from matplotlib.transforms import Bbox

from service.core.checker.check import check_testcase
from service.core.checker.verdict import CollisionRecord, Verdict
from service.core.generator.extension import extend_testcase
from service.core.motion.poses import PoseSample, generate_poses
from service.core.network import Intersection, load_intersection
from service.core.testcase import (
    TestCase,
    load_testcase_intersection,
    new_testcase,
    readable_name,
    renamed,
)
from service.pictures.animation import animate_testcase, draw_animation
from service.pictures.junction import STOP_LINE, plot_intersection
from service.pictures.plot import (
    TIME_FONT,
    draw_testcase,
    plot_testcase,
    queue_leaders,
    start_label,
    time_labels,
    verdict_lines,
)
from tests.conftest import TOWN05
from tests.helpers import car_ahead_of_ego, retime, with_nonegos


@pytest.fixture(autouse=True)
def text_as_text() -> object:
    with matplotlib.rc_context({"svg.fonttype": "none"}):
        yield


def test_every_lane_id_is_whole_and_exits_are_labelled(tmp_path: Path) -> None:
    intersection = load_intersection(TOWN05, "396", "allway_stop")
    picture = tmp_path / "junction.svg"
    plot_intersection(intersection, picture)
    text = picture.read_text()
    for fork in intersection.forks.values():  # "-8_0", not "8_0" under a stop marker
        assert f">{fork.lane} (stop)<" in text
    for exit_lane in intersection.exits.values():
        assert f">{exit_lane.lane} (exit)<" in text


def test_the_same_picture_is_the_same_bytes(tmp_path: Path) -> None:
    """SVG ids from a fixed salt and no date: a cached picture and a new one agree."""
    intersection = load_intersection("t-stop")
    for suffix in ("svg", "png"):
        first, second = tmp_path / f"a.{suffix}", tmp_path / f"b.{suffix}"
        plot_intersection(intersection, first)
        plot_intersection(intersection, second)
        assert first.read_bytes() == second.read_bytes(), suffix


def test_a_testcase_picture_marks_starts_times_and_stop_lines(tmp_path: Path) -> None:
    start = new_testcase("4way-stop", "E2C_1:C2S_1", duration=20.0)
    testcase = extend_testcase(start, ["S2C_1:C2N_1"], seed=0).testcase
    picture = tmp_path / "testcase.svg"
    plot_testcase(testcase, load_testcase_intersection(testcase), picture)
    text = picture.read_text()
    for words in ("start (t = 0)", "stop line (sign)", ">2s<", ">10s<", "car1 (level 1)",
                  "arrived (in the car's colour)"):  # fmt: skip
        assert words in text, words
    assert "signal-head" not in text and "signals at t = 0 s" not in text  # no traffic light


def test_the_car_behind_another_on_its_fork_is_marked() -> None:
    """The queue of docs/rules.md: the ego starts behind car1 on their fork."""
    case = car_ahead_of_ego()
    queues = queue_leaders(case, load_testcase_intersection(case))
    assert queues == {"car1": None, "ego": "car1"}
    assert start_label("ego", queues) == "ego behind car1"
    assert start_label("car1", queues) == "car1"


def _three_on_one_fork() -> TestCase:
    """Three non-egos on the fork E2C_0 (10, 20 and 30 m out, two routes), standing; the ego
    comes from the south."""
    # a picture of cars standing in a queue: 5 s, shorter than any ego needs to pass (which
    # new refuses), is enough to draw
    base = new_testcase("4way-stop", "S2C_1:C2N_1", duration=7.0).model_copy(
        update={"duration": 5.0}
    )
    junction = load_testcase_intersection(base)
    starts = [("first", "E2C_0:C2W_0", 10.0), ("second", "E2C_0:C2N_0", 20.0),
              ("third", "E2C_0:C2W_0", 30.0)]  # fmt: skip
    requests = [(junction.route(route), start) for _, route, start in starts]
    tracks = generate_poses(junction, requests, 5.0, 5.0, 0.1)
    return with_nonegos(
        base,
        [(car, route, retime(track, lambda t: (0.0, 0.0), 5.0, 0.1))
         for (car, route, _), track in zip(starts, tracks, strict=True)],
    )  # fmt: skip


def test_each_car_in_a_queue_names_the_car_right_ahead_of_it() -> None:
    case = _three_on_one_fork()
    queues = queue_leaders(case, load_testcase_intersection(case))
    assert queues == {"first": None, "second": "first", "third": "second"}  # not the ego
    assert start_label("third", queues) == "third behind second"


def test_a_queue_picture_labels_the_car_behind(tmp_path: Path) -> None:
    case = car_ahead_of_ego()
    intersection = load_testcase_intersection(case)
    picture = tmp_path / "queue.svg"
    plot_testcase(case, intersection, picture)
    text = picture.read_text()
    for words in (">ego behind car1<", ">car1<", "start on a shared fork (label: the car ahead)"):
        assert words in text, words
    plot_testcase(case, intersection, tmp_path / "queue.png")
    assert (tmp_path / "queue.png").read_bytes()[:4] == b"\x89PNG"


def test_a_car_standing_gets_one_time_label_for_its_stay() -> None:
    at = [0.0, 0.0, 5.0, 5.1, 5.2, 12.0]  # x every 2 s: moves, stands from 4 s to 8 s, moves
    shown = [PoseSample(2.0 * k, x, 0.0, 90.0, 0.0, x) for k, x in enumerate(at)]
    assert [text for _, text in time_labels(shown)] == ["2s", "4-8s", "10s"]


CHAIN = ["E2C_1:C2S_1", "N2C_0:C2S_0", "W2C_1:C2E_1", "E2C_1:C2W_1", "N2C_1:C2S_1",
         "W2C_0:C2E_0"]  # fmt: skip  # each crosses the ego's left turn


@pytest.fixture(scope="module")
def level6() -> tuple[TestCase, Intersection]:
    """A level-6 chain on the four-way stop (45 s): six cars on routes that cross the
    ego's, one a level, as `scengen extend` makes them; unnamed, as the library makes it."""
    testcase = new_testcase("4way-stop", "S2C_1:C2W_1", duration=45.0)
    for route in CHAIN:
        testcase = extend_testcase(testcase, [route], seed=0).testcase
    assert testcase.name == "" and len(testcase.nonegos) == 6
    return testcase, load_testcase_intersection(testcase)


@pytest.fixture
def figures() -> Iterator[list[Figure]]:
    drawn: list[Figure] = []
    yield drawn
    for figure in drawn:
        plt.close(figure)


def _labels(axes: Axes) -> list[Text]:
    """The words drawn on a map (not the arrowheads, which are annotations without text)."""
    return [
        text
        for text in axes.texts
        if isinstance(text, Annotation) and text.get_text() and text.get_visible()
    ]


def _boxes(figure: Figure, texts: Sequence[Text]) -> list[Bbox]:
    renderer = figure.canvas.get_renderer()
    return [text.get_window_extent(renderer) for text in texts]


def _apart_and_inside(figure: Figure, axes: Axes, texts: Sequence[Text]) -> None:
    """No two labels' boxes overlap; each is inside the axes (none over the axis numbers)."""
    boxes = _boxes(figure, texts)
    frame = axes.get_window_extent(figure.canvas.get_renderer())
    for text, box in zip(texts, boxes, strict=True):
        assert frame.x0 <= box.x0 and box.x1 <= frame.x1, text.get_text()
        assert frame.y0 <= box.y0 and box.y1 <= frame.y1, text.get_text()
    for (a, box_a), (b, box_b) in itertools.combinations(zip(texts, boxes, strict=True), 2):
        assert not box_a.overlaps(box_b), (a.get_text(), b.get_text())


def test_a_level_six_picture_is_titled_by_its_name_with_the_level(
    level6: tuple[TestCase, Intersection], figures: list[Figure], tmp_path: Path
) -> None:
    testcase, intersection = level6
    figures.append(draw_testcase(testcase, intersection))
    assert figures[-1].get_suptitle() == readable_name(testcase)  # the document has no name
    assert figures[-1].get_suptitle() == "4way-stop C S2C_1:C2W_1 level 6"
    named = renamed(testcase, "left turn into six")
    figures.append(draw_testcase(named, intersection))
    assert figures[-1].get_suptitle() == "left turn into six (level 6)"
    picture = tmp_path / "level6.svg"
    plot_testcase(renamed(testcase, "4way-stop C S2C_1:C2W_1 level 6"), intersection, picture)
    assert ">4way-stop C S2C_1:C2W_1 level 6<" in picture.read_text()


def test_a_level_six_map_keeps_its_labels_apart_and_beside_their_cars(
    level6: tuple[TestCase, Intersection], figures: list[Figure]
) -> None:
    testcase, intersection = level6
    figure = draw_testcase(testcase, intersection)
    figures.append(figure)
    axes = figure.axes[0]
    texts = _labels(axes)
    _apart_and_inside(figure, axes, texts)
    words = {text.get_text() for text in texts}
    assert {"car1", "car2", "car3", "car4 behind car1", "car5", "car6", "ego"} <= words
    times = [text for text in texts if text.get_text().endswith("s")]
    assert len(times) >= 60  # most of the times every 2 s find a place
    assert all(text.get_fontsize() >= TIME_FONT >= 6.5 for text in times)
    points_per_metre = _points_per_metre(figure, axes)
    for text, box in zip(times, _boxes(figure, times), strict=True):
        x, y = axes.transData.transform(text.xy)
        gap = math.hypot(max(box.x0 - x, 0.0, x - box.x1), max(box.y0 - y, 0.0, y - box.y1))
        reach = 2.5 * points_per_metre + 12.0  # half a car's length, and the farthest ring
        assert gap * 72.0 / figure.dpi <= reach, text.get_text()  # beside its rectangle


def _points_per_metre(figure: Figure, axes: Axes) -> float:
    origin, east = axes.transData.transform([(0.0, 0.0), (1.0, 0.0)])
    return float(east[0] - origin[0]) * 72.0 / figure.dpi


def test_a_long_verdict_is_wrapped_whole_inside_the_figure(
    level6: tuple[TestCase, Intersection], figures: list[Figure]
) -> None:
    testcase, intersection = level6
    reasons = tuple(f"reason {k}: " + "the ego entered the junction before car5 " * 4
                    for k in range(6))  # fmt: skip
    verdict = Verdict(testcase.name, "sumo", True, 30.0, errors=reasons, duration=45.0)
    ego = [PoseSample(**s.model_dump()) for s in testcase.certificates.solvability]
    figure = draw_testcase(testcase, intersection, ego, "ego: sumo", verdict)
    figures.append(figure)
    panel = figure.axes[1]
    shown = [t for t in (panel.title, panel._left_title) if t.get_text()]
    assert len(shown) == 1  # the verdict, not over another title
    title = shown[0]
    text = title.get_text()
    assert text.startswith("sumo: FAIL\n")
    for reason in reasons[:4]:  # each shown reason whole, wrapped
        assert " ".join(text.split()).count(" ".join(reason.split())) == 1
    assert "and 2 more" in text
    (box,) = _boxes(figure, [title])
    renderer = figure.canvas.get_renderer()
    room = panel.get_window_extent(renderer)
    assert figure.bbox.x0 <= box.x0 and box.x1 <= figure.bbox.x1  # nothing cut off
    assert box.y1 <= figure.bbox.y1 and box.width <= room.width
    suptitle = figure._suptitle
    assert not box.overlaps(_boxes(figure, [suptitle])[0])


def _stop_lines(axes: Axes) -> set[tuple[float, ...]]:
    """The stop-sign lines drawn on a map, by their ends (rounded)."""
    return {
        tuple(round(v, 3) for v in (*line.get_xdata(), *line.get_ydata()))
        for line in axes.get_lines()
        if isinstance(line, Line2D) and line.get_color() == STOP_LINE and len(line.get_xdata()) == 2
    }


def test_the_animation_draws_stop_lines_and_ids_inside_the_map(
    level6: tuple[TestCase, Intersection], figures: list[Figure], tmp_path: Path
) -> None:
    testcase, intersection = level6
    still = draw_testcase(testcase, intersection)
    figure, draw = draw_animation(testcase, intersection)
    figures += [still, figure]
    axes = figure.axes[0]
    signs = sum(1 for fork in intersection.forks.values() if fork.stop_sign)
    assert len(_stop_lines(axes)) == signs == 8
    assert _stop_lines(axes) == _stop_lines(still.axes[0])
    (low_x, high_x), (low_y, high_y) = axes.get_xlim(), axes.get_ylim()
    hidden = 0
    ego = testcase.certificates.solvability
    tracks = {car.id: car.trajectory for car in testcase.nonegos} | {"ego": ego}
    for frame in range(0, 451, 30):  # every 3 s of 45 s
        draw(frame)
        shown = _labels(axes)
        _apart_and_inside(figure, axes, shown)
        for car, track in tracks.items():
            if frame >= len(track):  # it left the map at the end of its road
                assert car not in {text.get_text() for text in shown}, (frame, car)
                hidden += 1
                continue
            x, y = track[frame].x, track[frame].y
            if not (low_x <= x <= high_x and low_y <= y <= high_y):
                assert car not in {text.get_text() for text in shown}, (frame, car)
                hidden += 1
    assert hidden > 0  # cars do leave the view, and their ids with them
    gif = tmp_path / "level6.gif"
    animate_testcase(testcase, intersection, gif, every=5.0)
    from PIL import Image

    with Image.open(gif) as image:
        assert image.n_frames == 10  # t = 0, 5, ..., 45 s


def test_the_ego_leaves_the_pictures_at_its_goal(
    level6: tuple[TestCase, Intersection], figures: list[Figure]
) -> None:
    """The test ends with the goal: the picture draws each certificate until its goal (the
    first sample at or after it), and the animation's ego, the solvability certificate,
    is gone after it, as the replay's ego leaves the simulation there."""
    testcase, intersection = level6
    assert testcase.certificates is not None
    figure = draw_testcase(testcase, intersection)
    figures.append(figure)
    panel = figure.axes[1]
    goals = {}
    for kind in ("solvability", "complexity"):
        certificate = [PoseSample(**s.model_dump()) for s in getattr(testcase.certificates, kind)]
        goal = check_testcase(testcase, certificate, kind, intersection, False).goal_time
        assert goal is not None
        goals[kind] = goal
        (curve,) = [line for line in panel.get_lines()
                    if line.get_label() == f"ego: {kind} certificate"]  # fmt: skip
        times = [float(t) for t in curve.get_xdata()]
        assert times[-2] < goal <= times[-1] < testcase.duration
    animated, draw = draw_animation(testcase, intersection)
    figures.append(animated)
    ego = 1 + 2 * len(testcase.nonegos)  # the clock, then each car's outline and id
    last = math.ceil(goals["solvability"] / testcase.timestep - 1e-9)  # its goal's sample
    assert len(draw(last)[ego].get_xy()) > 0
    assert len(draw(last + 1)[ego].get_xy()) == 0


def test_what_happened_after_the_goal_is_shown_as_information() -> None:
    late = CollisionRecord("car5", 40.525, 15.79, 117.01)
    verdict = Verdict("level 5", "sumo", True, 23.45, duration=45.0,
                      after_goal_collisions=(late,))  # fmt: skip
    lines = verdict_lines(verdict, 140)
    assert lines == [
        "sumo: PASS",
        "after its goal (not judged): collided with car5 at 40.52 s at (15.8, 117.0)",
    ]
