"""The junction's network as ASAM OpenDRIVE (``testcase.xodr`` of the OpenSCENARIO export).

netconvert (``--opendrive-output``) writes the network the test-case runs on (with its
control override applied). It keeps SUMO's network coordinates (the network offset already
applied), so a SUMO x, y is an OpenDRIVE x, y; the header's ``<offset>`` (OpenDRIVE 1.5,
the negated netOffset) leads back to the projected coordinates of the map, so the file is
declared OpenDRIVE 1.5. Every SUMO edge is a road whose reference line is the edge's left
border, with one lane per SUMO lane (a sidewalk, a lane only people on foot may use, is a
lane of type ``sidewalk``); a junction's connections are its connecting roads.

scengen adds what netconvert leaves out: a stop sign (signal 206, CARLA's catalogue) at the
end of every road into a stop line; at a signalized junction the junction's reference to
its traffic light's controller, after checking that every link has its head
(``openscenario_signals``); and where the network has crossings, every crossing as a
crosswalk object in place of netconvert's, which OpenDRIVE 1.5's schema refuses and which
stand beside the crossing, with the pedestrian signals' heads at a signalized junction
(``crosswalks``). Where there is nothing to add, the file is netconvert's, byte for byte,
with the two header edits.
"""

from __future__ import annotations

import datetime
import math
import re
import tempfile
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from pathlib import Path

from service.core.errors import NetworkBuildFailed
from service.core.export.crosswalks import CROSSWALK, add_pedestrian_heads, replace_crosswalks
from service.core.export.openscenario_signals import complete_signal_heads, headed_links
from service.core.network import Fork, Intersection, parsed_network
from service.core.network.override import run_netconvert

NAME = "testcase"
CREATED = datetime.datetime(2026, 1, 1)  # a fixed header date: the same test-case, the same bytes


def opendrive_text(intersection: Intersection) -> str:
    """The junction's network as OpenDRIVE, by netconvert, with scengen's additions."""
    with tempfile.TemporaryDirectory() as work:
        output = Path(work) / f"{NAME}.xodr"
        failed = run_netconvert(
            ["--sumo-net-file", str(intersection.network_file), "--opendrive-output", str(output)],
            output, "write OpenDRIVE", intersection.junction,
        )  # fmt: skip
        if failed is not None:
            raise NetworkBuildFailed(
                f"netconvert could not write OpenDRIVE: {failed}", junction=intersection.junction
            )
        text = output.read_text()
    # netconvert declares OpenDRIVE 1.4 but writes 1.5's <offset> (where the network has an
    # offset): the file is valid 1.5 either way
    text = re.sub(r'<header revMajor="1" revMinor="4"', '<header revMajor="1" revMinor="5"', text)
    text = re.sub(r' date="[^"]*"', f' date="{CREATED.isoformat()}"', text, count=1)
    return _with_additions(text, intersection)


def road_of(roads: Sequence[ET.Element], start: tuple[float, float], heading: float) -> ET.Element:
    """The road netconvert wrote for a SUMO edge: its reference line starts at the edge's
    left border, in the edge's direction (``heading``, radians from the x axis)."""

    def miss(road: ET.Element) -> float:
        first = road.find("planView/geometry")
        if first is None:
            return math.inf
        x, y = float(first.get("x", "nan")), float(first.get("y", "nan"))
        turn = abs((float(first.get("hdg", "nan")) - heading + math.pi) % (2 * math.pi) - math.pi)
        return math.hypot(x - start[0], y - start[1]) if turn < math.pi / 6 else math.inf

    best = min(roads, key=miss)
    if miss(best) > 0.5:
        raise NetworkBuildFailed(f"no OpenDRIVE road of netconvert starts at the edge {start}")
    return best


def _with_additions(text: str, intersection: Intersection) -> str:
    """netconvert's text with what scengen adds: the stop and yield signs, the crosswalks and the
    pedestrian signals' heads (``crosswalks``), and the junction's reference to its traffic
    light's controller (``openscenario_signals``); the text as netconvert wrote it (the
    same bytes) where there is nothing to add."""
    forks = [f for f in intersection.forks.values() if f.stop_sign or f.yield_sign]
    crosswalks = f'type="{CROSSWALK}"' in text
    if not forks and not headed_links(intersection) and not crosswalks:
        return text
    root = ET.fromstring(text)
    _add_signs(root, intersection, forks)
    placed = replace_crosswalks(root, intersection)
    add_pedestrian_heads(root, intersection, placed)
    complete_signal_heads(root, intersection)
    ET.indent(root, space="    ")
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def _add_signs(root: ET.Element, intersection: Intersection, forks: Sequence[Fork]) -> None:
    """A stop sign (OpenDRIVE signal, German catalogue 206 as CARLA reads it) at the end of
    every road whose lanes meet a stop line of the junction (``forks``), a yield sign (205)
    at the end of every road of a priority junction's minor road."""
    if not forks:
        return
    roads = [r for r in root.iter("road") if r.get("junction") == "-1"]
    path = intersection.network_file
    net = parsed_network(path)
    signed: dict[str, ET.Element] = {}
    kind: dict[str, tuple[str, str]] = {}  # edge -> (id prefix, catalogue type)
    for fork in forks:
        edge = net.getLane(fork.lane).getEdge()
        if edge.getID() in signed:
            continue
        kind[edge.getID()] = ("stop", "206") if fork.stop_sign else ("yield", "205")
        left = max(edge.getLanes(), key=lambda lane: lane.getIndex())
        (x0, y0), (x1, y1) = left.getShape()[:2]
        norm = math.hypot(x1 - x0, y1 - y0) or 1.0
        half = left.getWidth() / 2  # the reference line is the edge's left border
        start = (x0 - (y1 - y0) / norm * half, y0 + (x1 - x0) / norm * half)
        signed[edge.getID()] = road_of(roads, start, math.atan2(y1 - y0, x1 - x0))
    for number, (edge_id, road) in enumerate(sorted(signed.items()), start=1):
        signals = road.find("signals")
        if signals is None:
            signals = ET.SubElement(road, "signals")
        width = sum(lane.getWidth() for lane in net.getEdge(edge_id).getLanes())
        name, catalogue = kind[edge_id]
        ET.SubElement(signals, "signal", {
            "s": f"{max(0.0, float(road.get('length', 0)) - 1.0):.4f}",
            "t": f"{-width - 0.5:.4f}", "id": f"{name}{number}", "name": f"{name} {edge_id}",
            "dynamic": "no", "orientation": "+", "zOffset": "1.5", "country": "DEU",
            "type": catalogue, "subtype": "-1", "height": "0.8", "width": "0.8",
        })  # fmt: skip
