"""Defaults and names that the command line's help shows, each defined once, here.

``precontour --help`` must not import the numerical stack (numpy, scipy, numba and the
compiled kernels take a second or more to load), so the option defaults and the names its help
text lists live in this module, which imports only the standard library; the stages that use
them import them from here. Also here: the catalogue of the built-in machines read straight
from their TOML files (:func:`builtin_machines`), for ``precontour machines`` and the help of
``run`` and ``export``; :func:`precontour.machine.load_machine` is what checks a machine file.
"""

from __future__ import annotations

import os
import tomllib
from dataclasses import dataclass
from importlib import resources

#: Built-in machines: the paper's, LinuxCNC's two trunnion-table simulator configurations
#: (``configs/sim/axis/vismach/5axis/table-rotary-tilting``), a head-table B-C machine,
#: LinuxCNC's head-head bridge mill (``configs/sim/axis/vismach/5axis/bridgemill``) and a
#: head-table A-C machine as a generic kinematic chain, and LinuxCNC's A-B table dual rotary
#: (``configs/sim/axis/vismach/5axis/table-dual-rotary``); files in ``machine/data``.
BUILTIN_MACHINES: tuple[str, ...] = ("zhang2013", "linuxcnc-xyzac-trt", "linuxcnc-xyzbc-trt",
                                     "head-table-bc", "linuxcnc-bridgemill", "head-table-ac",
                                     "linuxcnc-xyzab-tdr")
#: Servo period of a machine file that gives none, s.
DEFAULT_SERVO_PERIOD = 0.001
#: Names of the built-in test paths (:func:`precontour.trajectory.builtin_path`).
BUILTIN_PATHS: tuple[str, ...] = ("paper", "circle", "cone", "fan")

# -- tool paths in ----------------------------------------------------------------------------
#: Tool path formats (``read_toolpath(format=...)``, ``trajectory``/``run --format``); the
#: reader of each is :mod:`precontour.toolpath.readers`.
TOOLPATH_FORMATS: tuple[str, ...] = ("clcsv", "apt", "gcode", "heidenhain")

# -- trajectory planning ------------------------------------------------------------------
#: Default maximum tool tip feed, mm/s (the paper's test path).
DEFAULT_FEED = 100.0
#: Default time (s) the final command is held so that the drives settle inside the trajectory.
DEFAULT_DWELL = 0.2
#: Default corner tolerance of a G-code program, mm: the blend of a corner passes within this
#: of it.
DEFAULT_CORNER_TOLERANCE = 0.01
#: Default floor of the local slow-downs that keep the machine's limits, as a fraction of the
#: planned speed (``run`` / ``compensate --min-speed``): where a limit would need a slower
#: motion, the corrections there taper to the planned commands instead.
DEFAULT_MIN_SPEED = 0.5
#: Default number of machines ``run`` checks its result on (``--draws``): the machine file's
#: and draws of its friction, inertia, damping and encoder (the learning's ensemble,
#: :class:`precontour.simulation.ensemble.MachineEnsemble`). Where an axis stops under
#: friction, the outcome on one exact machine is decided by nanometres; the table reports
#: the median and the worst over the draws.
DEFAULT_CHECK_DRAWS = 5
#: Default lowest feed of ``run --tolerance``, as a fraction of the programmed feed
#: (``--feed-scale-min``): where a contour-error tolerance would need a slower motion, the
#: tolerance counts as not met there.
DEFAULT_FEED_SCALE_MIN = 0.05
#: Default highest feed of ``run --tolerance`` for an NC program, as a multiple of the
#: programmed feed (``--feed-scale-max``): the programmed feed is an upper bound.
DEFAULT_FEED_SCALE_MAX = 1.0
#: The same for CL data (issue 42 item 6): a CAM system's CL feed is a plain request, not a
#: feed a machinist tuned on the machine, so the search may go up to twice it (the axis limits
#: hold whatever the feed).
DEFAULT_FEED_SCALE_MAX_CL = 2.0
#: Peak memory per trajectory sample of the commands a machinist's program goes through
#: (trajectory, predict, compensate, simulate, run), bytes, with a margin:
#: ``scripts/measure_memory.py`` measured the growth of peak RSS per sample (built-in ``paper``
#: path, 2,769 vs 8,867 and 21,529 samples) at most 1.6 kB for those, and 4.8-6.7 kB for the
#: research command ``compare`` (six compensations, seven simulations), which is not sized
#: for hour-long programs.
BYTES_PER_SAMPLE = 2_000
#: Share of the physical memory the default sample limit may use.
MEMORY_SHARE = 0.5


def default_max_samples() -> int:
    """The default largest number of trajectory samples: :data:`MEMORY_SHARE` of this
    machine's physical memory at :data:`BYTES_PER_SAMPLE` (1 GiB assumed if unknown)."""
    try:
        memory = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):  # pragma: no cover - non-POSIX
        memory = 1 << 30
    return max(100_000, int(MEMORY_SHARE * memory / BYTES_PER_SAMPLE))


# -- prediction and compensation --------------------------------------------------------------
#: Default spline fit tolerances: 1 um for linear axes (mm), 1 urad for rotary axes (rad).
FIT_TOL_LINEAR = 1e-3
FIT_TOL_ROTARY = 1e-6
#: Spline fit tolerances used when compensating: ten times finer than for prediction alone,
#: since the fit error of each axis goes straight into the residual contour error.
COMPENSATION_TOL_LINEAR = 1e-4
COMPENSATION_TOL_ROTARY = 1e-7
#: Compensation methods: contour-error pre-compensation, and the paper's tracking baseline.
COMPENSATION_METHODS: tuple[str, ...] = ("contour", "tracking")
#: Learning passes against the machine model by default (CLI ``compensate --learn``).
DEFAULT_LEARNING_PASSES = 4

# -- programs out -----------------------------------------------------------------------------
#: Default decimation tolerances: 1 um on X, Y, Z and 1e-5 rad on A, C (``--tol 0.001,1e-5``).
GCODE_TOL_LINEAR = 1e-3
GCODE_TOL_ROTARY = 1e-5
#: Default orientation tolerance of a G-code program's corners, rad (``--corner-ori-tol``):
#: where the blend of a corner passes within the corner tolerance of it at the tool tip (or
#: the linear axes), the tool orientation there is within this of the programmed one. The
#: rotary decimation tolerance: what an output program keeps the rotary axes within.
DEFAULT_CORNER_ORIENTATION_TOLERANCE = GCODE_TOL_ROTARY
#: Formats of ``precontour export``.
EXPORT_FORMATS: tuple[str, ...] = ("gcode", "halstreamer", "csv", "npz", "parquet")

# -- identification -----------------------------------------------------------------------
#: Servo log formats ``precontour identify`` reads: the library's table, LinuxCNC's
#: halsampler and halscope, the traces of Heidenhain TNCscope, Siemens Sinumerik Operate and
#: Beckhoff TwinCAT Scope View, and any CSV through a column map.
LOG_FORMATS: tuple[str, ...] = ("table", "halsampler", "halscope", "sco", "sinumerik-xml",
                                "twincat-csv", "csv")
#: Default half travel of the excitation, mm (X, Y, Z) and rad (A, C).
DEFAULT_TRAVEL_LINEAR = 25.0
DEFAULT_TRAVEL_ROTARY = 0.5
#: Default fraction of each drive's v_max, a_max, j_max the motion may use.
DEFAULT_SAFETY = 0.5


# -- the built-in machines --------------------------------------------------------------------
def builtin_machine_text(name: str = "zhang2013") -> str:
    """TOML text of a built-in machine (:data:`BUILTIN_MACHINES`); ``KeyError`` for others.

    Read through the ``precontour`` package's resources, not ``precontour.machine.data``'s,
    so that no stage is imported."""
    if name not in BUILTIN_MACHINES:
        raise KeyError(name)
    return (resources.files("precontour").joinpath("machine", "data", f"{name}.toml")
            .read_text(encoding="utf-8"))


@dataclass(frozen=True)
class BuiltinMachine:
    """What a built-in machine file says about itself, read without checking it (the tests
    check that :func:`precontour.machine.load_machine` agrees)."""

    name: str
    description: str
    kinematics: str
    #: The drives' axis letters in file order: X Y Z A C, or X Y Z B C on a B-C machine.
    axes: tuple[str, ...]
    #: (name, type) of each controller, in file order.
    controllers: tuple[tuple[str, str], ...]
    servo_period: float


def builtin_machines() -> tuple[BuiltinMachine, ...]:
    """The built-in machines, in the order of :data:`BUILTIN_MACHINES`."""
    machines = []
    for name in BUILTIN_MACHINES:
        data = tomllib.loads(builtin_machine_text(name))
        machines.append(BuiltinMachine(
            name=data["name"], description=data.get("description", ""),
            kinematics=data["kinematics"]["type"], axes=tuple(data["drives"]),
            controllers=tuple((key, table["type"]) for key, table in data["controllers"].items()),
            servo_period=float(data.get("servo_period", DEFAULT_SERVO_PERIOD))))
    return tuple(machines)

#: The release that removes the former spellings (options' keyword names, module paths); until
#: then they work and warn (DeprecationWarning).
FORMER_SPELLINGS_REMOVED_IN = "0.2.0"
