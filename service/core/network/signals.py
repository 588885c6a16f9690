"""Fixed-time traffic-light programs: SUMO's tlLogic, as a test-case carries it.

A program is a cycle of phases; each phase has a duration (s) and a state: one colour
character per link (connection) the traffic light controls, indexed by SUMO's link index.
Colours (SUMO's): ``G`` green with priority (a protected movement), ``g`` green without
priority (permissive: yield to conflicting traffic), ``y`` yellow and ``Y`` yellow with
priority (SUMO's minor and major yellow: both yellow to the rules), ``r`` red, ``u``
red-yellow (red, before green), ``s`` a green right-turn arrow that requires a stop first
(right turn on red), ``O`` signal off without blinking (the link has priority: read as
``G``) and ``o`` signal off, blinking (the link yields: read as ``g``).

Program types: SUMO's ``static`` programs are fixed-time. ``actuated`` and
``delay_based`` ones are read as fixed-time too, each phase lasting its ``duration`` (not
stretched between minDur and maxDur by detected traffic); the program keeps a ``note``
that says so. Other types (``NEMA``, a program without phases such as ``off``) are no time
line and are refused.

Time: SUMO shows the phase at program position ``(t - offset) mod cycle`` at simulation
time t (t = 0 is the test-case's start). A phase instance is one occurrence of a phase on
the test-case's time line, from its start (inclusive) to its end (exclusive).
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from defusedxml import ElementTree as SafeElementTree
from defusedxml.common import DefusedXmlException

from service.core.errors import InvalidInput
from service.core.inputs import MAX_PARAMETER_FILE_BYTES, parse_json, read_bounded

# SUMO colour -> the colour the signal rules reason with (asp/signals.lp)
RULE_COLOURS = {
    "G": "green",
    "g": "permissive",
    "y": "yellow",
    "Y": "yellow",
    "r": "red",
    "u": "red",
    "s": "redTurn",
    "O": "green",  # off, no signal: the link has priority, as under a protected green
    "o": "permissive",  # off, blinking: the link yields, as under a permissive green
}
COLOUR_WORDS = {
    "G": "protected green",
    "g": "permissive green",
    "y": "yellow",
    "Y": "yellow with priority",
    "r": "red",
    "u": "red-yellow",
    "s": "right on red after a stop",
    "O": "off (priority)",
    "o": "off, blinking (yield)",
}
VALID_COLOURS = "".join(RULE_COLOURS)
GO_COLOURS = "GgyYsOo"  # a car may enter (s: after a full stop); the rules' goColour, redTurn
# The bounds of a program, at every entry (the API's schema, --signals, a test-case
# document, a network's program): every phase lasts at least one of SUMO's default steps
# (the test-case's default timestep; a shorter phase is no signal a car can obey, and
# thousands of them per second ran plots out of memory and made SUMO refuse the replay),
# the cycle at least a second, and a program has at most MAX_PHASES phases (real maps:
# 12 at most). So a 600 s test-case has at most 6,000 phase instances.
MIN_PHASE_DURATION = 0.1  # s
MIN_CYCLE = 1.0  # s
MAX_PHASES = 64
# A phase may outlast any test-case (a road green until a pedestrian asks: 10,000 s in
# real maps). The bound keeps every phase instance's end, in ms, within clingo's 32-bit
# integers (signals.lp's phaseSpan): 1e6 s of a phase before t = 0 or after the horizon.
MAX_PHASE_DURATION = 1e6  # s
MAX_OFFSET = 1e6  # s, either way
# --signals FILE: scengen's JSON up to MAX_PARAMETER_FILE_BYTES, SUMO XML (an additional
# file, or a whole network with many lights) up to this
MAX_SIGNALS_FILE_BYTES = 64_000_000
STATIC = "static"
READ_AS_FIXED_TIME = ("actuated", "delay_based")  # phases with durations, run in order
PROGRAM_TYPES = (STATIC, *READ_AS_FIXED_TIME)


@dataclass(frozen=True)
class SignalPhase:
    duration: float  # s, positive
    state: str  # one colour per link of the traffic light


@dataclass(frozen=True)
class PhaseInstance:
    """One occurrence of a phase on the test-case's time line: [start, end) seconds."""

    index: int  # position on the time line (0: the phase at t = 0)
    phase: int  # which phase of the program
    start: float
    end: float
    state: str


@dataclass(frozen=True)
class SignalProgram:
    """A fixed-time program of traffic light ``tls``."""

    tls: str
    program_id: str
    offset: float
    phases: tuple[SignalPhase, ...]
    note: str | None = None  # how it was read, when not as given (an actuated program)

    @property
    def cycle(self) -> float:
        return sum(phase.duration for phase in self.phases)

    @property
    def links(self) -> int:
        return len(self.phases[0].state)

    def instances(self, horizon: float) -> list[PhaseInstance]:
        """The phase instances that cover [0, horizon], in order."""
        position = (0.0 - self.offset) % self.cycle
        phase, begun = 0, 0.0
        while begun + self.phases[phase].duration <= position:
            begun += self.phases[phase].duration
            phase += 1
        start = begun - position + 0.0  # never -0.0
        found: list[PhaseInstance] = []
        while start <= horizon:
            end = start + self.phases[phase].duration
            found.append(PhaseInstance(len(found), phase, start, end, self.phases[phase].state))
            start, phase = end, (phase + 1) % len(self.phases)
        return found

    def instance_at(self, t: float, instances: Sequence[PhaseInstance]) -> PhaseInstance:
        """The instance of ``instances`` (from ``instances``) showing at time ``t``."""
        for instance in instances:
            if instance.start <= t < instance.end:
                return instance
        return instances[-1] if t >= instances[-1].end else instances[0]

    def colour(self, link: int, t: float) -> str:
        """The SUMO colour of ``link`` at time ``t``."""
        position = (t - self.offset) % self.cycle
        for phase in self.phases:
            if position < phase.duration:
                return phase.state[link]
            position -= phase.duration
        return self.phases[-1].state[link]

    def timeline(self, link: int, horizon: float) -> list[tuple[float, float, str]]:
        """(start, end, colour) of ``link`` over [0, horizon], runs of one colour merged,
        clipped to the horizon."""
        runs: list[tuple[float, float, str]] = []
        for instance in self.instances(horizon):
            colour = instance.state[link]
            start, end = max(instance.start, 0.0), min(instance.end, horizon)
            if end <= start:
                continue
            if runs and runs[-1][2] == colour:
                runs[-1] = (runs[-1][0], end, colour)
            else:
                runs.append((start, end, colour))
        return runs

    def first_go(self, link: int, after: float = 0.0) -> float | None:
        """The first moment at or after ``after`` at which ``link`` lets a car enter (a
        colour of GO_COLOURS); None when it never does (red in every phase: one cycle
        after ``after`` shows every colour it ever will)."""
        for start, end, colour in self.timeline(link, after + self.cycle):
            if colour in GO_COLOURS and end > after:
                return max(start, after)
        return None

    def goes_within(self, link: int, duration: float) -> bool:
        """Whether ``link`` lets a car enter at some moment of a test-case of ``duration``."""
        go = self.first_go(link)
        return go is not None and go < duration

    def to_document(self) -> dict[str, Any]:
        """The program as the test-case's ``signals`` field."""
        document: dict[str, Any] = {
            "tls": self.tls,
            "program": self.program_id,
            "offset": self.offset,
            "phases": [{"duration": p.duration, "state": p.state} for p in self.phases],
        }
        if self.note is not None:
            document["note"] = self.note
        return document

    def to_sumo_xml(self) -> str:
        """An additional file that makes this program the active one of its traffic light
        (SUMO activates the program loaded last)."""
        from xml.sax.saxutils import quoteattr

        lines = [
            "<additional>",
            f"    <tlLogic id={quoteattr(self.tls)} programID={quoteattr(self.program_id)} "
            f'offset="{_seconds(self.offset)}" type="static">',
        ]
        lines += [
            f'        <phase duration="{_seconds(p.duration)}" state="{p.state}"/>'
            for p in self.phases
        ]
        lines += ["    </tlLogic>", "</additional>", ""]
        return "\n".join(lines)


def _seconds(value: float) -> str:
    """Seconds as SUMO reads them back exactly: short where ``g`` is exact (31, 0.1), all
    digits where it is not (a long phase of 123456.5 s)."""
    short = f"{value:g}"
    return short if float(short) == value else repr(value)


def program_problems(phases: Iterable[tuple[float, str]], where: str = "phases") -> list[str]:
    """What is wrong with a program's phases (durations, colours, lengths); empty if
    nothing."""
    listed = list(phases)
    problems = []
    if not listed:
        return [f"{where}: a program needs at least one phase"]
    if len(listed) > MAX_PHASES:  # the phases themselves are not looked at: one line
        return [f"{where}: {len(listed)} phases, at most {MAX_PHASES}"]
    for k, (duration, state) in enumerate(listed):
        if not (math.isfinite(duration) and MIN_PHASE_DURATION <= duration <= MAX_PHASE_DURATION):
            problems.append(
                f"{where}.{k}.duration is {duration:g} s; a phase lasts from "
                f"{MIN_PHASE_DURATION:g} s (SUMO's step) to {MAX_PHASE_DURATION:g} s"
            )
        bad = sorted({c for c in state if c not in VALID_COLOURS})
        if bad:
            problems.append(
                f"{where}.{k}.state {state!r} has unknown colours {''.join(bad)!r}; "
                f"valid colours: {', '.join(f'{c} {COLOUR_WORDS[c]}' for c in VALID_COLOURS)}"
            )
        if not state:
            problems.append(f"{where}.{k}.state is empty")
    cycle = math.fsum(duration for duration, _ in listed)
    if math.isfinite(cycle) and cycle < MIN_CYCLE:
        problems.append(
            f"{where}: the cycle (the phases' durations added) is {cycle:g} s; a cycle lasts "
            f"at least {MIN_CYCLE:g} s"
        )
    return problems + _unequal_states(listed, where)


def _unequal_states(phases: Sequence[tuple[float, str]], where: str) -> list[str]:
    """One problem naming the states whose length differs from most phases' (phase 0's
    where as many are of each): they are the ones to correct."""
    lengths = Counter(len(state) for _, state in phases if state)
    if len(lengths) < 2:
        return []
    first = len(phases[0][1])
    usual = max(lengths, key=lambda n: (lengths[n], n == first))
    odd = [f"{where}.{k}.state has {len(s)} colour{'s' * (len(s) != 1)}"
           for k, (_, s) in enumerate(phases) if s and len(s) != usual]  # fmt: skip
    return [
        f"{', '.join(odd)} where the other phases have {usual}: every state has one colour "
        "per link of the traffic light"
    ]


def make_program(
    tls: str,
    program_id: str,
    offset: float,
    phases: Sequence[tuple[float, str]],
    note: str | None = None,
) -> SignalProgram:
    """A checked program; InvalidInput naming every problem."""
    problems = program_problems(phases)
    if not math.isfinite(offset) or abs(offset) > MAX_OFFSET:
        problems.append(
            f"offset is {offset:g} s; an offset is from {-MAX_OFFSET:g} to {MAX_OFFSET:g} s"
        )
    if problems:
        raise InvalidInput(f"traffic-light program of {tls!r}: " + "; ".join(problems))
    return SignalProgram(
        tls, program_id, float(offset), tuple(SignalPhase(float(d), s) for d, s in phases), note
    )


def timeline_note(tls: str, program_id: str, kind: str, where: str) -> str | None:
    """How a program of SUMO type ``kind`` is read: None for a fixed-time one, a note for
    one read as fixed-time; InvalidInput naming the valid types for one that is no time
    line. ``where``: the program's source, as the note names it (the network, a file)."""
    if kind == STATIC:
        return None
    if kind in READ_AS_FIXED_TIME:
        return (
            f"traffic light {tls!r}: {where}'s {kind} program {program_id!r} read as "
            "fixed-time, each phase lasting its duration (SUMO would stretch or cut a phase "
            "between minDur and maxDur by the traffic it detects)"
        )
    raise InvalidInput(
        f"traffic light {tls!r}: {where}'s program {program_id!r} is of type {kind!r}, which "
        f"scengen cannot read as a time line of phases; it reads types {', '.join(PROGRAM_TYPES)} "
        f"({' and '.join(READ_AS_FIXED_TIME)} as fixed-time, each phase lasting its "
        "duration): give such a program (--signals FILE on the command line, a SUMO "
        "<tlLogic> or scengen's JSON; the signals field of the API and of batch campaigns), "
        "or rebuild the network with netconvert --tls.default-type static"
    )


def _successor_problem(nexts: Sequence[Sequence[int]]) -> str | None:
    """Why phases with SUMO's ``next`` are no cycle in order (None when they are): a phase
    that names another successor than the one after it."""
    count = len(nexts)
    for k, chosen in enumerate(nexts):
        if list(chosen) not in ([], [(k + 1) % count]):
            return (
                f"phase {k} names its successors (next {' '.join(map(str, chosen))}) instead "
                "of running the phases in order, which is no fixed time line"
            )
    return None


def network_program(net: Any, tls_id: str) -> SignalProgram:
    """The active program of traffic light ``tls_id`` in a sumolib network read with its
    programs (the last one loaded, as SUMO does). InvalidInput when it is not fixed-time."""
    programs = net.getTLS(tls_id).getPrograms()
    if not programs:
        raise InvalidInput(
            f"traffic light {tls_id!r} has no program in the network; give a fixed-time one "
            "(--signals FILE on the command line, a SUMO tlLogic of type static or scengen's "
            "JSON; the signals field of the API and of batch campaigns)"
        )
    program_id, program = list(programs.items())[-1]
    note = timeline_note(tls_id, str(program_id), str(program.getType()), "the network")
    _refuse_successors(tls_id, [list(p.next or ()) for p in program.getPhases()])
    phases = [(float(p.duration), str(p.state)) for p in program.getPhases()]
    return make_program(tls_id, str(program_id), float(program.getOffset()), phases, note)


def _refuse_successors(tls: str, nexts: Sequence[Sequence[int]]) -> None:
    """InvalidInput when the phases choose their successors (SUMO's ``next``)."""
    problem = _successor_problem(nexts)
    if problem is not None:
        raise InvalidInput(
            f"traffic light {tls!r}: {problem}; give a fixed-time program (--signals FILE; "
            "the signals field of the API and of batch campaigns)"
        )


def read_signals_file(path: Path, tls: str | None = None) -> SignalProgram:
    """A fixed-time program from a file: scengen's JSON (the test-case's ``signals``
    field) or SUMO XML with a ``<tlLogic>`` (the one of ``tls`` where there are several).
    InvalidInput naming the problem."""
    data = read_bounded(path, "the signals file", MAX_SIGNALS_FILE_BYTES, _json_or_xml(path))
    if data.lstrip(BLANK).startswith(b"{"):
        if len(data) > MAX_PARAMETER_FILE_BYTES:
            raise InvalidInput(
                f"the signals file {path} is larger than {MAX_PARAMETER_FILE_BYTES:,} bytes, "
                "the limit of a JSON program"
            )
        return program_from_document(parse_json(data, f"signals file {path}"), str(path))
    try:
        text = data.decode()
    except UnicodeDecodeError as exc:
        raise InvalidInput(f"signals file {path} is not UTF-8 ({exc.reason})") from None
    return program_from_xml(text, str(path), tls)


BLANK = b"\xef\xbb\xbf \t\r\n"  # a byte-order mark and white space before the first character


def _json_or_xml(path: Path) -> Callable[[bytes], None]:
    """A check of a signals file's first bytes: JSON or XML (a link to /dev/zero is refused
    after 64 kB, not read to the limit)."""

    def check(start: bytes) -> None:
        first = start.lstrip(BLANK)[:1]
        if first not in (b"{", b"<") and (first or len(start) < 65_536):
            raise InvalidInput(
                f"signals file {path} is neither JSON ({{...}}) nor SUMO XML (<...>)"
            )

    return check


def program_from_document(document: Any, where: str = "signals") -> SignalProgram:
    """A program from the JSON form (``{"tls", "program", "offset", "phases": [{"duration",
    "state"}]}``)."""
    if not isinstance(document, dict) or not isinstance(document.get("phases"), list):
        raise InvalidInput(
            f"{where}: a program is an object with tls, program, offset and phases "
            '([{"duration": seconds, "state": "GGrr..."}])'
        )
    phases = []
    for k, phase in enumerate(document["phases"]):
        if (
            not isinstance(phase, dict)
            or not isinstance(phase.get("state"), str)
            or not (
                isinstance(phase.get("duration"), int | float)
                and not isinstance(phase.get("duration"), bool)
            )
        ):
            raise InvalidInput(
                f"{where}: phases.{k} needs a duration (seconds) and a state (a string)"
            )
        phases.append((float(phase["duration"]), phase["state"]))
    offset = document.get("offset", 0.0)
    if not isinstance(offset, int | float) or isinstance(offset, bool):
        raise InvalidInput(f"{where}: offset must be a number of seconds")
    tls = document.get("tls", "")
    program = document.get("program", "scengen")
    note = document.get("note")
    if not isinstance(tls, str) or not isinstance(program, str):
        raise InvalidInput(f"{where}: tls and program must be strings")
    if note is not None and not isinstance(note, str):
        raise InvalidInput(f"{where}: note must be a string")
    return make_program(tls, program or "scengen", float(offset), phases, note)


def program_from_xml(text: str, where: str, tls: str | None = None) -> SignalProgram:
    """A program from SUMO XML (an additional file or a network with ``<tlLogic>``)."""
    try:
        root = SafeElementTree.fromstring(text, forbid_dtd=True)
    except (SafeElementTree.ParseError, DefusedXmlException) as exc:
        raise InvalidInput(f"signals file {where} is neither JSON nor XML: {exc}") from None
    logics = [root] if root.tag == "tlLogic" else list(root.iter("tlLogic"))
    if not logics:
        raise InvalidInput(f"signals file {where} has no <tlLogic> element")
    if tls is not None and len(logics) > 1:
        logics = [e for e in logics if e.get("id") == tls] or logics
    if len(logics) > 1:
        ids = ", ".join(sorted({str(e.get("id")) for e in logics}))
        raise InvalidInput(f"signals file {where} has several <tlLogic> elements ({ids})")
    logic = logics[0]
    tls_id, program_id = str(logic.get("id", "")), str(logic.get("programID", "scengen"))
    note = timeline_note(tls_id, program_id, logic.get("type", STATIC), f"signals file {where}")
    phases, nexts = [], []
    for k, phase in enumerate(logic.iter("phase")):
        try:
            duration = float(phase.get("duration", ""))
            nexts.append([int(n) for n in phase.get("next", "").split()])
        except ValueError:
            raise InvalidInput(
                f"signals file {where}: phase {k} has no numeric duration or next"
            ) from None
        phases.append((duration, phase.get("state", "")))
    _refuse_successors(tls_id, nexts)
    try:
        offset = float(logic.get("offset", "0"))
    except ValueError:
        raise InvalidInput(f"signals file {where}: offset is not a number") from None
    return make_program(tls_id, program_id, offset, phases, note)
