"""Two real cities' networks as they are (issue 45): a cut of Nuremberg (built from
OpenStreetMap by its author) and West Oakland (OpenStreetMap, built with the options of
SUMO's OSM web wizard): every node is described or refused with a one-line reason, and every
junction works under its own control type, yield signs and actuated lights included, without
--control or --signals (tests/data/osm/README.md)."""

from __future__ import annotations

import json
from collections import Counter
from pathlib import Path

import pytest
import sumolib

from service import cli
from tests.cli.test_real_maps import _outcome
from tests.conftest import DATA

NUREMBERG = DATA / "osm" / "nuremberg-west.net.xml"
OAKLAND = DATA / "osm" / "west-oakland.net.xml"


@pytest.fixture
def private_cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    return tmp_path


@pytest.mark.parametrize(
    ("city", "types"),
    [
        (NUREMBERG, {"priority": 2, "right_before_left": 1, "traffic_light": 1}),
        (OAKLAND, {"priority": 10, "traffic_light": 1}),
    ],
    ids=["Nuremberg", "West-Oakland"],
)
def test_every_node_of_a_city_is_described_or_refused(
    city: Path, types: dict[str, int], private_cache: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`intersection` on every node under the map's own control: a junction of three or
    more car roads is described (its yield signs on the minor road; its actuated light read
    as fixed-time, said in one note), and `new` makes a test-case on its first route; any
    other node is refused in one line that names the roads leading into it."""
    net = sumolib.net.readNet(str(city))
    described: Counter[str] = Counter()
    for node in sorted(str(n.getID()) for n in net.getNodes()):
        flags = [str(city), "--junction", node]
        code = cli.main(["intersection", *flags, "--json"])
        out, err = capsys.readouterr()
        if _outcome(code, err) == "refused":
            assert "is not a junction to test:" in err and "lead" in err, err
            continue
        description = json.loads(out)
        control = description["control"]
        described[control] += 1
        assert not description["control_overridden"]
        yielding = {f["edge"] for f in description["forks"] if f["yield_sign"]}
        assert bool(yielding) == (control == "priority"), node
        longer: list[str] = []
        if control == "traffic_light":
            assert "the network's actuated program '0' read as fixed-time" in err
            longer = ["--duration", f"{description['signals']['cycle'] + 1:g}"]
        route = description["routes"][0]["id"]
        assert cli.main(["new", *flags, f"--ego={route}", *longer]) == 0, capsys.readouterr()
        made = json.loads(capsys.readouterr().out)
        assert (made["control"], made["ego"]["route"]["fork"]) == (control, route.split(":")[0])
    assert described == types
