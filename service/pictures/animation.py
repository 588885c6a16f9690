"""A test-case's cars moving, as a GIF: the map of the static picture with each car's
rectangle and id, a frame every half second."""

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
from PIL import Image

from service.core.checker.check import EGO
from service.core.motion.events import rectangles
from service.core.motion.poses import PoseSample
from service.core.network import Intersection
from service.core.testcase import TestCase
from service.pictures.labels import LabelPlacer
from service.pictures.plot import (
    CAR_COLOURS,
    STOP_LINE,
    DrawnPath,
    car_spot,
    draw_roads,
    draw_stop_lines,
    frame_map,
    normal,
    picture_title,
    queue_leaders,
)

DPI = 100
Frame = Callable[[int], list[Any]]  # draws sample k of every car; the artists it changed


def _animated_cars(
    testcase: TestCase, ego: Sequence[PoseSample], ego_label: str
) -> list[DrawnPath]:
    """What the animation moves: every non-ego, and the ego (an evaluation's trajectory,
    else the solvability certificate)."""
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
    return cars


def draw_animation(
    testcase: TestCase,
    intersection: Intersection,
    ego: Sequence[PoseSample] = (),
    ego_label: str = "",
) -> tuple[Figure, Frame]:
    """The animation's figure (the map, its axes first, framed with every start in view and
    stop lines drawn as in the static picture; the legend below it names the car each
    starts behind on a shared fork) and the function that draws a frame: each car's
    rectangle and its id beside it, inside the map and over no other id or car; a car out
    of view has no id. The artists that change are animated: a frame draws only them."""
    cars = _animated_cars(testcase, ego, ego_label)
    queues = queue_leaders(testcase, intersection)
    figure, axes = plt.subplots(figsize=(7.5, 8.2), dpi=DPI)
    draw_roads(axes, intersection)
    draw_stop_lines(axes, intersection)
    if any(fork.stop_sign for fork in intersection.forks.values()):
        axes.plot([], [], color=STOP_LINE, linewidth=2.2, label="stop line (sign)")
    frame_map(axes, intersection, [samples[0] for _, _, _, samples, _, _ in cars if samples])
    patches = []
    for car, name, colour, _, _, _ in cars:
        ahead = queues.get(car)
        name = name if ahead is None else f"{name}, starts behind {ahead}"
        (outline,) = axes.fill([], [], color=colour, alpha=0.8, label=name, zorder=3,
                               animated=True)  # fmt: skip
        label = axes.annotate(car, (0.0, 0.0), xytext=(0.0, 0.0), textcoords="offset points",
                              fontsize=8, color=colour, zorder=6, ha="center", va="center",
                              annotation_clip=False, visible=False, animated=True)  # fmt: skip
        patches.append((outline, label))
    axes.legend(loc="upper center", bbox_to_anchor=(0.5, -0.09), ncol=2, fontsize=7)
    axes.set_title(picture_title(testcase), pad=20)
    clock = axes.text(0.5, 1.01, "", transform=axes.transAxes, ha="center", va="bottom",
                      animated=True)  # fmt: skip
    figure.tight_layout()

    def draw(frame: int) -> list[Any]:
        clock.set_text(f"t = {frame * testcase.timestep:4.1f} s")
        shown = []
        for (outline, label), (_, _, _, samples, length, width) in zip(patches, cars, strict=True):
            label.set_visible(False)
            if frame >= len(samples):
                outline.set_xy(np.empty((0, 2)))
                continue
            s = samples[frame]
            rect = rectangles(np.array([s.x]), np.array([s.y]), np.array([s.heading]),
                              length, width)[0]  # fmt: skip
            outline.set_xy(np.array(rect.exterior.coords))
            shown.append((label, s, length, width, _covering(s, length, width)))
        _place_car_labels(axes, shown)
        return [clock, *(p for pair in patches for p in pair)]

    return figure, draw


def _covering(sample: PoseSample, length: float, width: float) -> np.ndarray:
    """Points that cover a car's rectangle (every metre or so): a label over any of them
    hides part of the car."""
    right = np.array(normal(sample.heading))
    forward = np.array([-right[1], right[0]])
    along = np.linspace(-length / 2.0, length / 2.0, max(2, math.ceil(length) + 1))
    across = np.linspace(-width / 2.0, width / 2.0, max(2, math.ceil(width) + 1))
    grid = along[:, None, None] * forward + across[None, :, None] * right
    points: np.ndarray = grid.reshape(-1, 2) + np.array([sample.x, sample.y])
    return points


Shown = tuple[Annotation, PoseSample, float, float, np.ndarray]  # label, pose, size, cover


def _place_car_labels(axes: Axes, shown: Sequence[Shown]) -> None:
    """Each car's id beside its rectangle where the car is in view and there is room."""
    low_x, high_x = axes.get_xlim()
    low_y, high_y = axes.get_ylim()
    covered = np.vstack([points for *_, points in shown]) if shown else None
    placer = LabelPlacer(axes, covered)
    for label, s, length, width, _ in shown:
        if not (low_x <= s.x <= high_x and low_y <= s.y <= high_y):
            continue  # out of view: its id would hang over the axis numbers
        label.xy = (s.x, s.y)
        label.set_visible(True)  # an invisible text has no size to place
        label.set_visible(placer.place(label, car_spot(s, length, width, "left")))


def animate_testcase(
    testcase: TestCase,
    intersection: Intersection,
    path: Path,
    ego: Sequence[PoseSample] = (),
    ego_label: str = "",
    every: float = 0.5,
    progress: Callable[[int, int], None] | None = None,
) -> None:
    """A GIF of the cars moving (one frame every ``every`` seconds of the test-case), as
    draw_animation draws them: the still map drawn once, each frame's cars drawn over it.
    ``progress(frame, frames)`` hears of each frame as it is drawn."""
    figure, draw = draw_animation(testcase, intersection, ego, ego_label)
    step = max(1, round(every / testcase.timestep))
    frames = list(range(0, round(testcase.duration / testcase.timestep) + 1, step))
    canvas = figure.canvas
    canvas.draw()  # the animated artists are left out: this is the still map
    still = canvas.copy_from_bbox(figure.bbox)  # type: ignore[attr-defined]

    def picture(frame: int) -> Image.Image:
        canvas.restore_region(still)  # type: ignore[attr-defined]
        for artist in draw(frame):
            if artist.get_visible():
                figure.draw_artist(artist)
        return Image.fromarray(np.asarray(canvas.buffer_rgba())[:, :, :3])  # type: ignore[attr-defined]

    palette = _palette([picture(frames[k * (len(frames) - 1) // 4]) for k in range(5)])
    images = []
    for k, frame in enumerate(frames):
        images.append(picture(frame).quantize(palette=palette, dither=Image.Dither.NONE))
        if progress is not None:
            progress(k, len(frames))
    plt.close(figure)
    images[0].save(path, save_all=True, append_images=images[1:], loop=0,
                   duration=round(every * 1000))  # fmt: skip


def _palette(samples: Sequence[Image.Image]) -> Image.Image:
    """One palette for every frame (a GIF holds 256 colours a frame; one palette lets it
    store only what changed), taken from a few frames side by side, no
    dither, so flat colours stay flat (median cut: it keeps near greys apart)."""
    strip = Image.new("RGB", (sum(s.width for s in samples), samples[0].height))
    for k, sample in enumerate(samples):
        strip.paste(sample, (k * sample.width, 0))
    return strip.quantize(256, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)
