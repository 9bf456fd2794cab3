"""precontour: analytical prediction and pre-compensation of five-axis CNC contour errors.

Pipeline (one module per stage): machine file -> kinematics -> trajectory -> spline fit ->
tracking-error prediction -> contour errors -> compensation -> simulation -> report.
"""

from .errors import InputError, MachineFileError, PrecontourError
from .machine import Machine, load_machine

__version__ = "0.1.0"

__all__ = ["InputError", "Machine", "MachineFileError", "PrecontourError", "load_machine",
           "__version__"]
