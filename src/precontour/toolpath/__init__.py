"""Tool paths as programmed: tool tip points and orientations in the workpiece frame.

NC programs (G-code, :mod:`.gcode`; Heidenhain conversational, :mod:`.heidenhain`) are read
by :func:`read_program` into a
:class:`~.program.Program` in machine axes, which the trajectory stage times as a CNC does.
Each reader (one module per file format: :mod:`.clcsv`, :mod:`.apt`, :mod:`.gcode`) returns a
:class:`ToolPath`; :func:`read_toolpath` picks one by file extension (:mod:`.readers`). The
``*_report`` variants return a :class:`ReadReport` with the source line of each point, rapid
flags, and what was dropped or skipped. All readers apply the same checks
(:func:`._common.finish`). Trajectory generation turns a tool path into a time-stamped
:class:`~precontour.trajectory.sampled.Trajectory`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class ToolPath:
    """Programmed tool path.

    Attributes
    ----------
    P : ndarray, shape (M, 3)
        Tool tip points, mm, workpiece frame.
    O : ndarray, shape (M, 3)
        Unit tool orientations, workpiece frame.
    feed : ndarray, shape (M,), optional
        Programmed feed in mm/s for the move that ends at each point (NaN where none was
        programmed; the first entry refers to the start point and is ignored).
    source : str
        File name or built-in name, for messages.
    """

    P: np.ndarray
    O: np.ndarray
    feed: np.ndarray | None = None
    source: str = ""

    @property
    def n_points(self) -> int:
        return int(np.asarray(self.P).shape[0])


# Readers import ToolPath from this module, so they are imported after it is defined.
from ._common import FEED_UNITS, ReadReport  # noqa: E402
from .apt import read_apt, read_apt_report  # noqa: E402
from .clcsv import read_clcsv, read_clcsv_report  # noqa: E402
from .gcode import read_gcode, read_gcode_report  # noqa: E402
from .heidenhain import read_heidenhain, read_heidenhain_report  # noqa: E402
from .program import Program, ProgrammedMoves, Stop  # noqa: E402
from .readers import (EXTENSIONS, PROGRAM_FORMATS, read_program, read_toolpath,  # noqa: E402
                      read_toolpath_report, toolpath_format)

__all__ = ["ToolPath", "ReadReport", "FEED_UNITS", "EXTENSIONS", "read_toolpath",
           "read_toolpath_report", "toolpath_format", "read_clcsv", "read_clcsv_report",
           "read_apt", "read_apt_report", "read_gcode", "read_gcode_report", "read_program",
           "read_heidenhain", "read_heidenhain_report", "PROGRAM_FORMATS", "Program",
           "ProgrammedMoves", "Stop"]
