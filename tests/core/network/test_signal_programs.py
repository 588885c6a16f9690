"""Every SUMO signal program that reads as a time line: actuated and delay_based ones as
fixed-time (with a note), every link state, phases longer than any test-case; programs
that are no time line refused naming the types that are (tests/data/signals: a T of our
own built by netconvert with one program each)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from service.core.checker.rules import signal_facts
from service.core.errors import InvalidInput
from service.core.network import load_intersection
from service.core.network.signals import (
    GO_COLOURS,
    MAX_PHASE_DURATION,
    MAX_PHASES,
    MIN_CYCLE,
    MIN_PHASE_DURATION,
    RULE_COLOURS,
    make_program,
    program_from_document,
    program_from_xml,
)
from service.core.testcase import Signals

SIGNALS = Path(__file__).parents[2] / "data" / "signals"
STATIC_PHASES = [(20.0, "rrGGGg"), (3.0, "rrGyyy"), (15.0, "GGGrrr"), (3.0, "yyGrrr")]
INT32 = 2**31 - 1  # clingo's integers: phaseSpan's bounds in ms


def _tee(program: str) -> Path:
    return SIGNALS / f"tee-{program}.net.xml"


def _with_type(folder: Path, kind: str, phases: str | None = None, name: str = "") -> Path:
    """The actuated T with its program's type (and phases) replaced, as a file of its own
    (``name``)."""
    text = _tee("actuated").read_text().replace('type="actuated"', f'type="{kind}"')
    if phases is not None:
        start, end = text.index("<tlLogic"), text.index("</tlLogic>")
        head = text[start : text.index(">", start) + 1]
        text = text[:start] + head + phases + text[end:]
    path = folder / f"tee-{kind}{name}.net.xml"
    path.write_text(text)
    return path


def test_an_actuated_program_is_read_as_fixed_time_with_a_note() -> None:
    junction = load_intersection(_tee("actuated"))
    program = junction.signals
    assert program is not None and junction.signals_refused is None
    assert [(p.duration, p.state) for p in program.phases] == STATIC_PHASES  # not minDur
    assert program.note is not None
    assert "actuated program '0' read as fixed-time" in program.note
    assert "minDur and maxDur" in program.note
    assert program.to_document()["note"] == program.note


def test_a_delay_based_program_is_read_as_fixed_time(tmp_path: Path) -> None:
    program = load_intersection(_with_type(tmp_path, "delay_based")).signals
    assert program is not None and program.note is not None
    assert "delay_based program '0' read as fixed-time" in program.note


@pytest.mark.parametrize("kind", ["NEMA", "off", "rail_signal"])
def test_a_program_that_is_no_time_line_is_refused_naming_the_types(
    kind: str, tmp_path: Path
) -> None:
    junction = load_intersection(_with_type(tmp_path, kind))
    assert junction.signals is None and junction.signals_refused is not None
    assert f"is of type {kind!r}, which scengen cannot read as a time line" in (
        junction.signals_refused
    )
    assert "it reads types static, actuated, delay_based" in junction.signals_refused
    assert "--signals FILE" in junction.signals_refused


def test_phases_that_choose_their_successor_are_refused(tmp_path: Path) -> None:
    phases = ('<phase duration="20" minDur="5" maxDur="40" state="rrGGGg" next="0 2"/>'
              '<phase duration="3" state="rrGyyy"/><phase duration="15" state="GGGrrr"/>'
              '<phase duration="3" state="yyGrrr" next="0"/>')  # fmt: skip
    refused = load_intersection(_with_type(tmp_path, "actuated", phases)).signals_refused
    assert refused is not None and "phase 0 names its successors (next 0 2)" in refused


def test_a_next_that_is_the_following_phase_is_a_cycle(tmp_path: Path) -> None:
    phases = ('<phase duration="20" state="rrGGGg" next="1"/><phase duration="3" '
              'state="rrGyyy"/><phase duration="15" state="GGGrrr"/>'
              '<phase duration="3" state="yyGrrr" next="0"/>')  # fmt: skip
    program = load_intersection(_with_type(tmp_path, "static", phases)).signals
    assert program is not None and program.note is None


def test_a_static_program_has_no_note_and_its_document_is_unchanged() -> None:
    program = load_intersection(_tee("major-yellow")).signals
    assert program is not None and program.note is None
    assert list(program.to_document()) == ["tls", "program", "offset", "phases"]


def test_a_signals_file_of_an_actuated_program_is_read_with_a_note() -> None:
    text = (SIGNALS / "tee-actuated.tll.xml").read_text()
    program = program_from_xml(text, "tee-actuated.tll.xml")
    assert [(p.duration, p.state) for p in program.phases] == STATIC_PHASES
    assert program.note is not None and "signals file tee-actuated.tll.xml's actuated" in (
        program.note
    )
    with pytest.raises(InvalidInput, match="of type 'NEMA', which scengen cannot read"):
        program_from_xml(text.replace("actuated", "NEMA"), "n.xml")


def test_the_note_survives_the_document_and_the_model() -> None:
    program = load_intersection(_tee("actuated")).signals
    assert program is not None
    document = json.loads(json.dumps(program.to_document()))
    assert program_from_document(document) == program
    assert Signals.model_validate(document).to_program() == program


@pytest.mark.parametrize("colour", list("rRyYgGsuoO"))
def test_every_sumo_link_state_is_understood(colour: str) -> None:
    """SUMO's r y Y g G s u o O (R is none of them)."""
    phases = [(10.0, colour + "r"), (5.0, "rG")]
    if colour == "R":
        with pytest.raises(InvalidInput, match="unknown colours 'R'"):
            make_program("J", "0", 0.0, phases)
        return
    program = make_program("J", "0", 0.0, phases)
    assert program.colour(0, 1.0) == colour
    expected = {"r": "red", "u": "red", "y": "yellow", "Y": "yellow", "g": "permissive",
                "o": "permissive", "G": "green", "O": "green", "s": "redTurn"}  # fmt: skip
    assert RULE_COLOURS[colour] == expected[colour]
    assert (colour in GO_COLOURS) == (colour not in "ru")


def test_the_off_program_reads_off_links_by_the_junctions_priority() -> None:
    """tee-off: the through road (O) has priority as under a protected green, the stem and
    the left turn off the through road (o) yield as under a permissive green."""
    junction = load_intersection(_tee("off"))
    assert junction.signals is not None
    colours = {r.id: junction.signal_colour(r, 1.0) for r in junction.routes.values()}
    assert colours == {"A2J_0:J2B_0": "O", "B2J_0:J2A_0": "O", "B2J_0:J2N_0": "O",
                       "A2J_0:J2N_0": "o", "N2J_0:J2A_0": "o", "N2J_0:J2B_0": "o"}  # fmt: skip


def test_a_phase_longer_than_the_test_case_is_fine() -> None:
    junction = load_intersection(_tee("long-phase"))
    program = junction.signals
    assert program is not None and junction.signals_refused is None
    assert program.phases[2].duration == 10000.0 and program.cycle == 10021.0
    assert program.timeline(3, 20.0) == [(0.0, 18.0, "r"), (18.0, 20.0, "G")]
    assert Signals.model_validate(program.to_document()).to_program() == program


def test_the_longest_phase_keeps_phase_spans_within_clingos_integers(tmp_path: Path) -> None:
    """A phase of MAX_PHASE_DURATION at either side of a 600 s test-case: every phaseSpan
    bound fits a 32-bit integer of ms; a longer phase is refused."""
    longest = int(MAX_PHASE_DURATION)
    for offset in (0, -longest + 1):
        phases = (f'<phase duration="{longest}" state="GGGrrr"/>'
                  '<phase duration="3" state="yyGrrr"/><phase duration="20" state="rrGGGg"/>'
                  '<phase duration="3" state="rrGyyy"/>')  # fmt: skip
        path = _with_type(tmp_path, "static", phases, name=str(offset))
        path.write_text(path.read_text().replace('offset="0"', f'offset="{offset}"', 1))
        junction = load_intersection(path)
        spans = [f for f in signal_facts(junction, 600.0) if f.name == "phaseSpan"]
        assert spans and all(abs(a.number) <= INT32 for f in spans for a in f.arguments[1:])
    with pytest.raises(InvalidInput, match=r"phases.0.duration is 1e\+06"):
        make_program("J", "0", 0.0, [(MAX_PHASE_DURATION + 1, "G")])


def test_a_program_at_its_bounds_is_read_and_one_past_them_is_not() -> None:
    """The shortest phase is SUMO's step, the shortest cycle a second, MAX_PHASES phases at
    most; each bound is valid, anything past it is refused naming the phase and the bound,
    and too many phases are one problem, not one per phase."""
    shortest = [(MIN_PHASE_DURATION, "G")] * round(MIN_CYCLE / MIN_PHASE_DURATION)
    assert make_program("J", "0", 0.0, shortest).cycle == pytest.approx(MIN_CYCLE)
    assert len(make_program("J", "0", 0.0, [(1.0, "G")] * MAX_PHASES).phases) == MAX_PHASES
    Signals.model_validate(make_program("J", "0", -1e6, shortest).to_document())
    with pytest.raises(InvalidInput, match=r"phases.3.duration is 0.099 s; a phase lasts from 0.1"):
        make_program("J", "0", 0.0, [(1.0, "G")] * 3 + [(0.099, "G")])
    with pytest.raises(InvalidInput, match=r"the cycle .* is 0.9 s; a cycle lasts at least 1 s"):
        make_program("J", "0", 0.0, [(0.3, "G")] * 3)
    with pytest.raises(InvalidInput) as many:
        make_program("J", "0", 0.0, [(0.001, "G")] * 1000)
    assert str(many.value) == "traffic-light program of 'J': phases: 1000 phases, at most 64"
    with pytest.raises(InvalidInput, match=r"offset is 1e\+300 s; an offset is from -1e\+06"):
        make_program("J", "0", 1e300, [(1.0, "G")])
