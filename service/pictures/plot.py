"""A test-case's picture: the junction with every road user's path, and the
time-distance panel with the events, the verdict and, at a signal, each car's signal
under it (matplotlib, no display)."""

from __future__ import annotations

import math
import textwrap
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Literal

import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.text import Annotation

from service.core.checker.check import EGO, Judge, until_goal
from service.core.checker.verdict import Verdict
from service.core.motion.events import rectangles
from service.core.motion.poses import PoseSample
from service.core.motion.queues import QueueCar, follows
from service.core.network import Intersection
from service.core.testcase import TestCase, readable_name, testcase_level
from service.pictures.junction import (
    draw_roads,
    draw_stop_lines,
    frame_map,
    save,
    sign_legend,
)
from service.pictures.labels import GAP, LabelPlacer, Spot
from service.pictures.pedestrians import (
    DISC,
    PEDESTRIAN_COLOURS,
    Walker,
    crosswalk_handles,
    draw_crosswalks,
    draw_pavements,
    draw_walker,
    walkers,
)
from service.pictures.signals import (
    STRIP_ROW,
    SignalHeads,
    colour_handles,
    draw_signal_strip,
    signal_rows,
)


def _arrow(axes: Axes, samples: Sequence[PoseSample], colour: str) -> None:
    """An arrowhead at the end of a drawn path: the direction of travel."""
    moved = [s for s in samples if math.dist((s.x, s.y), (samples[-1].x, samples[-1].y)) > 3.0]
    if not moved:
        return
    tail = moved[-1]
    axes.annotate("", xy=(samples[-1].x, samples[-1].y), xytext=(tail.x, tail.y), zorder=5,
                  arrowprops={"arrowstyle": "-|>", "color": colour, "lw": 1.4})  # fmt: skip


CAR_COLOURS = ["tab:blue", "tab:orange", "tab:purple", "tab:brown", "tab:pink", "tab:olive",
               "tab:cyan", "tab:gray"]  # fmt: skip
CERTIFICATE_COLOURS = {"solvability": "tab:green", "complexity": "tab:red"}
START_FONT, TIME_FONT = 8.0, 6.5  # points: a car's id at its start, the times on its path
# behind a label: the lines it crosses stay visible, and it stays legible over them
BACKDROP = {"boxstyle": "square,pad=0.1", "fc": "white", "ec": "none", "alpha": 0.75}
VERDICT_FONT, VERDICT_REASONS = 9.0, 4  # the verdict over the panel, the reasons it shows


QUEUE_START = "D"  # the start marker of a car that shares its fork with another car
DrawnPath = tuple[str, str, str, Sequence[PoseSample], float, float]  # car, label, colour, ...


def queue_leaders(testcase: TestCase, intersection: Intersection) -> dict[str, str | None]:
    """Every car (the ego included) that starts on a fork it shares with another car: the
    id of the car right ahead of it at the start, or None for the first car of its fork
    (who is ahead of whom as service.core.motion.queues has it; the ego by its start)."""
    route = intersection.route(testcase.ego.route.id)
    ego = testcase.ego
    cars = [car.in_queue for car in Judge(testcase, intersection).nonegos]
    cars.append(QueueCar(EGO, route.fork, route.connecting_lane, ego.length, ego.width,
                         ego.start.distance, 0.0))  # fmt: skip
    start = {car.id: car.start for car in cars}
    ahead: dict[str, str | None] = {}
    for follow in follows(cars, intersection):
        ahead.setdefault(follow.leader, None)
        nearest = ahead.get(follow.follower)
        if nearest is None or start[follow.leader] > start[nearest]:
            ahead[follow.follower] = follow.leader
    return ahead


def start_label(car: str, queues: dict[str, str | None]) -> str:
    """The text beside a car's start: its id, and the car it starts behind."""
    ahead = queues.get(car)
    return car if ahead is None else f"{car} behind {ahead}"


def picture_title(testcase: TestCase) -> str:
    """What a picture calls the test-case: its name (the readable default where it has
    none), with its level where the name does not end in it."""
    name = testcase.name or readable_name(testcase)
    level = testcase_level(testcase)
    return name if name.endswith(f"level {level}") else f"{name} (level {level})"


def _testcase_paths(
    testcase: TestCase, intersection: Intersection, ego: Sequence[PoseSample], ego_label: str
) -> list[DrawnPath]:
    """What plot_testcase draws: every non-ego, then the evaluated ego or the certificates,
    each until its goal (where its test ends: the replay's ego leaves there too)."""
    paths: list[DrawnPath] = []
    for k, nonego in enumerate(testcase.nonegos):
        samples = [PoseSample(**s.model_dump()) for s in nonego.trajectory]
        colour = CAR_COLOURS[k % len(CAR_COLOURS)]
        paths.append((nonego.id, f"{nonego.id} (level {nonego.added_in})", colour, samples,
                      nonego.length, nonego.width))  # fmt: skip
    if ego:
        paths.append((EGO, ego_label or "ego", "black", list(ego), testcase.ego.length,
                      testcase.ego.width))  # fmt: skip
    elif testcase.certificates is not None:
        for kind, colour in CERTIFICATE_COLOURS.items():
            certificate = until_goal(
                testcase,
                [PoseSample(**s.model_dump()) for s in getattr(testcase.certificates, kind)],
                intersection,
            )
            paths.append((EGO, f"ego: {kind} certificate", colour, certificate,
                          testcase.ego.length, testcase.ego.width))  # fmt: skip
    return paths


def normal(heading: float) -> tuple[float, float]:
    """The unit vector to the right of the direction of travel (plot axes: x east, y north)."""
    rad = math.radians(heading)  # clockwise from north
    return math.cos(rad), -math.sin(rad)


def time_labels(shown: Sequence[PoseSample], near: float = 3.0) -> list[tuple[PoseSample, str]]:
    """The times beside a path's rectangles (none at t = 0, the start has its own label):
    rectangles within ``near`` metres of the first of a run share one label, "8-14s", so a
    car that stands or crawls gets one label for its stay."""
    runs: list[list[PoseSample]] = []
    for sample in shown:
        if sample.t <= 0:
            continue
        if runs and math.dist((sample.x, sample.y), (runs[-1][0].x, runs[-1][0].y)) < near:
            runs[-1].append(sample)
        else:
            runs.append([sample])
    return [(run[0], f"{run[0].t:g}s" if len(run) == 1 else f"{run[0].t:g}-{run[-1].t:g}s")
            for run in runs]  # fmt: skip


def car_spot(
    sample: PoseSample, length: float, width: float, sides: Literal["right", "left"]
) -> Spot:
    """The places beside a car's rectangle at ``sample``: ``sides`` "right" tries the right
    of the direction of travel first (towards the kerb, away from oncoming lanes), "left"
    the left; then the other side, the four corners, behind and ahead."""
    right = normal(sample.heading)
    left = (-right[0], -right[1])
    forward = (-right[1], right[0])  # the right turned a quarter anticlockwise
    back = (-forward[0], -forward[1])
    first, second = (right, left) if sides == "right" else (left, right)
    corners = [(a[0] + b[0], a[1] + b[1]) for a in (first, second) for b in (back, forward)]
    directions = [first, second, *corners, back, forward]
    return Spot((sample.x, sample.y), directions, [_extent(d, forward, length, width)
                                                  for d in directions])  # fmt: skip


def _extent(
    direction: tuple[float, float], forward: tuple[float, float], length: float, width: float
) -> float:
    """How far a car's rectangle reaches from its centre in ``direction`` (metres)."""
    norm = math.hypot(*direction)
    along = abs(direction[0] * forward[0] + direction[1] * forward[1]) / norm
    across = abs(direction[0] * forward[1] - direction[1] * forward[0]) / norm
    return along * length / 2.0 + across * width / 2.0


def _draw_path(axes: Axes, panel: Axes, path: DrawnPath, every: int) -> np.ndarray:
    """One car's path, its rectangles every ``every`` samples, its arrow, and its
    time-distance curve. The points drawn on the map (the path and the rectangles' corners),
    which labels should not cover."""
    _, label, colour, drawn, length, width = path
    dashed = "--" if "complexity" in label else "-"
    axes.plot([s.x for s in drawn], [s.y for s in drawn], dashed, color=colour,
              linewidth=1.6, label=label, zorder=3)  # fmt: skip
    shown = list(drawn[::every])
    points = [np.array([(s.x, s.y) for s in drawn])]
    for rect in rectangles(
        np.array([s.x for s in shown]), np.array([s.y for s in shown]),
        np.array([s.heading for s in shown]), length, width,
    ):  # fmt: skip
        xs, ys = rect.exterior.xy
        axes.plot(xs, ys, color=colour, linewidth=0.6, alpha=0.7, zorder=3)
        points.append(np.column_stack([xs, ys]))
    _arrow(axes, drawn, colour)
    panel.plot([s.t for s in drawn], [s.distance for s in drawn], dashed, color=colour,
               label=label)  # fmt: skip
    return np.vstack(points)


def _draw_starts(axes: Axes, paths: Sequence[DrawnPath], queues: dict[str, str | None]) -> None:
    """Each path's start: a hollow circle, a diamond on a shared fork."""
    for car, _, colour, drawn, _, _ in paths:
        first = drawn[0]
        marker = QUEUE_START if car in queues else "o"
        axes.plot([first.x], [first.y], marker, mfc="white", mec=colour, ms=6, zorder=5)
    axes.plot([], [], "o", mfc="white", mec="0.3", label="start (t = 0)")
    if queues:
        axes.plot([], [], QUEUE_START, mfc="white", mec="0.3",
                  label="start on a shared fork (label: the car ahead)")  # fmt: skip


def _map_labels(
    paths: Sequence[DrawnPath],
    every: int,
    queues: dict[str, str | None],
    people: Sequence[Walker] = (),
) -> list[tuple[str, str, float, Spot]]:
    """The map's labels in the order they are placed (text, colour, font size, spot): each
    car's id at its start (once: the certificates start together) with the car it starts
    behind, to the left of its direction of travel; then the times beside the rectangles,
    to the right, the ego's first and the others' by time, a time that another path shows
    at the same place once."""
    starts: list[tuple[str, str, float, Spot]] = []
    times: list[tuple[float, int, str, str, Spot]] = []
    for k, (car, _, colour, drawn, length, width) in enumerate(paths):
        if car not in {text.split()[0] for text, *_ in starts}:
            spot = car_spot(drawn[0], length, width, "left")
            starts.append((start_label(car, queues), colour, START_FONT, spot))
        rank = -1 if car == EGO else k  # the ego's times first, in the order of its paths
        for sample, text in time_labels(list(drawn[::every])):
            if any(t == text and math.dist(s.anchor, (sample.x, sample.y)) < 1.0
                   for _, _, t, _, s in times):  # fmt: skip
                continue
            spot = car_spot(sample, length, width, "right")
            times.append((-1.0 if rank < 0 else sample.t, rank, text, colour, spot))
    for k, person in enumerate(people, start=len(paths)):
        spot = walker_spot(person, person.samples[0], "left")
        starts.append((person.id, person.colour, START_FONT, spot))
        for sample, text in time_labels(list(person.samples[::every]), near=WALKER_NEAR):
            times.append((sample.t, k, text, person.colour, walker_spot(person, sample, "right")))
    times.sort(key=lambda item: (item[0], item[1]))
    return starts + [(text, colour, TIME_FONT, spot) for _, _, text, colour, spot in times]


WALKER_NEAR = 0.5  # m: a pedestrian's discs this close share a time label (she waits)


def walker_spot(person: Walker, sample: PoseSample, sides: Literal["right", "left"]) -> Spot:
    """The places beside a pedestrian's disc at ``sample``, as car_spot's beside a car,
    clear of the disc (DISC points across)."""
    spot = car_spot(sample, person.length, person.width, sides)
    return Spot(spot.anchor, spot.directions, [0.0] * len(spot.directions), GAP + DISC / 2.0)


def place_map_labels(
    axes: Axes, labels: Sequence[tuple[str, str, float, Spot]], obstacles: np.ndarray
) -> list[Annotation]:
    """Each label at its best free place beside its spot (service.pictures.labels); one
    that finds none is left out. The labels drawn."""
    placer = LabelPlacer(axes, obstacles)
    drawn = []
    for text, colour, size, spot in labels:
        label = axes.annotate(text, spot.anchor, xytext=(0.0, 0.0), textcoords="offset points",
                              fontsize=size, color=colour, zorder=6, ha="center", va="center",
                              annotation_clip=False, bbox=BACKDROP)  # fmt: skip
        if placer.place(label, spot):
            drawn.append(label)
        else:
            label.remove()
    return drawn


def draw_testcase(
    testcase: TestCase,
    intersection: Intersection,
    ego: Sequence[PoseSample] = (),
    ego_label: str = "",
    verdict: Verdict | None = None,
    progress: Callable[[str], None] | None = None,
) -> Figure:
    """The figure plot_testcase saves: the map (its axes first) and the time-distance panel,
    titled by the test-case's name; at a signalized junction the signal strip under the
    panel (the third axes). ``progress`` hears of each stage."""
    say = progress or (lambda message: None)
    paths = _testcase_paths(testcase, intersection, ego, ego_label)
    people = walkers(testcase)
    rows = signal_rows(
        testcase, intersection, [(drawn[2], drawn[3]) for drawn in paths if drawn[0] == EGO],
        [CAR_COLOURS[k % len(CAR_COLOURS)] for k in range(len(testcase.nonegos))],
        [person.colour for person in people],
    )  # fmt: skip
    figure, axes, panel, strip = _figure(len(rows))
    draw_roads(axes, intersection)
    draw_pavements(axes, intersection)
    draw_crosswalks(axes, intersection)
    draw_stop_lines(axes, intersection)
    sign_legend(axes, intersection)
    heads = SignalHeads(axes, intersection)
    heads.show(0.0)  # the moment of the starts' markers; the strip has the rest
    step = max(1, round(2.0 / testcase.timestep))
    say(f"drawing {len(paths)} paths" + (f" and {len(people)} pedestrians" if people else ""))
    obstacles = [_draw_path(axes, panel, drawn, step) for drawn in paths]
    obstacles += [draw_walker(axes, panel, person, step) for person in people]
    queues = queue_leaders(testcase, intersection)
    _draw_starts(axes, paths, queues)
    _draw_events(panel, testcase, verdict, ego)
    starts = [drawn[3][0] for drawn in paths if drawn[3]]
    frame_map(axes, intersection, starts + [p.samples[0] for p in people if p.samples])
    _map_legend(axes, heads, intersection)
    figure.suptitle(picture_title(testcase), fontsize=13)
    signals = "; signals at t = 0 s" if heads.heads else ""
    axes.set_title(f"junction {testcase.junction} ({intersection.control.value}), "
                   f"ego {testcase.ego.route.id}{signals}", fontsize=10)  # fmt: skip
    if strip is not None and intersection.signals is not None:
        draw_signal_strip(strip, intersection.signals, rows, testcase.duration)
        panel.tick_params(labelbottom=False)  # the strip under it has the times
    else:
        panel.set_xlabel("time (s)")
    panel.set_ylabel("distance travelled or walked (m)" if people else "distance travelled (m)")
    panel.grid(alpha=0.3)
    panel.legend(loc="upper left", fontsize=7)
    figure.tight_layout()
    if verdict is not None:
        _fit_verdict(figure, panel, verdict)
    else:
        panel.set_title("distance over time; markers: events")
    labels = _map_labels(paths, step, queues, people)
    say(f"placing {len(labels)} labels")
    if heads.heads:
        obstacles.append(heads.points())
    place_map_labels(axes, labels, np.vstack(obstacles) if obstacles else np.empty((0, 2)))
    return figure


def _figure(strip_rows: int) -> tuple[Figure, Axes, Axes, Axes | None]:
    """The figure of draw_testcase: the map, the time-distance panel beside it and, with
    ``strip_rows``, the signal strip under the panel (on the panel's time axis)."""
    if not strip_rows:
        figure, (axes, panel) = plt.subplots(
            1, 2, figsize=(15, 7.5), dpi=110, gridspec_kw={"width_ratios": [1, 1.1]}
        )  # the dpi it is saved at: labels are kept apart on that canvas
        return figure, axes, panel, None
    strip_height = 0.75 + STRIP_ROW * strip_rows  # inches: its rows, title and times
    figure = plt.figure(figsize=(15, 7.5 + strip_height), dpi=110)
    grid = figure.add_gridspec(
        2, 2, width_ratios=[1, 1.1], height_ratios=[6.6, strip_height]
    )  # fmt: skip
    axes = figure.add_subplot(grid[:, 0])
    panel = figure.add_subplot(grid[0, 1])
    strip = figure.add_subplot(grid[1, 1], sharex=panel)
    return figure, axes, panel, strip


def _map_legend(axes: Axes, heads: SignalHeads, intersection: Intersection) -> None:
    """The map's legend below it: the paths (the pedestrians' among them), starts and stop
    lines, the crosswalks and sidewalks, then the signals' colours (those the heads show
    at some time: the strip's colours too)."""
    handles, labels = axes.get_legend_handles_labels()
    walking, names = crosswalk_handles(intersection)
    handles, labels = handles + walking, labels + names
    more, words = colour_handles(heads.colours_used())
    axes.legend(handles + more, labels + words, loc="upper center",
                bbox_to_anchor=(0.5, -0.08), ncol=3, fontsize=7)  # fmt: skip


def _draw_events(
    panel: Axes, testcase: TestCase, verdict: Verdict | None, ego: Sequence[PoseSample]
) -> None:
    """The non-egos' events in their colours and an evaluated ego's in black, on the panel;
    a pedestrian's (at the curb, onto and off her crossing) in hers."""
    users = [(nonego.events, CAR_COLOURS[k % len(CAR_COLOURS)])
             for k, nonego in enumerate(testcase.nonegos)]  # fmt: skip
    users += [(person.events, PEDESTRIAN_COLOURS[k % len(PEDESTRIAN_COLOURS)])
              for k, person in enumerate(testcase.pedestrians)]  # fmt: skip
    for events, colour in users:
        for event in events:
            if event.kind.value in EVENT_MARKERS:
                panel.plot([event.t], [event.distance], EVENT_MARKERS[event.kind.value],
                           color=colour, ms=6)  # fmt: skip
    if verdict is not None and ego:
        for ref in verdict.ego_events:
            if ref.kind in EVENT_MARKERS:
                at = min(ego, key=lambda s: abs(s.t - ref.t))
                panel.plot([ref.t], [at.distance], EVENT_MARKERS[ref.kind], color="black", ms=6)
    whose = "road user's" if testcase.pedestrians else "car's"
    for kind, marker in EVENT_MARKERS.items():
        panel.plot([], [], marker, color="0.3", label=f"{kind} (in the {whose} colour)")


def verdict_lines(verdict: Verdict, columns: int) -> list[str]:
    """The verdict over the panel: the controller and PASS or FAIL, then each reason and
    then what happened after the goal (information) wrapped to ``columns`` characters (the
    first VERDICT_REASONS of them, and how many more)."""
    lines = [f"{verdict.controller}: {'PASS' if verdict.passed else 'FAIL'}"]
    said = [*verdict.reasons, *verdict.information]
    for reason in said[:VERDICT_REASONS]:
        lines += textwrap.wrap(reason, columns, subsequent_indent="  ", break_long_words=True)
    more = len(said) - VERDICT_REASONS
    if more > 0:
        lines.append(f"and {more} more (scengen check prints every reason)")
    return lines


def _fit_verdict(figure: Figure, panel: Axes, verdict: Verdict) -> None:
    """The verdict as the panel's title, wrapped to the narrowest width that fits the
    panel, then the layout redone for its height."""
    renderer = figure.canvas.get_renderer()  # type: ignore[attr-defined]
    room = panel.get_window_extent(renderer).width
    colour = "tab:green" if verdict.passed else "tab:red"
    columns = 140
    while True:
        title = panel.set_title("\n".join(verdict_lines(verdict, columns)), fontsize=VERDICT_FONT,
                                color=colour, loc="left")  # fmt: skip
        if title.get_window_extent(renderer).width <= room or columns <= 20:
            break
        columns -= 5
    figure.tight_layout()


def plot_testcase(
    testcase: TestCase,
    intersection: Intersection,
    path: Path,
    ego: Sequence[PoseSample] = (),
    ego_label: str = "",
    verdict: Verdict | None = None,
    progress: Callable[[str], None] | None = None,
) -> None:
    """The intersection with every car's path (coloured by car, rectangles every 2 s with
    their times, the car's id at its start, and the car ahead of it where it shares a fork),
    the certificates (green solvability, red complexity) or an evaluated ego's path and its
    verdict, stop lines; and a time-distance panel with each car's curve and its events
    (arrived, entered, exited); titled by the test-case's name. At a signalized junction,
    each signal head in its colour at t = 0 s, and each car's signal over time under the
    panel (service.pictures.signals). PNG or SVG by the file's
    suffix. ``progress`` hears of each stage."""
    figure = draw_testcase(testcase, intersection, ego, ego_label, verdict, progress)
    if progress is not None:
        progress(f"writing {path}")
    save(figure, path)


EVENT_MARKERS = {"arrived": "o", "entered": "^", "exited": "s"}
