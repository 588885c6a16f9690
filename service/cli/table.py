"""The parts of the command table: a command, its arguments, and the parser built from them.

Each command module declares its commands with ``@command``: the name, the help line, and
the arguments right above the handler, so a command reads as one piece. Arguments that
several commands share are tuples of ``Argument`` defined once (service.cli.arguments).
"""

from __future__ import annotations

import argparse
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

Handler = Callable[[argparse.Namespace], int]  # a command's work: its exit code


class _Target(Protocol):
    def add_argument(self, *flags: str, **options: Any) -> Any: ...


@dataclass(frozen=True)
class Argument:
    """One argument, as ``argparse``'s ``add_argument`` takes it."""

    flags: tuple[str, ...]
    options: Mapping[str, Any]

    def add_to(self, parser: _Target) -> None:
        parser.add_argument(*self.flags, **self.options)


def arg(*flags: str, **options: Any) -> Argument:
    return Argument(flags, options)


@dataclass(frozen=True)
class OneOf:
    """Arguments that exclude each other; with ``required``, exactly one of them."""

    arguments: tuple[Argument, ...]
    required: bool = False

    def add_to(self, parser: argparse.ArgumentParser) -> None:
        group = parser.add_mutually_exclusive_group(required=self.required)
        for argument in self.arguments:
            argument.add_to(group)


@dataclass(frozen=True)
class Command:
    """A subcommand: ``scengen NAME ARGUMENTS``, run by ``run``."""

    name: str
    help: str
    run: Handler
    arguments: tuple[Argument | OneOf, ...]
    description: str | None = None


def command(
    name: str,
    help: str,
    *arguments: Argument | OneOf | Sequence[Argument],
    description: str | None = None,
) -> Callable[[Handler], Command]:
    """Declare the handler below as the command ``name``; a tuple of arguments (a shared
    group) stands for its members, in order."""
    flat: list[Argument | OneOf] = []
    for given in arguments:
        flat += [given] if isinstance(given, Argument | OneOf) else list(given)

    def declare(run: Handler) -> Command:
        return Command(name, help, run, tuple(flat), description)

    return declare


def build_parser(commands: Sequence[Command], **options: Any) -> argparse.ArgumentParser:
    """The parser of a table of commands, in the table's order (the order of ``--help``);
    each parsed namespace carries its handler (``run``) and its command's parser
    (``usage``, for usage errors found after parsing)."""
    parser = argparse.ArgumentParser(**options)
    subparsers = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for entry in commands:
        sub = subparsers.add_parser(entry.name, help=entry.help, description=entry.description)
        for argument in entry.arguments:
            argument.add_to(sub)
        sub.set_defaults(run=entry.run, usage=sub)
    return parser
