"""Real maps through the command line: --major, the automatic start, side lanes, and every
junction of CARLA's Town05 and Town07 under every control type (works, or exit 2 with a
one-line reason; never a traceback)."""

from __future__ import annotations

import json
from collections import Counter
from pathlib import Path

import pytest
import sumolib

from service import cli
from service.core.network import load_intersection
from tests.conftest import TOWN05, TOWN07
from tests.core.network.test_forks import entered

pytestmark = pytest.mark.slow  # 14 s of work or more: `make test-fast` leaves it out

CONTROLS = (None, "allway_stop", "priority_stop", "right_before_left")


@pytest.fixture
def private_cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    return tmp_path


def test_major_names_the_road_that_keeps_the_right_of_way(
    private_cache: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    junction = [str(TOWN05), "--junction", "1882", "--control", "priority_stop"]
    assert cli.main(["intersection", *junction]) == 0
    assert "major road -45 46 (the roads closest to straight across" in capsys.readouterr().out
    assert cli.main(["intersection", *junction, "--major", "46,4", "--json"]) == 0
    described = json.loads(capsys.readouterr().out)
    assert described["major_road"] == ["46", "4"]
    assert {f["edge"] for f in described["forks"] if f["stop_sign"]} == {"-45"}
    made = private_cache / "t0.json"
    assert (
        cli.main(["new", *junction, "--major", "46,4", "--ego=-45_0:-46_0", "-o", str(made)]) == 0
    )
    assert json.loads(made.read_text())["major_road"] == ["46", "4"]
    # a later command rebuilds the same network from the test-case
    assert cli.main(["drive", str(made), "--network", str(TOWN05)]) == 0
    capsys.readouterr()
    assert cli.main(["intersection", *junction, "--major", "46,45"]) == 2
    assert "'45' is not a road into junction '1882'; roads into it: -45, 4, 46" in (
        capsys.readouterr().err
    )


def test_major_is_two_edges_and_not_for_a_campaign(
    private_cache: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as usage:
        cli.main(["intersection", "t-stop", "--major", "S2C"])
    assert usage.value.code == 2
    assert "two edge ids separated by a comma (EDGE,EDGE), not 'S2C'" in capsys.readouterr().err
    with pytest.raises(SystemExit) as usage:
        cli.main(["campaign", "t-stop", "--major", "S2C,E2C", "--ego", "S2C_0:C2E_0",
                  "--depth", "1", "--chains", "1", "--controller", "sumo",
                  "-o", str(private_cache / "c")])  # fmt: skip
    assert usage.value.code == 2 and "--major: a campaign takes" in capsys.readouterr().err


def test_new_fits_its_automatic_start_and_says_so(
    private_cache: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    junction = [str(TOWN07), "--junction", "725", "--control", "allway_stop"]
    assert cli.main(["new", *junction, "--ego=-26#1_0:14_0"]) == 0
    out, err = capsys.readouterr()
    assert json.loads(out)["ego"]["start"]["distance"] == 17.91
    assert "ego start: 17.91 m before the stop line, the whole road before fork -26#1_0" in err
    assert cli.main(["new", *junction, "--ego=-26#1_0:14_0", "--start-distance", "30"]) == 2
    assert "start distance 30 m is longer than the road" in capsys.readouterr().err


def test_intersection_lists_side_lanes_apart(
    private_cache: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert cli.main(["intersection", str(TOWN05), "--junction", "53", "--control",
                     "allway_stop"]) == 0  # fmt: skip
    out = capsys.readouterr().out
    routes, _, side = out.partition("side lanes, not offered (a route on one works when named):")
    assert "-4_0:" not in routes and "-4_0  1.39 m/s where its road allows 13.89 m/s" in side


def _a_route(net: object, node: str) -> str:
    """Some connection through ``node`` from the network itself (for junctions that are
    refused before they have routes)."""
    for edge in sorted(net.getNode(node).getIncoming(), key=lambda e: e.getID()):  # type: ignore[attr-defined]
        for lane in edge.getLanes():
            for connection in lane.getOutgoing():
                if not connection.getToLane().getID().startswith(":"):
                    return f"{lane.getID()}:{connection.getToLane().getID()}"
    return "X_0:Y_0"


def _outcome(code: int, err: str) -> str:
    """'worked', or 'refused' with exit 2 and one line naming the reason."""
    if code == 0:
        return "worked"
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and lines[0].startswith("scengen: error: "), err
    return "refused"


@pytest.mark.slow
@pytest.mark.parametrize("town", [TOWN05, TOWN07], ids=["Town05", "Town07"])
def test_every_junction_works_or_is_refused_with_a_reason(
    town: Path, private_cache: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`intersection` and `new` on every node of the map under its own control type and every
    other one: the command works, or exits 2 with a one-line reason (every junction works
    under its own type, priority ones under their yield signs, without --control); an
    exception escaping cli.main fails the test (the user would see its traceback). Where
    `intersection` works, `new` works on every route tried: under allway_stop every route
    offered and two on side lanes, named (a route, and the road before and after it, is the
    same under every control type); under the others, the first route offered. Where it
    refuses, `new` refuses too. About 25 s of CPU per town, most of it netconvert (one
    override per junction and control type, as a user's first command runs it)."""
    net = sumolib.net.readNet(str(town), withInternal=True)
    nodes = sorted(str(n.getID()) for n in net.getNodes() if n.getType() != "internal")
    outcomes: Counter[str] = Counter()
    for node in nodes:
        for control in CONTROLS:
            flags = [str(town), "--junction", node, *(["--control", control] if control else [])]
            code = cli.main(["intersection", *flags, "--json"])
            out, err = capsys.readouterr()
            outcome = _outcome(code, err)
            outcomes[f"intersection {outcome}"] += 1
            routes, longer = [_a_route(net, node)], []
            if outcome == "worked":
                outcomes["forks at their limit line"] += _limit_lines(town, node, control)
                described = json.loads(out)
                if control is None:
                    outcomes["own type worked"] += 1
                    own_type = net.getNode(node).getType()
                    assert described["control"] == own_type and not described["control_overridden"]
                    yielding = [f for f in described["forks"] if f["yield_sign"]]
                    assert bool(yielding) == (own_type == "priority"), node
                routes = [r["id"] for r in described["routes"]]
                side = sorted(s["lane"] for s in described["side_lanes"])
                forks = [lane for lane in side if _ends_at(net, lane, node)]
                routes += [f"{f}:{e}" for f in forks for e in _exits_of(net, f)][:2]
                routes = routes if control == "allway_stop" else routes[:1]
                if described["signals"]:  # a light may stay red for 20 s: a whole cycle
                    longer = ["--duration", f"{described['signals']['cycle'] + 1:g}"]
            for route in routes:
                code = cli.main(["new", *flags, f"--ego={route}", *longer])
                _, err = capsys.readouterr()
                assert _outcome(code, err) == outcome, (node, control, route, err)
                outcomes[f"new {outcome}"] += 1
    # junctions of 3+ approaches: every one works under the map's own control type too (the
    # signalized ones' programs are fixed-time; the others are of SUMO type priority, tested
    # under their yield signs), and under each of the three overrides
    junctions, own = {"Town05": (21, {"traffic_light": 15, "priority": 6}),
                      "Town07": (22, {"traffic_light": 5, "priority": 17})}[
        town.name.removesuffix(".net.xml")
    ]  # fmt: skip
    assert sum(own.values()) == junctions
    assert outcomes["own type worked"] == junctions
    assert outcomes["intersection worked"] == 4 * junctions
    assert outcomes["intersection refused"] == 4 * len(nodes) - 4 * junctions
    assert outcomes["new worked"] > 5 * junctions
    assert outcomes["forks at their limit line"] >= 3 * outcomes["intersection worked"]


@pytest.mark.parametrize(
    ("town", "node", "control"),
    [(TOWN05, "1126", None), (TOWN05, "2014", None), (TOWN07, "358", "right_before_left")],
    ids=["Town05-1126", "Town05-2014", "Town07-358"],
)
def test_guessed_crossings_on_real_junctions(
    town: Path,
    node: str,
    control: str | None,
    private_cache: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """A four-way light, a light whose median splits two roads (traffic islands) and a Y:
    with --guess-crossings every junction gets walks, its routes keep their turns on lanes
    one index up, and its limit lines still hold (before the crosswalks)."""
    flags = [str(town), "--junction", node, *(["--control", control] if control else [])]
    assert cli.main(["intersection", *flags, "--json"]) == 0
    plain = json.loads(capsys.readouterr().out)
    assert plain["walks"] == []
    assert cli.main(["intersection", *flags, "--guess-crossings", "--json"]) == 0
    guessed = json.loads(capsys.readouterr().out)
    assert guessed["crossings_guessed"] and len(guessed["walks"]) >= 6
    assert all(walk["conflicts"] for walk in guessed["walks"])
    turns = {(_up(r["fork"]), _up(r["exit"]), r["turn"]) for r in plain["routes"]}
    assert {(r["fork"], r["exit"], r["turn"]) for r in guessed["routes"]} == turns
    route = guessed["routes"][0]["id"]
    longer = ["--duration", f"{guessed['signals']['cycle'] + 1:g}"] if guessed["signals"] else []
    made = private_cache / "t.json"
    assert cli.main(["new", *flags, "--guess-crossings", f"--ego={route}", *longer,
                     "-o", str(made)]) == 0  # fmt: skip
    assert json.loads(made.read_text())["crossings_guessed"] is True
    intersection = load_intersection(town, node, control, guess_crossings=True)
    for fork in intersection.forks.values():
        assert not entered(fork, 0.3) and entered(fork, -0.2), (node, fork.lane)


def _up(lane: str) -> str:
    edge, _, index = lane.rpartition("_")
    return f"{edge}_{int(index) + 1}"


def _limit_lines(town: Path, node: str, control: str | None) -> int:
    """Every fork's limit line is its own end (no light of either town controls the node
    before a fork), and the model's entry is at it: a car 0.3 m before the line has not
    entered (where the road bends at the line a corner of the car crosses it a few
    centimetres first), 0.2 m past it has (tests/core/network/test_forks.py drives SUMO's
    driver to these lines). The model is the one the command just loaded (cached)."""
    intersection = load_intersection(town, node, control)
    for fork in intersection.forks.values():
        assert (fork.limit_lane, fork.limit_offset) == (fork.lane, 0.0), (node, control)
        assert not entered(fork, 0.3) and entered(fork, -0.2), (node, control, fork.lane)
    return len(intersection.forks)


def _ends_at(net: object, lane: str, node: str) -> bool:
    return bool(net.getLane(lane).getEdge().getToNode().getID() == node)  # type: ignore[attr-defined]


def _exits_of(net: object, lane: str) -> list[str]:
    found = net.getLane(lane).getOutgoing()  # type: ignore[attr-defined]
    return sorted(c.getToLane().getID() for c in found if not c.getToLane().getID().startswith(":"))
