"""Writing: ``run``'s outputs as one set (:func:`write_run_outputs`: the G-code, and
optionally the halstreamer file and the command table), and ``export``, an existing command
file in one of those formats (:func:`export_commands`)."""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Sequence

import numpy as np

from ..defaults import EXPORT_FORMATS
from ..errors import InputError, MachineLimitError, renamed_keyword
from ..machine.machine_file import load_machine
from ..tables import (SUPPORTED_SUFFIXES, check_output_path, read_trajectory, trajectory_columns,
                      write_columns, write_text)
from ..toolpath.writers import ProgramInfo, gcode_program, gcode_tolerances, halstreamer_lines
from ..trajectory.limits import AxisLimits, check_limits, check_travel
from .program import GCODE_SUFFIXES
from .result import RunOutputs, RunResult


def write_run_outputs(result: RunResult, outputs: RunOutputs,
                      inputs: Sequence[str | Path]) -> list[Path]:
    """Write the program and the optional stream and command files as one set
    (:class:`~precontour.files.OutputSet`: all replace the old files, or none does; inside
    an outer set, e.g. with the report, with that one)."""
    commands = result.commands
    final = check_limits(commands.q, commands.ts, AxisLimits.from_machine(result.machine))
    if not final.ok:  # compensate_within_limits guarantees it; this guards the writing
        raise MachineLimitError("refusing to write commands beyond the machine's limits: "
                                + final.format())
    info = ProgramInfo(machine=result.machine.name, controller=result.controller,
                       method="contour pre-compensation within axis limits",
                       source=result.source)
    with outputs.output_set(inputs):
        written = [write_text(outputs.program, result.program.text, inputs=inputs)]
        if outputs.stream is not None:
            written.append(write_text(outputs.stream,
                                      halstreamer_lines(commands.q, commands.ts, info=info),
                                      inputs=inputs))
        if outputs.commands is not None:
            # with the source line of each sample, where known: what the table's largest
            # errors name can be looked up in it
            table = commands if result.limited.line is None else replace(
                commands, line=result.limited.line)
            written.append(write_columns(outputs.commands,
                                         trajectory_columns(table, result.machine.axis_names),
                                         inputs=inputs))
    return written


@dataclass(frozen=True)
class ExportResult:
    """What ``export`` wrote."""

    path: Path
    format: str
    n_samples: int
    n_blocks: int | None


def export_format(path: Path, format: str | None) -> str:
    """The export format: given, or from the output's extension."""
    if format is not None:
        if format not in EXPORT_FORMATS:
            raise InputError(f"unknown format {format!r}; use one of {', '.join(EXPORT_FORMATS)}",
                             field="format")
        return format
    suffix = path.suffix.lower()
    if suffix in GCODE_SUFFIXES:
        return "gcode"
    if suffix in SUPPORTED_SUFFIXES:
        return suffix[1:]
    raise InputError(f"cannot tell the format from the extension {suffix or '(none)'!r}; "
                     "give --format", source=str(path))


def export_commands(commands_path: str | Path, output: str | Path, *, format: str | None = None,
                    machine: str | Path, controller: str = "",
                    gcode_tolerance: np.ndarray | None = None,
                    tolerance: np.ndarray | None = None) -> ExportResult:
    """Write a command file (``t,X,Y,Z,A,C[,...]``) as G-code, a halstreamer file or a table.

    G-code and halstreamer files are programs a machine runs: the commands must keep the
    machine's limits (checked first; :class:`~precontour.errors.MachineLimitError` names the
    worst excess otherwise), and a halstreamer file needs samples at the servo period.

    Parameters
    ----------
    commands_path : str or Path
        The command file (``precontour compensate`` or ``run --commands`` writes one).
    output : str or Path
        The file to write; never an input.
    format : str, optional
        One of :data:`~precontour.defaults.EXPORT_FORMATS` (default: by the output's
        suffix).
    machine : str or Path
        A built-in machine's name or a machine file; no default: its limits decide what may
        be written.
    controller : str
        Named in the written program's header (an unknown name is an error).
    gcode_tolerance : ndarray, shape (5,), optional
        The G-code decimation tolerance per axis
        (:func:`~precontour.toolpath.writers.gcode_tolerances`).
    tolerance : ndarray, optional
        The former spelling of ``gcode_tolerance``, accepted with a DeprecationWarning.

    Returns
    -------
    ExportResult
        The path, the format, the samples and the blocks written.
    """
    tolerance = renamed_keyword(gcode_tolerance, tolerance, "gcode_tolerance", "tolerance")
    output = Path(output)
    format = export_format(output, format)
    inputs = [commands_path] + ([machine] if Path(str(machine)).exists() else [])
    suffixes = {"gcode": GCODE_SUFFIXES, "halstreamer": None}.get(format, (f".{format}",))
    check_output_path(output, inputs=inputs, suffixes=suffixes)
    tolerance = gcode_tolerances() if tolerance is None else np.asarray(tolerance, dtype=float)
    machine_obj = load_machine(machine)
    traj = read_trajectory(commands_path, axis_names=machine_obj.axis_names)
    if format not in ("gcode", "halstreamer"):
        write_columns(output, trajectory_columns(traj, machine_obj.axis_names), inputs=inputs)
        return ExportResult(output, format, traj.n_samples, None)
    if controller:
        machine_obj.controller(controller)  # an unknown name is an error, as elsewhere
    limits = AxisLimits.from_machine(machine_obj)
    # each axis within its travel (the tilt axis within +-180 deg at most), named by row
    check_travel(traj.q, limits, source=str(commands_path), axis_names=machine_obj.axis_names)
    check = check_limits(traj.q, traj.ts, limits, t0=traj.t[0])
    if not check.ok:
        raise MachineLimitError(f"{commands_path}: the commands exceed the machine's limits "
                                f"({check.format()}); `precontour run` slows such places down "
                                "and compensates again")
    info = ProgramInfo(machine=machine_obj.name, controller=controller,
                       method="exported commands", source=str(commands_path))
    if format == "halstreamer":
        if not machine_obj.at_servo_period(traj.ts):
            raise InputError(f"sampled every {traj.ts:.6g} s, but a halstreamer file needs one "
                             f"line per servo period ({machine_obj.servo_period:g} s of "
                             f"{machine_obj.name})", source=str(commands_path), field="t")
        write_text(output, halstreamer_lines(traj.q, traj.ts, info=info), inputs=inputs)
        return ExportResult(output, format, traj.n_samples, None)
    program = gcode_program(traj.t, traj.q, tolerance=tolerance, info=info,
                            axis_names=machine_obj.axis_names)
    if "\nG1 " not in program.text:
        # dwells only: a program the G-code reader (and so run and trajectory) refuses
        raise InputError("the commands do not move by more than the written decimals (1e-5 mm, "
                         "1e-6 deg): no motion to write as G-code", source=str(commands_path))
    write_text(output, program.text, inputs=inputs)
    return ExportResult(output, format, traj.n_samples, program.n_blocks)
