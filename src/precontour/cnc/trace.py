"""A controller's own trace of a program: the timing compensation works at.

A controller re-plans what it is given, so compensation is computed for the commands the
controller itself produced for the *uncompensated* program: its servo trace, one row per servo
(or interpolation) period. :class:`ControllerTrace` holds it in machine axes (mm, rad), with
the actual positions when the trace has them (what learning from the machine needs) and the
program line the controller executed (LinuxCNC's ``motion.program-line``).

:func:`read_controller_trace` reads any servo log format the identification reads
(:func:`precontour.identification.servo_log.read_servo_log`: tables, halsampler, halscope and
the commercial controllers' exports) and the recordings of LinuxCNC's headless runs
(:func:`trace_from_recording`); :meth:`ControllerTrace.reference` is the trajectory whose
tracking errors are predicted and compensated.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..machine.drives import AXES, LINEAR_AXES
from ..trajectory.sampled import Trajectory

__all__ = ["ControllerTrace", "read_controller_trace", "trace_from_recording"]


def degrees_per_unit() -> np.ndarray:
    """Per q slot: 1 on the linear axes, 180/pi on the rotary ones (rad -> degrees, the
    unit of controllers and of programs' rotary words)."""
    return np.array([1.0 if a in LINEAR_AXES else 180.0 / np.pi for a in AXES])


@dataclass(frozen=True)
class ControllerTrace:
    """A controller's servo trace of one run of a program.

    Attributes
    ----------
    t : ndarray, shape (N,)
        Time, s, uniform (one row per servo or interpolation period).
    command : ndarray, shape (N, 5)
        Commanded machine axes, mm and rad (q slots X Y Z A C).
    actual : ndarray, shape (N, 5) or None
        Measured machine axes, mm and rad, when the trace has them.
    line : ndarray of int, shape (N,) or None
        Program line the controller executed at each sample (0 or less: none).
    source : str
        Where it came from, for messages.
    """

    t: np.ndarray
    command: np.ndarray
    actual: np.ndarray | None = None
    line: np.ndarray | None = None
    source: str = ""

    def __post_init__(self):
        t = np.asarray(self.t, dtype=float)
        command = np.asarray(self.command, dtype=float)
        if t.ndim != 1 or command.shape != (t.size, len(AXES)):
            raise ValueError(f"a trace needs t (N,) and command (N, 5); got {t.shape} and "
                             f"{command.shape}")
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "command", command)
        if self.actual is not None:
            actual = np.asarray(self.actual, dtype=float)
            if actual.shape != command.shape:
                raise ValueError(f"actual must have the commands' shape {command.shape}")
            object.__setattr__(self, "actual", actual)
        if self.line is not None:
            line = np.asarray(self.line).astype(np.int64)
            if line.shape != t.shape:
                raise ValueError("line must have shape (N,)")
            object.__setattr__(self, "line", line)

    @property
    def period(self) -> float:
        return float((self.t[-1] - self.t[0]) / (self.t.size - 1))

    @property
    def n_samples(self) -> int:
        return int(self.t.size)

    def reference(self, kinematics) -> Trajectory:
        """The commands as a trajectory (time from 0, the program lines kept), with the tool
        tip and orientation they put the tool at (``kinematics``) as its reference path."""
        P, O = kinematics.forward(self.command)
        return Trajectory(t=self.t - self.t[0], q=self.command, P=P, O=O, line=self.line)

    def window(self, start: int, stop: int) -> "ControllerTrace":
        """Samples ``start:stop``."""
        part = slice(start, stop)
        return ControllerTrace(t=self.t[part], command=self.command[part],
                               actual=None if self.actual is None else self.actual[part],
                               line=None if self.line is None else self.line[part],
                               source=self.source)

    def program_span(self, lines) -> tuple[int, int]:
        """First and one-past-last sample in which the controller executes one of ``lines``
        (the program's moves), from the trace's ``line`` column."""
        if self.line is None:
            raise InputError("the trace has no program line column (line): it cannot be "
                             "matched to the program's blocks", source=self.source,
                             field="line")
        inside = np.flatnonzero(np.isin(self.line, np.asarray(lines)))
        if inside.size == 0:
            raise InputError("the trace never executes one of the program's moves (its line "
                             "column names none of the program's move lines): a trace of "
                             "another program?", source=self.source, field="line")
        return int(inside[0]), int(inside[-1]) + 1


def trace_from_recording(recording, source: str = "") -> ControllerTrace:
    """The trace of a LinuxCNC recording (:class:`~precontour.linuxcnc.run.
    Recording`): the joints' commands (mm, degrees) in rad, plus the overlay where the
    configuration has one (``o0``..``o4``: the position loops' command is the motion
    controller's plus the overlay), the actual positions when it simulates drives
    (``a0``..``a4``), the planner's program line."""
    scale = 1.0 / degrees_per_unit()
    columns = recording.columns
    command = np.asarray(recording.joints, dtype=float)
    if all(f"o{i}" in columns for i in range(5)):
        command = command + np.column_stack([columns[f"o{i}"] for i in range(5)])
    actual = None
    if all(f"a{i}" in columns for i in range(5)):
        actual = np.column_stack([columns[f"a{i}"] for i in range(5)]) * scale
    return ControllerTrace(t=recording.t, command=command * scale, actual=actual,
                           line=columns.get("line"), source=source)


def read_controller_trace(path: str | Path, machine, *, fmt: str | None = None,
                          columns=None, period: float | None = None,
                          angles: str = "deg") -> ControllerTrace:
    """Read a controller's servo trace of a program (any servo log format the
    identification reads; see :func:`~precontour.identification.servo_log.read_servo_log`).
    Commanded positions are needed on every axis, actual ones are optional, and a ``line``
    column matches the trace to the program's blocks. ``angles``: the rotary axes' unit in
    the file (controllers record degrees)."""
    from ..identification.servo_log import read_servo_log

    if angles not in ("deg", "rad"):
        raise ValueError(f"angles must be 'deg' or 'rad', got {angles!r}")
    log = read_servo_log(path, fmt=fmt, columns=columns, period=period,
                         default_period=machine.servo_period,
                         angle_scale=np.pi / 180.0 if angles == "deg" else 1.0,
                         axis_names=machine.axis_names, require_actual=False)
    missing = [machine.axis_names[i] for i, a in enumerate(AXES) if a not in log.command]
    if missing:
        raise InputError(f"the trace has no commanded position of axis {missing[0]}: a timing "
                         "trace needs every axis's command", source=str(path),
                         field=missing[0])
    command = np.column_stack([log.command[a] for a in AXES])
    actual = None
    if all(a in log.actual and log.actual[a].size for a in AXES):
        actual = np.column_stack([log.actual[a] for a in AXES])
    return ControllerTrace(t=log.t, command=command, actual=actual,
                           line=log.line, source=str(path))
