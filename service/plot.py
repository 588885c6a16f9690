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
from shapely.geometry import Polygon

from service.core.events import rectangles
from service.core.network import Intersection
from service.core.poses import PoseSample
from service.core.testcase import TestCase
from service.core.verdict import Verdict

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


def plot_testcase(
    testcase: TestCase,
    intersection: Intersection,
    path: Path,
    ego: Sequence[PoseSample] = (),
    ego_label: str = "",
    verdict: Verdict | None = None,
) -> None:
    """The intersection with every car's path (coloured by car, rectangles every 2 s, the
    car's id at its start), the certificates (green solvability, red complexity) or an
    evaluated ego's path, stop lines; and a time-distance panel with each car's curve and
    its events (arrived, entered, exited). PNG or SVG by the file's suffix."""
    figure, (axes, panel) = plt.subplots(
        1, 2, figsize=(15, 7.5), gridspec_kw={"width_ratios": [1, 1.1]}
    )
    _draw_roads(axes, intersection)
    _draw_stop_lines(axes, intersection)
    if any(fork.stop_sign for fork in intersection.forks.values()):
        axes.plot([], [], color=STOP_LINE, linewidth=2.2, label="stop line (sign)")
    paths: list[tuple[str, str, Sequence[PoseSample], float, float]] = []
    for k, nonego in enumerate(testcase.nonegos):
        samples = [PoseSample(**s.model_dump()) for s in nonego.trajectory]
        colour = CAR_COLOURS[k % len(CAR_COLOURS)]
        paths.append((f"{nonego.id} (level {nonego.added_in})", colour, samples,
                      nonego.length, nonego.width))  # fmt: skip
    if ego:
        paths.append((ego_label or "ego", "black", list(ego), testcase.ego.length,
                       testcase.ego.width))  # fmt: skip
    elif testcase.certificates is not None:
        for kind, colour in CERTIFICATE_COLOURS.items():
            certificate = [
                PoseSample(**s.model_dump()) for s in getattr(testcase.certificates, kind)
            ]
            paths.append((f"ego: {kind} certificate", colour, certificate, testcase.ego.length,
                          testcase.ego.width))  # fmt: skip
    step = max(1, round(2.0 / testcase.timestep))
    for label, colour, drawn, length, width in paths:
        dashed = "--" if "complexity" in label else "-"
        axes.plot([s.x for s in drawn], [s.y for s in drawn], dashed, color=colour,
                  linewidth=1.6, label=label, zorder=3)  # fmt: skip
        shown = list(drawn[::step])
        for sample, rect in zip(shown, rectangles(
            np.array([s.x for s in shown]), np.array([s.y for s in shown]),
            np.array([s.heading for s in shown]), length, width,
        ), strict=True):  # fmt: skip
            xs, ys = rect.exterior.xy
            axes.plot(xs, ys, color=colour, linewidth=0.6, alpha=0.7, zorder=3)
            if sample.t > 0:  # the time of each rectangle, beside it
                axes.annotate(f"{sample.t:g}s", (sample.x, sample.y), xytext=(3, 3),
                              textcoords="offset points", fontsize=5, color=colour,
                              zorder=5)  # fmt: skip
        first = drawn[0]
        axes.plot([first.x], [first.y], "o", mfc="white", mec=colour, ms=6, zorder=5)
        axes.annotate(label.split(" ")[0].rstrip(":"), (first.x, first.y), xytext=(4, -10),
                      textcoords="offset points", fontsize=8, color=colour,
                      zorder=5)  # fmt: skip
        _arrow(axes, drawn, colour)
        panel.plot([s.t for s in drawn], [s.distance for s in drawn], dashed, color=colour,
                   label=label)  # fmt: skip
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
    axes.plot([], [], "o", mfc="white", mec="0.3", label="start (t = 0)")
    for kind, marker in EVENT_MARKERS.items():
        panel.plot([], [], marker, color="0.3", label=f"{kind} (in the car's colour)")
    minx, miny, maxx, maxy = intersection.polygon.bounds
    margin = 25.0
    starts = [(drawn[0].x, drawn[0].y) for _, _, drawn, _, _ in paths if drawn]
    low_x = min([minx - margin, *(x - 6.0 for x, _ in starts)])  # every start in view
    low_y = min([miny - margin, *(y - 6.0 for _, y in starts)])
    high_x = max([maxx + margin, *(x + 6.0 for x, _ in starts)])
    high_y = max([maxy + margin, *(y + 6.0 for _, y in starts)])
    axes.set_xlim(low_x, high_x)
    axes.set_ylim(low_y, high_y)
    axes.set_aspect("equal")
    axes.set_xlabel("x (m)")
    axes.set_ylabel("y (m)")
    axes.legend(loc="upper left", fontsize=7)
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
    figure.savefig(path, dpi=110)
    plt.close(figure)


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
    non-ego, and the ego (an evaluation's trajectory, else the solvability certificate).
    ``progress(frame, frames)`` hears of each frame as it is saved."""
    from matplotlib.animation import FuncAnimation, PillowWriter

    cars: list[tuple[str, str, Sequence[PoseSample], float, float]] = []
    for k, nonego in enumerate(testcase.nonegos):
        samples = [PoseSample(**s.model_dump()) for s in nonego.trajectory]
        cars.append((nonego.id, CAR_COLOURS[k % len(CAR_COLOURS)], samples, nonego.length,
                     nonego.width))  # fmt: skip
    if not ego and testcase.certificates is not None:
        ego = [PoseSample(**s.model_dump()) for s in testcase.certificates.solvability]
        ego_label = ego_label or "ego (solvability certificate)"
    if ego:
        cars.append((ego_label or "ego", "black", ego, testcase.ego.length, testcase.ego.width))
    figure, axes = plt.subplots(figsize=(7, 7))
    _draw_roads(axes, intersection)
    minx, miny, maxx, maxy = intersection.polygon.bounds
    axes.set_xlim(minx - 25, maxx + 25)
    axes.set_ylim(miny - 25, maxy + 25)
    axes.set_aspect("equal")
    patches = []
    for name, colour, _, _, _ in cars:
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
        for (outline, label), (car, _, samples, length, width) in zip(patches, cars, strict=True):
            if frame >= len(samples):
                outline.set_xy(np.empty((0, 2)))
                label.set_text("")
                continue
            s = samples[frame]
            rect = rectangles(np.array([s.x]), np.array([s.y]), np.array([s.heading]),
                              length, width)[0]  # fmt: skip
            outline.set_xy(np.array(rect.exterior.coords))
            label.set_text(car.split(" ")[0].rstrip(":"))
            label.set_position((s.x + 2.0, s.y + 2.0))
        return [title, *(p for pair in patches for p in pair)]

    animation = FuncAnimation(figure, draw, frames=frames, blit=False)
    animation.save(str(path), writer=PillowWriter(fps=round(1 / every)), progress_callback=progress)
    plt.close(figure)
