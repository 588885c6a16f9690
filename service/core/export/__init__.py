"""A test-case as files for other tools, one module per format: the SUMO bundle
(``bundle``) and ASAM OpenSCENARIO XML (``openscenario``) on ASAM OpenDRIVE
(``opendrive``), with the signals of a signalized junction (``openscenario_signals``) and
the pass-fail criteria beside them (``verdict_rules``).

The flavours of the OpenSCENARIO export are named here, so that the command line and the API
can name them without importing the exporter (and the scenariogeneration library).
"""

from typing import Literal, get_args

from service.core.errors import InvalidInput

Flavour = Literal["asam", "carla"]
FLAVOURS: tuple[Flavour, ...] = get_args(Flavour)


def check_flavour(flavour: str) -> Flavour:
    """``flavour`` as a Flavour; InvalidInput naming the flavours when it is none."""
    for known in FLAVOURS:
        if flavour == known:
            return known
    raise InvalidInput(f"unknown OpenSCENARIO flavour {flavour!r}; choose one of {FLAVOURS}")
