"""The dependency bounds CI tests: ``.ci/lower-bounds.txt`` pins exactly the lower bounds of
pyproject.toml (runtime and test extras), so the oldest allowed versions are the ones tested."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _release(version: str) -> tuple[int, ...]:
    """``"3.8"`` and ``"3.8.0"`` alike: the release numbers without trailing zeros."""
    numbers = [int(part) for part in version.split(".")]
    while numbers and numbers[-1] == 0:
        numbers.pop()
    return tuple(numbers)


def _lower_bounds(requirements):
    bounds = {}
    for requirement in requirements:
        match = re.fullmatch(r"([A-Za-z0-9_.-]+)\s*>=\s*([0-9][0-9A-Za-z.]*)", requirement.strip())
        assert match, f"pyproject.toml: {requirement!r} has no plain '>=' lower bound"
        bounds[match[1].lower()] = _release(match[2])
    return bounds


def test_lower_bounds_file_pins_pyprojects_lower_bounds():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    wanted = _lower_bounds(project["dependencies"] + project["optional-dependencies"]["test"])
    pinned = {}
    for line in (ROOT / ".ci" / "lower-bounds.txt").read_text().splitlines():
        line = line.split("#", 1)[0].strip()
        if line:
            name, version = line.split("==")
            pinned[name.strip().lower()] = _release(version.strip())
    assert pinned == wanted
