"""Program in, program out: the ``precontour run`` and ``precontour export`` workflows.

``run``: read an NC program (or CL data), plan its trajectory, predict and contour
pre-compensate the axis commands, keep them within the machine's limits (slowing down locally
and compensating again where needed), optionally learn against the realistic virtual
machine within those limits (``learn``), check uncompensated and compensated commands on the
realistic virtual machine (discrete controller, friction, feed-forward friction compensation),
and write the compensated program (G-code), optionally a halstreamer file and the command
table. ``export``: write an existing command file in one of those formats. Every output
location is checked before any computing, and nothing is written when a step fails.

The parts: :mod:`.program` (the program read and planned), :mod:`.run` (the workflow and the
compensation within the limits), :mod:`.checks` (the virtual machine and its draws),
:mod:`.result` (the outputs' locations and the result with its table), :mod:`.export` (writing).
"""

from ..defaults import EXPORT_FORMATS
from .checks import (DrawCheck, check_on_draws, check_on_virtual_machine, errors_on_draws,
                     worse_in_whole_message)
from .export import ExportResult, export_commands, export_format, write_run_outputs
from .program import (GCODE_SUFFIXES, RunProgram, load_program_trajectory, plan_run_program,
                      read_run_program)
from .result import (LargestError, RunOutputs, RunResult, WorseLine, check_run_outputs,
                     largest_error)
from .run import can_learn, compensate_keeping_limits, learn_on_ensemble, run_program

__all__ = ["EXPORT_FORMATS", "LargestError", "RunOutputs", "RunProgram", "RunResult",
           "ExportResult", "check_run_outputs", "compensate_keeping_limits", "largest_error",
           "export_commands", "export_format", "learn_on_ensemble", "load_program_trajectory",
           "plan_run_program", "read_run_program", "run_program", "write_run_outputs",
           "DrawCheck", "WorseLine", "GCODE_SUFFIXES", "can_learn", "check_on_draws",
           "check_on_virtual_machine", "errors_on_draws", "worse_in_whole_message"]
