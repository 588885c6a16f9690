"""The ``scengen`` command line: a thin adapter over ``service.core`` and the service.

``main`` runs the table of commands (service.cli.main); each command group has a module
(networks, testcases, judging, exports, servers, campaigns) with its commands' arguments
beside their handlers; the arguments they share are defined once (service.cli.arguments).
``submit``, ``campaign_folder`` and ``examples`` do the work behind some of them.
"""

from service.cli.main import main

__all__ = ["main"]
