"""Reader for G-code programs in machine axes (X Y Z in mm or inch, A C in degrees).

Each ``G0``/``G1`` block gives machine-axis positions q = [X, Y, Z, A, C]; a missing axis
word keeps its previous value (axes never programmed start at 0), and the motion mode is
modal. The machine's direct kinematics turns q into tool tip and orientation. Supported:
``G90``/``G91`` (absolute default), ``G20``/``G21`` (mm default; inch lengths and feeds are
converted), ``G94`` feed ``F`` per minute (to mm/s), ``G4`` dwell, comments ``( )`` and
``;``, ``N`` numbers, ``%`` lines, ``O`` program numbers and block delete ``/`` (such blocks
are skipped by default). Codes that do not change the axis commands (plane selection,
compensation and cycle cancels, work offsets, path modes, ``G43`` tool length, which the
machine's kinematics is taken to include) and the words ``M S T H D`` are counted in
``ReadReport.skipped``. Arcs, inverse-time and per-revolution feed, canned cycles, tool-centre
point / tilted-plane modes, parameters and every other code are errors naming the line.
"""

from __future__ import annotations

import re
from collections import Counter
from pathlib import Path

import numpy as np

from ..errors import InputError, ToolPathError
from ._common import INCH, ReadReport, finish, read_text

#: Machine-axis words, in the order of q.
AXIS_WORDS = ("X", "Y", "Z", "A", "C")

#: G codes read and ignored: they do not change the axis commands the program gives.
IGNORED_G = frozenset(["G17", "G18", "G19", "G40", "G43", "G49", "G54", "G55", "G56", "G57",
                       "G58", "G59", "G61", "G64", "G80"])

#: Words other than G, F and the axes that are read and ignored.
IGNORED_WORDS = frozenset("NOMSTHD")

_UNSUPPORTED_G = {
    "G2": "circular interpolation (G2) is not supported; output linear G1 moves",
    "G3": "circular interpolation (G3) is not supported; output linear G1 moves",
    "G93": "inverse-time feed (G93) is not supported; output G94 feeds in mm/min",
    "G95": "feed per revolution (G95) is not supported; output G94 feeds in mm/min",
    "G43.4": "tool centre point control (G43.4) gives tool-tip coordinates, not machine "
             "axes; write the tip path as CL data (CSV or APT) instead",
    "G43.5": "tool centre point control (G43.5) gives tool-tip coordinates, not machine "
             "axes; write the tip path as CL data (CSV or APT) instead",
    "G68.2": "tilted working plane (G68.2) is not supported",
}

_NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)\Z")
_WORD = re.compile(r"([A-Z])([^A-Z]*)")
_COMMENT = re.compile(r"\([^)]*\)")
_SPACE = re.compile(r"\s+")

__all__ = ["read_gcode", "read_gcode_report", "AXIS_WORDS", "IGNORED_G", "IGNORED_WORDS"]


def read_gcode(path: str | Path, machine, *, block_delete: bool = True):
    """Read a G-code program into a :class:`~precontour.toolpath.ToolPath`.

    Parameters
    ----------
    path : str or Path
        G-code file in machine axes (see the module docstring).
    machine : Machine or str
        The machine (or a built-in machine name / machine file for
        :func:`~precontour.machine.load_machine`); ``machine.kinematics.forward(q)`` maps
        axis positions to tool tip and orientation.
    block_delete : bool
        Skip blocks starting with ``/`` (block-delete switch on).

    Returns
    -------
    ToolPath
        P (M, 3) mm and unit O (M, 3) in the workpiece frame, feed (M,) mm/s (NaN for
        ``G0`` moves and before the first ``F``).
    """
    return read_gcode_report(path, machine, block_delete=block_delete).toolpath


def read_gcode_report(path: str | Path, machine, *, block_delete: bool = True) -> ReadReport:
    """Like :func:`read_gcode`, returning the :class:`ReadReport`, whose ``axes`` holds the
    machine-axis positions q (M, 5) [mm, mm, mm, rad, rad] of the points.

    Raises
    ------
    ToolPathError
        One line naming the file, line and word: an unparseable number or text, an
        unsupported G code or word, two motion codes in a block, axis words before any
        ``G0``/``G1``, no motion at all, and the checks common to all readers.
    """
    source = str(path)
    kinematics = _kinematics(machine)
    text = read_text(path)

    q = [0.0] * 5                 # current axis positions, mm and degrees
    points: list[list[float]] = []
    point_lines: list[int] = []
    feeds: list[float] = []
    rapid: list[bool] = []
    skipped: Counter[str] = Counter()
    motion = None                 # modal "G0"/"G1"
    incremental = False
    scale = 1.0                   # mm per program length unit
    feed = np.nan                 # mm/s

    for number, raw in enumerate(text.splitlines(), start=1):
        block = raw
        if "(" in block:
            block = _COMMENT.sub(" ", block)
            if "(" in block or ")" in block:
                raise ToolPathError("unbalanced or nested '(' comment", source=source,
                                    row=number)
        semi = block.find(";")
        if semi >= 0:
            block = block[:semi]
        block = _SPACE.sub("", block).upper()
        if not block or block.startswith("%"):
            continue
        if block.startswith("/"):
            if block_delete:
                skipped["/"] += 1
                continue
            block = block[1:]
        words = _WORD.findall(block)
        if not block[0].isalpha():
            raise ToolPathError(f"cannot parse {block!r}", source=source, row=number)

        axes: dict[str, float] = {}
        codes: list[str] = []
        f_word = None
        p_word = None
        unknown = None
        for letter, value in words:
            if not _NUMBER.match(value):
                raise ToolPathError(f"cannot parse number {letter + value!r}", source=source,
                                    row=number, field=letter)
            if letter == "G":
                codes.append("G" + _code(value))
            elif letter in AXIS_WORDS:
                if letter in axes:
                    raise ToolPathError(f"axis word {letter} appears twice in the block",
                                        source=source, row=number, field=letter)
                axes[letter] = float(value)
            elif letter == "F":
                f_word = float(value)
            elif letter in IGNORED_WORDS:
                if letter != "N":
                    skipped[letter + _code(value) if letter == "M" else letter] += 1
            elif letter == "P":
                p_word = letter + value  # allowed with G4 only; checked below
            elif unknown is None:
                unknown = (letter, value)  # reported after the G codes, which explain more

        new_motion = None
        dwell = False
        for code in codes:
            if code in ("G0", "G1"):
                if new_motion is not None:
                    raise ToolPathError(f"two motion codes ({new_motion}, {code}) in one "
                                        "block", source=source, row=number, field="G")
                new_motion = code
            elif code == "G90":
                incremental = False
            elif code == "G91":
                incremental = True
            elif code == "G20":
                scale = INCH
            elif code == "G21":
                scale = 1.0
            elif code == "G94":
                pass
            elif code == "G4":
                dwell = True
            elif code in IGNORED_G:
                skipped[code] += 1
            elif code in _UNSUPPORTED_G:
                raise ToolPathError(_UNSUPPORTED_G[code], source=source, row=number,
                                    field="G")
            else:
                raise ToolPathError(f"unsupported G code {code}", source=source, row=number,
                                    field="G")
        if unknown is not None:
            letter, value = unknown
            raise ToolPathError(f"unsupported word {letter + value!r} (axes are "
                                f"{' '.join(AXIS_WORDS)})", source=source, row=number,
                                field=letter)
        if p_word is not None and not dwell:
            raise ToolPathError(f"unsupported word {p_word!r} (P is read only with G4)",
                                source=source, row=number, field="P")
        if f_word is not None:
            if not f_word > 0:
                raise ToolPathError(f"feed must be positive, got F{f_word:g}", source=source,
                                    row=number, field="F")
            feed = f_word * scale / 60.0
        if new_motion is not None:
            motion = new_motion
        if dwell:
            if new_motion is not None:
                raise ToolPathError("dwell (G4) and a motion code in one block",
                                    source=source, row=number, field="G")
            continue  # G4's X/P word is the dwell time, not a position
        if not axes:
            continue
        if motion is None:
            raise ToolPathError("axis words before any motion code (G0 or G1)",
                                source=source, row=number, field="G")
        for j, letter in enumerate(AXIS_WORDS):
            if letter in axes:
                value = axes[letter] * (scale if j < 3 else 1.0)
                q[j] = q[j] + value if incremental else value
        points.append(list(q))
        point_lines.append(number)
        rapid.append(motion == "G0")
        feeds.append(np.nan if motion == "G0" else feed)

    q_all = np.asarray(points, dtype=float).reshape(-1, 5)
    q_all[:, 3:] = np.radians(q_all[:, 3:])
    P, O = kinematics.forward(q_all)
    return finish(P, O, np.asarray(feeds), lines=point_lines, source=source,
                  format="gcode", empty="no motion (no G0/G1 block with an axis word)",
                  rapid=rapid, skipped=skipped, axes=q_all)


def _code(value: str) -> str:
    """Canonical spelling of a G or M number: ``01`` -> ``1``, ``43.40`` -> ``43.4``."""
    number = float(value)
    return f"{number:g}" if number == int(number) else f"{number:.10g}"


def _kinematics(machine):
    if isinstance(machine, (str, Path)):
        from ..machine import load_machine
        machine = load_machine(machine)
    kinematics = getattr(machine, "kinematics", None)
    if kinematics is None or not hasattr(kinematics, "forward"):
        raise InputError("reading G-code needs a machine whose kinematics has forward(q); "
                         f"got {type(machine).__name__}", field="machine")
    return kinematics
