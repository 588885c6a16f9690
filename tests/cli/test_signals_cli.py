"""Signalized junctions on the command line: `new` and `intersection` with a program of
one's own (a SUMO file or scengen's JSON), and every kind of bad program refused before
any work with one line and exit 2."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from service import cli
from service.core.network import bundled_networks
from service.core.testcase import read_testcase
from tests.conftest import TOWN05

# the bundled four-way's program with other durations and an offset (16 links)
PHASES = [(15, "GGGgrrrrGGGgrrrr"), (4, "yyyyrrrryyyyrrrr"), (1, "r" * 16),
          (15, "rrrrGGGgrrrrGGGg"), (4, "rrrryyyyrrrryyyy"), (1, "r" * 16)]  # fmt: skip


def sumo_file(folder: Path, name: str, tls: str = "C", kind: str = "static",
              phases: list[tuple[int, str]] = PHASES) -> Path:  # fmt: skip
    """An additional file with one tlLogic, as a SUMO user writes it."""
    rows = "".join(f'<phase duration="{d}" state="{s}"/>' for d, s in phases)
    path = folder / name
    path.write_text(f'<additional><tlLogic id="{tls}" type="{kind}" programID="alt" '
                    f'offset="5">{rows}</tlLogic></additional>')  # fmt: skip
    return path


def json_file(folder: Path, name: str, **changes: object) -> Path:
    """The test-case's signals field as a file."""
    document = {"tls": "C", "program": "mine", "offset": 0,
                "phases": [{"duration": d, "state": s} for d, s in reversed(PHASES)]}  # fmt: skip
    path = folder / name
    path.write_text(json.dumps(document | changes))
    return path


def new(*args: str) -> int:
    return cli.main(["new", "4way-signal", "--ego", "S2C_1:C2W_1", *args])


def test_new_takes_a_sumo_program_or_a_json_one(tmp_path: Path) -> None:
    assert new("-o", str(tmp_path / "network.json")) == 0
    assert new("--signals", str(sumo_file(tmp_path, "alt.add.xml")),
               "-o", str(tmp_path / "xml.json")) == 0  # fmt: skip
    # reversed, the program shows the ego red until 21 s: 30 s leave it a green
    assert new("--signals", str(json_file(tmp_path, "mine.json")), "--duration", "30",
               "-o", str(tmp_path / "json.json")) == 0  # fmt: skip
    own = read_testcase(tmp_path / "network.json").signals
    xml = read_testcase(tmp_path / "xml.json").signals
    mine = read_testcase(tmp_path / "json.json").signals
    assert own is not None and (own.program, own.offset) == ("0", 0.0)  # the network's
    assert xml is not None and (xml.tls, xml.program, xml.offset) == ("C", "alt", 5.0)
    assert [(p.duration, p.state) for p in xml.phases] == PHASES
    assert mine is not None and mine.program == "mine"
    assert [(p.duration, p.state) for p in mine.phases] == PHASES[::-1]


def test_new_takes_the_junctions_light_from_a_file_of_many(tmp_path: Path) -> None:
    """A whole network holds every light's program: the junction's is taken, as by
    `intersection --signals`."""
    out = tmp_path / "t.json"
    code = cli.main(["new", str(TOWN05), "--junction", "1126", "--ego=-6_1:-47_1",
                     "--signals", str(TOWN05), "-o", str(out)])  # fmt: skip
    assert code == 0
    signals = read_testcase(out).signals
    assert signals is not None and signals.tls == "1126" and len(signals.phases[0].state) == 16


def _nema_network(folder: Path) -> Path:
    """The bundled four-way with its program's type made NEMA: a controller of its own
    kind, no time line of phases."""
    text = bundled_networks()["4way-signal"].read_text()
    assert text.count('type="static"') == 1
    path = folder / "nema.net.xml"
    path.write_text(text.replace('type="static"', 'type="NEMA"'))
    return path


ONE_PHASE = [{"duration": 9, "state": "GGGG"}]
NO_TIME = [{"duration": 0, "state": "G" * 16}]
TINY = [{"duration": 1e-6, "state": "G" * 16}]
BAD = [  # (how the program is given, what the one line says)
    (lambda d: ["--signals", str(sumo_file(d, "a.xml", kind="NEMA"))],
     "program 'alt' is of type 'NEMA', which scengen cannot read as a time line of phases; "
     "it reads types static, actuated, delay_based"),
    (lambda d: [],  # the network's own program is NEMA
     "the network's program '0' is of type 'NEMA', which scengen cannot read"),
    (lambda d: ["--signals", str(sumo_file(d, "w.xml", phases=[(9, "G" * 15), *PHASES[1:]]))],
     "phases.0.state has 15 colours where the other phases have 16"),
    (lambda d: ["--signals", str(json_file(d, "l.json", phases=ONE_PHASE))],
     "states have 4 colours, but traffic light 'C' controls 16 links (indices 0 to 15"),
    (lambda d: ["--signals", str(sumo_file(d, "c.xml", phases=[(9, "GGGGzzzzGGGGrrrr")]))],
     "unknown colours 'z'; valid colours: G protected green, g permissive green"),
    (lambda d: ["--signals", str(json_file(d, "o.json", tls="J7"))],
     "the signal program is for traffic light 'J7', but junction 'C' is controlled by"),
    (lambda d: ["--signals", str(json_file(d, "z.json", phases=NO_TIME))],
     "phases.0.duration is 0 s; a phase lasts from 0.1 s (SUMO's step) to 1e+06 s"),
    (lambda d: ["--signals", str(json_file(d, "u.json", phases=TINY))],
     "phases.0.duration is 1e-06 s; a phase lasts from 0.1 s (SUMO's step) to 1e+06 s"),
    (lambda d: ["--signals", str(json_file(d, "d.json", phases=[{**TINY[0], "duration": 5e-324}]))],
     "phases.0.duration is 4.94066e-324 s; a phase lasts from 0.1 s"),
    (lambda d: ["--signals", str(sumo_file(d, "u.xml", phases=[(0.000001, "G" * 16)]))],
     "phases.0.duration is 1e-06 s; a phase lasts from 0.1 s (SUMO's step)"),
    (lambda d: ["--signals", str(json_file(d, "s.json", phases=TINY * 1000))],
     "traffic-light program of 'C': phases: 1000 phases, at most 64"),
    (lambda d: ["--signals", str(sumo_file(d, "k.xml", phases=[(0.2, "G" * 16)] * 3))],
     "the cycle (the phases' durations added) is 0.6 s; a cycle lasts at least 1 s"),
    (lambda d: ["--signals", str(json_file(d, "f.json", offset=1e300))],
     "offset is 1e+300 s; an offset is from -1e+06 to 1e+06 s"),
    (lambda d: ["--signals", str(d / "missing.json")], "cannot read the signals file"),
]  # fmt: skip


@pytest.mark.parametrize(("given", "message"), BAD, ids=range(len(BAD)))
def test_a_bad_program_is_one_line_and_exit_2(
    given: object, message: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    options = given(tmp_path)  # type: ignore[operator]
    network = str(_nema_network(tmp_path)) if not options else "4way-signal"
    for command in ("new", "intersection"):
        ego = ["--ego", "S2C_1:C2W_1", "-o", str(tmp_path / "out.json")] if command == "new" else []
        if command == "intersection" and not options:
            continue  # intersection shows a NEMA junction, with a note (below)
        assert cli.main([command, network, *ego, *options]) == 2
        captured = capsys.readouterr()
        lines = captured.err.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("scengen: error: "), captured.err
        assert message in lines[0] and captured.out == ""
    assert not (tmp_path / "out.json").exists()


def test_signals_on_a_junction_without_lights_is_one_line_and_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    signals = str(json_file(tmp_path, "s.json"))
    assert cli.main(["new", "4way-stop", "--ego", "S2C_1:C2W_1", "--signals", signals]) == 2
    line = capsys.readouterr().err.strip()
    assert "\n" not in line and "of type allway_stop, without traffic lights" in line
    assert "traffic_light or traffic_light_right_on_red" in line  # the valid choices


def test_intersection_notes_a_program_it_cannot_use(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert cli.main(["intersection", str(_nema_network(tmp_path))]) == 0
    captured = capsys.readouterr()
    assert "control traffic_light" in captured.out
    assert "traffic light C  program" not in captured.out  # no program to show
    assert ("scengen: note: traffic light 'C': the network's program '0' is of type 'NEMA'"
            in captured.err)  # fmt: skip
    assert cli.main(["intersection", str(_nema_network(tmp_path)),
                     "--signals", str(json_file(tmp_path, "s.json"))]) == 0  # fmt: skip
    assert "traffic light C  program mine" in capsys.readouterr().out


@pytest.mark.parametrize("duration", [1e-6, 5e-324])
def test_a_document_with_a_sub_millisecond_phase_is_one_line_and_exit_2(
    duration: float, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A test-case file edited to a phase shorter than SUMO's step is refused by every
    command that reads it, before any work (it made SUMO refuse the replay: exit 3)."""
    made = tmp_path / "t0.json"
    assert new("--signals", str(sumo_file(tmp_path, "p.xml")), "-o", str(made)) == 0
    document = json.loads(made.read_text())
    document["signals"]["phases"][0]["duration"] = duration
    edited = tmp_path / "tiny.json"
    edited.write_text(json.dumps(document))
    capsys.readouterr()
    for command in (["evaluate", str(edited)], ["extend", str(edited), "--add", "N2C_0:C2S_0"]):
        assert cli.main(command) == 2, command
        captured = capsys.readouterr()
        lines = captured.err.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("scengen: error: "), captured.err
        assert "signals.phases.0.duration" in lines[0] and "0.1" in lines[0], lines[0]
