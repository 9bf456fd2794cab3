"""Measurement pages in docs/: the stamp each carries, and how they are written.

A measurement page says when, how and on what it was measured: the command that wrote it, the
date, the precontour version, the versions of the numerical libraries (round-off moves some
results) and the computer (cores, load average at the start: timings depend on them). Pages
are written to a temporary file beside the target and renamed, so a failed run leaves the old
page. A page written by several runs (``speed.md``: one section per benchmark) keeps each
run's section between ``<!-- begin NAME -->`` and ``<!-- end NAME -->`` markers, each with its
own stamp.

Used by the scripts that write pages (``from docpage import ...``; they run from ``scripts/``).
"""

from __future__ import annotations

import datetime
import os
import platform
import re
import shlex
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"

#: When the script started (it imports this module first) and the load average then.
STARTED = datetime.datetime.now()
try:
    LOAD_AT_START: float | None = os.getloadavg()[0]
except OSError:  # pragma: no cover - platforms without a load average
    LOAD_AT_START = None


def versions() -> str:
    """precontour's version and those of the numerical stack it ran on."""
    import numpy
    import scipy

    import precontour
    parts = [f"precontour {precontour.__version__}", f"Python {platform.python_version()}",
             f"numpy {numpy.__version__}", f"scipy {scipy.__version__}"]
    try:
        import numba
        parts.append(f"numba {numba.__version__}")
    except ImportError:
        pass
    return ", ".join(parts)


def computer(load: float | None = None) -> str:
    """Cores, and the load average when the measurement started."""
    cores = os.cpu_count() or 0
    load = LOAD_AT_START if load is None else load
    text = "" if load is None else f", load average {load:.1f} at the start"
    return f"{cores} cores{text}"


def load_average() -> float | None:
    try:
        return os.getloadavg()[0]
    except OSError:
        return None


def command_line(argv: list[str] | None = None) -> str:
    """The command that is running, as it would be typed from the repository root."""
    argv = sys.argv if argv is None else argv
    script = Path(argv[0]).resolve()
    try:
        script = script.relative_to(ROOT)
    except ValueError:
        pass
    return "python " + " ".join(shlex.quote(a) for a in [str(script), *argv[1:]])


def stamp(command: str | None = None, *, started: datetime.datetime | None = None,
          load: float | None = None) -> str:
    """One Markdown paragraph: generated when, by which command, on what (``started`` and
    ``load`` default to the script's start)."""
    started = started or STARTED
    return (f"*Generated on {started:%Y-%m-%d} by `{command or command_line()}` with "
            f"{versions()}; computer: {computer(load)}.*")


def write_page(path: str | Path, text: str) -> Path:
    """Write ``text`` to ``path`` atomically (temporary file beside it, then rename)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        tmp.write_text(text if text.endswith("\n") else text + "\n")
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()
    return path


def replace_section(path: str | Path, name: str, body: str) -> Path:
    """Put ``body`` between the page's markers for section ``name`` (appended at the end when
    the page has none yet), keeping the rest of the page as it is."""
    path = Path(path)
    text = path.read_text() if path.exists() else ""
    begin, end = f"<!-- begin {name} -->", f"<!-- end {name} -->"
    block = f"{begin}\n{body.strip()}\n{end}"
    pattern = re.compile(re.escape(begin) + r".*?" + re.escape(end), re.S)
    if pattern.search(text):
        text = pattern.sub(lambda _: block, text, count=1)
    else:
        text = text.rstrip("\n") + ("\n\n" if text else "") + block + "\n"
    return write_page(path, text)


def markdown_table(header: list[str], rows: list[list], align: str | None = None) -> str:
    """A Markdown table; ``align`` one character per column, ``l`` or ``r``."""
    align = align or "l" * len(header)
    rule = ["---:" if a == "r" else "---" for a in align]
    lines = ["| " + " | ".join(header) + " |", "| " + " | ".join(rule) + " |"]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)
