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
    """The side file: what scengen judges and OpenSCENARIO cannot say; with pedestrians,
    their rules; at a signalized junction, its signals too (``intersection``: the
    test-case's, loaded when None)."""
    p = testcase.params
    junction = intersection
    if junction is None and (testcase.signals is not None or testcase.pedestrians):
        junction = load_testcase_intersection(testcase)
    sections = ""  # sections of their own, before the coordinates
    if testcase.pedestrians and junction is not None:
        sections += pedestrian_rules_text(testcase, junction) + "\n"
    if testcase.signals is not None and junction is not None:
        program = testcase.signals.to_program()
        sections += signal_rules_text(program, junction, check_flavour(flavour)) + "\n"
    collisions = """- it collides with no other car (footprints of {length:g} m x
  {width:g} m for the ego, the non-egos' own sizes);"""
    coordinates = """Coordinates: SUMO's network coordinates (the OpenDRIVE file's), \
a vehicle's reference
point at the centre of its footprint, headings in radians counter-clockwise from the x
axis. Run the trajectory of your player back through `scengen check` as SUMO FCD, CSV or
JSON (README, `scengen check`)."""
    if testcase.pedestrians:
        collisions = """- it collides with no other road user (footprints of {length:g} m x
  {width:g} m for the ego, the cars' and the pedestrians' own sizes);"""
        coordinates = """Coordinates: SUMO's network coordinates (the OpenDRIVE file's), \
a vehicle's reference
point at the centre of its footprint and a pedestrian's at the centre of its rectangle,
headings in radians counter-clockwise from the x axis. Run the trajectory of your player
back through `scengen check` as SUMO FCD, CSV or JSON (README, `scengen check`)."""
    collisions = collisions.format(length=testcase.ego.length, width=testcase.ego.width)
    return f"""# Pass-fail criteria of this test-case (scengen)

OpenSCENARIO has no right-of-way criteria, so the scenario files only stop the run, when
the ego has reached its goal (its reference point on the road just past its exit lane's
start, its rear out of the junction: `ego_reached_its_goal`) or at {testcase.duration:g} s.
scengen judges the ego's trajectory (`scengen check testcase.json --ego TRAJECTORY`) with
these criteria; the ego passes when all of them hold:

- it reaches its exit lane (route `{testcase.ego.route.id}`) within {testcase.duration:g} s;
{collisions}
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

{sections}{coordinates}
"""


def pedestrian_rules_text(testcase: TestCase, intersection: Intersection) -> str:
    """The section of ``verdict-rules.md`` on the test-case's pedestrians and the rules
    that protect them (docs/pedestrians.md, "The rules on an event trace")."""
    p, walking = testcase.params, testcase.params.walk
    people = []
    for person in testcase.pedestrians:
        walk = intersection.walks.get(person.walk)
        crossing = walk.crossing if walk is not None else ":" + person.walk[:-1]
        along = "along" if person.walk.endswith("+") else "against"
        people.append(
            f"  - `{person.id}`: walk `{person.walk}`, over crossing `{crossing}` {along} its\n"
            f"    centreline, {person.length:g} m x {person.width:g} m, from "
            f"{person.trajectory[0].t:g} s to {person.trajectory[-1].t:g} s"
        )
    signals = ""
    if testcase.signals is not None:
        signals = """
- 21451 (a), (b) and 21453 (b): turning on a green or a green arrow, or right on red, the
  ego yields to pedestrians lawfully within an adjacent crosswalk: the reading of 21950
  (a), the pedestrian having stepped onto the crosswalk on her walk signal;
- 21456 (`walkAgainstSignal`, a rule of the pedestrian): she starts to cross only on a
  steady walk, her crossing's link `G` or `g`; a flashing or steady don't walk (`y`, `r`)
  forbids starting, and one who started on walk may finish. scengen's pedestrians never
  walk against their signal. Each crossing's link is a pedestrian signal head (below),
  its state `green` walk, `yellow` flashing don't walk, `red` steady don't walk."""
    return f"""## Pedestrians

People on foot walk over the junction's crosswalks on fixed trajectories, as the non-ego
cars drive theirs. In `testcase.xosc` each is a `Pedestrian` entity (its bounding box its
rectangle, property `scengen_walk` its walk) that follows its trajectory from t = 0 and
leaves the map where it ends; in `testcase.xodr` each crossing of the junction is a
crosswalk object (`<object type="crosswalk">`, id the crossing's) whose outline is the
crossing's polygon, where scengen's rules place it:

{chr(10).join(people)}

The ego obeys the California Vehicle Code's rules on pedestrians, judged on the event
trace. The ego enters a crosswalk when its footprint first overlaps the crossing's
polygon. A pedestrian arrives at the curb when her front comes within {walking.arrival_distance:g} m
of the polygon, steps onto the crosswalk when her rectangle first overlaps it, and is off
it when it stops overlapping it for good; she is in the ego's path until she has left
the ego's connecting lane. Perceptibly is by at least m = {p.m:g} s.

- 21950 (a) (`yieldToPedestrian`): the ego yields to a pedestrian crossing within a
  crosswalk: it violates her right-of-way when it enters the crosswalk perceptibly after
  she stepped onto it and perceptibly before she has left its connecting lane, she having
  stepped onto it lawfully (not against 21950 (b) nor, at a signal, 21456);
- 21950 (b) (`leavesCurbIntoHazard`, a rule of the pedestrian): she does not suddenly
  leave the curb into the path of a vehicle so close as to be an immediate hazard: when
  the ego enters the crosswalk not perceptibly after she stepped onto it and she reaches
  its lane before it has left the crosswalk, she has no 21950 (a) right-of-way against
  it. scengen's pedestrians never do that to a car of the test-case;
- 21951 (`passesCarStoppedForPedestrian`): the ego does not overtake and pass a vehicle
  stopped at a crosswalk for a pedestrian: it does not enter the crosswalk while a car on
  a lane of the same road in the same direction stands before it (stopped at its limit
  line, not yet entered) and a pedestrian is on the crosswalk in the path of either of
  them;{signals}
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
