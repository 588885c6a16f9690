"""A test-case as files for other tools, one module per format: the SUMO bundle
(``bundle``) and ASAM OpenSCENARIO XML on ASAM OpenDRIVE (``openscenario``, with the
signals of a signalized junction in ``openscenario_signals``).

The flavours of the OpenSCENARIO export are named here, so that the command line and the API
can name them without importing the exporter (and the scenariogeneration library).
"""

from typing import Literal, get_args

Flavour = Literal["asam", "carla"]
FLAVOURS: tuple[Flavour, ...] = get_args(Flavour)
