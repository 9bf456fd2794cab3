"""The README and the manual in docs/ stay true: the CLI reference matches the parser, every
relative link and anchor resolves, the README's library example runs, the machine-file
examples load and the page documents every key the built-in machines use."""

import importlib.util
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
README = ROOT / "README.md"
PAGES = [README] + sorted(DOCS.rglob("*.md"))
#: The README is one page: what precontour is, how to start, where to read on.
README_MAX_BYTES = 12 * 1024
#: Measurement pages: written by scripts, each saying when and how it was measured.
MEASUREMENT_PAGES = ("accuracy.md", "compensation.md", "programs.md",
                     "identification-measured.md", "claims.md", "speed.md", "feed.md")

_FENCE = re.compile(r"^(```|~~~).*?^\1[ \t]*$", re.M | re.S)
_COMMENT = re.compile(r"<!--.*?-->", re.S)
_LINK = re.compile(r"!?\[(?:[^\[\]]|\[[^\]]*\])*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
_HEADING = re.compile(r"^#{1,6}[ \t]+(.+?)[ \t#]*$", re.M)


def _prose(text: str) -> str:
    """The text outside code fences and HTML comments (where links and headings count)."""
    return _COMMENT.sub("", _FENCE.sub("", text))


def _slug(heading: str) -> str:
    """GitHub's anchor of a heading: lower case, punctuation dropped, spaces to hyphens."""
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", heading)      # a link: its text
    text = text.strip().lower()
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


def _anchors(page: Path) -> set[str]:
    anchors, seen = set(), {}
    for heading in _HEADING.findall(_prose(page.read_text())):
        slug = _slug(heading)
        n = seen.get(slug, 0)
        seen[slug] = n + 1
        anchors.add(slug if n == 0 else f"{slug}-{n}")
    return anchors


def _links(page: Path) -> list[str]:
    return _LINK.findall(_prose(page.read_text()))


def test_the_pages_are_found():
    assert README in PAGES and DOCS / "README.md" in PAGES and len(PAGES) > 10


@pytest.mark.parametrize("page", PAGES, ids=[str(p.relative_to(ROOT)) for p in PAGES])
def test_relative_links_and_anchors_resolve(page):
    broken = []
    for target in _links(page):
        if re.match(r"^[a-z][a-z0-9+.-]*:", target):      # http:, https:, mailto:
            continue
        path, _, anchor = target.partition("#")
        resolved = (page.parent / path).resolve() if path else page
        if not resolved.exists():
            broken.append(f"{target}: no such file {resolved.relative_to(ROOT)}")
        elif anchor and resolved.suffix == ".md" and anchor not in _anchors(resolved):
            broken.append(f"{target}: no heading with anchor #{anchor} in "
                          f"{resolved.relative_to(ROOT)}")
    assert not broken, f"{page.relative_to(ROOT)}: " + "; ".join(broken)


def test_slugs_follow_github():
    assert _slug("1. The machine: A-C trunnion table") == "1-the-machine-a-c-trunnion-table"
    assert _slug("`[drives.AXIS]`") == "drivesaxis"
    assert _slug("Learning within the limits (`--learn`)") == "learning-within-the-limits---learn"
    assert _slug("precontour run") == "precontour-run"


def test_the_link_checker_finds_broken_links(tmp_path):
    page = tmp_path / "page.md"
    page.write_text("# Title\n\n[ok](#title) [gone](missing.md) [anchor](#nowhere)\n"
                    "```\n[in code](ignored.md)\n```\n")
    assert _links(page) == ["#title", "missing.md", "#nowhere"]
    assert _anchors(page) == {"title"}


def test_the_readme_is_one_page():
    size = len(README.read_bytes())
    assert size <= README_MAX_BYTES, f"README.md is {size} bytes; move detail to docs/"


def test_every_manual_page_is_in_the_table_of_contents():
    index = DOCS / "README.md"
    linked = {(index.parent / target.partition("#")[0]).resolve()
              for target in _links(index) if target.partition("#")[0]}
    pages = {p.resolve() for p in DOCS.glob("*.md") if p != index}
    missing = sorted(str(p.relative_to(ROOT)) for p in pages - linked)
    assert not missing, f"not linked from docs/README.md: {missing}"


@pytest.mark.parametrize("name", MEASUREMENT_PAGES)
def test_measurement_pages_say_when_and_how_they_were_measured(name):
    text = (DOCS / name).read_text()
    assert re.search(r"\*(Generated|Measured) on \d{4}-\d{2}-\d{2}", text), name
    assert "precontour 0." in text or "precontour 1." in text, name


# --- the CLI reference ------------------------------------------------------------------------

def _cli_reference_module():
    spec = importlib.util.spec_from_file_location("make_cli_reference",
                                                  ROOT / "scripts" / "make_cli_reference.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_cli_reference_matches_the_parser():
    text = _cli_reference_module().reference_text()
    current = (DOCS / "cli.md").read_text()
    assert current == text, ("docs/cli.md differs from precontour.cli.build_parser(): run "
                             "python scripts/make_cli_reference.py")


def test_cli_reference_lists_every_command_and_option():
    import argparse

    from precontour.cli import build_parser

    text = (DOCS / "cli.md").read_text()
    parser = build_parser()
    commands = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    for name, sub in commands.choices.items():
        assert f"## precontour {name}\n" in text or f"`{name}`" in text, name
        for action in sub._actions:
            hidden = isinstance(action, argparse._HelpAction) or action.help == argparse.SUPPRESS
            for option in ([] if hidden else action.option_strings):
                assert f"`{option}`" in text, (name, option)


def test_cli_reference_replaces_machine_dependent_defaults():
    module = _cli_reference_module()
    for value in module.machine_dependent_values():
        assert not re.search(rf"(?<![\w.]){re.escape(value)}(?![\w.])",
                             (DOCS / "cli.md").read_text()), value


# --- examples in the pages ------------------------------------------------------------------

def _code_blocks(page: Path, language: str) -> list[str]:
    return re.findall(rf"^```{language}\n(.*?)^```", page.read_text(), re.M | re.S)


def test_the_readme_library_example_runs():
    blocks = _code_blocks(README, "python")
    assert len(blocks) == 1
    code = blocks[0]
    assert len([line for line in code.splitlines() if line.strip()]) <= 12
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                            timeout=900, cwd=ROOT)
    assert result.returncode == 0, result.stderr
    lines = result.stdout.strip().splitlines()
    assert [line.split(":")[0] for line in lines] == ["uncompensated", "pre-compensated"]
    tip_max = [float(re.search(r"tip max ([\d.]+) um", line).group(1)) for line in lines]
    # the virtual machine with friction: the paper's single pass removes most of the error
    assert tip_max[1] < 0.5 * tip_max[0], tip_max


def test_machine_file_examples_load():
    from precontour.machine.machine_file import parse_machine

    machines = [b for b in _code_blocks(DOCS / "machine-file.md", "toml") if "[kinematics]" in b]
    kinds = set()
    for block in machines:
        machine = parse_machine(block, source="docs/machine-file.md")
        kinds.add(tomllib.loads(block)["kinematics"]["type"])
        assert machine.controllers
    from precontour.machine.kinematics import KINEMATICS_TYPES
    assert kinds == set(KINEMATICS_TYPES), "one example per kinematics type"


def _keys(table: dict) -> set[str]:
    keys = set()
    for key, value in table.items():
        keys.add(key)
        if isinstance(value, dict):
            keys |= _keys(value)
    return keys


def test_machine_file_page_documents_every_key_of_the_built_in_machines():
    from precontour.machine.machine_file import BUILTIN_MACHINES, machine_data

    text = (DOCS / "machine-file.md").read_text()
    axes_and_names = {"X", "Y", "Z", "A", "B", "C", "drives", "controllers", "kinematics"}
    for name in BUILTIN_MACHINES:
        data, _ = machine_data(name)
        controllers = set(data["controllers"])
        for key in _keys(data) - axes_and_names - controllers:
            assert f"`{key}`" in text, (name, key)


def test_machine_file_gcode_example_loads():
    from precontour.machine.machine_file import builtin_machine_text, parse_machine

    blocks = [b for b in _code_blocks(DOCS / "machine-file.md", "toml")
              if b.startswith("[gcode]")]
    assert blocks, "docs/machine-file.md shows a [gcode] table"
    for block in blocks:
        machine = parse_machine(builtin_machine_text("linuxcnc-xyzac-trt") + "\n" + block,
                                source="docs/machine-file.md")
        assert machine.gcode.g28 is not None and machine.gcode.work_offsets


def _documented_parameters(function) -> set[str]:
    """The names a numpydoc ``Parameters`` section of ``function``'s docstring describes."""
    import inspect

    doc = inspect.getdoc(function) or ""
    found = re.search(r"Parameters\n-+\n(.*?)(?:\n\n[A-Z][a-z]+\n-+\n|\Z)", doc, re.S)
    names = set()
    for line in (found.group(1).splitlines() if found else ()):
        if line and not line.startswith(" "):
            names.update(n.strip().lstrip("*") for n in line.split(" : ")[0].split(","))
    return names


def test_the_public_entry_points_have_numpydoc_docstrings():
    """Every function the package's top level gives, and ``run`` and ``export`` without the
    files, describes each of its parameters in a numpydoc ``Parameters`` section and what
    it gives in ``Returns``."""
    import inspect

    import precontour
    from precontour.workflow import export_commands, run_program

    functions = [getattr(precontour, name) for name in precontour.__all__
                 if inspect.isfunction(getattr(precontour, name))]
    assert len(functions) >= 14
    for function in functions + [run_program, export_commands]:
        missing = set(inspect.signature(function).parameters) - _documented_parameters(function)
        assert not missing, (function.__name__, sorted(missing))
        assert "\nReturns\n-------\n" in inspect.getdoc(function), function.__name__
