"""The command-line reference in Markdown, generated from the argparse parser itself
(:func:`precontour.cli.build_parser`), so that it cannot drift from what the commands accept:
per command its description, usage, and a table of every argument with its default, whether it
is required, its choices and its help; then the epilog (the built-in machines, for run and
export).

    PYTHONPATH=src python scripts/make_cli_reference.py [OUT.md]    # default: stdout

Defaults that depend on the computer (``--max-samples``, sized to its memory) are written as
the help says them, from the computer that runs the script.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from precontour import __version__
from precontour.cli import build_parser

#: Width of the usage lines (argparse reads COLUMNS).
WIDTH = 100


def subcommands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    """The parser of each command, in the order of ``precontour --help``."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}


def _cell(text: str) -> str:
    return " ".join(str(text).split()).replace("|", "\\|")


def _argument(action: argparse.Action) -> str:
    if not action.option_strings:
        return f"`{action.metavar or action.dest}`"
    if action.nargs == 0:
        return ", ".join(f"`{s}`" for s in action.option_strings)
    metavar = action.metavar or action.dest.upper()
    return ", ".join(f"`{s} {metavar}`" for s in action.option_strings)


def _default(action: argparse.Action) -> str:
    if action.required or action.nargs == 0 or action.default in (None, argparse.SUPPRESS):
        return ""
    return f"`{action.default}`" if action.default != "" else '`""`'


def command_reference(name: str, parser: argparse.ArgumentParser) -> list[str]:
    formatter = parser._get_formatter()
    lines = [f"## `precontour {name}`", "", _cell(parser.description or ""), "", "```",
             parser.format_usage().strip(), "```", "",
             "| argument | required | default | choices | meaning |",
             "|---|---|---|---|---|"]
    for action in parser._actions:
        if isinstance(action, argparse._HelpAction):
            continue
        required = "yes" if action.required or (not action.option_strings
                                                and action.nargs is None) else ""
        choices = ", ".join(f"`{c}`" for c in action.choices) if action.choices else ""
        meaning = formatter._expand_help(action) if action.help else ""
        lines.append(f"| {_argument(action)} | {required} | {_default(action)} | {choices} | "
                     f"{_cell(meaning)} |")
    if parser.epilog:
        lines += ["", _cell(parser.epilog)]
    return lines + [""]


def reference() -> str:
    os.environ["COLUMNS"] = str(WIDTH)
    parser = build_parser()
    commands = subcommands(parser)
    lines = ["# Command-line reference", "",
             f"precontour {__version__}. Generated from the parser by "
             "`scripts/make_cli_reference.py`; do not edit by hand.", "",
             _cell(parser.description or ""), "",
             "| command | what it does |", "|---|---|"]
    helps = {a.dest: a.help for action in parser._actions
             if isinstance(action, argparse._SubParsersAction) for a in action._choices_actions}
    lines += [f"| [`{name}`](#precontour-{name}) | {_cell(helps.get(name, ''))} |"
              for name in commands]
    lines.append("")
    for name, sub in commands.items():
        lines += command_reference(name, sub)
    return "\n".join(lines)


def main(argv: list[str]) -> None:
    text = reference()
    if argv:
        Path(argv[0]).write_text(text)
        print(f"wrote {argv[0]}")
    else:
        sys.stdout.write(text)


if __name__ == "__main__":
    main(sys.argv[1:])
