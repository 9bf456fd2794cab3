"""Program in, program out: the ``precontour run`` and ``precontour export`` workflows.

``run``: read an NC program (or CL data), plan its trajectory, predict and contour
pre-compensate the axis commands, keep them within the machine's limits (slowing down locally
and compensating again where needed), optionally learn against the realistic virtual
machine within those limits (``learn``), check uncompensated and compensated commands on the
realistic virtual machine (discrete controller, friction, feed-forward friction compensation),
and write the compensated program (G-code), optionally a halstreamer file and the command
table. ``export``: write an existing command file in one of those formats. Every output
location is checked before any computing, and nothing is written when a step fails.

The parts: :mod:`.program` (the program read and planned), :mod:`.run` (the workflow's
orchestration; compensating and learning are :mod:`precontour.compensation`'s),
:mod:`.checks` (the virtual machine and its draws), :mod:`.result` (the outputs' locations
and the result), :mod:`.export` (writing).
"""

from ..defaults import EXPORT_FORMATS
from ..errors import warn_former
from .checks import (DrawCheck, check_on_draws, check_on_virtual_machine, errors_on_draws,
                     worse_in_whole_message)
from .export import ExportResult, export_commands, export_format, write_run_outputs
from .program import (GCODE_SUFFIXES, RunProgram, load_program_trajectory, plan_run_program,
                      read_run_program)
from .result import (LargestError, RunOutputs, RunResult, WorseLine, check_run_outputs,
                     largest_error)
from .run import run_program

__all__ = ["EXPORT_FORMATS", "LargestError", "RunOutputs", "RunProgram", "RunResult",
           "ExportResult", "check_run_outputs", "largest_error",
           "export_commands", "export_format", "load_program_trajectory",
           "plan_run_program", "read_run_program", "run_program", "write_run_outputs",
           "DrawCheck", "WorseLine", "GCODE_SUFFIXES", "check_on_draws",
           "check_on_virtual_machine", "errors_on_draws", "worse_in_whole_message"]


def _compensate_keeping_limits(traj, machine_obj, controller, **options):
    """The former ``workflow.compensate_keeping_limits(traj, machine, controller, ...)``."""
    from ..compensation.routes import keep_limits
    from ..machine.servo import load_servo

    return keep_limits(load_servo(machine_obj, controller), traj, **options)


def _learn_on_ensemble(limited, machine_obj, controller, models, limits, passes, **options):
    """The former ``workflow.learn_on_ensemble(limited, machine, controller, models, limits,
    passes, ...)``; ``models`` and ``limits`` are the servo's."""
    from ..compensation.routes import learn_on_ensemble
    from ..machine.servo import load_servo

    return learn_on_ensemble(load_servo(machine_obj, controller), limited, passes, **options)


#: Former names of this package, now :mod:`precontour.compensation.routes`' (servo first).
_FORMER = {"compensate_keeping_limits": (_compensate_keeping_limits, "compensate"),
           "learn_on_ensemble": (_learn_on_ensemble, "compensation.routes.learn_on_ensemble")}


def __getattr__(name):
    if name in _FORMER:
        function, now = _FORMER[name]
        warn_former(f"precontour.workflow.{name}",
                    f"use precontour.{now}, which takes the servo first")
        return function
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
