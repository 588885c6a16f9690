"""The version of scengen: the installed package's (its metadata, from pyproject.toml), the
one the command line, the API and its documents all say."""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError, version

NOT_INSTALLED = "0+unknown"  # run from a source tree that was never installed


def package_version() -> str:
    try:
        return version("scengen")
    except PackageNotFoundError:
        return NOT_INSTALLED
