"""The traffic signals of a signalized test-case in the OpenSCENARIO export: the signal
heads in the OpenDRIVE network, the test-case's program as an OpenSCENARIO
TrafficSignalController, and their words in ``verdict-rules.md``.

Heads: SUMO gives every connection (link) of a traffic light its own colour, and one fork
lane may carry links of different colours at once (a protected left arrow beside a red
straight on, a permissive left beside a protected straight on). So there is one OpenDRIVE
signal head per link, as ``netconvert --opendrive-output`` writes them: id
``<tls>_<link index>`` (``head_id``), on the road into the junction at its end (the stop
line, s = the road's length), over the fork lane (``<validity>`` of that lane; a link index
shared by several lanes gets one validity each), ``dynamic="yes"``, ``country="OpenDRIVE"``,
type 1000011 (an arrow light) with the movement as subtype (10 left, 20 right, 30 straight)
or 1000001 (a three-light head) where one link has several movements, all of them traffic
lights to CARLA; and one ``<controller id="<tls>">`` that lists them. scengen checks that
netconvert wrote a head for every link of the test-case's traffic light (and fails loudly
if not), and adds the ``<controller>`` reference to the junction, which netconvert leaves
out.

Program: one TrafficSignalController named after the traffic light, a Phase per phase of
the program with a TrafficSignalState for every head. OpenSCENARIO's ``delay`` is relative
to a ``reference`` controller (a controller's first phase virtually starts ``delay``
seconds after its reference's first phase; ``delay`` requires ``reference``), so a lone
controller starts its first phase at simulation time 0 and has no attribute that shifts
it. SUMO shows the phase at ``(t - offset) mod cycle``, so the controller's cycle starts
where SUMO's stands at t = 0 (``controller_phases``): the phase showing then comes first,
cut at t = 0 when t = 0 falls inside it (``phase_K_end``, the part after t = 0, first;
``phase_K_start``, the part before, last), the others in order (``phase_K``). The phases'
durations still sum to the cycle, and the controller's colour at every t is SUMO's.

Colours: SUMO ``G`` (protected) and ``g`` (permissive: yields) -> ``green``; ``y`` ->
``yellow``; ``r`` -> ``red``; ``u`` (red-yellow, before green) -> ``red;yellow`` (the
state is a free string in OpenSCENARIO) or ``red`` in the CARLA flavour (CARLA's lights
have no red-yellow); ``s`` (a right turn that may go on red after a full stop) -> ``red``,
which it is (CVC 21453 (b) allows the turn). The head shows the colour only: whether a
green is protected and whether a red allows the turn after a stop is in the test-case's
program and ``verdict-rules.md``.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass

from scenariogeneration import xosc

from service.core.errors import InvalidInput, NetworkBuildFailed
from service.core.export import Flavour
from service.core.network import Intersection, parsed_network
from service.core.network.signals import SignalProgram

_ASAM_WORDS = {"G": "green", "g": "green", "y": "yellow", "Y": "yellow", "r": "red",
               "u": "red;yellow", "s": "red", "O": "off", "o": "off"}  # fmt: skip
STATE_WORDS: dict[str, dict[str, str]] = {
    "asam": _ASAM_WORDS,
    "carla": {**_ASAM_WORDS, "u": "red"},
}
# SUMO colour -> what the verdict rules read (service.core.network.signals.RULE_COLOURS)
SUMO_MEANING = {
    "G": "protected green",
    "g": "permissive green (the driver yields)",
    "y": "yellow",
    "r": "red",
    "u": "red-yellow (red; green follows)",
    "s": "red on which a right turn may go after a full stop",
    "Y": "yellow (SUMO's major yellow)",
    "O": "signal off, the link has priority (read as protected green)",
    "o": "signal off and blinking, the link yields (read as permissive green)",
}
ROUNDING = 6  # decimals of a cut phase's duration (microseconds)


@dataclass(frozen=True)
class ControllerPhase:
    """A phase of the exported controller: the program from t = 0."""

    name: str
    duration: float
    state: str  # SUMO colours by link index


def head_id(tls: str, link: int) -> str:
    """The OpenDRIVE signal id of a link's head (netconvert's)."""
    return f"{tls}_{link}"


def headed_links(intersection: Intersection) -> list[int]:
    """The link indices of the junction's traffic light that have a connection in the
    network (each has a head), in order; empty where the junction has no traffic light."""
    if intersection.tls is None or not intersection.control.signalized:
        return []
    tls = parsed_network(intersection.network_file).getTLS(intersection.tls)
    return sorted({int(link) for _, _, link in tls.getConnections()})


def crossing_links(intersection: Intersection) -> dict[int, str]:
    """The pedestrian signals of the junction's traffic light: the link index of every
    connection onto a crossing, and that crossing's id; empty without a traffic light."""
    if intersection.tls is None or not intersection.control.signalized:
        return {}
    tls = parsed_network(intersection.network_file).getTLS(intersection.tls)
    return {
        int(link): outgoing.getEdge().getID()
        for _, outgoing, link in tls.getConnections()
        if outgoing.getEdge().getFunction() == "crossing"
    }


def controller_phases(program: SignalProgram) -> list[ControllerPhase]:
    """The program's cycle as it runs from t = 0 (module docstring): the phase showing at
    t = 0 first, cut there when t = 0 falls inside it."""
    first = program.instances(0.0)[0]  # the instance showing at t = 0; start <= 0
    done = round(-first.start, ROUNDING)  # how long it has shown at t = 0
    count = len(program.phases)
    order = [(first.phase + k) % count for k in range(count)]
    whole = [ControllerPhase(f"phase_{k}", program.phases[k].duration, program.phases[k].state)
             for k in order]  # fmt: skip
    duration = program.phases[first.phase].duration
    if done <= 0.0:
        return whole
    if done >= duration:  # t = 0 is the phase's end, to a microsecond: the next one starts
        return [*whole[1:], whole[0]]
    state = program.phases[first.phase].state
    return [
        ControllerPhase(f"phase_{first.phase}_end", round(duration - done, ROUNDING), state),
        *whole[1:],
        ControllerPhase(f"phase_{first.phase}_start", done, state),
    ]


def signal_controller(
    program: SignalProgram, intersection: Intersection, flavour: Flavour
) -> xosc.TrafficSignalController:
    """The test-case's program as a TrafficSignalController over the junction's heads,
    named after its traffic light (as the OpenDRIVE controller is)."""
    tls, links = _light(program, intersection)
    words = STATE_WORDS[flavour]
    controller = xosc.TrafficSignalController(tls)
    for phase in controller_phases(program):
        exported = xosc.Phase(phase.name, phase.duration)
        for link in links:
            exported.add_signal_state(head_id(tls, link), words[phase.state[link]])
        controller.add_phase(exported)
    return controller


def _light(program: SignalProgram, intersection: Intersection) -> tuple[str, list[int]]:
    """The junction's traffic light and its heads' link indices; InvalidInput where the
    program does not fit them (a test-case loaded with its junction never gets here)."""
    links = headed_links(intersection)
    if intersection.tls is None or not links or links[-1] >= program.links:
        raise InvalidInput(
            f"the signal program of traffic light {program.tls!r} ({program.links} links) "
            f"does not fit junction {intersection.junction!r} (traffic light "
            f"{intersection.tls!r}, link indices {links})",
            junction=intersection.junction,
        )
    return intersection.tls, links


def complete_signal_heads(root: ET.Element, intersection: Intersection) -> None:
    """Check that ``root`` (netconvert's OpenDRIVE) has a head for every link of the
    junction's traffic light, and make the junction name its controller; nothing where the
    junction has no traffic light. NetworkBuildFailed when a head or the controller is
    missing."""
    links = headed_links(intersection)
    if not links or intersection.tls is None:
        return
    tls = intersection.tls
    written = {e.get("id") for tag in ("signal", "signalReference") for e in root.iter(tag)}
    missing = [head_id(tls, k) for k in links if head_id(tls, k) not in written]
    controllers = [c for c in root.findall("controller") if c.get("id") == tls]
    junctions = [j for j in root.findall("junction") if j.get("name") == intersection.junction]
    if missing or not controllers or len(junctions) != 1:
        raise NetworkBuildFailed(
            f"netconvert's OpenDRIVE lacks the signals of traffic light {tls!r} at junction "
            f"{intersection.junction!r}: heads missing: {', '.join(missing) or 'none'}; "
            f"controller {'found' if controllers else 'missing'}; {len(junctions)} junctions "
            "of that name",
            junction=intersection.junction,
        )
    junction = junctions[0]
    if not any(c.get("id") == tls for c in junction.findall("controller")):
        # after the connections and priorities, before a surface (the schema's order)
        after = [e for e in junction if e.tag in ("connection", "priority")]
        junction.insert(list(junction).index(after[-1]) + 1, ET.Element("controller", id=tls))


def _shows(program: SignalProgram, colour: str) -> bool:
    """Some phase of ``program`` shows ``colour``."""
    return any(colour in phase.state for phase in program.phases)


def signal_rules_text(program: SignalProgram, intersection: Intersection, flavour: Flavour) -> str:
    """The section of ``verdict-rules.md`` on the test-case's program."""
    tls, _ = _light(program, intersection)
    words = STATE_WORDS[flavour]
    colours = "\n".join(
        f"  - `{colour}` {SUMO_MEANING[colour]}: `{words[colour]}`"
        for colour in "Ggyrus" + "".join(c for c in "YOo" if _shows(program, c))
    )
    routes = sorted(
        (r for r in intersection.routes.values() if r.link_index >= 0), key=lambda r: r.link_index
    )
    heads = "\n".join(
        f"  - `{head_id(tls, r.link_index)}`: `{r.id}` ({r.turn.value})" for r in routes
    )
    crossings = crossing_links(intersection)
    if crossings:  # the pedestrian signals, beside the crosswalks (module crosswalks)
        heads += "\n" + "\n".join(
            f"  - `{head_id(tls, link)}`: the pedestrian signal of crossing `{crossing}`, "
            "at the curb beside its crosswalk"
            for link, crossing in sorted(crossings.items())
        )
    phases = "\n".join(
        f"  - `phase_{k}`: {p.duration:g} s, `{p.state}`" for k, p in enumerate(program.phases)
    )
    return f"""## Signals

Traffic light `{tls}` runs the test-case's fixed-time program `{program.program_id}`:
cycle {program.cycle:g} s, offset {program.offset:g} s (at time t it shows the phase at
(t - offset) mod cycle, as SUMO does), one colour per link in each phase's state:

{phases}

`testcase.xosc` holds it as the TrafficSignalController `{tls}`, whose cycle starts
where the program stands at t = 0 (a phase that t = 0 cuts is `phase_K_end` first and
`phase_K_start` last). Each link is a signal head of `testcase.xodr` at the stop line of
its lane, `<traffic light>_<link index>`:

{heads}

Each phase's state gives every link one SUMO colour; a TrafficSignalState shows it as:

{colours}

The signal rules are the California Vehicle Code 21451 to 21453 (`asp/laws/cvc2145*.lp`):
on green the ego proceeds and yields to traffic lawfully inside the junction, and a left
turn on a permissive green yields to oncoming traffic that may go (21451, with 21801 (a));
yellow is a warning, and entering on it is lawful (21452); on red the ego stops at the
stop line and stays there until its signal lets it go, except that where the program
shows `s` it may turn right after a full stop, yielding to traffic that may go (21453).
A colour counts at the moment the ego's footprint first enters the junction.
"""
