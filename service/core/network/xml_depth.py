"""How deep an XML file nests its elements, read as a stream and stopped at a limit, so
that a small file of deeply nested elements (200,000 levels in 1.4 MB) is refused in a
fraction of a second instead of being handed to a parser or netconvert that works on it
for minutes.

A SUMO network nests 4 levels, an OpenStreetMap extract 3, an OpenDRIVE map about 10
(``tests/data``; OpenDRIVE's ``userData`` may add a few): ``MAX_XML_DEPTH`` leaves room.
"""

from __future__ import annotations

from pathlib import Path
from typing import IO
from xml.etree.ElementTree import ParseError

from defusedxml import ElementTree as SafeElementTree
from defusedxml.common import DefusedXmlException

from service.core.errors import InvalidInput

MAX_XML_DEPTH = 64


def too_deep(source: Path | IO[bytes], limit: int = MAX_XML_DEPTH) -> bool:
    """Whether ``source`` nests elements more than ``limit`` deep. A file that is not
    well-formed, or has a DTD or entities, before that depth is not too deep: the full
    parse that follows refuses it with its own message."""
    depth = 0
    try:
        for event, element in SafeElementTree.iterparse(
            source, events=("start", "end"), forbid_dtd=True
        ):
            if event == "start":
                depth += 1
                if depth > limit:
                    return True
            else:
                depth -= 1
                element.clear()
    except (DefusedXmlException, ParseError):
        return False
    return False


def depth_refusal(name: str, limit: int = MAX_XML_DEPTH) -> str:
    """The one line that refuses ``name`` for nesting too deep."""
    return (
        f"{name} nests its XML elements more than {limit} levels deep, at most {limit} "
        "are read (a SUMO network nests 4, OpenStreetMap 3, OpenDRIVE about 10)"
    )


def check_depth(path: Path, limit: int = MAX_XML_DEPTH) -> None:
    """InvalidInput when the XML file ``path`` nests elements more than ``limit`` deep."""
    if too_deep(path, limit):
        raise InvalidInput(depth_refusal(path.name, limit))
