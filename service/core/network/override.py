"""Rebuild a network with netconvert so that one junction gets another control type.

Relabelling the junction in the model alone would leave SUMO's right-of-way logic (link
states, foes) as it was; netconvert recomputes it, so SUMO and our rules agree.
"""

from __future__ import annotations

import hashlib
import os
import re
import subprocess
import tempfile
from collections.abc import Mapping
from pathlib import Path
from xml.sax.saxutils import quoteattr

from service.core.errors import NetworkBuildFailed
from service.core.sumo.binaries import sumo_binary

NETCONVERT_BUDGET = 120.0  # seconds
_GENERATED = re.compile(rb"<!-- generated on .*?-->\s*", re.DOTALL)


def file_sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with path.open("rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def default_cache_dir() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "scengen" / "networks"


def rebuild_with_control(
    network_file: Path,
    junction: str,
    control: str,
    cache_dir: Path | None = None,
    edge_priorities: Mapping[str, int] | None = None,
) -> Path:
    """A copy of ``network_file`` whose ``junction`` has type ``control``, built once, cached.

    ``edge_priorities`` gives roads new priorities (how a ``priority_stop`` or ``priority``
    junction gets the major road the user or service.core.network.major chose); they are
    part of what the copy is cached by."""
    return rebuild_network(network_file, junction, control, cache_dir, edge_priorities)


GUESS_CROSSINGS = ["--sidewalks.guess", "true", "--crossings.guess", "true"]


def rebuild_network(
    network_file: Path,
    junction: str | None = None,
    control: str | None = None,
    cache_dir: Path | None = None,
    edge_priorities: Mapping[str, int] | None = None,
    guess_crossings: bool = False,
) -> Path:
    """A copy of ``network_file`` rebuilt with netconvert, built once and cached by what
    was asked: ``junction`` gets type ``control`` (None: its own), ``edge_priorities`` give
    roads new priorities, and with ``guess_crossings`` every road gets a sidewalk (lane 0:
    the car lanes' indices move up by one) and every junction crossings
    (``--sidewalks.guess --crossings.guess``; a network that has them keeps its own)."""
    cache = cache_dir or default_cache_dir()
    cache.mkdir(parents=True, exist_ok=True)
    priorities = sorted((edge_priorities or {}).items())
    lifted = ",".join(f"{edge}={value}" for edge, value in priorities)
    retyped = junction is not None and control is not None
    identity = file_sha256(network_file)
    if retyped:
        identity += f"|{junction}|{control}"
    identity += f"|{lifted}" if lifted else ""  # without: the key of a plain override
    identity += "|crossings" if guess_crossings else ""
    key = hashlib.sha256(identity.encode()).hexdigest()
    target = cache / f"{network_file.name.removesuffix('.net.xml')}-{key[:16]}.net.xml"
    if target.exists():
        return target
    doing = " and ".join(
        [
            *([f"give junction {junction!r} control type {control!r}"] if retyped else []),
            *(["make " + ",".join(edge for edge, _ in priorities) + " the major road"]
              if priorities else []),
            *(["guess sidewalks and crossings"] if guess_crossings else []),
        ]
    ) or "rebuild the network"  # fmt: skip
    with tempfile.TemporaryDirectory(dir=cache) as work:
        nodes, edges = Path(work) / "override.nod.xml", Path(work) / "override.edg.xml"
        arguments = ["--sumo-net-file", str(network_file)]
        if retyped:
            nodes.write_text(
                f"<nodes>\n    <node id={quoteattr(str(junction))} "
                f"type={quoteattr(str(control))}/>\n</nodes>\n"
            )
            arguments += ["--node-files", str(nodes)]
        if priorities:
            edges.write_text("<edges>\n" + "".join(
                f"    <edge id={quoteattr(edge)} priority=\"{value:d}\"/>\n"
                for edge, value in priorities
            ) + "</edges>\n")  # fmt: skip
            arguments += ["--edge-files", str(edges)]
        if guess_crossings:
            arguments += GUESS_CROSSINGS
        output = Path(work) / "rebuilt.net.xml"
        failed = run_netconvert([*arguments, "--output-file", str(output)], output, doing, junction)
        if failed is not None:
            raise NetworkBuildFailed(
                f"netconvert failed to {doing}: {failed}",
                **({"junction": junction} if junction else {}),
            )
        output.replace(target)
    return target


def run_netconvert(
    arguments: list[str], output: Path, doing: str, junction: str | None = None
) -> str | None:
    """Run netconvert with ``arguments`` to write ``output``: None when it did, else its
    error message. NetworkBuildFailed when it does not finish within NETCONVERT_BUDGET
    (``doing`` says what it was asked to do). The output's generated-by comment (the time,
    the input paths) is left out: the same input gives the same bytes."""
    command = [sumo_binary("netconvert"), *arguments, "--no-warnings", "true"]
    try:
        result = subprocess.run(
            command, capture_output=True, text=True, timeout=NETCONVERT_BUDGET, check=False
        )
    except subprocess.TimeoutExpired as exc:
        raise NetworkBuildFailed(
            f"netconvert did not {doing} within {NETCONVERT_BUDGET:.0f} s",
            **({"junction": junction} if junction else {}),
        ) from exc
    if result.returncode == 0 and output.exists():
        output.write_bytes(_GENERATED.sub(b"", output.read_bytes(), count=1))
        return None
    lines = [line.strip() for line in (result.stderr or result.stdout).splitlines()]
    lines = [line for line in lines if line]
    return next((x for x in lines if x.startswith("Error")), lines[-1] if lines else "no output")
