"""precontour: analytical prediction and pre-compensation of five-axis CNC contour errors.

The package is laid out by pipeline stage; data flows one way, and a stage imports only the
stages before it::

    machine/       machine file, drives, controllers, kinematics
    linuxcnc/      LinuxCNC configurations and the headless runs that record every period
    toolpath/      programs in: CL CSV, APT CL data, G-code (Program)
    trajectory/    path splines, feed planning, program timing, 1 kHz axis commands (Trajectory)
    prediction/    minimum-jerk spline fit, closed-form tracking error, contour errors
    compensation/  pre-compensation (contour, tracking)
    simulation/    the virtual machine and its control laws
    planning/      the fastest feed within a contour tolerance
    identification/ drive models from servo logs, the excitation motion
    options.py     the jobs' options as small frozen objects (learning, limits, tolerance)
    workflow/      run and export: program in, compensated program (G-code, halstreamer) out
    batch.py       run over many programs and machines (processes or a Dask cluster)
    system.py      the servo system (machine + controller, made once) and the entry points
                   that take it first: predict, compensate, simulate, contour_errors
    reports/       demo and compare: figures, tables, HTML (the only matplotlib users)
    cnc/           the real controller: its trace, the program's own blocks corrected
    tables.py      checked CSV / .npz / .parquet in and out
    defaults.py    option defaults and names the help shows (standard library only)
    parallel.py    the jobs setting and the executors of independent work
    cli/           the ``precontour`` command: its parser, and what each command calls

The names below are the entry points a library user needs; each is imported when first used.
Each job has one: ``servo = load_servo(machine, controller)`` is made once and goes first in
``predict``, ``compensate``, ``simulate`` and ``contour_errors`` (:mod:`precontour.system`).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

__version__ = "0.1.0"

#: Each public name and the module it comes from. They are imported when first used (PEP 562),
#: so that the command line starts without the numerical stack (``precontour --help``).
_PUBLIC = {
    "Compensation": "system", "Servo": "system", "compensate": "system",
    "contour_errors": "system", "load_servo": "system", "plot_contour_errors": "system",
    "predict": "system",
    "simulate": "system",
    "InputError": "errors", "MachineFileError": "errors", "PrecontourError": "errors",
    "ProgramError": "errors", "ToolPathError": "errors",
    "Machine": "machine", "load_machine": "machine",
    "ContourErrors": "prediction", "ReferencePath": "prediction",
    "MachineEnsemble": "simulation", "SimulationResult": "simulation",
    "LearningOptions": "options", "LimitOptions": "options", "ToleranceOptions": "options",
    "ContourTolerance": "planning",
    "read_trajectory": "tables", "write_columns": "tables",
    "Program": "toolpath", "ToolPath": "toolpath", "read_program": "toolpath",
    "read_toolpath": "toolpath",
    "Trajectory": "trajectory", "builtin_path": "trajectory",
    "generate_trajectory": "trajectory", "program_trajectory": "trajectory",
}

__all__ = sorted(_PUBLIC) + ["__version__"]

if TYPE_CHECKING:  # pragma: no cover - for type checkers and editors
    from .errors import (InputError, MachineFileError, PrecontourError, ProgramError,
                         ToolPathError)
    from .machine import Machine, load_machine
    from .prediction import ContourErrors, ReferencePath
    from .options import LearningOptions, LimitOptions, ToleranceOptions
    from .planning import ContourTolerance
    from .simulation import MachineEnsemble, SimulationResult
    from .system import (Compensation, Servo, compensate, contour_errors, load_servo,
                         plot_contour_errors, predict, simulate)
    from .tables import read_trajectory, write_columns
    from .toolpath import Program, ToolPath, read_program, read_toolpath
    from .trajectory import Trajectory, builtin_path, generate_trajectory, program_trajectory


def __getattr__(name: str):
    module = _PUBLIC.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_PUBLIC))
