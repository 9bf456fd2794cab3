"""A LinuxCNC configuration for running ``run``'s outputs on a machine: what
``precontour linuxcnc-config`` writes.

One folder, written as a set (a temporary folder beside the target, then a rename), with:

- ``machine.ini`` / ``machine.hal``: the G-code path. The interpreter, the task, the trajectory
  planner and the motion controller, the machine file's axis limits (travel ``p_min``/``p_max``,
  ``v_max``, ``a_max``; A, B and C in degrees) and servo period, and the joints looped back
  (commanded position = feedback) as LinuxCNC's sim configurations do; replace the loop-back
  nets by the machine's position loops. ``run``'s G-code is in machine axes, so the kinematics
  maps the program's X Y Z A C (X Y Z B C, X Y Z A B) to the joints one to one: ``trivkins``
  on a machine type LinuxCNC has no module for (``ac-trunnion``, ``xyzbc-head-table``), and on
  the LinuxCNC types their own module (``xyzac-trt-kins``, ``xyzbc-trt-kins`` with the machine
  file's offsets; ``xyzab_tdr_kins`` on ``xyzab-tdr`` with its rotation point and offsets;
  ``5axiskins`` on ``xyzbc-head-head``, its pivot length plus the tool length through a
  ``sum2``, as LinuxCNC's bridge mill sim does, and the W joint it requires standing at 0)
  loaded identity first, with ``M428`` (tool centre point) and ``M429`` (identity)
  switching as in LinuxCNC's trunnion sim configurations.
- ``headless.ini``: the same machine with a display program (``headless.py``, the system
  Python's ``linuxcnc`` module) that resets E-stop, turns the machine on, homes, runs one
  program and records every servo period with ``halsampler`` (``record.hal``): how the tests
  run LinuxCNC without a screen.
- ``stream.hal``: the stream path, for ``halrun``: a servo thread at the machine's period and
  LinuxCNC's ``streamer`` component, fed by ``halstreamer`` with ``run --stream``'s file, one
  sample per servo period straight to the joints, past the interpreter and the planner.

The planner settings written into ``[TRAJ]`` are those the G-code needs (see
:data:`TRAJ_SETTINGS` and docs/linuxcnc.md).
"""

from __future__ import annotations

import math
import os
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping

from ..errors import InputError, OutputError
from ..machine.drives import LINEAR_AXES
from ..machine.kinematics import (XYZABTableDualRotary, XYZACTrunnion, XYZBCHeadHead,
                                  XYZBCTrunnion)
from .drives import (ACTUAL_COLUMNS, DRIVES, FERROR, MIN_FERROR, OVERLAY_COLUMNS,
                     drives_hal, joint_plants)
from .streamer import STREAMER_FLOAT, streamer_depth

#: The file that marks a folder as a configuration this module wrote (it may be replaced).
MARKER = "machine.ini"
#: First line of every INI this module writes; a folder whose machine.ini starts with it is
#: replaced by a new configuration, any other non-empty folder is refused.
HEADER = "# LinuxCNC configuration written by precontour linuxcnc-config"
#: Columns ``record.hal`` samples every servo period (``halsampler -t`` adds the sample
#: number first): the five joint position commands (mm, degrees; what goes to the position
#: loops), the planner's Cartesian position (``axis.L.pos-cmd``: X Y Z, A or B, C in the
#: program's coordinates, before kinematics and motion's cubic interpolator), the line of the
#: program the planner executes, and the motion type (0 none, 1 rapid, 2 feed, 3 arc, ...).
RECORD_COLUMNS: tuple[str, ...] = ("j0", "j1", "j2", "j3", "j4", "w0", "w1", "w2", "w3", "w4",
                                   "line", "motion_type")
#: Columns ``stream.hal`` samples: the five streamer pins, the streamer's underrun count and
#: its FIFO depth.
STREAM_COLUMNS: tuple[str, ...] = ("j0", "j1", "j2", "j3", "j4", "underruns", "depth")
#: Seconds of samples the recorders' FIFOs hold, against pauses of ``halsampler``.
RECORD_BUFFER_SECONDS = 20.0
#: The motion controller's analog output that selects the kinematics (the sims' choice).
SWITCHKINS_PIN = 3
#: Planner settings of ``[TRAJ]``: LinuxCNC 2.9's defaults, written out. None of them changes
#: how the planner blends blocks in which a rotary axis moves (tp.c makes neither blend arcs
#: nor tangent blends with rotary motion, only parabolic blends); a lookahead of 200 blocks
#: instead of 50 moved the 3+2 test program's 13.3 s by 2 ms (docs/linuxcnc.md).
TRAJ_SETTINGS: Mapping[str, str] = {
    "ARC_BLEND_ENABLE": "1",
    "ARC_BLEND_FALLBACK_ENABLE": "0",
    "ARC_BLEND_OPTIMIZATION_DEPTH": "50",
    "ARC_BLEND_GAP_CYCLES": "4",
    "ARC_BLEND_RAMP_FREQ": "100",
}

__all__ = ["HEADER", "LinuxcncConfig", "RECORD_COLUMNS", "STREAM_COLUMNS", "TRAJ_SETTINGS",
           "linuxcnc_config", "write_linuxcnc_config"]


@dataclass(frozen=True)
class JointLimits:
    """One joint as LinuxCNC's INI gives it: mm or degrees (per s, per s^2)."""

    letter: str
    rotary: bool
    minimum: float | None
    maximum: float | None
    velocity: float
    acceleration: float

    @property
    def home(self) -> float:
        """0, or the travel's end nearest to it: homing puts the joint here at once."""
        low = -math.inf if self.minimum is None else self.minimum
        high = math.inf if self.maximum is None else self.maximum
        return min(max(0.0, low), high)


@dataclass(frozen=True)
class LinuxcncConfig:
    """A LinuxCNC configuration as text: ``files`` maps relative paths to contents;
    ``executable`` names those that must be executable. ``kinematics`` is the module loaded,
    ``tcp`` whether ``M428`` switches it into tool centre point mode."""

    machine: str
    kinematics: str
    tcp: bool
    servo_period_ns: int
    joints: tuple[JointLimits, ...]
    files: Mapping[str, str]
    executable: tuple[str, ...] = ("headless.py",)
    drives: str = "looped"
    controller: str | None = None


def joint_limits(machine) -> tuple[JointLimits, ...]:
    """The five joints' limits from the machine file: rad become degrees."""
    joints = []
    for letter, drive in zip(machine.axis_names, machine.drives):
        rotary = letter not in LINEAR_AXES
        scale = 180.0 / math.pi if rotary else 1.0
        for key in ("v_max", "a_max"):
            value = getattr(drive, key)
            if value is None or not math.isfinite(value) or value <= 0:
                raise InputError(f"LinuxCNC needs a velocity and an acceleration limit for "
                                 f"every axis; axis {letter} has no {key}",
                                 source=machine.source or machine.name, field=key)
        low, high = drive.p_min, drive.p_max
        if letter == machine.axis_names[3]:  # the tilt travel of the kinematics counts too
            tilt_low, tilt_high = getattr(machine.kinematics, "tilt_limits", (None, None))
            low = tilt_low if low is None else (low if tilt_low is None else max(low, tilt_low))
            high = (tilt_high if high is None
                    else (high if tilt_high is None else min(high, tilt_high)))
        joints.append(JointLimits(letter=letter, rotary=rotary,
                                  minimum=None if low is None else low * scale,
                                  maximum=None if high is None else high * scale,
                                  velocity=drive.v_max * scale,
                                  acceleration=drive.a_max * scale))
    return tuple(joints)


def _num(value: float) -> str:
    """A number for an INI or HAL file: 12 significant digits, no exponent for ordinary
    values (LinuxCNC reads them with strtod)."""
    return f"{value:.12g}"


def _kinematics(machine) -> tuple[str, str, bool, list[str]]:
    """(module, loadrt line, tcp, HAL lines setting its parameters)."""
    kin = machine.kinematics
    coordinates = "".join(machine.axis_names)
    if isinstance(kin, XYZBCHeadHead):
        return _five_axis_kins(machine, kin)
    if isinstance(kin, XYZABTableDualRotary):
        return _tdr_kins(kin)
    if not isinstance(kin, (XYZACTrunnion, XYZBCTrunnion)):
        return "trivkins", f"trivkins coordinates={coordinates}", False, []
    tilt_x = isinstance(kin, XYZACTrunnion)
    module = "xyzac-trt-kins" if tilt_x else "xyzbc-trt-kins"
    offsets = ("y_offset", "y-offset") if tilt_x else ("x_offset", "x-offset")
    lines = [f"setp {module}.{pin} {_num(getattr(kin, key))}"
             for key, pin in (("x_rot_point", "x-rot-point"), ("y_rot_point", "y-rot-point"),
                              ("z_rot_point", "z-rot-point"), offsets,
                              ("z_offset", "z-offset"))]
    directions = (kin.tilt_direction, kin.turn_direction)
    if directions == (1.0, 1.0):
        # LinuxCNC 2.10's pin; 2.9's module has none and always turns both axes the other way,
        # so on 2.9 this line fails at start-up rather than running the wrong kinematics
        lines.append(f"setp {module}.conventional-directions 1   "
                     "# needs LinuxCNC >= 2.10 (2.9: directions -1 only)")
    elif directions != (-1.0, -1.0):
        raise InputError("LinuxCNC's trunnion kinematics turns both rotary axes the same way "
                         f"(both directions -1, or both +1), got {directions[0]:+g} and "
                         f"{directions[1]:+g}", source=machine.source or machine.name,
                         field="kinematics")
    # The tool length comes from the tool table through G43, as in LinuxCNC's sims: the
    # controlled point is then the tool tip plus tool_offset along z (see xyzac_trt.py).
    lines.append(f"net :tool-offset motion.tooloffset.z => {module}.tool-offset")
    lines.append(f"net :kinstype-select motion.analog-out-{SWITCHKINS_PIN:02d} => "
                 "motion.switchkins-type")
    return module, f"{module} coordinates={coordinates} sparm=identityfirst", True, lines


#: The coordinate 5axiskins requires besides X Y Z B C: W, the tool's travel along its axis,
#: which precontour's programs never move (a joint of its own, looped back like the others).
FIVE_AXIS_EXTRA = "W"


def _five_axis_kins(machine, kin) -> tuple[str, str, bool, list[str]]:
    """LinuxCNC's ``5axiskins`` (bridge mill, head-head) for ``xyzbc-head-head``: its senses
    of rotation are fixed (B -1, C +1), its ``pivot-length`` pin is the pivot to the tool tip,
    the machine file's ``pivot_length`` plus the tool length from the tool table (G43)."""
    directions = (kin.b_direction, kin.c_direction)
    if directions != (-1.0, 1.0):
        raise InputError("LinuxCNC's 5axiskins turns B with direction -1 and C with +1, got "
                         f"{directions[0]:+g} and {directions[1]:+g}",
                         source=machine.source or machine.name, field="kinematics")
    module = "5axiskins"
    coordinates = "".join(machine.axis_names) + FIVE_AXIS_EXTRA
    lines = ["# 5axiskins.pivot-length = pivot_length + the tool length (5axiskins.c's notes)",
             "loadrt sum2 names=pivot-sum",
             "addf pivot-sum servo-thread 1   # before the motion controller",
             f"setp pivot-sum.offset {_num(kin.pivot_length)}",
             "net :tool-offset motion.tooloffset.z => pivot-sum.in0",
             f"net :pivot-length pivot-sum.out => {module}.pivot-length",
             f"net :kinstype-select motion.analog-out-{SWITCHKINS_PIN:02d} => "
             "motion.switchkins-type"]
    return module, f"{module} coordinates={coordinates} sparm=identityfirst", True, lines


def _tdr_kins(kin) -> tuple[str, str, bool, list[str]]:
    """LinuxCNC's ``xyzab_tdr_kins`` (A-B table dual rotary) for ``xyzab-tdr``: its pins
    are the machine file's keys (it has no direction pins and no module parameters; it
    starts in identity kinematics, type 0)."""
    module = "xyzab_tdr_kins"
    lines = [f"setp {module}.{pin} {_num(getattr(kin, key))}"
             for key, pin in (("x_rot_point", "x-rot-point"), ("y_rot_point", "y-rot-point"),
                              ("z_rot_point", "z-rot-point"), ("x_offset", "x-offset"),
                              ("z_offset", "z-offset"))]
    lines.append(f"net :tool-offset motion.tooloffset.z => {module}.tool-offset-z")
    lines.append(f"net :kinstype-select motion.analog-out-{SWITCHKINS_PIN:02d} => "
                 "motion.switchkins-type")
    return module, module, True, lines


def linuxcnc_config(machine, *, drives: str = "looped",
                    controller: str | None = None) -> LinuxcncConfig:
    """The configuration of ``machine`` (a :class:`~precontour.machine.machine_file.Machine`)
    as text; :func:`write_linuxcnc_config` writes it.

    ``drives``: ``"looped"``, each joint's command looped back as its feedback (LinuxCNC's
    sims: timing only), or ``"simulated"``, each joint closed through LinuxCNC's ``pid``
    with the gains of ``controller`` (a ``pid`` controller of the machine file, or a ``tf``
    with a ``base``) around a plant of the machine file's drive
    (:mod:`~precontour.linuxcnc.config_drives`); the recorder then also samples the
    actual positions."""
    if drives not in DRIVES:
        raise ValueError(f"drives must be one of {DRIVES}, got {drives!r}")
    plants = None
    if drives == "simulated":
        if controller is None:
            raise InputError("simulated drives need a controller (--controller NAME: a pid "
                             "controller of the machine file)",
                             source=machine.source or machine.name, field="controller")
        plants = joint_plants(machine, controller)
    joints = joint_limits(machine)
    period_ns = int(round(machine.servo_period * 1e9))
    if not 1e4 <= period_ns <= 1e8:
        raise InputError(f"servo period {machine.servo_period:g} s is outside what LinuxCNC "
                         "runs (10 us .. 100 ms)", source=machine.source or machine.name,
                         field="servo_period")
    module, loadrt, tcp, kins_lines = _kinematics(machine)
    if module == "5axiskins":
        z = joints[2]
        joints += (JointLimits(letter=FIVE_AXIS_EXTRA, rotary=False, minimum=z.minimum,
                               maximum=z.maximum, velocity=z.velocity,
                               acceleration=z.acceleration),)
    tool_length = getattr(machine.kinematics, "tool_offset", 0.0)
    files = {
        "machine.ini": _ini(machine, joints, period_ns, loadrt, tcp, display="axis",
                            halfiles=("machine.hal",), simulated=plants is not None),
        "headless.ini": _ini(machine, joints, period_ns, loadrt, tcp,
                             display="./headless.py", halfiles=("machine.hal", "record.hal"),
                             simulated=plants is not None),
        "machine.hal": _machine_hal(kins_lines, len(joints), plants, period_ns),
        "record.hal": _record_hal(machine, period_ns, simulated=plants is not None),
        "stream.hal": _stream_hal(machine, period_ns),
        "headless.py": HEADLESS_PY,
        "tool.tbl": f"T1 P1 Z{_num(tool_length)} D0 ;tool {_num(tool_length)} mm long\n",
    }
    if tcp:
        files["remap/428remap.ngc"] = _switch_sub("428", 1, "tool centre point kinematics")
        files["remap/429remap.ngc"] = _switch_sub("429", 0, "identity kinematics")
    return LinuxcncConfig(machine=machine.name, kinematics=module, tcp=tcp,
                          servo_period_ns=period_ns, joints=joints, files=files, drives=drives,
                          controller=controller)


def _ini(machine, joints, period_ns, loadrt, tcp, *, display, halfiles,
         simulated: bool = False) -> str:
    # X Y Z (5axiskins's W joint is no feed axis of the planner's Cartesian speed cap)
    linear = [j for j in joints[:5] if not j.rotary]
    rotary = [j for j in joints if j.rotary]
    coordinates = " ".join(j.letter for j in joints)
    lines = [HEADER,
             f"# machine: {machine.name} ({machine.source or 'built-in'})",
             "# Limits are the machine file's (A, B, C in degrees); "
             + ("each joint is closed through pid around a simulated drive (machine.hal)."
                if simulated else "the joints are looped back"),
             "# " + ("Replace the simulated drives by the machine's own." if simulated
                     else "(machine.hal): replace those nets by the machine's position loops."),
             "", "[EMC]", "VERSION = 1.1", f"MACHINE = precontour {machine.name}", "DEBUG = 0",
             "", "[DISPLAY]", f"DISPLAY = {display}", "CYCLE_TIME = 0.100",
             "POSITION_OFFSET = RELATIVE", "POSITION_FEEDBACK = COMMANDED",
             "MAX_FEED_OVERRIDE = 1.0",
             f"MAX_LINEAR_VELOCITY = {_num(max(j.velocity for j in linear))}",
             f"MAX_ANGULAR_VELOCITY = {_num(max(j.velocity for j in rotary))}",
             "", "[TASK]", "TASK = milltask", "CYCLE_TIME = 0.001",
             "", "[RS274NGC]", "PARAMETER_FILE = linuxcnc.var"]
    if tcp:
        lines += ["SUBROUTINE_PATH = remap", "HAL_PIN_VARS = 1",
                  "# M428: tool centre point kinematics, M429: identity (run's G-code)",
                  "REMAP = M428 modalgroup=10 ngc=428remap",
                  "REMAP = M429 modalgroup=10 ngc=429remap"]
    lines += ["", "[EMCMOT]", "EMCMOT = motmod", "COMM_TIMEOUT = 1.0",
              f"SERVO_PERIOD = {period_ns}",
              "", "[EMCIO]", "EMCIO = io", "CYCLE_TIME = 0.100", "TOOL_TABLE = tool.tbl",
              "", "[HAL]"]
    lines += [f"HALFILE = {name}" for name in halfiles]
    lines += ["", "[KINS]", f"KINEMATICS = {loadrt}", f"JOINTS = {len(joints)}",
              "", "[TRAJ]", f"COORDINATES = {coordinates}", "LINEAR_UNITS = mm",
              "ANGULAR_UNITS = degree",
              # the Cartesian speed cap: never below what the X Y Z limits allow together
              f"MAX_LINEAR_VELOCITY = {_num(math.hypot(*(j.velocity for j in linear)))}",
              f"DEFAULT_LINEAR_VELOCITY = {_num(min(j.velocity for j in linear))}",
              f"MAX_LINEAR_ACCELERATION = "
              f"{_num(math.hypot(*(j.acceleration for j in linear)))}"]
    lines += [f"{key} = {value}" for key, value in TRAJ_SETTINGS.items()]
    for j in joints:
        lines += ["", f"[AXIS_{j.letter}]"] + _limit_lines(j)
    for n, j in enumerate(joints):
        lines += ["", f"[JOINT_{n}]", f"TYPE = {'ANGULAR' if j.rotary else 'LINEAR'}"]
        lines += _limit_lines(j)
        lines += [f"HOME = {_num(j.home)}", "HOME_SEARCH_VEL = 0", "HOME_SEQUENCE = 0"]
        if simulated and n < 5:
            lines += [f"FERROR = {_num(FERROR)}", f"MIN_FERROR = {_num(MIN_FERROR)}"]
    return "\n".join(lines) + "\n"


def _limit_lines(j: JointLimits) -> list[str]:
    lines = []
    if j.minimum is not None:
        lines.append(f"MIN_LIMIT = {_num(j.minimum)}")
    if j.maximum is not None:
        lines.append(f"MAX_LIMIT = {_num(j.maximum)}")
    return lines + [f"MAX_VELOCITY = {_num(j.velocity)}",
                    f"MAX_ACCELERATION = {_num(j.acceleration)}"]


def _machine_hal(kins_lines: list[str], n_joints: int = 5, plants=None,
                 period_ns: int = 1_000_000) -> str:
    looped = range(n_joints) if plants is None else range(5, n_joints)
    # a sum2 the kinematics lines load (5axiskins's pivot) loads with the drives' sum2s
    extra_sum2 = ()
    if plants is not None:
        extra_sum2 = tuple(line.split("names=")[1] for line in kins_lines
                           if line.startswith("loadrt sum2 names="))
        kins_lines = [line for line in kins_lines if not line.startswith("loadrt sum2 ")]
    lines = ["# precontour linuxcnc-config: motion, kinematics and the joints "
             + ("looped back" if plants is None else "closed through simulated drives"),
             "loadrt [KINS]KINEMATICS",
             "loadrt [EMCMOT]EMCMOT servo_period_nsec=[EMCMOT]SERVO_PERIOD "
             "num_joints=[KINS]JOINTS",
             "addf motion-command-handler servo-thread",
             "addf motion-controller servo-thread",
             *(drives_hal(plants, extra_sum2, period_ns) if plants is not None else
               ["# commanded position = feedback (a simulated machine): replace by the "
                "position", "# loops, e.g. net j0-cmd joint.0.motor-pos-cmd => pid.0.command"]),
             *[f"net j{n}-pos joint.{n}.motor-pos-cmd => joint.{n}.motor-pos-fb"
               for n in looped],
             "net estop-loop iocontrol.0.user-enable-out => iocontrol.0.emc-enable-in",
             "net tool-prep-loop iocontrol.0.tool-prepare => iocontrol.0.tool-prepared",
             "net tool-change-loop iocontrol.0.tool-change => iocontrol.0.tool-changed",
             *kins_lines]
    return "\n".join(lines) + "\n"


def _depth(period_ns: int) -> int:
    return int(math.ceil(RECORD_BUFFER_SECONDS * 1e9 / period_ns))


def record_columns(simulated: bool) -> tuple[str, ...]:
    """The columns ``record.hal`` samples: :data:`RECORD_COLUMNS`, or with simulated drives
    the joint commands, the program line, the joints' actual positions (``a0``..``a4``) and
    the overlay (``o0``..``o4``): a sampler has at most 20 pins, so the planner's Cartesian
    position and the motion type are left out there."""
    if not simulated:
        return RECORD_COLUMNS
    return RECORD_COLUMNS[:5] + ("line",) + ACTUAL_COLUMNS + OVERLAY_COLUMNS


def _record_hal(machine, period_ns: int, simulated: bool = False) -> str:
    columns = record_columns(simulated)
    lines = ["# precontour linuxcnc-config: every servo period recorded (headless.ini)",
             f"# columns after halsampler -t's sample number: {' '.join(columns)}"]
    if not simulated:
        lines += [f"loadrt sampler depth={_depth(period_ns)} cfg=ffffffffffss",
                  "addf sampler.0 servo-thread",  # after motion-controller: this period's
                  *[f"net j{n}-pos => sampler.0.pin.{n}" for n in range(5)],
                  *[f"net {letter.lower()}-world axis.{letter.lower()}.pos-cmd => "
                    f"sampler.0.pin.{5 + n}" for n, letter in enumerate(machine.axis_names)],
                  "net program-line motion.program-line => sampler.0.pin.10",
                  "net motion-type motion.motion-type => sampler.0.pin.11"]
        return "\n".join(lines) + "\n"
    lines += [f"loadrt sampler depth={_depth(period_ns)} cfg=fffffsffffffffff",
              "addf sampler.0 servo-thread",
              *[f"net j{n}-cmd => sampler.0.pin.{n}" for n in range(5)],
              "net program-line motion.program-line => sampler.0.pin.5",
              *[f"net j{n}-pos => sampler.0.pin.{6 + n}" for n in range(5)],
              *[f"net j{n}-overlay => sampler.0.pin.{11 + n}" for n in range(5)]]
    return "\n".join(lines) + "\n"


def _stream_hal(machine, period_ns: int) -> str:
    depth = streamer_depth(period_ns * 1e-9)
    letters = machine.axis_names
    lines = ["# precontour linuxcnc-config: the stream path, for halrun (no motion module:",
             "# motion's following-error check would trip on commands it did not make).",
             "#   halrun -I -f stream.hal, then: halstreamer -c 0 FILE (run --stream's file),",
             "#   then: sets stream-enable 1 once the FIFO is full (streamer.0.curr-depth);",
             "#   record with halsampler -c 0 -t (columns: "
             f"{' '.join(STREAM_COLUMNS)}).",
             f"loadrt threads name1=servo-thread period1={period_ns}",
             f"loadrt streamer depth={depth} cfg={STREAMER_FLOAT * 5}",
             f"loadrt sampler depth={_depth(period_ns)} cfg=fffffss",
             "addf streamer.0 servo-thread   # first in the thread, before the position loops",
             "addf sampler.0 servo-thread",
             "net stream-enable => streamer.0.enable sampler.0.enable",
             "sets stream-enable 0"]
    for n, letter in enumerate(letters):
        unit = "deg" if letter not in LINEAR_AXES else "mm"
        lines.append(f"net {letter.lower()}-cmd streamer.0.pin.{n} => sampler.0.pin.{n}"
                     f"   # {letter}, {unit}: also to the {letter} position loop")
    lines += ["net stream-underruns streamer.0.underruns => sampler.0.pin.5",
              "net stream-depth streamer.0.curr-depth => sampler.0.pin.6",
              "start"]
    return "\n".join(lines) + "\n"


def _switch_sub(number: str, kinstype: int, what: str) -> str:
    return (f"; M{number}: {what} (motion.switchkins-type {kinstype}; written by precontour)\n"
            f"o<{number}remap> sub\n"
            f"  M68 E{SWITCHKINS_PIN} Q{kinstype}\n"
            "  M66 E0 L0   ; wait for the switch before the next move\n"
            f"o<{number}remap> endsub\n")


#: The display program of ``headless.ini``: E-stop reset, machine on, home, auto mode, then
#: the program of $PRECONTOUR_PROGRAM, recorded into $PRECONTOUR_RECORD by halsampler; exit
#: status 0 when it ran to its end without an error. Runs under the system Python (the
#: ``linuxcnc`` module is LinuxCNC's), so it uses nothing of precontour's.
HEADLESS_PY = '''#!/usr/bin/python3
"""Headless display for LinuxCNC (written by precontour linuxcnc-config): run one program.

Environment: PRECONTOUR_PROGRAM (the G-code file), PRECONTOUR_RECORD (halsampler output, one
line per servo period: sample number, then record.hal's pins), PRECONTOUR_TIMEOUT (s, default
3600). Exit status 0 when the program ran to its end without an error.
"""
import os
import subprocess
import sys
import time

import linuxcnc

program = os.path.abspath(os.environ["PRECONTOUR_PROGRAM"])
record = os.environ.get("PRECONTOUR_RECORD")
timeout = float(os.environ.get("PRECONTOUR_TIMEOUT", "3600"))
command, status, errors = linuxcnc.command(), linuxcnc.stat(), linuxcnc.error_channel()
failed = []


def check_errors():
    while True:
        message = errors.poll()
        if not message:
            return
        kind, text = message
        if kind in (linuxcnc.NML_ERROR, linuxcnc.OPERATOR_ERROR):
            failed.append(text)
        print(f"headless: {text}", file=sys.stderr)


def wait(condition, what, limit=30.0):
    end = time.monotonic() + limit
    while time.monotonic() < end:
        status.poll()
        check_errors()
        if condition():
            return
        time.sleep(0.01)
    raise SystemExit(f"headless: timed out waiting for {what}")


sampler = streamer = None
overlay = os.environ.get("PRECONTOUR_OVERLAY")
if record:
    sampler = subprocess.Popen(["halsampler", "-c", "0", "-t", record])
if overlay:
    # the overlay's samples wait in the streamer's FIFO until the program's M62 starts it
    streamer = subprocess.Popen(["halstreamer", "-c", "0", overlay])
try:
    command.state(linuxcnc.STATE_ESTOP_RESET)
    command.state(linuxcnc.STATE_ON)
    wait(lambda: status.task_state == linuxcnc.STATE_ON, "machine on")
    command.mode(linuxcnc.MODE_MANUAL)
    command.wait_complete()
    command.teleop_enable(0)
    command.wait_complete()
    command.home(-1)
    wait(lambda: all(status.homed[:status.joints]), "homing")
    command.mode(linuxcnc.MODE_AUTO)
    command.wait_complete()
    command.program_open(program)
    command.wait_complete()
    command.auto(linuxcnc.AUTO_RUN, 0)
    wait(lambda: status.interp_state != linuxcnc.INTERP_IDLE, "program start", 10.0)
    wait(lambda: (status.interp_state == linuxcnc.INTERP_IDLE and status.queue == 0
                  and status.inpos) or failed, "program end", timeout)
    time.sleep(0.2)  # the last samples reach the recorder
    check_errors()
finally:
    for process in (streamer, sampler):
        if process is not None and process.poll() is None:
            process.terminate()
        if process is not None:
            process.wait()
if failed:
    raise SystemExit("headless: " + "; ".join(failed))
print(f"headless: ran {program}", file=sys.stderr)
'''


def write_linuxcnc_config(machine, folder: str | os.PathLike, *, drives: str = "looped",
                          controller: str | None = None) -> list[Path]:
    """Write :func:`linuxcnc_config` of ``machine`` into ``folder`` as one set: into a
    temporary folder beside it, then renamed. An existing ``folder`` is replaced only when
    it is empty or holds a configuration written here (its ``machine.ini`` starts with
    :data:`HEADER`); otherwise :class:`~precontour.errors.OutputError`. Returns the files
    written."""
    folder = Path(folder)
    check_config_folder(folder)
    config = linuxcnc_config(machine, drives=drives, controller=controller)
    parent = folder.parent if str(folder.parent) else Path(".")
    staging = Path(tempfile.mkdtemp(prefix=f".{folder.name}.", suffix=".tmp", dir=parent))
    old = None
    try:
        for name, text in config.files.items():
            path = staging / name
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(text)
            if name in config.executable:
                path.chmod(0o755)
        staging.chmod(0o755)
        if folder.exists():
            old = Path(tempfile.mkdtemp(prefix=f".{folder.name}.", suffix=".old", dir=parent))
            os.replace(folder, old / "config")
        os.replace(staging, folder)
        staging = None
    except OSError as exc:
        if old is not None and not folder.exists():
            os.replace(old / "config", folder)  # put the old configuration back
        raise OutputError(f"cannot write the configuration: {exc.strerror or exc}",
                          source=str(folder)) from None
    finally:
        if staging is not None:
            shutil.rmtree(staging, ignore_errors=True)
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
    return [folder / name for name in config.files]


def check_config_folder(folder: str | os.PathLike) -> Path:
    """Refuse, before anything is computed, a folder that cannot take a configuration: a
    file, a folder with other contents, a missing or read-only parent."""
    folder = Path(folder)
    parent = folder.parent if str(folder.parent) else Path(".")
    if folder.exists() or folder.is_symlink():
        if not folder.is_dir() or folder.is_symlink():
            raise OutputError("is not a folder; give a folder for the configuration",
                              source=str(folder))
        marker = folder / MARKER
        ours = marker.is_file() and marker.read_text(errors="replace").startswith(HEADER)
        if any(folder.iterdir()) and not ours:
            raise OutputError("is a folder with other contents (not a configuration written "
                              "by precontour linuxcnc-config); not replaced",
                              source=str(folder))
    if not parent.is_dir():
        raise OutputError(f"the folder's parent does not exist ({parent})", source=str(folder))
    if not os.access(parent, os.W_OK | os.X_OK):
        raise OutputError(f"cannot write in folder {str(parent)!r}: permission denied",
                          source=str(folder))
    return folder
