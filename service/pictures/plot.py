"""Pictures of an intersection, its routes and a car's drive (matplotlib, no display)."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.text import Annotation
from shapely.geometry import Polygon

from service.core.checker.check import EGO, Judge
from service.core.checker.verdict import Verdict
from service.core.motion.events import rectangles
from service.core.motion.poses import PoseSample
from service.core.motion.queues import QueueCar, follows
from service.core.network import Intersection
from service.core.testcase import TestCase

TURN_COLOURS = {"left": "tab:red", "right": "tab:green", "straight": "tab:blue"}


def _fill(axes: Axes, polygon: Polygon, **style: Any) -> None:
    for part in getattr(polygon, "geoms", [polygon]):
        xs, ys = part.exterior.xy
        axes.fill(xs, ys, **style)


def _draw_roads(axes: Axes, intersection: Intersection) -> None:
    _fill(axes, intersection.polygon, color="0.85", zorder=0)
    for fork in intersection.forks.values():
        _fill(axes, fork.approach.buffer(fork.width / 2, cap_style="flat"), color="0.9", zorder=0)
    for exit_lane in intersection.exits.values():
        road = exit_lane.departure.buffer(exit_lane.width / 2, cap_style="flat")
        _fill(axes, road, color="0.93", zorder=0)


STOP_LINE = "firebrick"  # a stop sign's line; other forks' lines are grey


def _draw_stop_lines(axes: Axes, intersection: Intersection) -> None:
    """Each fork's line across its lane at the junction: red with a stop sign, else grey
    (lines, so that they clash with no event marker)."""
    for fork in intersection.forks.values():
        x, y = fork.stop_line
        heading = math.radians(fork.heading)  # degrees clockwise from north
        dx, dy = math.cos(heading) * fork.width / 2, -math.sin(heading) * fork.width / 2
        colour, width = (STOP_LINE, 2.2) if fork.stop_sign else ("0.45", 1.0)
        axes.plot([x - dx, x + dx], [y - dy, y + dy], color=colour, linewidth=width,
                  solid_capstyle="butt", zorder=4)  # fmt: skip


def _back_along(line: Any, metres: float, from_end: bool = True) -> tuple[float, float]:
    """The point ``metres`` from the end (or the start) of a line, along it."""
    length = line.length
    at = line.interpolate(max(length - metres, 0.0) if from_end else min(metres, length))
    return at.x, at.y


def _arrow(axes: Axes, samples: Sequence[PoseSample], colour: str) -> None:
    """An arrowhead at the end of a drawn path: the direction of travel."""
    moved = [s for s in samples if math.dist((s.x, s.y), (samples[-1].x, samples[-1].y)) > 3.0]
    if not moved:
        return
    tail = moved[-1]
    axes.annotate("", xy=(samples[-1].x, samples[-1].y), xytext=(tail.x, tail.y), zorder=5,
                  arrowprops={"arrowstyle": "-|>", "color": colour, "lw": 1.4})  # fmt: skip


def plot_intersection(
    intersection: Intersection,
    path: Path,
    highlight: Sequence[str] = (),
    track: Sequence[PoseSample] = (),
    car: tuple[float, float] = (5.0, 1.8),
) -> None:
    """Draw the junction, every connecting lane (coloured by turn), forks with their names,
    the highlighted routes, and optionally a car's rectangles every second."""
    figure, axes = plt.subplots(figsize=(8, 8))
    _draw_roads(axes, intersection)
    for route in intersection.routes.values():
        lane = intersection.connecting_lanes[route.connecting_lane]
        chosen = route.id in highlight
        xs, ys = lane.centreline.xy
        axes.plot(
            xs, ys, color=TURN_COLOURS[route.turn.value],
            linewidth=2.5 if chosen else 0.8, alpha=1.0 if chosen else 0.5, zorder=2,
        )  # fmt: skip
        if chosen:
            _fill(axes, lane.polygon, color=TURN_COLOURS[route.turn.value], alpha=0.15, zorder=1)
        xs, ys = lane.centreline.xy
        axes.annotate("", xy=(xs[-1], ys[-1]), xytext=(xs[-2], ys[-2]), zorder=2,
                      arrowprops={"arrowstyle": "-|>", "color": TURN_COLOURS[route.turn.value],
                                  "lw": 0.8, "alpha": 1.0 if chosen else 0.6})  # fmt: skip
    _draw_stop_lines(axes, intersection)
    for fork in intersection.forks.values():
        sign = " (stop)" if fork.stop_sign else ""
        _label_outward(axes, f"{fork.lane}{sign}", _back_along(fork.approach, 1.5), fork.approach)
    for exit_lane in intersection.exits.values():
        start = _back_along(exit_lane.departure, 1.5, from_end=False)
        _label_outward(axes, f"{exit_lane.lane} (exit)", start, exit_lane.departure, True)
    if track:
        step = max(1, round(1.0 / max(track[1].t - track[0].t, 1e-9))) if len(track) > 1 else 1
        shown = list(track[::step])
        rects = rectangles(
            np.array([s.x for s in shown]), np.array([s.y for s in shown]),
            np.array([s.heading for s in shown]), car[0], car[1],
        )  # fmt: skip
        for rect in rects:
            xs, ys = rect.exterior.xy
            axes.plot(xs, ys, color="black", linewidth=0.6, zorder=3)
        axes.plot([s.x for s in track], [s.y for s in track], "k:", linewidth=0.8, zorder=3)
    minx, miny, maxx, maxy = intersection.polygon.bounds
    margin = 20.0
    axes.set_xlim(minx - margin, maxx + margin)
    axes.set_ylim(miny - margin, maxy + margin)
    axes.set_aspect("equal")
    axes.set_title(
        f"junction {intersection.junction} ({intersection.control.value}): "
        "left red, right green, straight blue"
    )
    figure.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(figure)


def _label_outward(
    axes: Any, text: str, at: tuple[float, float], line: Any, outward: bool = False
) -> None:
    """A label that runs from ``at`` away from the junction along a lane (an approach ends
    at the junction; a departure, ``outward``, starts there): labels of lanes side by side
    on one arm stay apart, and none is upside down."""
    (x0, y0), (x1, y1) = line.coords[0], line.coords[-1]
    if outward:
        (x0, y0), (x1, y1) = (x1, y1), (x0, y0)
    angle = math.degrees(math.atan2(y0 - y1, x0 - x1))
    flipped = not -90.0 <= angle <= 90.0
    axes.text(
        at[0], at[1], text, fontsize=7, zorder=4,
        rotation=angle + 180.0 if flipped else angle, rotation_mode="anchor",
        ha="right" if flipped else "left", va="center",
    )  # fmt: skip


CAR_COLOURS = ["tab:blue", "tab:orange", "tab:purple", "tab:brown", "tab:pink", "tab:olive",
               "tab:cyan", "tab:gray"]  # fmt: skip
CERTIFICATE_COLOURS = {"solvability": "tab:green", "complexity": "tab:red"}


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


def _testcase_paths(
    testcase: TestCase, ego: Sequence[PoseSample], ego_label: str
) -> list[DrawnPath]:
    """What plot_testcase draws: every non-ego, then the evaluated ego or the certificates."""
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
            certificate = [
                PoseSample(**s.model_dump()) for s in getattr(testcase.certificates, kind)
            ]
            paths.append((EGO, f"ego: {kind} certificate", colour, certificate,
                          testcase.ego.length, testcase.ego.width))  # fmt: skip
    return paths


def _normal(heading: float) -> tuple[float, float]:
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


def _draw_path(axes: Axes, panel: Axes, path: DrawnPath, every: int, rank: int) -> list[Annotation]:
    """One car's path, its rectangles every ``every`` samples with their times (to the right
    of the direction of travel, towards the kerb and away from oncoming lanes; further out
    for each earlier path on its fork, so that cars that drive one lane keep their times
    apart), its arrow, and its time-distance curve. The time labels drawn."""
    _, label, colour, drawn, length, width = path
    dashed = "--" if "complexity" in label else "-"
    axes.plot([s.x for s in drawn], [s.y for s in drawn], dashed, color=colour,
              linewidth=1.6, label=label, zorder=3)  # fmt: skip
    shown = list(drawn[::every])
    for rect in rectangles(
        np.array([s.x for s in shown]), np.array([s.y for s in shown]),
        np.array([s.heading for s in shown]), length, width,
    ):  # fmt: skip
        xs, ys = rect.exterior.xy
        axes.plot(xs, ys, color=colour, linewidth=0.6, alpha=0.7, zorder=3)
    labels = []
    for sample, text in time_labels(shown):
        right_x, right_y = _normal(sample.heading)
        if abs(right_x) > abs(right_y):  # beside a road up or down the picture: a column each
            out, ha = 4.0 + 22.0 * rank, "left" if right_x > 0 else "right"
        else:  # above or below a road across it: a row each
            out, ha = 7.0 + 9.0 * rank, "center"
        labels.append(axes.annotate(
            text, (sample.x, sample.y), xytext=(right_x * out, right_y * out),
            textcoords="offset points", fontsize=5, color=colour, zorder=5, ha=ha, va="center",
        ))  # fmt: skip
    _arrow(axes, drawn, colour)
    panel.plot([s.t for s in drawn], [s.distance for s in drawn], dashed, color=colour,
               label=label)  # fmt: skip
    return labels


def _draw_starts(
    axes: Axes, paths: Sequence[DrawnPath], queues: dict[str, str | None], forks: dict[str, str]
) -> list[Annotation]:
    """Each path's start: a hollow circle, a diamond on a shared fork; each car's id once
    (the certificates start together) with the car it starts behind, to the left of the
    direction of travel (the times are on the right) and running towards the junction,
    further out for each car labelled before on its fork. The labels drawn."""
    labelled: list[str] = []
    labels = []
    for car, _, colour, drawn, _, _ in paths:
        first = drawn[0]
        marker = QUEUE_START if car in queues else "o"
        axes.plot([first.x], [first.y], marker, mfc="white", mec=colour, ms=6, zorder=5)
        if car in labelled:
            continue
        rank = sum(1 for other in labelled if forks[other] == forks[car])
        labelled.append(car)
        labels.append(_start_text(axes, start_label(car, queues), first, colour, rank))
    axes.plot([], [], "o", mfc="white", mec="0.3", label="start (t = 0)")
    if queues:
        axes.plot([], [], QUEUE_START, mfc="white", mec="0.3",
                  label="start on a shared fork (label: the car ahead)")  # fmt: skip
    return labels


def _start_text(axes: Axes, text: str, first: PoseSample, colour: str, rank: int) -> Annotation:
    """A start's label, ``8 + 10 x rank`` points to the left of the direction of travel."""
    left_x, left_y = (-v for v in _normal(first.heading))
    out = 8.0 + 10.0 * rank
    if abs(left_x) > abs(left_y):  # a road up or down the picture: beside it
        ha, va = ("left" if left_x > 0 else "right"), "center"
    else:  # across the picture: above or below it, running towards the junction
        ahead = math.sin(math.radians(first.heading))
        ha, va = ("right" if ahead < 0 else "left"), ("bottom" if left_y > 0 else "top")
    return axes.annotate(text, (first.x, first.y), fontsize=8, color=colour, zorder=5,
                         xytext=(left_x * out, left_y * out), textcoords="offset points",
                         ha=ha, va=va)  # fmt: skip


def _keep_apart(figure: Figure, labels: Sequence[Annotation], step: float = 8.0) -> None:
    """Move each label that overlaps one placed before it further out from its point, by
    ``step`` points at a time, or else to the other side, so that no label hides another
    (one with no free place in reach stays where it was drawn)."""
    renderer = figure.canvas.get_renderer()  # type: ignore[attr-defined]
    placed: list[Any] = []
    for label in labels:
        dx, dy = label.xyann
        reach = max(math.hypot(dx, dy), 1.0)
        tries = [(side * (reach + step * k) / reach) for side in (1, -1) for k in range(4)]
        for scale in tries:
            label.xyann = (dx * scale, dy * scale)
            if not any(_padded(label, renderer).overlaps(o) for o in placed):
                break
        else:
            label.xyann = (dx, dy)
        placed.append(_padded(label, renderer))


def _padded(label: Annotation, renderer: Any) -> Any:
    """A label's box on the canvas with a margin of a point and a half."""
    return label.get_window_extent(renderer).padded(1.5 * label.figure.dpi / 72.0)


def plot_testcase(
    testcase: TestCase,
    intersection: Intersection,
    path: Path,
    ego: Sequence[PoseSample] = (),
    ego_label: str = "",
    verdict: Verdict | None = None,
) -> None:
    """The intersection with every car's path (coloured by car, rectangles every 2 s, the
    car's id at its start, and the car ahead of it where it shares a fork), the
    certificates (green solvability, red complexity) or an evaluated ego's path, stop
    lines; and a time-distance panel with each car's curve and its events (arrived,
    entered, exited). PNG or SVG by the file's suffix."""
    figure, (axes, panel) = plt.subplots(
        1, 2, figsize=(15, 7.5), dpi=110, gridspec_kw={"width_ratios": [1, 1.1]}
    )  # the dpi it is saved at: labels are kept apart on that canvas
    _draw_roads(axes, intersection)
    _draw_stop_lines(axes, intersection)
    if any(fork.stop_sign for fork in intersection.forks.values()):
        axes.plot([], [], color=STOP_LINE, linewidth=2.2, label="stop line (sign)")
    paths = _testcase_paths(testcase, ego, ego_label)
    forks = {n.id: n.route.fork for n in testcase.nonegos} | {EGO: testcase.ego.route.fork}
    step = max(1, round(2.0 / testcase.timestep))
    times = []
    for k, drawn in enumerate(paths):
        rank = sum(1 for other in paths[:k] if forks[other[0]] == forks[drawn[0]])
        times += _draw_path(axes, panel, drawn, step, rank)
    starts = _draw_starts(axes, paths, queue_leaders(testcase, intersection), forks)
    for k, nonego in enumerate(testcase.nonegos):
        colour = CAR_COLOURS[k % len(CAR_COLOURS)]
        for event in nonego.events:
            if event.kind.value in EVENT_MARKERS:
                panel.plot([event.t], [event.distance], EVENT_MARKERS[event.kind.value],
                           color=colour, ms=6)  # fmt: skip
    if verdict is not None:
        for ref in verdict.ego_events:
            if ref.kind in EVENT_MARKERS and ego:
                at = min(ego, key=lambda s: abs(s.t - ref.t))
                panel.plot([ref.t], [at.distance], EVENT_MARKERS[ref.kind], color="black", ms=6)
    for kind, marker in EVENT_MARKERS.items():
        panel.plot([], [], marker, color="0.3", label=f"{kind} (in the car's colour)")
    _frame(axes, intersection, [drawn[3][0] for drawn in paths if drawn[3]])
    axes.legend(loc="upper center", bbox_to_anchor=(0.5, -0.08), ncol=3, fontsize=7)
    title = testcase.name or f"{testcase.network.ref} {testcase.junction}"
    axes.set_title(f"{title}: {intersection.control.value}, ego {testcase.ego.route.id}")
    panel.set_xlabel("time (s)")
    panel.set_ylabel("distance travelled (m)")
    panel.grid(alpha=0.3)
    panel.legend(loc="upper left", fontsize=7)
    if verdict is not None:
        status = "PASS" if verdict.passed else "FAIL"
        reasons = "; ".join(verdict.reasons)[:160]
        panel.set_title(f"{verdict.controller}: {status}" + (f"\n{reasons}" if reasons else ""),
                        fontsize=9, color="tab:green" if verdict.passed else "tab:red")  # fmt: skip
    else:
        panel.set_title("distance over time; markers: events")
    figure.tight_layout()
    _keep_apart(figure, [*starts, *times])
    figure.savefig(path, dpi=110, bbox_inches="tight")  # the legend below the map included
    plt.close(figure)


def _frame(axes: Axes, intersection: Intersection, starts: Sequence[PoseSample]) -> None:
    """The junction with a margin, every start in view, metres on both axes."""
    minx, miny, maxx, maxy = intersection.polygon.bounds
    margin = 25.0
    low_x = min([minx - margin, *(s.x - 6.0 for s in starts)])  # every start in view
    low_y = min([miny - margin, *(s.y - 6.0 for s in starts)])
    high_x = max([maxx + margin, *(s.x + 6.0 for s in starts)])
    high_y = max([maxy + margin, *(s.y + 6.0 for s in starts)])
    axes.set_xlim(low_x, high_x)
    axes.set_ylim(low_y, high_y)
    axes.set_aspect("equal")
    axes.set_xlabel("x (m)")
    axes.set_ylabel("y (m)")


EVENT_MARKERS = {"arrived": "o", "entered": "^", "exited": "s"}


def animate_testcase(
    testcase: TestCase,
    intersection: Intersection,
    path: Path,
    ego: Sequence[PoseSample] = (),
    ego_label: str = "",
    every: float = 0.5,
    progress: Callable[[int, int], None] | None = None,
) -> None:
    """A GIF of the cars moving (one frame every ``every`` seconds of the test-case): every
    non-ego, and the ego (an evaluation's trajectory, else the solvability certificate); the
    legend names the car each starts behind on a shared fork. ``progress(frame, frames)``
    hears of each frame as it is saved."""
    from matplotlib.animation import FuncAnimation, PillowWriter

    cars: list[DrawnPath] = []
    for k, nonego in enumerate(testcase.nonegos):
        samples = [PoseSample(**s.model_dump()) for s in nonego.trajectory]
        cars.append((nonego.id, nonego.id, CAR_COLOURS[k % len(CAR_COLOURS)], samples,
                     nonego.length, nonego.width))  # fmt: skip
    if not ego and testcase.certificates is not None:
        ego = [PoseSample(**s.model_dump()) for s in testcase.certificates.solvability]
        ego_label = ego_label or "ego (solvability certificate)"
    if ego:
        cars.append((EGO, ego_label or "ego", "black", ego, testcase.ego.length,
                     testcase.ego.width))  # fmt: skip
    queues = queue_leaders(testcase, intersection)
    figure, axes = plt.subplots(figsize=(7, 7))
    _draw_roads(axes, intersection)
    minx, miny, maxx, maxy = intersection.polygon.bounds
    axes.set_xlim(minx - 25, maxx + 25)
    axes.set_ylim(miny - 25, maxy + 25)
    axes.set_aspect("equal")
    patches = []
    for car, name, colour, _, _, _ in cars:
        ahead = queues.get(car)
        name = name if ahead is None else f"{name}, starts behind {ahead}"
        (outline,) = axes.fill([], [], color=colour, alpha=0.8, label=name, zorder=3)
        label = axes.text(0, 0, "", fontsize=8, color=colour, zorder=4)
        patches.append((outline, label))
    axes.legend(loc="upper left", fontsize=7)
    title = axes.set_title("")
    step = max(1, round(every / testcase.timestep))
    frames = list(range(0, round(testcase.duration / testcase.timestep) + 1, step))

    def draw(frame: int) -> list[Any]:
        t = frame * testcase.timestep
        title.set_text(f"{testcase.name or testcase.ego.route.id}  t = {t:4.1f} s")
        for (outline, label), (car, _, _, samples, length, width) in zip(
            patches, cars, strict=True
        ):
            if frame >= len(samples):
                outline.set_xy(np.empty((0, 2)))
                label.set_text("")
                continue
            s = samples[frame]
            rect = rectangles(np.array([s.x]), np.array([s.y]), np.array([s.heading]),
                              length, width)[0]  # fmt: skip
            outline.set_xy(np.array(rect.exterior.coords))
            label.set_text(car)
            label.set_position((s.x + 2.0, s.y + 2.0))
        return [title, *(p for pair in patches for p in pair)]

    animation = FuncAnimation(figure, draw, frames=frames, blit=False)
    animation.save(str(path), writer=PillowWriter(fps=round(1 / every)), progress_callback=progress)
    plt.close(figure)
