"""Axis commands out as programs a CNC runs: G-code and a LinuxCNC ``halstreamer`` file.

``gcode``: machine-axis G-code, ``G90 G93`` (inverse-time feed) with ``G1 X Y Z A C F`` blocks,
A and C in degrees and F = 60 / block time (1/min). The commands, sampled at the servo period,
are decimated into the fewest blocks whose linear interpolation in time stays within a
per-axis tolerance of every sample (:func:`decimate`, one linear scan); block ends are samples,
so no block is shorter than the servo period. Non-motion lines of the source program (tool
change, spindle, coolant, comments) are kept at their places when the samples carry their
source line numbers.

``halstreamer``: one line ``X Y Z A C`` per servo period (A, C in degrees) for LinuxCNC's
``streamer`` real-time component, fed by the ``halstreamer`` program; ``#`` lines are comments
(``streamer_usr.c`` skips lines whose first character is ``#``), values are read by ``strtod``.

The functions here build text only; :func:`precontour.tables.write_text` writes it atomically.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Iterator, Sequence

import numpy as np

from ..defaults import GCODE_TOL_LINEAR as DEFAULT_TOL_LINEAR
from ..defaults import GCODE_TOL_ROTARY as DEFAULT_TOL_ROTARY
from ..errors import InputError
from ..kernels import jit
from ..linuxcnc.streamer import STREAMER_FLOAT, streamer_depth
from ..machine.drives import AXES

# DEFAULT_TOL_LINEAR, DEFAULT_TOL_ROTARY, the default decimation tolerances (1 um on X, Y, Z,
# 1e-5 rad on A, C: ``--tol 0.001,1e-5``), are defined in precontour.defaults.
#: Decimals written: X Y Z in mm (5 nm rounding), A C in degrees (8.7e-9 rad rounding).
LINEAR_DECIMALS = 5
ANGLE_DECIMALS = 6
#: Significant digits of F (1/min) and of G4 P (s): the block times they give are exact to
#: 5e-11 relative, far below one servo period over any program length.
TIME_DIGITS = 10
#: Half a unit of the last written decimal: the rounding the decimation tolerance must leave.
LINEAR_ROUNDING = 0.5 * 10.0**-LINEAR_DECIMALS
ROTARY_ROUNDING = math.radians(0.5 * 10.0**-ANGLE_DECIMALS)
#: Program end words: when a kept source line already ends the program, none is added.
_PROGRAM_END = re.compile(r"(?<![A-Z0-9.])M0*(2|30)(?![0-9.])", re.IGNORECASE)
#: What the program needs of the CNC's planner, and where LinuxCNC 2.9's does not give it
#: (measured with LinuxCNC itself, docs/linuxcnc.md): the G-code header says so, with the
#: number of blocks that move a rotary axis.
PLANNER_NOTE = ("timing: each block must take exactly its 60/F s, blended at full speed "
                "into the next. LinuxCNC 2.9's planner does not for blocks that move "
                "{rotary}, here {count} of {blocks}: it blends them parabolically and "
                "stretches them. On LinuxCNC run the stream instead, run --stream or export "
                "--format halstreamer; precontour's docs/linuxcnc.md has the numbers")

__all__ = ["DEFAULT_TOL_LINEAR", "DEFAULT_TOL_ROTARY", "PLANNER_NOTE", "ProgramInfo",
           "GcodeProgram", "decimate", "gcode_program", "halstreamer_lines", "rotary_moves",
           "streamer_depth", "gcode_tolerances"]


@dataclass(frozen=True)
class ProgramInfo:
    """What the header comments of a written program name."""

    machine: str = ""
    controller: str = ""
    method: str = ""
    source: str = ""
    notes: tuple[str, ...] = ()

    def comment_lines(self) -> list[str]:
        items = [("machine", self.machine), ("controller", self.controller),
                 ("method", self.method), ("source", self.source)]
        lines = [f"{key}: {value}" for key, value in items if value]
        return lines + list(self.notes)


@dataclass(frozen=True)
class GcodeProgram:
    """A G-code program as text, and what it holds.

    Attributes
    ----------
    text : str
        The program, lines ending in ``\\n``.
    kept : ndarray of int
        Indices of the command samples that end a block (the first is the start point, which
        the initial ``G0`` goes to).
    n_blocks : int
        ``G1`` and ``G4`` blocks written (the ``G0`` not counted).
    tolerance : ndarray, shape (5,)
        Per-axis decimation tolerance, mm and rad.
    rotary_blocks : int
        Blocks that move a rotary axis (its written word changes). LinuxCNC 2.9's planner
        blends those parabolically and stretches them (see :data:`PLANNER_NOTE`).
    """

    text: str
    kept: np.ndarray
    n_blocks: int
    tolerance: np.ndarray
    rotary_blocks: int = 0


def gcode_tolerances(tol_linear: float = DEFAULT_TOL_LINEAR,
                    tol_rotary: float = DEFAULT_TOL_ROTARY) -> np.ndarray:
    """Per-axis tolerance (5,), mm on X Y Z and rad on A C; each must exceed the rounding of
    the written numbers (:data:`LINEAR_ROUNDING`, :data:`ROTARY_ROUNDING`) tenfold."""
    for name, value, rounding in (("linear", tol_linear, LINEAR_ROUNDING),
                                  ("rotary", tol_rotary, ROTARY_ROUNDING)):
        if not (np.isfinite(value) and value >= 10 * rounding):
            raise InputError(f"{name} tolerance must be at least {10 * rounding:.3g} "
                             f"(ten times the rounding of the written numbers), got {value!r}",
                             field="tol")
    return np.array([tol_linear] * 3 + [tol_rotary] * 2)


def decimate(t: np.ndarray, q: np.ndarray, tolerance: np.ndarray,
             must_keep: np.ndarray | None = None) -> np.ndarray:
    """Indices of the samples to keep so that linear interpolation in time between kept
    samples stays within ``tolerance`` (per column) of every sample.

    Greedy: from each kept sample the block is extended while the straight line to the next
    sample passes every sample in between within tolerance. That holds when the line's
    slope lies inside each in-between sample's slope interval
    [(q_k - tol - q_i) / (t_k - t_i), (q_k + tol - q_i) / (t_k - t_i)], so one running
    intersection of intervals makes the scan linear in the samples. The first and last
    samples and those flagged in ``must_keep`` are always kept.
    """
    t = np.ascontiguousarray(t, dtype=float)
    q = np.ascontiguousarray(q, dtype=float)
    if q.ndim != 2 or q.shape[0] != t.size:
        raise ValueError(f"q must have shape (N, k) with N = t.size, got {q.shape}")
    tolerance = np.ascontiguousarray(np.broadcast_to(tolerance, q.shape[1]), dtype=float)
    if must_keep is None:
        must_keep = np.zeros(t.size, dtype=np.bool_)
    must_keep = np.ascontiguousarray(must_keep, dtype=np.bool_)
    if t.size == 0:
        return np.zeros(0, dtype=np.int64)
    return np.flatnonzero(_decimate_scan(t, q, tolerance, must_keep))


@jit
def _decimate_scan(t, q, tol, must_keep):  # pragma: no cover - compiled
    n, m = q.shape
    keep = np.zeros(n, dtype=np.bool_)
    keep[0] = True
    keep[n - 1] = True
    lo = np.empty(m)
    hi = np.empty(m)
    lo[:] = -np.inf
    hi[:] = np.inf
    anchor = 0
    j = 1
    while j < n:
        dt = t[j] - t[anchor]
        fits = True
        for a in range(m):
            slope = (q[j, a] - q[anchor, a]) / dt
            if slope < lo[a] or slope > hi[a]:
                fits = False
                break
        if not fits:
            # j - 1 > anchor always fits (its interval set was empty when it was tried).
            anchor = j - 1
            keep[anchor] = True
            lo[:] = -np.inf
            hi[:] = np.inf
            continue
        if must_keep[j]:
            keep[j] = True
            anchor = j
            lo[:] = -np.inf
            hi[:] = np.inf
        else:
            for a in range(m):
                lo[a] = max(lo[a], (q[j, a] - tol[a] - q[anchor, a]) / dt)
                hi[a] = min(hi[a], (q[j, a] + tol[a] - q[anchor, a]) / dt)
        j += 1
    return keep


#: Program words that switch tool centre point mode on or off (Fanuc/LinuxCNC, Sinumerik).
_TCP_SWITCH = re.compile(r"G0*43\.[45](?!\d)|G0*49(?!\d)|TRAORI|TRAFOOF", re.IGNORECASE)
#: M codes every CNC knows; any other M code in a program read with ``--tcp`` may be the
#: controller's own TCP switch (LinuxCNC's remapped M428/M429).
_STANDARD_M = re.compile(r"M0*(?:[0-9]|30)(?!\d)", re.IGNORECASE)
_ANY_M = re.compile(r"M\d+", re.IGNORECASE)


def machine_axes_passthrough(passthrough: Sequence[tuple[int, str]], *, tcp: bool,
                             tcp_all: bool = False) -> tuple[tuple[int, str], ...]:
    """Pass-through lines of a program made safe for an output in machine axes.

    A written program gives machine axes, so a line that would switch the controller into
    tool centre point mode must not reach it: where the source program used TCP (``tcp``),
    G43.4/G43.5/G49/TRAORI/TRAFOOF lines, and with ``tcp_all`` (the whole program read with
    ``--tcp``) also lines with a non-standard M code (the controller's own TCP switch), are
    kept only as comments saying so.
    """
    if not tcp:
        return tuple(passthrough)
    kept = []
    for line, text in passthrough:
        code = text.split(";", 1)[0]
        code = re.sub(r"\([^)]*\)", "", code)
        switch = bool(_TCP_SWITCH.search(code)) or (
            tcp_all and any(not _STANDARD_M.fullmatch(m) for m in _ANY_M.findall(code)))
        if switch:
            text = "(" + _comment("precontour: left out, this program is in machine axes, not "
                                  "tool centre point mode: " + text) + ")"
        kept.append((line, text))
    return tuple(kept)


def gcode_program(t: np.ndarray, q: np.ndarray, *, tolerance: np.ndarray | None = None,
                  info: ProgramInfo = ProgramInfo(),
                  passthrough: Sequence[tuple[int, str]] | None = None,
                  line: np.ndarray | None = None,
                  axis_names: Sequence[str] = AXES) -> GcodeProgram:
    """Machine-axis G-code for the commands ``q`` (N, 5: mm, rad) at times ``t`` (s).

    ``axis_names`` are the words written for the five axes (``Machine.axis_names``: X Y Z B C
    on a B-C machine).

    Parameters
    ----------
    t, q
        Command samples, strictly increasing times.
    tolerance : array_like, shape (5,), optional
        Per-axis decimation tolerance in mm and rad (default 1 um, 1e-5 rad). The rounding
        of the written numbers is taken out of it, so the written program, interpolated
        linearly in time, is within ``tolerance`` of every sample.
    info : ProgramInfo
        Named in the header comments.
    passthrough : sequence of (source line, text), optional
        Non-motion lines of the source program. Each goes before the first block whose samples
        come from a later source line (blocks are split there), or before the initial ``G0``
        when it precedes the first sample's line; without ``line`` they all go before it.
    line : array_like of int, shape (N,), optional
        Source line number of each sample (non-decreasing).
    """
    t = np.asarray(t, dtype=float)
    q = np.asarray(q, dtype=float)
    if q.shape != (t.size, len(AXES)) or t.size < 2:
        raise ValueError(f"need at least 2 samples of t (N,) and q (N, 5), got {t.shape}, "
                         f"{q.shape}")
    tolerance = gcode_tolerances() if tolerance is None else np.asarray(tolerance, dtype=float)
    rounding = np.array([LINEAR_ROUNDING] * 3 + [ROTARY_ROUNDING] * 2)
    # The rounding of both block ends shifts the interpolating line by at most one rounding.
    effective = (tolerance - rounding) * (1.0 - 1e-9)
    passthrough = list(passthrough or ())
    must_keep = None
    before_start: list[str] = []
    inserted: dict[int, list[str]] = {}
    if line is not None and passthrough:
        line = np.asarray(line)
        if line.shape != t.shape:
            raise ValueError(f"line must have shape {t.shape}, got {line.shape}")
        pass_lines = np.array([number for number, _ in passthrough])
        # A block ends where the source line passes a kept line, so that line goes between.
        boundary = np.searchsorted(line, pass_lines, side="right")  # first sample after it
        must_keep = np.zeros(t.size, dtype=bool)
        inside = (boundary > 0) & (boundary < t.size)
        must_keep[boundary[inside] - 1] = True
    kept = decimate(t, q, effective, must_keep)
    if line is not None and passthrough:
        # Block b runs from kept[b] to kept[b + 1]; its samples come from line[kept[b] + 1] on.
        first_line = line[kept[:-1] + 1]
        for (number, text), at_sample in zip(passthrough, boundary):
            if at_sample == 0:
                before_start.append(text)
            else:
                block = int(np.searchsorted(first_line, number, side="right"))
                inserted.setdefault(block, []).append(text)
    elif passthrough:
        before_start = [text for _, text in passthrough]

    rotary_blocks = rotary_moves(q[kept])
    text_lines = list(_gcode_lines(t, q, kept, info, tolerance, before_start, inserted,
                                    tuple(axis_names), int(rotary_blocks.sum())))
    n_blocks = kept.size - 1
    return GcodeProgram(text="".join(text_lines), kept=kept, n_blocks=n_blocks,
                        tolerance=tolerance, rotary_blocks=int(rotary_blocks.sum()))


def rotary_moves(q_kept: np.ndarray) -> np.ndarray:
    """For each block between consecutive rows of ``q_kept`` (block ends, rad): whether a
    rotary axis word changes as written (degrees, :data:`ANGLE_DECIMALS`)."""
    written = np.round(np.degrees(np.asarray(q_kept, dtype=float)[:, 3:]), ANGLE_DECIMALS)
    return np.any(np.diff(written, axis=0) != 0, axis=1)


def _gcode_lines(t, q, kept, info, tolerance, before_start, inserted,
                 axis_names, rotary_blocks) -> Iterator[str]:
    duration = t[kept[-1]] - t[kept[0]]
    linear, rotary = " ".join(axis_names[:3]), " ".join(axis_names[3:])
    yield "%\n"
    yield (f"(precontour: compensated axis commands, machine axes {linear} mm, {rotary} "
           "degrees)\n")
    for text in info.comment_lines():
        yield f"({_comment(text)})\n"
    yield (f"(tolerance {tolerance[0]:g} mm on {linear}, {tolerance[3]:g} rad on {rotary}; "
           f"{kept.size - 1} blocks, {duration:.3f} s of motion)\n")
    yield "(inverse-time feed G93: F = 60 / block time in s)\n"
    note = PLANNER_NOTE.format(rotary=" or ".join(axis_names[3:]), count=rotary_blocks,
                               blocks=kept.size - 1)
    for part in _wrap(note):
        yield f"({_comment(part)})\n"
    yield "G21 G90 G94\n"
    for text in before_start:
        yield text.rstrip("\n") + "\n"
    words = _axis_words(q[kept], axis_names)
    yield f"G0 {words[0]}\n"
    yield f"G64 P{tolerance[0]:g}\n"
    yield "G93\n"
    dt = np.diff(t[kept])
    feeds = [f"{60.0 / step:.{TIME_DIGITS}g}" for step in dt]
    for b in range(kept.size - 1):
        for text in inserted.get(b, ()):
            yield text.rstrip("\n") + "\n"
        if words[b + 1] == words[b]:
            # No axis moves in the written digits: a dwell keeps the time (a zero-length G1
            # would be dropped by the interpreter).
            yield f"G4 P{dt[b]:.{TIME_DIGITS}g}\n"
        else:
            yield f"G1 {words[b + 1]} F{feeds[b]}\n"
    yield "G94\n"
    tail = inserted.get(kept.size - 1, [])
    for text in tail:
        yield text.rstrip("\n") + "\n"
    if not any(_PROGRAM_END.search(text) for text in tail):
        yield "M2\n"
    yield "%\n"


def _axis_words(q: np.ndarray, axis_names: Sequence[str] = AXES) -> list[str]:
    """``X.. Y.. Z.. A.. C..`` per row (the machine's axis letters): mm, and degrees for the
    rotary axes."""
    decimals = [LINEAR_DECIMALS] * 3 + [ANGLE_DECIMALS] * 2
    values = np.column_stack([np.round(q[:, :3], LINEAR_DECIMALS),
                              np.round(np.degrees(q[:, 3:]), ANGLE_DECIMALS)]) + 0.0  # no -0
    fmt = " ".join(f"{axis}{{:.{d}f}}" for axis, d in zip(axis_names, decimals))
    return [fmt.format(*row) for row in values.tolist()]


def _wrap(text: str, width: int = 90) -> list[str]:
    """``text`` in lines of at most about ``width`` characters, broken between words."""
    lines, current = [], ""
    for word in text.split():
        if current and len(current) + 1 + len(word) > width:
            lines.append(current)
            current = word
        else:
            current = f"{current} {word}" if current else word
    return lines + ([current] if current else [])


def _comment(text: str) -> str:
    """Text safe inside a ``( )`` comment: no parentheses, one line."""
    return " ".join(str(text).replace("(", "[").replace(")", "]").split())


def halstreamer_lines(q: np.ndarray, ts: float, *, info: ProgramInfo = ProgramInfo(),
                      chunk: int = 100_000) -> Iterator[str]:
    """Text of a ``halstreamer`` file, in chunks: a ``#`` comment header, then one line
    ``X Y Z A C`` (mm, degrees; shortest round-trip decimals) per servo period ``ts``."""
    import pyarrow as pa
    import pyarrow.csv as pacsv

    q = np.asarray(q, dtype=float)
    if q.ndim != 2 or q.shape[1] != len(AXES):
        raise ValueError(f"q must have shape (N, 5), got {q.shape}")
    depth = streamer_depth(ts)
    period_ns = int(round(ts * 1e9))
    header = ["precontour: compensated axis commands for LinuxCNC's streamer component",
              *info.comment_lines(),
              f"columns: X Y Z (mm) A C (degrees), one line per servo period of {ts:g} s "
              f"({1.0 / ts:g} Hz), {q.shape[0]} lines = {q.shape[0] * ts:.3f} s",
              f"HAL: loadrt streamer depth={depth} cfg={STREAMER_FLOAT * len(AXES)}",
              "HAL: addf streamer.0 servo-thread   (servo thread period "
              f"{period_ns} ns)",
              "HAL: pins streamer.0.pin.0 .. pin.4 are X Y Z A C; then: "
              "halstreamer -c 0 < this-file"]
    yield "".join(f"# {text}\n" for text in header)
    values = np.column_stack([q[:, :3], np.degrees(q[:, 3:])])
    options = pacsv.WriteOptions(include_header=False, delimiter=" ")
    for start in range(0, values.shape[0], chunk):
        block = values[start:start + chunk]
        table = pa.table({axis: block[:, i] for i, axis in enumerate(AXES)})
        sink = pa.BufferOutputStream()
        pacsv.write_csv(table, sink, write_options=options)
        yield sink.getvalue().to_pybytes().decode()

