"""The ``scengen`` command line: a thin adapter over ``service.core`` and the service."""

from service.cli.commands import main

__all__ = ["main"]
