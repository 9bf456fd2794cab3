"""Checks and bookkeeping shared by the tool-path readers.

Every reader parses its format into raw arrays (points, orientations, feeds, the source line
of each point) and hands them to :func:`finish`, which applies the same validation to all
formats and returns a :class:`ReadReport` holding the :class:`~precontour.toolpath.ToolPath`
and what was dropped or skipped on the way.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Mapping

import numpy as np

from ..errors import InputError, ToolPathError
from ..files import check_input_file, refuse_non_text
from ..machine.kinematics import UNIT_TOLERANCE, normalize_orientations
from . import ToolPath

#: Feed units a reader accepts for numbers that do not carry their own unit, and the factor
#: that converts each to mm/s.
FEED_UNITS: Mapping[str, float] = MappingProxyType({"mm/min": 1.0 / 60.0, "mm/s": 1.0})

#: mm per inch (exact by definition).
INCH = 25.4

#: Largest |Px|, |Py|, |Pz| read, mm (1 km): beyond any machine's travel.
MAX_COORDINATE = 1e6

#: |O| below which an orientation is called zero-length rather than non-unit.
ZERO_LENGTH = 1e-9

_FIELDS = ("Px", "Py", "Pz", "Oi", "Oj", "Ok")


@dataclass(frozen=True)
class ReadReport:
    """A tool path as read, with what the reader dropped or skipped.

    Attributes
    ----------
    toolpath : ToolPath
        The validated tool path (M points).
    format : str
        ``"clcsv"``, ``"apt"`` or ``"gcode"``.
    lines : ndarray of int, shape (M,)
        1-based line in the file of the statement, block or row that programmed each point.
    rapid : ndarray of bool, shape (M,)
        True where the move ending at the point is a rapid (APT ``RAPID``, G-code ``G0``);
        its feed is NaN.
    n_read : int
        Points read before consecutive duplicates were dropped.
    n_duplicates : int
        Consecutive duplicate points (same P and O, exactly) dropped; ``n_read - M``.
    skipped : Mapping[str, int]
        Statements, codes or words that were read and ignored, with their counts
        (e.g. ``{"SPINDL": 1, "PAINT": 12}`` for APT, ``{"M3": 1, "S": 1}`` for G-code).
    axes : ndarray, shape (M, 5), or None
        Machine-axis positions [X, Y, Z, A, C] (mm, rad) of each point, for G-code.
    """

    toolpath: ToolPath
    format: str
    lines: np.ndarray
    rapid: np.ndarray
    n_read: int
    n_duplicates: int
    skipped: Mapping[str, int] = field(default_factory=dict)
    axes: np.ndarray | None = None

    @property
    def n_skipped(self) -> int:
        """Total number of statements, codes or words ignored."""
        return int(sum(self.skipped.values()))


def feed_factor(feed_units: str) -> float:
    """Factor from ``feed_units`` to mm/s; raise naming the allowed units."""
    try:
        return FEED_UNITS[feed_units]
    except (KeyError, TypeError):
        raise InputError(f"unknown feed unit {feed_units!r}; use one of "
                         f"{', '.join(map(repr, FEED_UNITS))}", field="feed_units") from None


def read_bytes(path: str | Path) -> bytes:
    """Read a tool-path file, turning OS errors into :class:`ToolPathError` (a folder or a
    FIFO is called that)."""
    check_input_file(path, "tool-path file", error=ToolPathError)
    try:
        data = Path(path).read_bytes()
    except OSError as exc:
        raise ToolPathError(f"cannot read tool-path file: {exc.strerror or exc}",
                            source=str(path)) from None
    refuse_non_text(data, str(path), error=ToolPathError)
    return data


def read_text(path: str | Path) -> str:
    """Read a text tool-path file. Numbers are ASCII; bytes that are not UTF-8 can only sit
    in comments, so they are replaced instead of failing the read. Compressed, UTF-16 and
    binary files are refused."""
    return read_bytes(path).decode("utf-8-sig", errors="replace")


def finish(P, O, feed, *, lines, source: str, format: str, empty: str, rapid=None,
           skipped: Mapping[str, int] | None = None, axes=None) -> ReadReport:
    """Validate raw reader output and build the :class:`ReadReport`.

    Parameters
    ----------
    P, O : array_like, shape (N, 3)
        Tool tip points (mm) and orientations as read (not yet normalized).
    feed : array_like, shape (N,)
        Feed in mm/s, NaN where none was programmed.
    lines : array_like of int, shape (N,)
        Source line of each point, for messages.
    source : str
        File name, for messages.
    format : str
        Format name stored in the report.
    empty : str
        Message when there are no points at all (says what the format calls a motion).
    rapid : array_like of bool, shape (N,), optional
    skipped : mapping, optional
    axes : array_like, shape (N, 5), optional

    Raises
    ------
    ToolPathError
        No points; a non-finite value; a zero-length orientation; an orientation whose
        length is off one by more than :data:`~precontour.machine.kinematics.UNIT_TOLERANCE`; a
        non-positive or infinite feed; fewer than two distinct points; an orientation that
        turns by more than 90 degrees in one move.
    """
    P = np.asarray(P, dtype=float).reshape(-1, 3)
    O = np.asarray(O, dtype=float).reshape(-1, 3)
    feed = np.asarray(feed, dtype=float).reshape(-1)
    lines = np.asarray(lines, dtype=np.int64).reshape(-1)
    n = P.shape[0]
    rapid = np.zeros(n, dtype=bool) if rapid is None else np.asarray(rapid, dtype=bool)
    if n == 0:
        raise ToolPathError(empty, source=source)

    PO = np.concatenate([P, O], axis=1)
    bad = ~np.isfinite(PO)
    if bad.any():
        r, c = np.argwhere(bad)[0]
        raise ToolPathError(f"value is not finite ({float(PO[r, c])})", source=source,
                            row=int(lines[r]), field=_FIELDS[c])
    big = np.abs(PO) > np.array([MAX_COORDINATE] * 3 + [2.0] * 3)
    if big.any():
        r, c = np.argwhere(big)[0]
        what = "no machine coordinate" if c < 3 else "no unit vector component"
        raise ToolPathError(f"value {float(PO[r, c]):g} is out of range ({what})",
                            source=source, row=int(lines[r]), field=_FIELDS[c])
    bad_feed = (feed <= 0.0) | np.isinf(feed)
    if bad_feed.any():
        r = int(np.flatnonzero(bad_feed)[0])
        raise ToolPathError(f"feed must be positive and finite, got {feed[r]:g} mm/s",
                            source=source, row=int(lines[r]), field="F")

    norm = np.linalg.norm(O, axis=1)
    zero = norm < ZERO_LENGTH
    if zero.any():
        r = int(np.flatnonzero(zero)[0])
        raise ToolPathError("orientation vector has zero length", source=source,
                            row=int(lines[r]), field="O")
    off = np.abs(norm - 1.0) > UNIT_TOLERANCE
    if off.any():
        r = int(np.flatnonzero(off)[0])
        raise ToolPathError(f"orientation vector is not unit length (|O| = {norm[r]:.9g}; "
                            f"only deviations up to {UNIT_TOLERANCE:g} are normalized)",
                            source=source, row=int(lines[r]), field="O")
    O = normalize_orientations(O, source=source)

    # CAM output repeats points (segment joins, re-emitted orientations); a zero-length move
    # carries no geometry, so the first of each run is kept.
    keep = np.ones(n, dtype=bool)
    keep[1:] = np.any(P[1:] != P[:-1], axis=1) | np.any(O[1:] != O[:-1], axis=1)
    P, O, feed, lines, rapid = P[keep], O[keep], feed[keep], lines[keep], rapid[keep]
    if axes is not None:
        axes = np.asarray(axes, dtype=float)[keep]
    m = P.shape[0]
    if m < 2:
        raise ToolPathError(f"fewer than 2 distinct points ({n} read, {n - m} consecutive "
                            "duplicates dropped)", source=source, row=int(lines[0]))

    # A reader sees only the end orientations of a move; beyond 90 degrees (e.g. an
    # orientation flipped through A = 0) it cannot know which way the tool should turn.
    cos_turn = np.einsum("ij,ij->i", O[1:], O[:-1])
    flip = cos_turn < 0.0
    if flip.any():
        k = int(np.flatnonzero(flip)[0])
        angle = np.degrees(np.arccos(np.clip(cos_turn[k], -1.0, 1.0)))
        raise ToolPathError(
            f"tool orientation turns by {angle:.1f} deg (more than 90) in one move from "
            f"line {lines[k]}; the direction of rotation is ambiguous (e.g. a flip through "
            "A = 0): add intermediate orientations", source=source, row=int(lines[k + 1]),
            field="O")

    toolpath = ToolPath(P=P, O=O, feed=feed, source=source)
    return ReadReport(toolpath=toolpath, format=format, lines=lines, rapid=rapid, n_read=n,
                      n_duplicates=n - m, skipped=MappingProxyType(dict(skipped or {})),
                      axes=axes)
