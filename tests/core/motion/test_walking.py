"""Step 1 for people on foot: libsumo walks each pedestrian over its own crossing, from its
start distance before it, at the pace, for as long as the test-case lasts (real SUMO)."""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import pytest
from shapely.geometry import Point

from service.core.errors import InvalidInput
from service.core.motion.events import EventKind, pedestrian_events
from service.core.motion.walking import walk_tracks
from service.core.network import Intersection, load_intersection
from tests.conftest import TOWN05

LENGTH, WIDTH, PACE = 0.215, 0.478, 1.3
JUNCTIONS = Path(__file__).parents[2] / "data" / "junctions"


@pytest.fixture(scope="module")
def skewed() -> Intersection:
    """The bundled all-way stop with crosswalks, whose east arm is 25 degrees off."""
    return load_intersection("crosswalk-stop")


@pytest.fixture(scope="module")
def y_shaped() -> Intersection:
    return load_intersection(JUNCTIONS / "y-crosswalk.net.xml")


def _entered(junction: Intersection, walk: str, track_samples: list) -> float:  # type: ignore[type-arg]
    events = pedestrian_events(track_samples, LENGTH, WIDTH, junction, walk, 1.0, 0.1)
    (entered,) = [e for e in events if e.kind is EventKind.ENTERED]
    return entered.distance


@pytest.mark.parametrize("network", ["skewed", "y_shaped"])
def test_every_walk_goes_over_its_crossing_from_its_start(
    network: str, request: pytest.FixtureRequest
) -> None:
    junction: Intersection = request.getfixturevalue(network)
    walks = sorted(junction.walks.values(), key=lambda w: w.id)
    tracks = walk_tracks(junction, [(w, 4.0) for w in walks], PACE, 20.0, 0.1, LENGTH, WIDTH)
    for walk, track in zip(walks, tracks, strict=True):
        samples = list(track.samples)
        # it steps onto its crossing after the 4 m of path it starts with (a step's grid)
        assert _entered(junction, walk.id, samples) == pytest.approx(4.0, abs=PACE * 0.1)
        # at the pace, every step, for the whole duration (the sidewalks go on)
        assert samples[-1].t >= 20.0 and track.road == math.inf
        steps = [b.distance - a.distance for a, b in itertools.pairwise(samples)]
        assert max(abs(s - PACE * 0.1) for s in steps) < 1e-6
        # and over the crossing it is given: off it at its far curb, along its heading
        crossing = junction.crossings[walk.crossing]
        on = [s for s in samples if crossing.polygon.contains(Point(s.x, s.y))]
        assert on, walk.id
        far = walk.path.coords[-1]
        assert math.dist((on[-1].x, on[-1].y), far) < crossing.width


def test_a_start_further_back_than_the_sidewalk_goes_is_refused(skewed: Intersection) -> None:
    walk = skewed.walk("C_c0-")
    with pytest.raises(InvalidInput, match="further back than its sidewalk goes"):
        walk_tracks(skewed, [(walk, 400.0)], PACE, 20.0, 0.1, LENGTH, WIDTH)


def test_walks_to_and_from_traffic_islands_are_walked_along_their_crossing(
    tmp_path: Path,
) -> None:
    """Town05 junction 2014 with guessed crossings has islands: no sidewalk leads onto them,
    so those walks go straight along the crossing's line (SUMO makes no such walk)."""
    junction = load_intersection(TOWN05, "2014", cache_dir=tmp_path, guess_crossings=True)
    islands = [w for w in junction.walks.values()
               if not w.before or w.after == junction.crossings[w.crossing].lane]  # fmt: skip
    assert islands
    tracks = walk_tracks(junction, [(w, 3.0) for w in islands], PACE, 15.0, 0.1, LENGTH, WIDTH)
    for walk, track in zip(islands, tracks, strict=True):
        samples = list(track.samples)
        assert _entered(junction, walk.id, samples) == pytest.approx(3.0, abs=PACE * 0.1)
        assert all(abs(s.heading - walk.heading) < 1e-6 for s in samples)
