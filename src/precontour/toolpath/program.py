"""An NC program as the machine executes it: moves in machine axes, stops, and the lines an
output program keeps.

:class:`Program` is what :func:`precontour.toolpath.read_program` returns and what
:func:`precontour.trajectory.program_trajectory` times and the program writers re-emit. Arcs
are already subdivided into chords (each chord a move with the arc's source line); tool
centre point (TCP) moves are already converted to machine axes, and flagged, because their
interpolation between end points runs in the tool-tip frame.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Mapping

import numpy as np

__all__ = ["Program", "ProgrammedMoves", "Stop", "STOP_KINDS", "MOVE_KINDS"]

#: What makes the program stop, as :attr:`Stop.kind`.
STOP_KINDS = ("dwell", "program stop", "optional stop", "tool change", "end")


@dataclass(frozen=True)
class Stop:
    """A point where the program stops: the axes come to rest there.

    Attributes
    ----------
    index : int
        Number of moves executed before the stop (it happens at the end of move
        ``index - 1``, or at the start when 0).
    line : int
        1-based source line of the block that stops.
    kind : str
        One of :data:`STOP_KINDS` (G4, M0, M1, M6, M2/M30).
    seconds : float
        Programmed dwell time (G4 P or X), s; NaN for the other kinds (the trajectory holds
        them for its ``dwell``).
    """

    index: int
    line: int
    kind: str
    seconds: float = float("nan")


#: Kinds of programmed move (:attr:`ProgrammedMoves.kind` 0, 1, 2), LinuxCNC's canonical
#: STRAIGHT_TRAVERSE, STRAIGHT_FEED and ARC_FEED.
MOVE_KINDS = ("traverse", "feed", "arc")


def _frozen(obj, spec):
    """Set ``obj``'s array fields to read-only arrays of the given dtypes and row shapes."""
    m = None
    for name, dtype, width in spec:
        value = np.asarray(getattr(obj, name), dtype=dtype)
        if m is None:
            m = value.shape[0] if value.ndim else 0
        value = value.reshape((m, width) if width else (m,))
        value.setflags(write=False)
        object.__setattr__(obj, name, value)


@dataclass(frozen=True)
class ProgrammedMoves:
    """The moves as programmed: one row per straight move or arc, before arcs are cut into
    chords and TCP tool tips become machine axes -- what an RS274/NGC interpreter hands its
    motion planner (LinuxCNC's canonical STRAIGHT_TRAVERSE, STRAIGHT_FEED and ARC_FEED).

    Attributes
    ----------
    kind : ndarray of int8, shape (K,)
        0 traverse (G0, G28/G30/G53 rapids), 1 straight feed, 2 arc (see :data:`MOVE_KINDS`).
    end : ndarray, shape (K, 5)
        Absolute end point, mm and degrees: the words plus the work and G92 offsets; for a
        TCP move the tool tip (workpiece frame) and the rotary axes, else the machine axes.
    centre : ndarray, shape (K, 3)
        Arc centre, absolute, mm, in the arc plane's two axes (NaN in its normal axis and for
        straight moves).
    plane : ndarray of int8, shape (K,)
        Arc plane, 17, 18 or 19 (G17-G19); 0 for straight moves.
    turns : ndarray of int, shape (K,)
        Arc turns with their sense, as ARC_FEED's rotation: +n counter-clockwise (G3), -n
        clockwise (G2), n = P (1 without it); 0 for straight moves.
    inverse_time : ndarray of bool, shape (K,)
        Programmed in G93.
    feed : ndarray, shape (K,)
        F as programmed: mm/min (G94; degrees/min for a rotary-only move) or 1/min (G93);
        NaN for traverses.
    line : ndarray of int, shape (K,)
        1-based source line of the block (the line executing, inside a subroutine its own).
    tcp : ndarray of bool, shape (K,)
        Programmed in TCP mode.
    first : ndarray of int, shape (K,)
        Index of the first of :attr:`Program.q`'s moves it became; an arc's chords are
        ``first[k]`` up to ``first[k + 1] - 1``.
    """

    kind: np.ndarray
    end: np.ndarray
    centre: np.ndarray
    plane: np.ndarray
    turns: np.ndarray
    inverse_time: np.ndarray
    feed: np.ndarray
    line: np.ndarray
    tcp: np.ndarray
    first: np.ndarray

    def __post_init__(self):
        _frozen(self, (("kind", np.int8, 0), ("end", float, 5), ("centre", float, 3),
                       ("plane", np.int8, 0), ("turns", np.int64, 0),
                       ("inverse_time", bool, 0), ("feed", float, 0), ("line", np.int64, 0),
                       ("tcp", bool, 0), ("first", np.int64, 0)))

    @property
    def n_moves(self) -> int:
        return int(self.kind.shape[0])


@dataclass(frozen=True)
class Program:
    """A parsed NC program in machine axes.

    Attributes
    ----------
    start : ndarray, shape (5,)
        Machine axes q = [X, Y, Z, A, C] (mm, rad) at the start: the first block after which
        all five axes are known (axes never programmed before the first feed move are 0, in
        the frame they were unknown in).
    start_line : int
        Source line of that block.
    q : ndarray, shape (M, 5)
        Machine axes at the end of each move, mm and rad. Rotary axes as programmed
        (negative A, multi-turn C, never re-branched).
    rapid : ndarray of bool, shape (M,)
        True for G0 moves (timed by the machine's rapid rate, i.e. its axis velocity limits).
    duration : ndarray, shape (M,)
        Programmed time of each feed move, s: 60/F for G93 (inverse time), path length / F
        for G94; NaN for rapids. A subdivided arc shares its time equally among its chords.
    feed : ndarray, shape (M,)
        Programmed G94 feed, mm/s (deg/s for a rotary-only move); NaN for G93 and rapids.
    line : ndarray of int, shape (M,)
        1-based source line of the block that programmed each move.
    tcp_move : ndarray of bool, shape (M,)
        Move programmed in TCP mode: tool tip and rotary axes interpolate linearly in the
        workpiece frame, the linear axes follow from the kinematics.
    stops : tuple of Stop
        Program stops, in program order.
    passthrough : tuple of (int, str)
        (source line, text) of the non-motion content an output program keeps: comments,
        tool change, spindle, coolant, other M codes and mode words (G17-G19, G40, G43, G49,
        G61, G64, G80). A line that also moves keeps only those words. Work offsets
        (G54-G59.3) are applied to ``q``, not kept.
    source : str
        File name.
    tcp : bool
        True when any move was programmed in TCP mode (``--tcp`` or G43.4/G43.5/TRAORI).
    axes : tuple of str
        Axis letters of q (the machine's), e.g. ``("X", "Y", "Z", "A", "C")``.
    notices : tuple of str
        One-line notices for the user (unknown M codes kept as pass-through, axes taken as 0).
    skipped : Mapping[str, int]
        Codes and words read and not acted on, with counts (``{"M3": 1, "S": 1, "/": 2}``).
    path_tolerance : ndarray, shape (M,)
        Path tolerance in force at each move, mm: G64 P, 0 under G61/G61.1 (exact path), NaN
        where the program gives none (the trajectory's default applies).
    programmed : ProgrammedMoves or None
        The moves as programmed (straight moves and whole arcs, before the kinematics), from
        :func:`~precontour.toolpath.read_program`.
    """

    start: np.ndarray
    start_line: int
    q: np.ndarray
    rapid: np.ndarray
    duration: np.ndarray
    feed: np.ndarray
    line: np.ndarray
    tcp_move: np.ndarray
    stops: tuple[Stop, ...] = ()
    passthrough: tuple[tuple[int, str], ...] = ()
    source: str = ""
    tcp: bool = False
    axes: tuple[str, ...] = ("X", "Y", "Z", "A", "C")
    notices: tuple[str, ...] = ()
    skipped: Mapping[str, int] = field(default_factory=lambda: MappingProxyType({}))
    path_tolerance: np.ndarray | None = None
    programmed: ProgrammedMoves | None = None

    def __post_init__(self):
        m = np.asarray(self.q).reshape(-1, 5).shape[0]
        if self.path_tolerance is None:
            object.__setattr__(self, "path_tolerance", np.full(m, np.nan))
        for name, dtype in (("q", float), ("rapid", bool), ("duration", float),
                            ("feed", float), ("line", np.int64), ("tcp_move", bool),
                            ("path_tolerance", float)):
            value = np.asarray(getattr(self, name), dtype=dtype)
            value = value.reshape(m, 5) if name == "q" else value.reshape(m)
            value.setflags(write=False)
            object.__setattr__(self, name, value)
        start = np.asarray(self.start, dtype=float).reshape(5)
        start.setflags(write=False)
        object.__setattr__(self, "start", start)

    @property
    def n_moves(self) -> int:
        return int(self.q.shape[0])

    @property
    def points(self) -> np.ndarray:
        """Start and every move's end point, shape (M + 1, 5)."""
        return np.concatenate([self.start[None, :], self.q])
