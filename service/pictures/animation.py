"""A test-case's road users moving, as a GIF: the map of the static picture with each
car's rectangle and id, each pedestrian's disc and id, and each signal head in its
colour, a frame every half second."""

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
from matplotlib.colors import to_rgb
from matplotlib.figure import Figure
from matplotlib.text import Annotation
from PIL import Image

from service.core.checker.check import EGO, until_goal
from service.core.motion.events import rectangles
from service.core.motion.poses import PoseSample
from service.core.network import Intersection
from service.core.network.signals import COLOUR_WORDS
from service.core.testcase import TestCase
from service.pictures.junction import draw_roads, draw_stop_lines, frame_map, sign_legend
from service.pictures.labels import GAP, LabelPlacer, Spot
from service.pictures.pedestrians import (
    GIF_DISC,
    crosswalk_handles,
    draw_crosswalks,
    draw_pavements,
    walker_artist,
    walkers,
)
from service.pictures.plot import (
    CAR_COLOURS,
    DrawnPath,
    car_spot,
    normal,
    picture_title,
    queue_leaders,
)
from service.pictures.signals import (
    MARK,
    SIGNAL_COLOURS,
    UNKNOWN,
    SignalHeads,
    colour_handles,
    signalized,
)

DPI = 100
Frame = Callable[[int], list[Any]]  # draws sample k of every car; the artists it changed


def _animated_cars(
    testcase: TestCase, intersection: Intersection, ego: Sequence[PoseSample], ego_label: str
) -> list[DrawnPath]:
    """What the animation moves: every non-ego, and the ego (an evaluation's trajectory,
    which ends where the replay's ego left, else the solvability certificate until its
    goal): once its test is over, the ego is gone."""
    cars: list[DrawnPath] = []
    for k, nonego in enumerate(testcase.nonegos):
        samples = [PoseSample(**s.model_dump()) for s in nonego.trajectory]
        cars.append((nonego.id, nonego.id, CAR_COLOURS[k % len(CAR_COLOURS)], samples,
                     nonego.length, nonego.width))  # fmt: skip
    if not ego and testcase.certificates is not None:
        certificate = [PoseSample(**s.model_dump()) for s in testcase.certificates.solvability]
        ego = until_goal(testcase, certificate, intersection)
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
    rectangle and each pedestrian's disc (crosswalks drawn as in the static picture), with
    its id beside it, inside the map and over no other id, road user or signal head; one
    out of view has no id, one whose trajectory has ended is gone; at a signalized junction
    each head in its colour at the frame's time (over the road users) and the ego's signal
    beside the clock. The artists that change are animated: a frame draws only them."""
    cars = _animated_cars(testcase, intersection, ego, ego_label)
    people = walkers(testcase)
    queues = queue_leaders(testcase, intersection)
    figure, axes = plt.subplots(figsize=(7.5, 8.2), dpi=DPI)
    draw_roads(axes, intersection)
    draw_pavements(axes, intersection)
    draw_crosswalks(axes, intersection)
    draw_stop_lines(axes, intersection)
    sign_legend(axes, intersection)
    starts = [samples[0] for _, _, _, samples, _, _ in cars if samples]
    frame_map(axes, intersection, starts + [p.samples[0] for p in people if p.samples])
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
    discs = []
    for person in people:
        label = axes.annotate(person.id, (0.0, 0.0), xytext=(0.0, 0.0), fontsize=8,
                              textcoords="offset points", color=person.colour, zorder=6,
                              ha="center", va="center", annotation_clip=False, visible=False,
                              animated=True)  # fmt: skip
        discs.append((walker_artist(axes, person), label))
    heads = SignalHeads(axes, intersection, animated=True)
    handles, labels = axes.get_legend_handles_labels()
    walking, names = crosswalk_handles(intersection)
    more, words = colour_handles(heads.colours_used())  # the signals' colours last
    axes.legend(handles + walking + more, labels + names + words, loc="upper center",
                bbox_to_anchor=(0.5, -0.09), ncol=2, fontsize=7)  # fmt: skip
    axes.set_title(picture_title(testcase), pad=20)
    ego_route = intersection.route(testcase.ego.route.id)
    lit = heads.points()
    clock = axes.text(0.5, 1.01, "", transform=axes.transAxes, ha="center", va="bottom",
                      animated=True)  # fmt: skip
    figure.tight_layout()

    def draw(frame: int) -> list[Any]:
        t = round(frame * testcase.timestep, 9)  # 20.0 s, not 19.999999999999996 s
        colour = intersection.signal_colour(ego_route, t)
        ego_signal = f" · ego's signal: {COLOUR_WORDS[colour]}" if colour else ""
        clock.set_text(f"t = {t:4.1f} s{ego_signal}")
        lights = heads.show(t)
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
            spot = car_spot(s, length, width, "left")
            shown.append((label, s, spot, _covering(s, length, width)))
        for (disc, label), person in zip(discs, people, strict=True):
            label.set_visible(False)
            if frame >= len(person.samples):  # her trajectory has ended: she is gone
                disc.set_data([], [])
                continue
            s = person.samples[frame]
            disc.set_data([s.x], [s.y])
            spot = car_spot(s, person.length, person.width, "left")
            spot = Spot(spot.anchor, spot.directions, [0.0] * len(spot.metres),
                        GAP + GIF_DISC / 2.0)  # fmt: skip
            shown.append((label, s, spot, np.array([[s.x, s.y]])))
        _place_car_labels(axes, shown, lit)
        moving = [p for pair in [*patches, *discs] for p in pair]
        return [clock, *moving, *lights]  # lights over road users

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


Shown = tuple[Annotation, PoseSample, Spot, np.ndarray]  # label, pose, where, cover


def _place_car_labels(axes: Axes, shown: Sequence[Shown], lights: np.ndarray) -> None:
    """Each road user's id beside it (``Spot``) where it is in view and there is room,
    over no other road user and no signal head (``lights``: points that cover the
    heads)."""
    low_x, high_x = axes.get_xlim()
    low_y, high_y = axes.get_ylim()
    covered = np.vstack([points for *_, points in shown]) if shown else None
    if len(lights):  # a signal head is not to be hidden either
        covered = lights if covered is None else np.vstack([covered, lights])
    placer = LabelPlacer(axes, covered)
    for label, s, spot, _ in shown:
        if not (low_x <= s.x <= high_x and low_y <= s.y <= high_y):
            continue  # out of view: its id would hang over the axis numbers
        label.xy = (s.x, s.y)
        label.set_visible(True)  # an invisible text has no size to place
        label.set_visible(placer.place(label, spot))


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

    shown = {*SIGNAL_COLOURS.values(), UNKNOWN, MARK}  # kept exact: no frame mixes them up
    exact = sorted(shown) if signalized(intersection) else []
    palette = _palette([picture(frames[k * (len(frames) - 1) // 4]) for k in range(5)], exact)
    images = []
    for k, frame in enumerate(frames):
        images.append(picture(frame).quantize(palette=palette, dither=Image.Dither.NONE))
        if progress is not None:
            progress(k, len(frames))
    plt.close(figure)
    images[0].save(path, save_all=True, append_images=images[1:], loop=0,
                   duration=round(every * 1000))  # fmt: skip


def _palette(samples: Sequence[Image.Image], exact: Sequence[str] = ()) -> Image.Image:
    """One palette for every frame (a GIF holds 256 colours a frame; one palette lets it
    store only what changed), taken from a few frames side by side, no
    dither, so flat colours stay flat (median cut: it keeps near greys apart). The
    ``exact`` colours are in it as they are, alone in their neighbourhood (PIL maps a
    pixel to the entry nearest its 4x4x4 cell of colours, EXACT_ROOM wide): a signal keeps
    its colour in every frame, shown in a sampled one or not."""
    strip = Image.new("RGB", (sum(s.width for s in samples), samples[0].height))
    for k, sample in enumerate(samples):
        strip.paste(sample, (k * sample.width, 0))
    palette = strip.quantize(
        256 - len(exact), method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE
    )
    if exact:
        wanted = np.array([[round(v * 255) for v in to_rgb(c)] for c in exact], dtype=float)
        found = np.array(palette.getpalette(), dtype=float).reshape(-1, 3)
        near = np.linalg.norm(found[:, None, :] - wanted[None, :, :], axis=2).min(axis=1)
        kept = np.vstack([found[near >= EXACT_ROOM], wanted]).astype(int)
        palette.putpalette(kept.ravel().tolist())
    return palette


EXACT_ROOM = 12.0  # RGB distance from an exact colour to any other entry: twice a cell's
# diagonal (3 * sqrt(3)) and more, so that no other entry is nearer any pixel of its cell
