"""The ``scengen`` command line: a thin adapter over ``service.core`` and the service."""
