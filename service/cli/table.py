"""The parts of the command table: a command, its arguments, and the parser built from them.

Each command module declares its commands with ``@command``: the name, the help line, and
the arguments right above the handler, so a command reads as one piece. Arguments that
several commands share are tuples of ``Argument`` defined once (service.cli.arguments).

A help text or a description may be a function that writes it (``Later``): it is called
only when that help is shown, so that what it names (the controllers, which are found
among the installed packages' entry points) costs nothing to a command that only runs.
"""

from __future__ import annotations

import argparse
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal, NoReturn, Protocol

Handler = Callable[[argparse.Namespace], int]  # a command's work: its exit code
# a command's budget from its arguments: seconds, and how they come about (``--budget``)
Limit = Callable[[argparse.Namespace], tuple[float, str]]
Later = Callable[[], str]  # a help text or description, written when the help is shown


class _Target(Protocol):
    def add_argument(self, *flags: str, **options: Any) -> Any: ...


Writes = Literal["file", "folder"]  # what an argument names that the command writes


@dataclass(frozen=True)
class Argument:
    """One argument, as ``argparse``'s ``add_argument`` takes it; ``writes`` marks a path
    the command writes (a file or a folder), checked before the command's work starts."""

    flags: tuple[str, ...]
    options: Mapping[str, Any]
    writes: Writes | None = None

    def add_to(self, parser: _Target) -> list[tuple[str, Writes]]:
        """Add it; the written paths it declares, as (destination, what) pairs."""
        later = self.options.get("help")
        if not callable(later):
            action = parser.add_argument(*self.flags, **self.options)
        else:  # argparse gets a text: Parser.format_help writes it when it is shown
            action = parser.add_argument(*self.flags, **{**self.options, "help": "..."})
            action.later_help = later
        return [(action.dest, self.writes)] if self.writes else []


def arg(*flags: str, writes: Writes | None = None, **options: Any) -> Argument:
    return Argument(flags, options, writes)


@dataclass(frozen=True)
class OneOf:
    """Arguments that exclude each other; with ``required``, exactly one of them."""

    arguments: tuple[Argument, ...]
    required: bool = False

    def add_to(self, parser: argparse.ArgumentParser) -> list[tuple[str, Writes]]:
        group = parser.add_mutually_exclusive_group(required=self.required)
        return [written for argument in self.arguments for written in argument.add_to(group)]


@dataclass(frozen=True)
class Command:
    """A subcommand: ``scengen NAME ARGUMENTS``, run by ``run``; with a ``limit``, in a
    child process stopped at that budget (service.cli.budgeted)."""

    name: str
    help: str
    run: Handler
    arguments: tuple[Argument | OneOf, ...]
    description: str | Later | None = None
    limit: Limit | None = None


def command(
    name: str,
    help: str,
    *arguments: Argument | OneOf | Sequence[Argument],
    description: str | Later | None = None,
    limit: Limit | None = None,
) -> Callable[[Handler], Command]:
    """Declare the handler below as the command ``name``; a tuple of arguments (a shared
    group) stands for its members, in order. ``limit``: the command's budget (its work
    runs in a child stopped at it)."""
    flat: list[Argument | OneOf] = []
    for given in arguments:
        flat += [given] if isinstance(given, Argument | OneOf) else list(given)

    def declare(run: Handler) -> Command:
        return Command(name, help, run, tuple(flat), description, limit)

    return declare


def build_parser(commands: Sequence[Command], **options: Any) -> argparse.ArgumentParser:
    """The parser of a table of commands, in the table's order (the order of ``--help``);
    each parsed namespace carries its handler (``run``), its command's parser (``usage``,
    for usage errors found after parsing), the paths it writes (``writes``: destination
    and file or folder) and its budget (``limit``, or None)."""
    parser = Parser(**options)
    subparsers = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for entry in commands:
        given = entry.description
        sub = subparsers.add_parser(
            entry.name, help=entry.help, description=None if callable(given) else given
        )
        sub.later_description = given if callable(given) else None
        writes = [written for argument in entry.arguments for written in argument.add_to(sub)]
        sub.set_defaults(run=entry.run, usage=sub, writes=tuple(writes), limit=entry.limit)
    return parser


class Parser(argparse.ArgumentParser):
    """argparse's parser, with a hint where its error does not say how to go on."""

    given: Sequence[str] = ()  # the words being parsed: main() sets them for every parser
    later_description: Later | None = None

    def format_help(self) -> str:
        """The help, its texts given as functions (``Later``) written first."""
        if self.later_description is not None:
            self.description = self.later_description()
        for action in self._actions:
            later = getattr(action, "later_help", None)
            if later is not None:
                action.help = later()
        return super().format_help()

    def error(self, message: str) -> NoReturn:
        if "expected one argument" in message:
            message += _dash_hint(message, Parser.given)
        super().error(message)


def _dash_hint(message: str, given: Sequence[str]) -> str:
    """For an option whose value starts with '-' (a lane id such as -44_1:-9_1), which
    argparse takes for an option: how to write it."""
    flags = re.findall(r"(--?[A-Za-z][\w-]*)", message.split(":", 1)[0])
    for index, word in enumerate(given[:-1]):
        if word in flags and given[index + 1].startswith("-"):
            return f"; a value that starts with '-' goes after '=': {word}={given[index + 1]}"
    return ""
