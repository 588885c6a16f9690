"""Real maps' signal programs on the command line without --signals: `intersection`,
`new` and `extend` on an actuated program (said on stderr, kept in the document), SUMO's
Y and u, a 10,000 s phase and a program switched off (o and O) (tests/data/signals)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from service import cli
from service.core.testcase import read_testcase
from tests.conftest import DATA

SIGNALS = DATA / "signals"
NOTE = "scengen: note: traffic light 'J': the network's actuated program '0' read as fixed-time"
# (program, ego, a new car whose extension exists)
CASES = [
    ("actuated", "N2J_0:J2A_0", "B2J_0:J2A_0"),
    ("major-yellow", "A2J_0:J2N_0", "B2J_0:J2A_0"),
    ("long-phase", "A2J_0:J2N_0", "B2J_0:J2A_0"),  # both enter in the 10,000 s phase
    ("off", "N2J_0:J2A_0", "B2J_0:J2A_0"),
]


@pytest.mark.parametrize(("program", "ego", "route"), CASES, ids=[c[0] for c in CASES])
def test_intersection_new_and_extend_take_the_networks_program(
    program: str, ego: str, route: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    network = str(SIGNALS / f"tee-{program}.net.xml")
    assert cli.main(["intersection", network]) == 0
    captured = capsys.readouterr()
    assert "traffic light J  program 0" in captured.out
    assert (NOTE in captured.err) == (program == "actuated")
    root, level1 = tmp_path / "root.json", tmp_path / "level1.json"
    assert cli.main(["new", network, "--ego", ego, "--duration", "30", "-o", str(root)]) == 0
    assert (NOTE in capsys.readouterr().err) == (program == "actuated")
    signals = json.loads(root.read_text())["signals"]
    assert ("note" in signals) == (program == "actuated")
    assert cli.main(["extend", str(root), "--add", route, "-o", str(level1)]) == 0
    extended = read_testcase(level1)
    assert extended.signals == read_testcase(root).signals  # the note too
    assert extended.provenance is not None and extended.provenance["level"] == 1


def test_signals_still_overrides_an_actuated_program(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    program = tmp_path / "mine.json"
    program.write_text(json.dumps({"tls": "J", "program": "mine", "phases": [
        {"duration": 10, "state": "GGGrrr"}, {"duration": 3, "state": "yyGrrr"},
        {"duration": 20, "state": "rrGGGg"}, {"duration": 3, "state": "rrGyyy"}]}))  # fmt: skip
    out = tmp_path / "t.json"
    assert cli.main(["new", str(SIGNALS / "tee-actuated.net.xml"), "--ego", "N2J_0:J2A_0",
                     "--signals", str(program), "-o", str(out)]) == 0  # fmt: skip
    assert NOTE not in capsys.readouterr().err
    signals = read_testcase(out).signals
    assert signals is not None and signals.program == "mine" and signals.note is None
