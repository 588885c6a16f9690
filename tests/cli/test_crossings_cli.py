"""Walks through the command line: `intersection` lists them (text and --json), says how to
add crossings where there are none, and --guess-crossings travels from `new` in the
test-case (crossings_guessed) to every later command."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from service import cli
from service.core.testcase import read_testcase

WALK_KEYS = {
    "id", "crossing", "from", "to", "before", "after", "heading", "length", "width",
    "conflicts", "signal",
}  # fmt: skip


@pytest.fixture
def private_cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    return tmp_path


def test_intersection_json_lists_the_walks_with_their_signal(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert cli.main(["intersection", "crosswalk-signal", "--json"]) == 0
    described = json.loads(capsys.readouterr().out)
    assert described["crossings_guessed"] is False
    walks = {w["id"]: w for w in described["walks"]}
    assert list(walks) == [f"C_c{k}{d}" for k in range(4) for d in "+-"]
    north = walks["C_c0+"]
    assert set(north) == WALK_KEYS
    assert north | {"conflicts": None} == north | {
        "crossing": ":C_c0", "from": ":C_w1", "to": ":C_w0", "before": "E2C_0",
        "after": "C2W_0", "heading": 270.0, "length": 12.8, "width": 4.0, "conflicts": None,
        "signal": {"link_index": 16, "timeline": [
            [0.0, 25.0, "r"], [25.0, 40.0, "G"], [40.0, 45.0, "y"], [45.0, 50.0, "r"]]},
    }  # fmt: skip
    assert north["conflicts"] == sorted(north["conflicts"])
    assert {r.split(":")[0][:3] for r in north["conflicts"]} >= {"N2C"}
    assert all(r.startswith("N2C") or r.endswith(("C2N_1", "C2N_2")) for r in north["conflicts"])
    assert walks["C_c0-"]["from"] == ":C_w0" and walks["C_c0-"]["heading"] == 90.0


def test_intersection_table_shows_walks_and_their_colours(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert cli.main(["intersection", "crosswalk-signal"]) == 0
    out = capsys.readouterr().out
    assert re.search(
        r"^C_c1\+ +:C_c1 +:C_w2 \(S2C_0\) +:C_w1 \(C2N_0\) +12\.80 +4\.00 +E2C_1:C2N_1 ",
        out,
        re.MULTILINE,
    )
    assert re.search(r"^C_c1\+ +17 +0: G  15: y  20: r$", out, re.MULTILINE)
    assert "pedestrian signals: G or g walk, y flashing don't walk" in out


def test_a_junction_without_crossings_says_how_to_add_them(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert cli.main(["intersection", "4way-stop"]) == 0
    assert (
        "no pedestrian crossings: add sidewalks and crossings with --guess-crossings "
        "(car lane indices then move up by one)"
    ) in capsys.readouterr().out
    assert cli.main(["intersection", "4way-stop", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["walks"] == []


def test_guess_crossings_from_new_to_drive(
    private_cache: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert cli.main(["intersection", "4way-stop", "--guess-crossings", "--json"]) == 0
    described = json.loads(capsys.readouterr().out)
    assert described["crossings_guessed"] and not described["control_overridden"]
    assert len(described["walks"]) == 8
    assert {r["fork"][-1] for r in described["routes"]} == {"1", "2"}  # lane 0: sidewalk
    made = private_cache / "guessed.json"
    ego = "--ego=S2C_2:C2W_2"
    assert cli.main(["new", "4way-stop", "--guess-crossings", ego, "-o", str(made)]) == 0
    document = json.loads(made.read_text())
    assert document["crossings_guessed"] is True
    assert read_testcase(made).crossings_guessed
    capsys.readouterr()
    assert cli.main(["drive", str(made), "--json"]) == 0  # rebuilt from the test-case
    drive = json.loads(capsys.readouterr().out)
    assert any(e["lane"] == "C2W_2" or e["kind"] == "exited" for e in drive["events"])
    plain = private_cache / "plain.json"
    assert cli.main(["new", "4way-stop", "--ego=S2C_1:C2W_1", "-o", str(plain)]) == 0
    assert "crossings_guessed" not in json.loads(plain.read_text())


def test_a_route_of_the_network_without_crossings_says_the_lanes_moved(
    private_cache: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert cli.main(["new", "4way-stop", "--guess-crossings", "--ego=S2C_1:C2W_1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("scengen: error: no connection from fork")
    assert err[0].endswith(
        "(with guessed crossings the sidewalk is lane 0: every car lane's index is one "
        "higher than on the network without them)"
    )


def test_a_campaign_refuses_guessed_crossings(
    private_cache: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as usage:
        cli.main(["campaign", "4way-stop", "--guess-crossings", "--ego", "S2C_2:C2W_2",
                  "--depth", "1", "--chains", "1", "--controller", "sumo", "-o",
                  str(private_cache / "c")])  # fmt: skip
    assert usage.value.code == 2
    assert "--guess-crossings: a campaign grows cars only" in capsys.readouterr().err
