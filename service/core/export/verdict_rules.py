"""``verdict-rules.md`` of the OpenSCENARIO export: the pass-fail criteria scengen applies,
which OpenSCENARIO cannot state (it has no right-of-way criteria), for a user of another
simulator who runs the scenario and judges the ego's trajectory with ``scengen check``; at
a signalized junction also the program, which head is which route, the colour words and
the signal rules (``openscenario_signals``)."""

from __future__ import annotations

from service.core.checker.rules import rule_set_file, solve_rules
from service.core.export import check_flavour
from service.core.export.openscenario_signals import signal_rules_text
from service.core.network import ControlType, Intersection
from service.core.testcase import TestCase, load_testcase_intersection

RULES_FILE = "verdict-rules.md"


def rules_text(
    testcase: TestCase, intersection: Intersection | None = None, flavour: str = "asam"
) -> str:
    """The side file: what scengen judges and OpenSCENARIO cannot say; at a signalized
    junction, its signals too (``intersection``: the test-case's, loaded when None)."""
    p = testcase.params
    signals = ""  # a section of its own, before the coordinates
    if testcase.signals is not None:
        junction = intersection or load_testcase_intersection(testcase)
        program = testcase.signals.to_program()
        signals = signal_rules_text(program, junction, check_flavour(flavour)) + "\n"
    return f"""# Pass-fail criteria of this test-case (scengen)

OpenSCENARIO has no right-of-way criteria, so the scenario files only stop the run, when
the ego has reached its goal (its reference point on the road just past its exit lane's
start, its rear out of the junction: `ego_reached_its_goal`) or at {testcase.duration:g} s.
scengen judges the ego's trajectory (`scengen check testcase.json --ego TRAJECTORY`) with
these criteria; the ego passes when all of them hold:

- it reaches its exit lane (route `{testcase.ego.route.id}`) within {testcase.duration:g} s;
- it collides with no other car (footprints of {testcase.ego.length:g} m x
  {testcase.ego.width:g} m for the ego, the non-egos' own sizes);
- it obeys the traffic rules of `{testcase.rules}` at junction `{testcase.junction}`
  (control `{testcase.control}`): the California Vehicle Code as scengen reads it (README,
  "Traffic rules"), in the rule set `asp/rules/{testcase.rules}.lp`:

{_rule_set_text(testcase)}

- in a queue, each car stops at the limit line itself, a car behind another has not yet
  arrived, and the ego keeps {p.gap:g} m plus {p.headway:g} s of headway to the car
  ahead (running into it is a rear-end collision);
- the judgement ends with the goal: the moment the ego is on its exit lane with its whole
  footprint out of the junction (every rule of the junction is judged before it), or the
  duration when it never gets there; a collision or violation after it is reported as
  information, never as the ego's failure;
- parameters: minimum perceptible time difference m = {p.m:g} s, stopped at or below
  {p.v_stop:g} m/s, running a sign at or above {p.v_run:g} m/s, arrival within
  {p.arrival_distance:g} m of the line, speed limit {p.v_max:g} m/s.

{signals}Coordinates: SUMO's network coordinates (the OpenDRIVE file's), a vehicle's reference
point at the centre of its footprint, headings in radians counter-clockwise from the x
axis. Run the trajectory of your player back through `scengen check` as SUMO FCD, CSV or
JSON (README, `scengen check`).
"""


def _rule_set_text(testcase: TestCase) -> str:
    """The rule set's own summary (its header comment) and its rules with their sections
    (the rule set's law/2 atoms)."""
    control = ControlType(testcase.rules)
    lines = rule_set_file(control).read_text().splitlines()
    # the title (one line, or several: traffic_light.lp's) ends at the first empty comment
    title = next((k for k, line in enumerate(lines) if not line[1:].strip()), 1)
    header = []
    for line in lines[title:]:
        if not line.startswith("%") or line.startswith("% Input predicates"):
            break
        header.append("    " + line[1:].strip() if line[1:].strip() else "")
    while header and not header[-1]:
        header.pop()
    laws = [
        f"  - `{atom.arguments[0]}`: CVC {atom.arguments[1].string}"
        for atom in solve_rules(control, [], shown=[("law", 2)])
    ]
    return "\n".join([*header, "", *sorted(laws)]).strip("\n")
