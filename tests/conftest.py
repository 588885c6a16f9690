"""Session fixtures: each network is parsed once; overridden networks go to a temp cache."""

from __future__ import annotations

from pathlib import Path

import pytest

from service.core.network import Intersection, load_intersection
from service.core.testcase import TestCase

DATA = Path(__file__).parent / "data"
TOWN05 = DATA / "carla" / "Town05.net.xml"
TOWN07 = DATA / "carla" / "Town07.net.xml"


@pytest.fixture(scope="session")
def cache_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("networks")


@pytest.fixture(scope="session")
def four_way() -> Intersection:
    return load_intersection("4way-stop")


@pytest.fixture(scope="session")
def t_stop() -> Intersection:
    return load_intersection("t-stop")


@pytest.fixture(scope="session")
def y_junction() -> Intersection:
    return load_intersection("y-uncontrolled")


@pytest.fixture(scope="session")
def skewed_yield() -> Intersection:
    """A skewed four-way junction of SUMO type priority of our own: the minor road S-N
    crosses the major road W-E at about 60 degrees, with yield signs (CVC 21803)."""
    return load_intersection(DATA / "junctions" / "skewed-yield.net.xml")


@pytest.fixture(scope="session")
def town07_y(cache_dir: Path) -> Intersection:
    """Town07's Y-shaped junction 358 (plain priority in CARLA) made uncontrolled."""
    return load_intersection(TOWN07, "358", "right_before_left", cache_dir)


@pytest.fixture(scope="session")
def town05_allway(cache_dir: Path) -> Intersection:
    """Town05's four-arm junction 396 (plain priority in CARLA) made an all-way stop."""
    return load_intersection(TOWN05, "396", "allway_stop", cache_dir)


@pytest.fixture(scope="session")
def next_junction(tmp_path_factory: pytest.TempPathFactory) -> TestCase:
    """A chain's level 1 whose car1 drives on through the next junction, where a SUMO
    driver that did not leave at its goal would stand (tests.helpers)."""
    from tests.helpers import next_junction_network, past_the_next_junction

    return past_the_next_junction(next_junction_network(tmp_path_factory.mktemp("next")))


@pytest.fixture(scope="session")
def exported_cases(tmp_path_factory: pytest.TempPathFactory, worker_id: str) -> list[TestCase]:
    """Every level of every example, a queue and two real-map chains (tests.helpers'
    every_exported_case): grown once per test run, shared by the export tests of every
    worker."""
    from service.core.testcase import network_ref
    from tests.helpers import every_exported_case
    from tests.shared import made_once

    cases = made_once("exported-cases", every_exported_case, tmp_path_factory, worker_id)
    for network in (TOWN05, TOWN07):  # the maps the worker that made them read, read here
        network_ref(network)
    return cases
