"""precontour: analytical prediction and pre-compensation of five-axis CNC contour errors.

The package is laid out by pipeline stage; data flows one way, and a stage imports only the
stages before it::

    machine/       machine file, drives, controllers, kinematics
    toolpath/      programs in: CL CSV, APT CL data, G-code (Program)
    trajectory/    path splines, feed planning, program timing, 1 kHz axis commands (Trajectory)
    prediction/    minimum-jerk spline fit, closed-form tracking error, contour errors
    compensation/  pre-compensation (contour, tracking)
    simulation/    the virtual machine and its control laws
    identification/ drive models from servo logs, the excitation motion
    workflow.py    run and export: program in, compensated program (G-code, halstreamer) out
    reports/       demo and compare: figures, tables, HTML (the only matplotlib users)
    tables.py      checked CSV / .npz / .parquet in and out
    cli.py         the ``precontour`` command

The names below are the entry points a library user needs.
"""

from .compensation import CompensationResult, compensate
from .errors import InputError, MachineFileError, PrecontourError, ProgramError, ToolPathError
from .machine import Machine, load_machine
from .prediction import (AxisPrediction, ContourErrors, ReferencePath, contour_errors,
                         predict_tracking)
from .simulation import SimulationResult, simulate, simulate_trajectory
from .tables import read_trajectory, write_columns
from .toolpath import Program, ToolPath, read_program, read_toolpath
from .trajectory import Trajectory, builtin_path, generate_trajectory, program_trajectory

__version__ = "0.1.0"

__all__ = ["AxisPrediction", "CompensationResult", "ContourErrors", "InputError", "Machine",
           "MachineFileError", "PrecontourError", "Program", "ProgramError", "ReferencePath",
           "SimulationResult", "ToolPath", "ToolPathError", "Trajectory", "builtin_path",
           "compensate", "contour_errors", "generate_trajectory", "load_machine",
           "predict_tracking", "program_trajectory", "read_program", "read_toolpath",
           "read_trajectory", "simulate", "simulate_trajectory", "write_columns",
           "__version__"]
