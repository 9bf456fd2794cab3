"""The machine: its description file, drives, controllers and kinematics.

- :mod:`.machine_file` -- TOML machine files (and built-in machines) -> :class:`Machine`;
- :mod:`.drives` -- axis drives (inertia, damping, friction) and linear closed-loop error models;
- :mod:`.controllers` -- named controllers (PID, P-PI, sliding mode): gains, design, models;
- :mod:`.kinematics` -- inverse/direct kinematics, one module per machine type.

This is the bottom of the pipeline: it imports nothing from the other stages.
"""

from .controllers import CONTROLLER_TYPES, Controller, closed_loop_bandwidth
from .drives import AXES, LINEAR_AXES, ROTARY_AXES, Drive, Friction, LinearErrorModel
from .kinematics import KINEMATICS_TYPES, angle_between, normalize_orientations
from .machine_file import Machine, builtin_machine_text, load_machine, parse_machine

__all__ = ["AXES", "CONTROLLER_TYPES", "Controller", "Drive", "Friction", "KINEMATICS_TYPES",
           "LINEAR_AXES", "LinearErrorModel", "Machine", "ROTARY_AXES", "angle_between",
           "builtin_machine_text", "closed_loop_bandwidth", "load_machine",
           "normalize_orientations", "parse_machine"]
