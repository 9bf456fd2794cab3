"""Write docs/cli.md, the command-line reference, from the argparse parser itself.

Every command of ``precontour.cli.build_parser()``, with its one-line help, its description,
a usage line and one row per argument (name, value, default, help), so the reference cannot
drift from the parser: ``tests/test_docs.py`` regenerates the text in memory and compares.

The text is built from the parser's actions, not from argparse's own help formatter, whose
line wrapping depends on the terminal width and whose wording changes between Python
versions. Values computed from the machine it runs on (the memory-sized ``--max-samples``
default) are written as a placeholder, so the page is the same on every machine.

Run from the repository root:  python scripts/make_cli_reference.py [--check] [-o docs/cli.md]
"""

from __future__ import annotations

import argparse
import os
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
OUTPUT = ROOT / "docs" / "cli.md"

HEADER = """\
# Command-line reference

Generated from the argument parser by `python scripts/make_cli_reference.py`; do not edit by
hand (`tests/test_docs.py` fails when this page and the parser differ). `precontour COMMAND
--help` prints the same. What the commands are for: [the manual](README.md).

Units are mm, rad and s unless an option says otherwise. Bad input stops with one line
`precontour: error: ...` naming the file, row or line and field, and exit code 2.
"""


def machine_dependent_values() -> dict[str, str]:
    """Text of help strings that depends on the machine that builds the parser, and what the
    reference writes instead."""
    values = {}
    try:
        from precontour.trajectory.generate import default_max_samples
        values[str(default_max_samples())] = "N"
    except Exception:   # renamed or gone: nothing to replace
        pass
    return values


def _cell(text) -> str:
    """Text for one Markdown table cell: one line, pipes escaped."""
    return " ".join(str(text).split()).replace("|", "\\|")


def _expand(action: argparse.Action, prog: str) -> str:
    """An action's help with argparse's %-substitutions done (``%(default)s``, ``%%``)."""
    text = action.help or ""
    if "%" not in text:
        return text
    params = {k: v for k, v in vars(action).items() if v is not argparse.SUPPRESS}
    params["prog"] = prog
    if params.get("choices") is not None:
        params["choices"] = ", ".join(str(c) for c in params["choices"])
    try:
        return text % params
    except (KeyError, TypeError, ValueError):
        return text


def _name(action: argparse.Action) -> str:
    if not action.option_strings:
        return f"`{action.metavar or action.dest.upper()}`"
    return ", ".join(f"`{s}`" for s in action.option_strings)


def _value(action: argparse.Action) -> str:
    if action.nargs == 0:          # flags: store_true, store_const, help, version
        return ""
    if action.choices is not None and action.metavar is None:
        return " \\| ".join(f"`{c}`" for c in action.choices)
    if not action.option_strings:
        return ""
    return _cell(f"`{action.metavar or action.dest.upper()}`")


def _default(action: argparse.Action) -> str:
    if action.required:
        return "required"
    if not action.option_strings and action.nargs not in ("?", "*"):
        return "required"
    if action.nargs == 0:
        return ""
    default = action.default
    if default is None or default is argparse.SUPPRESS:
        return ""
    if isinstance(default, (list, tuple)):
        default = ",".join(str(d) for d in default)
    return f"`{default}`"


def _usage(name: str, parser: argparse.ArgumentParser) -> str:
    words = [f"precontour {name}"]
    groups = {id(a): g for g in parser._mutually_exclusive_groups for a in g._group_actions}
    done = set()
    for action in parser._actions:
        if isinstance(action, argparse._HelpAction) or id(action) in done \
                or action.help is argparse.SUPPRESS:
            continue
        group = groups.get(id(action))
        members = [action] if group is None else [
            a for a in group._group_actions if a.help is not argparse.SUPPRESS]
        done.update(id(a) for a in members)
        text = " | ".join(_usage_word(a) for a in members)
        required = (action.required if group is None else group.required) or (
            not action.option_strings and action.nargs not in ("?", "*") and group is None)
        words.append(text if required and group is None else
                     f"({text})" if required else f"[{text}]")
    return " ".join(words)


def _usage_word(action: argparse.Action) -> str:
    if not action.option_strings:
        return action.metavar or action.dest.upper()
    option = action.option_strings[0]
    if action.nargs == 0:
        return option
    if action.choices is not None and action.metavar is None:
        return f"{option} {{{','.join(str(c) for c in action.choices)}}}"
    return f"{option} {action.metavar or action.dest.upper()}"


def _arguments_table(parser: argparse.ArgumentParser, prog: str, replace: dict) -> list[str]:
    lines = ["| argument | value | default | meaning |", "|---|---|---|---|"]
    for action in parser._actions:
        if isinstance(action, argparse._HelpAction) or action.help is argparse.SUPPRESS:
            continue
        help_text = _expand(action, prog)
        for old, new in replace.items():
            help_text = re.sub(rf"(?<![\w.]){re.escape(old)}(?![\w.])", new, help_text)
        lines.append(f"| {_name(action)} | {_value(action)} | {_cell(_default(action))} | "
                     f"{_cell(help_text)} |")
    return lines


def reference_text(parser: argparse.ArgumentParser | None = None) -> str:
    """The Markdown text of docs/cli.md for ``parser`` (default: precontour's)."""
    if parser is None:
        from precontour.cli import build_parser
        parser = build_parser()
    replace = machine_dependent_values()
    subparsers = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    commands = subparsers[0] if subparsers else None
    one_line = {a.dest: a.help for a in commands._choices_actions} if commands else {}
    # a command's aliases map to the same parser: one section per parser, aliases named in it
    names, aliases = [], {}
    for name, sub in (commands.choices.items() if commands else ()):
        first = next((n for n in names if commands.choices[n] is sub), None)
        if first is None:
            names.append(name)
        else:
            aliases.setdefault(first, []).append(name)
    out = [HEADER]
    out.append("| command | what it does |")
    out.append("|---|---|")
    out += [f"| [`{name}`](#precontour-{name}) | {_cell(one_line.get(name, ''))} |"
            for name in names]
    out.append("")
    own = [a for a in parser._actions if a.option_strings
           and not isinstance(a, argparse._SubParsersAction) and a.help is not argparse.SUPPRESS]
    out.append("Options of `precontour` itself: " + "; ".join(
        f"{_name(a)}: {_cell(_expand(a, parser.prog))}" for a in own) + ".")
    for name in names:
        sub = commands.choices[name]
        out.append("")
        out.append(f"## precontour {name}")
        out.append("")
        if one_line.get(name):
            out.append(f"{_cell(one_line[name])[:1].upper()}{_cell(one_line[name])[1:]}.")
            out.append("")
        if aliases.get(name):
            out.append("Also spelt " + ", ".join(f"`{a}`" for a in aliases[name]) + ".")
            out.append("")
        if sub.description:
            out.append(" ".join(sub.description.split()))
            out.append("")
        out.append("```")
        out.append(_usage(name, sub))
        out.append("```")
        out.append("")
        out += _arguments_table(sub, f"precontour {name}", replace)
    return "\n".join(out) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("-o", "--output", type=Path, default=OUTPUT,
                        help="where to write (default docs/cli.md)")
    parser.add_argument("--check", action="store_true",
                        help="write nothing; exit 1 if the file differs from the parser")
    args = parser.parse_args(argv)
    text = reference_text()
    if args.check:
        current = args.output.read_text() if args.output.exists() else ""
        if current != text:
            print(f"{args.output} is out of date: run python scripts/make_cli_reference.py",
                  file=sys.stderr)
            return 1
        return 0
    # written beside the target and renamed: a failed run leaves the old page
    tmp = args.output.with_name(f".{args.output.name}.{os.getpid()}.tmp")
    tmp.write_text(text)
    os.replace(tmp, args.output)
    print(f"wrote {args.output}")
    return 0


if __name__ == "__main__":
    try:
        import precontour  # noqa: F401
    except ImportError:     # run from a checkout without installing: use its source tree
        sys.path.insert(0, str(ROOT / "src"))
    sys.exit(main())
