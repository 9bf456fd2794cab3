"""Pick the tool-path reader for a file by its extension (or an explicit ``format``).

=========  ============================================================  ===================
format     extensions                                                    reader
=========  ============================================================  ===================
clcsv      ``.csv``                                                      :mod:`.clcsv`
apt        ``.apt .cls .cl .aptsource``                                  :mod:`.apt`
gcode      ``.nc .ngc .gcode .gc .tap .mpf .cnc .iso`` (needs a machine)  :mod:`.gcode`
heidenhain ``.h`` (Heidenhain TNC conversational; needs a machine)          :mod:`.heidenhain`
=========  ============================================================  ===================

Extensions are matched without regard to case. ``.txt`` is deliberately not mapped (it is
used for all of them); pass ``format=`` for such files. :func:`read_program` reads either NC
language into a :class:`~.program.Program`.
"""

from __future__ import annotations

from pathlib import Path
from types import MappingProxyType

from ..errors import InputError, ToolPathError
from ._common import ReadReport
from ._dialects import REPOST
from .apt import read_apt_report
from .clcsv import read_clcsv_report
from .gcode import ARC_CHORD_TOLERANCE, read_gcode_report
from .gcode import read_program as read_gcode_program
from .heidenhain import read_heidenhain_program, read_heidenhain_report
from .program import Program

#: File extensions of each format.
EXTENSIONS = MappingProxyType({
    "clcsv": (".csv",),
    "apt": (".apt", ".cls", ".cl", ".aptsource"),
    "gcode": (".nc", ".ngc", ".gcode", ".gc", ".tap", ".mpf", ".cnc", ".iso"),
    "heidenhain": (".h",),
})

#: The formats that are NC programs (read into a :class:`~.program.Program`, need a machine).
PROGRAM_FORMATS = ("gcode", "heidenhain")

#: The formats, as the command line's ``--format`` offers them
#: (:data:`precontour.defaults.TOOLPATH_FORMATS`, which must list the same).
FORMATS = tuple(EXTENSIONS)

#: Extensions of programs in a language precontour does not read, and the language.
FOREIGN_EXTENSIONS = MappingProxyType({})

__all__ = ["read_toolpath", "read_toolpath_report", "read_program", "toolpath_format",
           "EXTENSIONS", "FORMATS", "PROGRAM_FORMATS"]


def toolpath_format(path: str | Path, format: str | None = None) -> str:
    """Format name (``"clcsv"``, ``"apt"``, ``"gcode"`` or ``"heidenhain"``) of a file: ``format`` when given
    (checked), else from the file's extension."""
    if format is not None:
        if format not in EXTENSIONS:
            raise InputError(f"unknown tool-path format {format!r}; use one of "
                             f"{', '.join(FORMATS)}", field="format")
        return format
    suffix = Path(path).suffix.lower()
    for name, suffixes in EXTENSIONS.items():
        if suffix in suffixes:
            return name
    if suffix in FOREIGN_EXTENSIONS:
        raise ToolPathError(f"{suffix!r} is the extension of {FOREIGN_EXTENSIONS[suffix]} "
                            f"programs, which precontour does not read; {REPOST} (if the file is "
                            "G-code after all: --format gcode, or format='gcode')",
                            source=str(path))
    known = ", ".join(s for suffixes in EXTENSIONS.values() for s in suffixes)
    raise ToolPathError(f"unknown tool-path extension {suffix or '(none)'!r}; supported: "
                        f"{known} (or give the format, --format or format=, one of "
                        f"{', '.join(FORMATS)})",
                        source=str(path))


def read_toolpath(path: str | Path, *, machine=None, feed_units: str = "mm/min",
                  format: str | None = None, tcp: bool = False, tool_table=None):
    """Read a tool path file of any supported format.

    Parameters
    ----------
    path : str or Path
        Tool path file; the format follows from the extension (see the module docstring).
    machine : Machine or str, optional
        Needed for G-code (machine axes -> tool tip and orientation); a built-in machine
        name or machine file path is loaded. Ignored for CL data.
    feed_units : {"mm/min", "mm/s"}
        Unit of CL-data feeds that carry none (CSV ``F`` column, bare APT ``FEDRAT``).
        G-code carries its own (G93 inverse time, G94 per minute) and ignores it. A G-code
        program read this way is its points only; :func:`~precontour.toolpath.read_program`
        gives the whole program (block times, stops, pass-through lines), which
        :func:`~precontour.trajectory.program_trajectory` times as a CNC does.
    format : {"clcsv", "apt", "gcode", "heidenhain"}, optional
        Override the extension.
    tcp : bool
        G-code only: the program starts in tool centre point mode (see
        :func:`~precontour.toolpath.gcode.read_program`).
    tool_table : str, Path or Mapping[int, float], optional
        G-code only: tool lengths, a LinuxCNC ``.tbl`` file or a mapping (see
        :func:`~precontour.toolpath.gcode.read_program`); None: the machine file's ``[tools]``.

    Returns
    -------
    ToolPath
    """
    return read_toolpath_report(path, machine=machine, feed_units=feed_units,
                                format=format, tcp=tcp, tool_table=tool_table).toolpath


def read_toolpath_report(path: str | Path, *, machine=None, feed_units: str = "mm/min",
                         format: str | None = None, tcp: bool = False,
                         tool_table=None) -> ReadReport:
    """Like :func:`read_toolpath`, returning the :class:`ReadReport` (line of each point,
    rapid flags, duplicates dropped, skipped statements, G-code axis positions)."""
    format = toolpath_format(path, format)
    if format == "clcsv":
        return read_clcsv_report(path, feed_units=feed_units)
    if format == "apt":
        return read_apt_report(path, feed_units=feed_units)
    if machine is None:
        language = "a Heidenhain program" if format == "heidenhain" else "G-code"
        raise ToolPathError(f"{language} gives machine-axis positions: reading it needs a "
                            "machine (machine=...)", source=str(path))
    if format == "heidenhain":
        _no_tcp_option(path, tcp)
        _no_tool_table(path, tool_table)
        return read_heidenhain_report(path, machine)
    return read_gcode_report(path, machine, tcp=tcp, tool_table=tool_table)


def read_program(path: str | Path, machine, *, tcp: bool = False, block_delete: bool = True,
                 arc_tolerance: float = ARC_CHORD_TOLERANCE,
                 format: str | None = None, tool_table=None) -> Program:
    """Read an NC program into machine-axis moves.

    Parameters
    ----------
    path : str or Path
        The program: G-code (:func:`~precontour.toolpath.gcode.read_program`, see there for
        the dialects) or Heidenhain conversational
        (:func:`~precontour.toolpath.heidenhain.read_heidenhain_program`), by ``format`` or
        the file's extension (an extension of neither is read as G-code).
    machine : Machine
        The machine the program is for (its kinematics and axes).
    tcp : bool
        The program starts in TCP mode (for controllers that switch it with M codes the
        machine file does not name).
    block_delete : bool
        Skip blocks starting with ``/``.
    arc_tolerance : float
        Largest distance between an arc and its chords, mm.
    format : str, optional
        The program's format instead of the one its extension says.
    tool_table : str, Path or Mapping[int, float], optional
        Tool lengths (mm) by tool number: a LinuxCNC tool table file or a mapping; it
        replaces the machine file's ``[tools]``.

    Returns
    -------
    Program
        Moves in machine axes, with their source lines, stops and pass-through lines.
    """
    name = None
    try:
        name = toolpath_format(path, format)
    except ToolPathError:
        if format is not None:
            raise
    if name == "heidenhain":
        _no_tcp_option(path, tcp)
        _no_tool_table(path, tool_table)
        return read_heidenhain_program(path, machine, block_delete=block_delete,
                                       arc_tolerance=arc_tolerance)
    return read_gcode_program(path, machine, tcp=tcp, block_delete=block_delete,
                              arc_tolerance=arc_tolerance, tool_table=tool_table)


def _no_tcp_option(path, tcp: bool) -> None:
    if tcp:
        raise InputError("--tcp (tcp=True) applies to G-code programs; a Heidenhain program "
                         "switches tool centre point mode itself (M128, FUNCTION TCPM)",
                         source=str(path), field="tcp")


def _no_tool_table(path, tool_table) -> None:
    if tool_table is not None:
        raise InputError("--tool-table (tool_table=) applies to G-code programs; a Heidenhain "
                         "program's TOOL CALL does not take lengths from a table yet: the "
                         "machine file's tool_offset is used", source=str(path),
                         field="tool_table")
