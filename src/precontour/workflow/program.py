"""The program ``run`` takes: an NC program or CL data read and checked
(:func:`read_run_program`, :class:`RunProgram`), and its trajectory planned as the controller
executes it (:func:`plan_run_program`; :func:`load_program_trajectory` for the commands that
take a program or a trajectory file)."""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Sequence

import numpy as np

from ..defaults import (DEFAULT_CORNER_ORIENTATION_TOLERANCE, DEFAULT_CORNER_TOLERANCE,
                        DEFAULT_DWELL, DEFAULT_FEED, default_max_samples)
from ..errors import InputError, notice
from ..machine.machine_file import Machine
from ..toolpath import (EXTENSIONS, PROGRAM_FORMATS, read_program, read_toolpath_report,
                        toolpath_format)
from ..toolpath.writers import machine_axes_passthrough
from ..trajectory.generate import generate_trajectory, unfed_notice
from ..trajectory.program import check_program_samples, program_trajectory
from ..trajectory.sampled import Trajectory


#: Extensions a G-code output may have (those the readers take as G-code).
GCODE_SUFFIXES: tuple[str, ...] = EXTENSIONS["gcode"]


def load_program_trajectory(path: str | Path, machine: Machine, *, tcp: bool = False,
                            dwell: float = DEFAULT_DWELL,
                            corner_tolerance: float = DEFAULT_CORNER_TOLERANCE,
                            corner_orientation_tolerance: float | None =
                            DEFAULT_CORNER_ORIENTATION_TOLERANCE,
                            max_samples: int | None = None, format: str | None = None,
                            tool_table=None
                            ) -> tuple[Trajectory, Sequence[tuple[int, str]] | None]:
    """The planned trajectory of a program, and its non-motion lines to keep (or None).

    The one place ``run`` reads its input (:func:`read_run_program`, then
    :func:`plan_run_program`). G-code is read as a CNC executes it
    (:func:`~precontour.toolpath.read_program`, then
    :func:`~precontour.trajectory.program_trajectory` at the machine's servo period): the
    trajectory carries the source line of every sample, and the program's pass-through lines
    (tool change, spindle, coolant, comments) come back for the output program. ``tcp`` puts
    the whole program in tool centre point mode. CL data (CSV, APT) gives the tool tip
    already: it goes through :func:`~precontour.trajectory.generate.generate_trajectory`, its
    samples carry the file line of the CL point they move to, and it has no lines to keep.
    ``dwell``, ``corner_tolerance``, ``corner_orientation_tolerance`` (G-code only) and
    ``max_samples`` (default
    :func:`~precontour.defaults.default_max_samples`) are the planning options of the
    ``trajectory`` command. ``format``: the file's format, instead of the one its extension
    says (:func:`~precontour.toolpath.read_toolpath`'s); ``tool_table``: tool lengths for
    G-code (a LinuxCNC ``.tbl`` file or a mapping; None: the machine file's ``[tools]``).
    """
    source = read_run_program(path, machine, tcp=tcp, dwell=dwell, max_samples=max_samples,
                              format=format, tool_table=tool_table)
    return plan_run_program(source, machine, dwell=dwell, corner_tolerance=corner_tolerance,
                            corner_orientation_tolerance=corner_orientation_tolerance,
                            max_samples=max_samples)


@dataclass(frozen=True)
class RunProgram:
    """A program as ``run`` read it: a G-code ``program`` (``tcp``: read with ``--tcp``) or
    CL data (``toolpath``, the :func:`~precontour.toolpath.read_toolpath_report`)."""

    path: Path
    program: object | None = None
    toolpath: object | None = None
    tcp: bool = False

    @property
    def format(self) -> str:
        """``"gcode"`` for an NC program (G-code or Heidenhain), or the CL data's format
        (``"clcsv"``, ``"apt"``)."""
        return "gcode" if self.program is not None else self.toolpath.format


def read_run_program(path: str | Path, machine: Machine, *, tcp: bool = False,
                     dwell: float = DEFAULT_DWELL, max_samples: int | None = None,
                     format: str | None = None, tool_table=None) -> RunProgram:
    """Read and check ``run``'s input, before any progress is shown: every error in the file
    comes first, and for G-code also a trajectory too long to make (the sample estimate of
    :func:`~precontour.trajectory.program.check_program_samples`, as ``trajectory``).
    ``format``, ``tool_table``: as :func:`~precontour.toolpath.read_toolpath`'s (None: from
    the extension; the machine file's ``[tools]``)."""
    format = toolpath_format(path, format)
    if format in PROGRAM_FORMATS:
        program = read_program(path, machine, tcp=tcp, format=format,
                               tool_table=tool_table)
        for text in program.notices:
            notice(text)
        check_program_samples(program, machine, ts=machine.servo_period, dwell=dwell,
                              max_samples=max_samples)
        return RunProgram(Path(path), program=program, tcp=tcp)
    if tcp:
        raise InputError("--tcp applies to G-code programs only (CL data gives the tool tip "
                         "already)", source=str(path), field="--tcp")
    if tool_table is not None:
        raise InputError("--tool-table applies to G-code programs only (CL data gives the tool "
                         "tip already)", source=str(path), field="--tool-table")
    report = read_toolpath_report(path, machine=machine, format=format)
    said = unfed_notice(report.toolpath)
    if said is not None:
        notice(said)
    return RunProgram(Path(path), toolpath=report)


def plan_run_program(source: RunProgram, machine: Machine, *, dwell: float = DEFAULT_DWELL,
                     corner_tolerance: float = DEFAULT_CORNER_TOLERANCE,
                     corner_orientation_tolerance: float | None =
                     DEFAULT_CORNER_ORIENTATION_TOLERANCE,
                     max_samples: int | None = None, feed_scale: float = 1.0
                     ) -> tuple[Trajectory, Sequence[tuple[int, str]] | None]:
    """The planned trajectory of a program read by :func:`read_run_program`, and its
    non-motion lines to keep (None for CL data). ``feed_scale``: the programmed feeds times
    this (a feed override: G-code feed moves take their programmed time over it, rapids
    keep the rapid rate; CL data's feeds and the default feed are multiplied); the axis
    limits hold whatever it is."""
    max_samples = default_max_samples() if max_samples is None else int(max_samples)
    if not (np.isfinite(feed_scale) and feed_scale > 0):
        raise InputError(f"the feed scale must be positive and finite, got {feed_scale!r}",
                         field="--feed-scale-max")
    if source.program is not None:
        program = source.program
        if feed_scale != 1.0:
            program = replace(program, duration=program.duration / feed_scale,
                              feed=program.feed * feed_scale)
        # the output gives machine axes: lines that switch TCP mode on or off stay comments
        passthrough = machine_axes_passthrough(program.passthrough, tcp=program.tcp,
                                               tcp_all=source.tcp)
        return program_trajectory(program, machine, ts=machine.servo_period, dwell=dwell,
                                  tolerance=corner_tolerance,
                                  orientation_tolerance=corner_orientation_tolerance,
                                  max_samples=max_samples), passthrough
    report = source.toolpath
    toolpath = report.toolpath
    if feed_scale != 1.0 and toolpath.feed is not None:
        toolpath = replace(toolpath, feed=np.asarray(toolpath.feed, dtype=float) * feed_scale)
    return generate_trajectory(toolpath, machine, ts=machine.servo_period, dwell=dwell,
                               feed=DEFAULT_FEED * feed_scale, max_samples=max_samples,
                               lines=report.lines), None
