"""Import maps that are not SUMO networks: ASAM OpenDRIVE (``.xodr``) and OpenStreetMap
(``.osm``), converted with netconvert into a ``.net.xml`` that everything else reads.

OpenDRIVE is read as CARLA's own SUMO conversion reads it (``--output.original-names``, so
each SUMO lane keeps its OpenDRIVE road and lane id as ``origId``; curves sampled every
metre; radii fixed; signal programs of the file discarded): a lane ``-12_0`` is road 12's
first right lane. OpenStreetMap is read with netconvert's usual urban options (SUMO's
documentation, "OSM import": joined junction clusters, guessed ramps, roundabouts and
signals, passenger roads only, isolated pieces removed).

The conversion is cached by the source's content; run_netconvert leaves netconvert's
generated-by comment (the time, the paths) out, so the same file gives the same network
bytes, and a test-case made from it the same network hash, wherever it is converted with
the same SUMO.
"""

from __future__ import annotations

import hashlib
import tempfile
from pathlib import Path

from service.core.errors import InvalidInput
from service.core.network.override import default_cache_dir, file_sha256, run_netconvert
from service.core.network.xml_depth import check_depth

FORMATS = {".xodr": "opendrive", ".osm": "openstreetmap"}
OPTIONS = {
    "opendrive": [
        "--output.original-names", "true",
        "--opendrive.curve-resolution", "1",
        "--geometry.min-radius.fix", "true",
        "--tls.discard-loaded", "true",
    ],
    "openstreetmap": [
        "--output.original-names", "true",
        "--geometry.remove", "true",
        "--roundabouts.guess", "true",
        "--ramps.guess", "true",
        "--junctions.join", "true",
        "--tls.guess-signals", "true",
        "--tls.discard-simple", "true",
        "--tls.join", "true",
        "--keep-edges.by-vclass", "passenger",
        "--remove-edges.isolated", "true",
    ],
}  # fmt: skip
INPUT = {"opendrive": "--opendrive-files", "openstreetmap": "--osm-files"}
NAMES = {"opendrive": "an OpenDRIVE", "openstreetmap": "an OpenStreetMap"}


def source_format(path: str | Path) -> str | None:
    """``opendrive`` or ``openstreetmap`` for a map netconvert must convert first, else
    None (a SUMO network)."""
    return FORMATS.get(Path(path).suffix.lower())


def convert_network(source: Path, cache_dir: Path | None = None) -> Path:
    """The SUMO network of the ``.xodr`` or ``.osm`` file ``source``, converted once and
    cached by its content. InvalidInput when netconvert cannot read the file (its own
    message), NetworkBuildFailed when it does not finish."""
    kind = source_format(source)
    if kind is None:
        raise InvalidInput(
            f"{source.name}: not a map to convert; give a .xodr (OpenDRIVE) or an .osm "
            "(OpenStreetMap) file, or a SUMO .net.xml"
        )
    cache = (cache_dir or default_cache_dir()) / "imports"
    cache.mkdir(parents=True, exist_ok=True)
    key = hashlib.sha256(f"{kind}|{file_sha256(source)}|{OPTIONS[kind]}".encode()).hexdigest()
    target = cache / f"{source.name}-{key[:16]}.net.xml"
    if target.exists():
        return target
    check_depth(source)  # netconvert would work on 200,000 nested elements for minutes
    with tempfile.TemporaryDirectory(dir=cache) as work:
        output = Path(work) / "converted.net.xml"
        failed = run_netconvert(
            [INPUT[kind], str(source), "--output-file", str(output), *OPTIONS[kind]],
            output, f"convert {source.name}",
        )  # fmt: skip
        if failed is not None:
            raise InvalidInput(
                f"{source.name} is not {NAMES[kind]} map netconvert can read: {failed}"
            )
        output.replace(target)
    return target
