"""The bundle's FCD for SUMO's fcd-replay device (plain ``sumo -c testcase.sumocfg``):
every non-ego car and every pedestrian at every step while it is on the map.

A car's row names its lane and its position on it (``lane``, ``pos``): the device builds a
replayed car's route from the lanes of its rows and inserts it on the lane and at the
position of its first row. A row without ``lane`` makes the device guess the nearest lane
that a passenger car may use; inside a junction that is an internal lane, whose index it
then gives the edge after it, where on a network with sidewalks that index is the sidewalk
("Invalid departLane definition"). Here every row is exact: the car's front is
``distance`` metres along the lanes it drives (the ones Step 1 drove it on, internal lanes
included), from its start.

A pedestrian's row is a ``<person>`` with the edge she is on (the device builds her walk
from them), her front, heading and speed. The device moves her to every row's place
(``moveToXY``) but takes her first row's speed as her walking speed for the whole replay,
the speed SUMO's walking model gives her: one that stands still at t = 0 crashes SUMO 1.28
(a segmentation fault), and one that walks a few centimetres a second is "waiting" to
SUMO's drivers after two seconds, and they no longer yield to her as she comes. Her first
row's speed is therefore her fastest (at least ``PERSON_DEPART_SPEED``).
"""

from __future__ import annotations

import bisect
from collections.abc import Sequence
from xml.sax.saxutils import quoteattr

from service.core.motion.poses import centre_to_front
from service.core.network import Intersection, parsed_network
from service.core.network.lanes import (
    straightest_predecessor,
    straightest_successor,
    via_chain,
)
from service.core.sim.pedestrians import Walker
from service.core.sim.replay import Departure
from service.core.testcase import NonEgo, TestCase

PERSON_DEPART_SPEED = 0.1  # m/s: the least speed of a person's first row


def drive_lanes(
    intersection: Intersection, nonego: NonEgo, car: Departure
) -> list[tuple[str, float]]:
    """Every lane ``car`` drives, internal lanes included, in driving order from the lane
    it departs on, each with its length (SUMO's): the lanes ``plan_drive`` chose (the
    straightest ones before the fork and after the exit, the route's connection between)."""
    net = parsed_network(intersection.network_file)
    route = intersection.route(nonego.route.id)
    junction = intersection.junction
    fork = net.getLane(route.fork)
    at_fork = list(car.edges).index(fork.getEdge().getID())
    lanes = [fork.getID()]
    current = fork
    for _ in range(at_fork):  # back to the lane it departs on
        incoming = straightest_predecessor(net, current, junction)
        assert incoming is not None, "plan_drive found this road"
        current = incoming.getFromLane()
        lanes = [current.getID(), *via_chain(net, incoming), *lanes]
    connection = next(c for c in fork.getOutgoing() if c.getToLane().getID() == route.exit)
    lanes += [*via_chain(net, connection), route.exit]
    current = connection.getToLane()
    for _ in car.edges[at_fork + 2 :]:  # the straightest road on after the exit
        onward = straightest_successor(net, current, junction)
        assert onward is not None, "plan_drive found this road"
        current = onward.getToLane()
        lanes += [*via_chain(net, onward), current.getID()]
    driven = [lane for lane in lanes if not lane.startswith(":")]
    assert [net.getLane(lane).getEdge().getID() for lane in driven] == list(car.edges)
    assert lanes[0] == f"{car.edges[0]}_{car.lane}"
    return [(lane, float(net.getLane(lane).getLength())) for lane in lanes]


class _LanePlaces:
    """Metres along a car's lanes as (lane, position on it)."""

    def __init__(self, lanes: Sequence[tuple[str, float]]) -> None:
        self.lanes = [lane for lane, _ in lanes]
        self.starts = [0.0]
        for _, length in lanes:
            self.starts.append(self.starts[-1] + length)

    def offset(self, lane: str, position: float) -> float:
        return self.starts[self.lanes.index(lane)] + position

    def place(self, along: float) -> tuple[str, float]:
        k = min(max(bisect.bisect_right(self.starts, along) - 1, 0), len(self.lanes) - 1)
        return self.lanes[k], along - self.starts[k]


def fcd_text(
    testcase: TestCase,
    nonegos: Sequence[Departure],
    intersection: Intersection,
    people: Sequence[Walker] = (),
) -> str:
    """The non-egos' trajectories as SUMO FCD: front bumper, angle, speed, lane and position
    on it, per time step, while the car is on the map (a car that drives on past the end of
    its road has left it, as SUMO would remove it there); and the pedestrians' poses while
    they are on the map (``Walker.poses``)."""
    lines = ['<?xml version="1.0" encoding="UTF-8"?>', "<fcd-export>"]
    steps = round(testcase.duration / testcase.timestep)
    cars = []
    for nonego, car in zip(testcase.nonegos, nonegos, strict=True):
        places = _LanePlaces(drive_lanes(intersection, nonego, car))
        lane, position = car.start_on or (f"{car.edges[0]}_{car.lane}", car.position)
        cars.append((nonego, car, places, places.offset(lane, position)))
    for k in range(steps + 1):
        lines.append(f'    <timestep time="{k * testcase.timestep:.2f}">')
        for nonego, car, places, offset in cars:
            if k >= len(nonego.trajectory):
                continue
            s = nonego.trajectory[k]
            travelled = s.distance - nonego.trajectory[0].distance
            if travelled > car.road:
                continue
            x, y = centre_to_front(s.x, s.y, s.heading, nonego.length)
            lane, position = places.place(offset + travelled)
            lines.append(
                f'        <vehicle id={quoteattr(nonego.id)} x="{x:.3f}" y="{y:.3f}" '
                f'angle="{s.heading:.3f}" type="type_{nonego.id}" speed="{s.speed:.3f}" '
                f'lane="{lane}" pos="{position:.3f}"/>'
            )
        for person in people:
            if k >= len(person.poses):
                continue
            x, y, heading, speed = person.poses[k]
            if k == 0:  # her walking speed in the device (the module docstring)
                speed = max(PERSON_DEPART_SPEED, *(pose[3] for pose in person.poses))
            lines.append(
                f'        <person id={quoteattr(person.id)} x="{x:.3f}" y="{y:.3f}" '
                f'angle="{heading:.3f}" type="type_{person.id}" speed="{speed:.3f}" '
                f'edge="{person.edge_at(k)}"/>'
            )
        lines.append("    </timestep>")
    lines.append("</fcd-export>")
    return "\n".join(lines) + "\n"
