"""MkDocs hook: the command reference page, made at build time from the CLI's own parsers.

``scengen``'s parser is built from the table of commands (service.cli.commands.COMMANDS);
this hook walks that parser, so the page lists every command, its usage, its description
and every argument with its help exactly as ``scengen COMMAND --help`` has them, and
cannot drift from the code. The page is ``reference/cli.md``; it exists only in the built
site.
"""

from __future__ import annotations

import argparse
import html
from typing import Any

from mkdocs.config.defaults import MkDocsConfig
from mkdocs.structure.files import File, Files

PAGE = "reference/cli.md"

# where each command is explained with examples (pages of docs/, from reference/)
GUIDES = {
    "networks": "../cli.md#scengen-networks",
    "intersection": "../intersections.md#scengen-intersection",
    "new": "../intersections.md#scengen-new",
    "drive": "../checking.md#scengen-drive",
    "check": "../checking.md#scengen-check",
    "extend": "../extending.md#scengen-extend",
    "example": "../extending.md#scengen-example",
    "evaluate": "../evaluating.md#scengen-evaluate",
    "cosim": "../cosim.md",
    "export": "../export.md",
    "plot": "../pictures.md",
    "serve": "../http-api.md#scengen-serve",
    "worker": "../jobs.md#scengen-worker",
    "submit": "../jobs.md#scengen-submit",
    "campaign": "../running-campaigns.md",
    "report": "../running-campaigns.md#scengen-report",
}


def on_files(files: Files, config: MkDocsConfig, **_: Any) -> Files:
    files.append(File.generated(config, PAGE, content=cli_reference()))
    return files


def cli_reference() -> str:
    from service.cli.commands import parser as scengen_parser

    parser = scengen_parser()
    subcommands = _subcommands(parser)
    lines = [
        "# Command reference",
        "",
        "Every command of `scengen`, its arguments and their help, as `scengen COMMAND "
        "--help` prints them. This page is made from the command line's own parsers when "
        "the site is built. Exit codes, file handling and how a test-case finds its network "
        "are on [The command line](../cli.md).",
        "",
        "```text",
        _usage(parser),
        "```",
        "",
        "| command | what it does |",
        "|---|---|",
    ]
    lines += [f"| [`{name}`](#scengen-{name}) | {_cell(help_line)} |"
              for name, help_line, _ in subcommands]  # fmt: skip
    for name, help_line, sub in subcommands:
        lines += ["", *_command_section(name, help_line, sub)]
    return "\n".join(lines) + "\n"


def _subcommands(parser: argparse.ArgumentParser) -> list[tuple[str, str, Any]]:
    """(name, help line, parser) of every subcommand, in the order of ``scengen --help``."""
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    helps = {choice.dest: choice.help or "" for choice in action._choices_actions}
    return [(name, helps.get(name, ""), sub) for name, sub in action.choices.items()]


def _command_section(name: str, help_line: str, sub: argparse.ArgumentParser) -> list[str]:
    usage = _usage(sub)
    lines = [f"## `scengen {name}`", "", help_line[:1].upper() + help_line[1:] + "."]
    if name in GUIDES:
        lines[-1] += f" [Guide with examples]({GUIDES[name]})."
    lines += ["", "```text", usage, "```", ""]
    if sub.description:
        lines += [_plain(sub.description), ""]
    formatter = sub._get_formatter()
    exclusive = _exclusive_groups(sub)
    for argument in sub._actions:
        if isinstance(argument, argparse._HelpAction):
            continue
        lines.append(f"- {_signature(argument)}: {_describe(argument, formatter, exclusive)}")
    return lines


def _usage(parser: argparse.ArgumentParser) -> str:
    """The usage lines without argparse's "usage: " and its indent after it."""
    prefix = "usage: "
    lines = parser.format_usage().strip().splitlines()
    return "\n".join(line.removeprefix(" " * len(prefix)) for line in lines).removeprefix(prefix)


def _exclusive_groups(sub: argparse.ArgumentParser) -> dict[int, list[str]]:
    """For each argument in a group of arguments that exclude each other: the others."""
    others: dict[int, list[str]] = {}
    for group in sub._mutually_exclusive_groups:
        names = [a.option_strings[0] for a in group._group_actions if a.option_strings]
        for action in group._group_actions:
            mine = action.option_strings[0] if action.option_strings else action.dest
            others[id(action)] = [n for n in names if n != mine]
            if group.required:
                others[id(action)].append("(one of them required)")
    return others


def _signature(argument: argparse.Action) -> str:
    given = argument.metavar
    metavar = given if isinstance(given, str) or given is None else " ".join(given)
    if not argument.option_strings:
        return f"`{metavar or argument.dest}{' ...' if argument.nargs in ('+', '*') else ''}`"
    value = ""
    if argument.nargs != 0:
        if metavar is None and argument.choices:
            metavar = "{" + ",".join(str(c) for c in argument.choices) + "}"
        value = f" {metavar or argument.dest.upper()}"
    return ", ".join(f"`{flag}{value}`" for flag in argument.option_strings)


def _describe(
    argument: argparse.Action, formatter: argparse.HelpFormatter, exclusive: dict[int, list[str]]
) -> str:
    text = formatter._expand_help(argument) if argument.help else ""
    notes = []
    if argument.required and argument.option_strings:
        notes.append("required")
    if isinstance(argument, argparse._AppendAction) and "repeat" not in text:
        notes.append("repeatable")
    if id(argument) in exclusive:
        others = [o for o in exclusive[id(argument)] if o.startswith("-")]
        required = "(one of them required)" in exclusive[id(argument)]
        notes.append(
            ("exactly one of this and " if required else "not with ")
            + ", ".join(f"`{o}`" for o in others)
        )
    prefix = f"({'; '.join(notes)}) " if notes else ""
    return prefix + _plain(text)


def _plain(text: str) -> str:
    """argparse's text as one Markdown paragraph (its line breaks are only wrapping), with
    angle brackets outside code spans shown as text, not read as HTML."""
    pieces = " ".join(text.split()).split("`")
    for k in range(0, len(pieces), 2):  # the even pieces are outside code spans
        pieces[k] = html.escape(pieces[k], quote=False)
    return "`".join(pieces)


def _cell(text: str) -> str:
    return _plain(text).replace("|", "\\|")
