"""Annotated machine files: every key of a machine file with its unit and meaning, one file per
kinematics type (``precontour machines --template TYPE``).

The values are those of a built-in machine of that type (:data:`precontour.defaults
.BUILTIN_MACHINES`), so a template loads back as that machine (tests/machine/test_template.py);
the words are in the tables below, one entry per key the loader reads (the same test checks
that none is missing). Optional keys the built-in machine leaves out are shown commented out.
"""

from __future__ import annotations

import textwrap
import tomllib

from ..defaults import builtin_machine_text, builtin_machines
from ..errors import MachineFileError
from .machine_file import _toml_key, _toml_value

#: Top-level keys: (key, unit, meaning).
TOP_KEYS: tuple[tuple[str, str, str], ...] = (
    ("name", "", "the machine's name, in reports and program headers (default unnamed)"),
    ("description", "", "optional: one line about the machine"),
    ("servo_period", "s", "sampling period of the position loops (optional, default 0.001)"),
)

_TILT_TRAVEL = ("optional: {which} travel of the tilt axis that inverse kinematics keeps the "
                "tilt sign within (default: p_{end} of [drives.A]; none: free)")
_LINUXCNC = "HAL pin {kins}.{pin}"
_DIRECTION = ("+1 or -1, the sense of rotation: -1 when the HAL pin "
              "{kins}.conventional-directions is false (default), +1 when true")


def _linuxcnc_keys(kins: str, tilt: str, offset_axis: str) -> tuple[tuple[str, str, str], ...]:
    centre = "C axis centre in the machine frame, {0} (" + _LINUXCNC + ")"
    return (
        ("x_rot_point", "mm", centre.format("x", kins=kins, pin="x-rot-point")),
        ("y_rot_point", "mm", centre.format("y", kins=kins, pin="y-rot-point")),
        ("z_rot_point", "mm", centre.format("z", kins=kins, pin="z-rot-point")),
        (f"{offset_axis}_offset", "mm",
         f"{tilt.upper()} axis centre relative to the C axis, {offset_axis} ("
         + _LINUXCNC.format(kins=kins, pin=f"{offset_axis}-offset") + ")"),
        ("z_offset", "mm", f"{tilt.upper()} axis centre relative to the C axis, z ("
         + _LINUXCNC.format(kins=kins, pin="z-offset") + ")"),
        ("tool_offset", "mm", "tool length, motion.tooloffset.z ("
         + _LINUXCNC.format(kins=kins, pin="tool-offset") + ")"),
        (f"{tilt}_direction", "", _DIRECTION.format(kins=kins)),
        ("c_direction", "", _DIRECTION.format(kins=kins)),
    )


#: ``[kinematics]`` keys of each type, after ``type``: (key, unit, meaning).
KINEMATICS_KEYS: dict[str, tuple[tuple[str, str, str], ...]] = {
    "ac-trunnion": (
        ("L_ac", "mm", "offset from the A axis to the C axis, along z"),
        ("L_ty", "mm", "offset from the A axis to the tool, along z"),
        ("a_min", "rad", _TILT_TRAVEL.format(which="lower", end="min")),
        ("a_max", "rad", _TILT_TRAVEL.format(which="upper", end="max")),
    ),
    "xyzac-trt": _linuxcnc_keys("xyzac-trt-kins", "a", "y"),
    "xyzbc-trt": _linuxcnc_keys("xyzbc-trt-kins", "b", "x"),
    "xyzbc-head-table": (
        ("x_rot_point", "mm", "C axis centre in the machine frame, x"),
        ("y_rot_point", "mm", "C axis centre in the machine frame, y"),
        ("z_rot_point", "mm", "height of the workpiece origin on the C axis"),
        ("pivot_length", "mm", "B pivot to the spindle nose (gauge line), along the tool axis"),
        ("tool_offset", "mm", "tool length, spindle nose to tip"),
        ("b_direction", "", "+1 or -1, the sense of rotation of the B head: +1 turns the tool "
                            "right-handed about +y (ISO 841)"),
        ("c_direction", "", "+1 or -1, the sense of rotation of the C table: -1 turns the table "
                            "left-handed about +z, the tool right-handed relative to the part "
                            "(ISO 841)"),
    ),
    "xyzbc-head-head": (
        ("pivot_length", "mm", "pivot of the B and C axes to the spindle nose (gauge line), "
                               "along the tool axis (HAL pin 5axiskins.pivot-length is this "
                               "plus the tool length)"),
        ("tool_offset", "mm", "tool length, spindle nose to tip (motion.tooloffset.z)"),
        ("b_direction", "", "+1 or -1, the sense of rotation of B: -1 is 5axiskins's (the tool "
                            "tilts towards -x at C = 0 for B > 0)"),
        ("c_direction", "", "+1 or -1, the sense of rotation of C: +1 is 5axiskins's "
                            "(right-handed about +z)"),
    ),
    "xyzab-tdr": (
        ("x_rot_point", "mm", "rotation point, where the B axis meets the A axis at zero "
                              "offsets, in the machine frame, x (HAL pin "
                              "xyzab_tdr_kins.x-rot-point)"),
        ("y_rot_point", "mm", "... y (HAL pin xyzab_tdr_kins.y-rot-point)"),
        ("z_rot_point", "mm", "... z (HAL pin xyzab_tdr_kins.z-rot-point)"),
        ("x_offset", "mm", "A table face centre relative to the rotation point, x: along the A "
                           "axis, so without effect on the kinematics (HAL pin "
                           "xyzab_tdr_kins.x-offset)"),
        ("z_offset", "mm", "A axis relative to the rotation point, z (HAL pin "
                           "xyzab_tdr_kins.z-offset)"),
        ("tool_offset", "mm", "tool length, motion.tooloffset.z (HAL pin "
                              "xyzab_tdr_kins.tool-offset-z); A and B have no direction "
                              "pins: both turn the part left-handed about +x, +y"),
    ),
    "chain": (
        ("tool_offset", "mm", "tool length: at the zero pose the tip is this far below the "
                              "spindle nose, the tool along +z"),
        ("linear_senses", "", "optional: +1 or -1 for X, Y, Z, -1 where the axis moves the "
                              "table, i.e. the tool the other way (default [1, 1, 1])"),
        ("workpiece_origin", "mm", "optional: origin of the workpiece frame in the machine "
                                   "frame at the zero pose; it turns with the table's axes "
                                   "(default [0, 0, 0])"),
        ("carrier", "", "two tilts A and B (no C) on the same side only: \"A\" or \"B\", the "
                        "one that carries the other (on a table nearer the base, on a head "
                        "nearer the ram)"),
    ),
}
#: Keys of a chain's rotary axis tables, ``[kinematics.A]`` (or B) and ``[kinematics.C]``, or
#: ``[kinematics.A]`` and ``[kinematics.B]``.
CHAIN_AXIS_KEYS: tuple[tuple[str, str, str], ...] = (
    ("carried_by", "", "table (the axis turns the part) or head (it turns the tool); on a "
                       "table C carries the part and the tilt carries C, on a head C carries "
                       "the tilt (two tilts: see carrier)"),
    ("direction", "", "unit vector of the axis, +-x for A, +-y for B, +-z for C: the command "
                      "turns right-handed about it"),
    ("point", "mm", "a point of the axis line at the zero pose: in the machine frame on a "
                    "table, relative to the spindle nose on a head"),
)

#: ``[drives.<axis>]`` keys: (key, unit on a linear axis, unit on a rotary axis, meaning).
DRIVE_KEYS: tuple[tuple[str, str, str, str], ...] = (
    ("ka", "A/V", "A/V", "current amplifier gain"),
    ("kt", "N m/A", "N m/A", "motor torque constant"),
    ("rg", "mm/rad", "rad/rad", "transmission: ball screw lead / (2 pi), or the gear ratio"),
    ("J", "kg m^2", "kg m^2", "inertia at the motor"),
    ("B", "kg m^2/s", "kg m^2/s", "viscous damping at the motor"),
    ("p_min", "mm", "rad", "optional: lower travel limit (none: unlimited)"),
    ("p_max", "mm", "rad", "optional: upper travel limit (none: unlimited)"),
    ("v_max", "mm/s", "rad/s", "velocity limit, for planning (a rapid needs it)"),
    ("a_max", "mm/s^2", "rad/s^2", "acceleration limit, for planning"),
    ("j_max", "mm/s^3", "rad/s^3", "jerk limit, for planning"),
)

#: ``[drives.<axis>.friction]`` keys (optional table; none: no friction), torque at the motor
#: Tf(w) = Ts exp(-w/W1) + Tc (1 - exp(-w/W2)) for motor speed w, each side on its own.
FRICTION_KEYS: tuple[tuple[str, str, str], ...] = (
    ("Ts_pos", "N m", "static torque at w > 0 (>= 0), fading over W1_pos"),
    ("W1_pos", "rad/s", "speed over which the static torque fades (> 0)"),
    ("Tc_pos", "N m", "Coulomb torque at w > 0 (>= 0), reached over W2_pos"),
    ("W2_pos", "rad/s", "speed over which the Coulomb torque builds up (> 0)"),
    ("Ts_neg", "N m", "static torque at w < 0 (<= 0)"),
    ("W1_neg", "rad/s", "its speed (< 0)"),
    ("Tc_neg", "N m", "Coulomb torque at w < 0 (<= 0)"),
    ("W2_neg", "rad/s", "its speed (< 0)"),
)

_FEEDFORWARD = (
    ("kvff", "", "optional: velocity feed-forward, fraction 0..1 of the nominal damping torque "
                 "B X' (default 0)"),
    ("kaff", "", "optional: acceleration feed-forward, fraction 0..1 of the nominal inertia "
                 "torque J X'' (default 0)"),
)
#: Per-axis keys of each controller type: (key, unit on a linear axis, meaning); on a rotary
#: axis "mm" reads "rad".
CONTROLLER_KEYS: dict[str, tuple[tuple[str, str, str], ...]] = {
    "pid": (("kp", "V/mm", "proportional gain"),
            ("ki", "V/(mm s)", "integral gain"),
            ("kd", "V/(mm/s)", "derivative gain")) + _FEEDFORWARD,
    "p-pi": (("kp", "1/s", "position-loop gain (velocity reference per position error)"),
             ("kv", "V/(mm/s)", "velocity-loop proportional gain"),
             ("ki_v", "V/mm", "velocity-loop integral gain"),
             ("kvff", "", "optional: velocity feed-forward into the velocity reference, "
                          "fraction 0..1 of X' (default 0)"),
             _FEEDFORWARD[1]),
    "smc": (("lambda", "1/s", "sliding-surface slope"),
            ("ks", "N m s/rad", "feedback gain on the sliding variable (motor side)"),
            ("gamma_d", "N m/rad", "adaptation rate of the disturbance torque estimate"),
            ("gamma_J", "kg m^2 s^2/rad^2", "optional: adaptation rate of the inertia "
                                            "estimate (default 0, as published)"),
            ("gamma_B", "kg m^2 s/rad^2", "optional: adaptation rate of the damping estimate "
                                          "(default 0, as published)")),
    "tf": (("num", "", "closed-loop x/X numerator in s, highest power first (a list)"),
           ("den", "", "closed-loop x/X denominator in s, highest power first (a list); "
                       "proper and stable")),
}
#: ``[gcode]`` keys (optional table; precontour.machine.gcode): (key, unit, meaning). The
#: positions are machine axes in the file's units; "{axes}" is the machine's axis names.
GCODE_KEYS: tuple[tuple[str, str, str], ...] = (
    ("g28", "mm, rad", "G28 reference position, the machine axes {axes} (default: the machine "
                       "origin, all 0, said once when a program uses it)"),
    ("g30", "mm, rad", "G30 reference position, the same (default: the machine origin)"),
    ("tcp_on", "", "M codes (or the site's own G codes) that switch tool centre point mode "
                   "on (default: M428, LinuxCNC's remapped switch; an empty list: none; "
                   "G43.4, G43.5 and Haas's G234 are read without it)"),
    ("tcp_off", "", "M codes (or G codes) that switch every tool centre point mode off "
                    "(default: M429)"),
)
_GCODE_EXAMPLE = {"tcp_on": ["M428"], "tcp_off": ["M429"]}

_CONTROLLER_TITLES = {
    "pid": "PID position controller per axis",
    "p-pi": "cascaded P position / PI velocity loops per axis",
    "smc": "adaptive sliding mode per axis (Altintas, Erkorkmaz & Zhu 2000)",
    "tf": "a closed loop x/X as a transfer function per axis",
}

#: Column of the comments after the values, and the width of the lines.
COMMENT_COLUMN = 28
WIDTH = 99
_LINEAR = ("X", "Y", "Z")


def template_types() -> tuple[str, ...]:
    """Kinematics types with a template: those of the built-in machines."""
    return tuple(dict.fromkeys(m.kinematics for m in builtin_machines()))


def machine_template(kinematics: str) -> str:
    """The annotated machine file of kinematics type ``kinematics``: the first built-in machine
    of that type, every key with its unit and meaning, optional keys it leaves out commented
    out, and a closed-loop (``tf``) controller as a commented example."""
    machines = {m.kinematics: m for m in reversed(builtin_machines())}
    if kinematics not in machines:
        raise MachineFileError(f"no template for kinematics type {kinematics!r}; choose one of "
                               f"{', '.join(template_types())}")
    builtin = machines[kinematics]
    text = builtin_machine_text(builtin.name)
    data = tomllib.loads(text)
    out = _Writer()
    out.comment(f"precontour machine file, kinematics type {kinematics!r}: every key with its "
                "unit and meaning.")
    out.comment(f"The values are those of the built-in machine {builtin.name} "
                f"({builtin.description}); put in yours.")
    out.comment("Units: mm, rad, s; drive parameters at the motor, SI. On rotary axes read rad "
                "for mm. Keys commented out are optional.")
    out.comment("Every value is checked when the file is loaded (any command's --machine FILE); "
                "unknown keys are errors.")
    out.comment("")
    out.comment(f"Where the values of {builtin.name} come from:")
    for line in text.splitlines():  # the built-in file's own opening comment
        if not line.startswith("#"):
            break
        out.line(line)
    out.blank()
    _plain_table(out, {k: v for k, v in data.items() if not isinstance(v, dict)}, TOP_KEYS,
                 "top level")
    out.blank()
    out.line("[kinematics]")
    kin = dict(data["kinematics"])
    out.entry("type", kin.pop("type"), f"kinematics type: one of {', '.join(KINEMATICS_KEYS)}")
    axes = {key: kin.pop(key) for key in list(kin) if isinstance(kin[key], dict)}
    _plain_table(out, kin, KINEMATICS_KEYS[kinematics], "[kinematics]")
    for letter, axis in axes.items():
        out.blank()
        out.line(f"[kinematics.{letter}]")
        _plain_table(out, dict(axis), CHAIN_AXIS_KEYS, f"[kinematics.{letter}]")
    for axis, drive in data["drives"].items():
        out.blank()
        out.line(f"[drives.{axis}]")
        drive = dict(drive)
        friction = drive.pop("friction", None)
        linear = axis in _LINEAR
        keys = tuple((key, lin if linear else rot, meaning) for key, lin, rot, meaning
                     in DRIVE_KEYS)
        _plain_table(out, drive, keys, f"[drives.{axis}]")
        if friction is not None:
            out.blank()
            out.line(f"[drives.{axis}.friction]")
            out.comment("optional table (none: no friction): torque at the motor Tf(w) = "
                        "Ts exp(-w/W1) + Tc (1 - exp(-w/W2)), per side of the motor speed w")
            _plain_table(out, dict(friction), FRICTION_KEYS, f"[drives.{axis}.friction]")
    explained = set()
    for name, table in data["controllers"].items():
        table = dict(table)
        kind = table.pop("type")
        base = table.pop("base", None)
        out.blank()
        if kind not in explained:
            _explain_controller(out, kind)
            explained.add(kind)
        out.line(f"[controllers.{_toml_key(name)}]")
        out.entry("type", kind, f"{_CONTROLLER_TITLES[kind]}; gains per axis, units above")
        if base is not None:
            out.entry("base", base, "the controller the drives run")
        for axis, gains in table.items():
            known = {key for key, _, _ in CONTROLLER_KEYS[kind]}
            unknown = [key for key in gains if key not in known]
            if unknown:
                raise MachineFileError(f"[controllers.{name}.{axis}] {unknown[0]}: no "
                                       "description in the template tables")
            out.line(f"{_toml_key(axis)} = {_toml_value(gains)}")
    if "tf" not in explained:
        out.blank()
        _explain_controller(out, "tf")
        linear = [name for name, table in data["controllers"].items()
                  if table["type"] in ("pid", "p-pi")]
        out.comment("[controllers.identified]")
        out.comment('type = "tf"')
        if linear:
            out.comment(f"base = {_toml_value(linear[0])}   # optional: the controller of "
                        "this file the drives run (the loop was identified with it), for "
                        "--learn")
        for axis in data["drives"]:
            out.comment(f"{axis} = {{ num = [...], den = [...] }}")
    out.blank()
    _tools_table(out, data.get("tools"))
    out.blank()
    _gcode_table(out, data.get("gcode"), tuple(data["drives"]))
    return out.text()


def _tools_table(out: "_Writer", table: dict | None) -> None:
    """The ``[tools]`` table: the machine's own, or commented out with an example."""
    out.comment("optional table: tool lengths by tool number, mm, spindle nose to tip "
                "(precontour.machine.tools): G43 H, G43.4 H, G234 H select one for TCP moves; "
                "a tool not given takes the kinematics' tool_offset (said once)")
    if not table:
        out.comment("[tools]")
        out.comment("1 = 50.0")
        return
    out.line("[tools]")
    for number, length in table.items():
        out.line(f"{_toml_key(str(number))} = {_toml_value(float(length))}")


def _gcode_table(out: "_Writer", table: dict | None, axes: tuple[str, ...]) -> None:
    """The ``[gcode]`` table: the machine's own, or commented out with example values."""
    names = " ".join(axes)
    keys = tuple((key, unit, meaning.format(axes=names)) for key, unit, meaning in GCODE_KEYS)
    offsets_comment = ("optional table: work offsets G54 ... G59, \"G59.1\" ... \"G59.3\", "
                       "\"G54.1 P1\" ... \"G54.1 P300\" (names with a dot or a space in "
                       f"quotes), each [mm, rad] the machine axes {names}; an offset not given "
                       "is zero (said once when a program selects it)")
    out.comment("optional table: what G-code programs refer to without giving it (machine "
                f"axes {names} in mm and rad), and the site's tool centre point switches")
    if table is None:
        zeros = [0.0] * len(axes)
        out.comment("[gcode]")
        for key, unit, meaning in keys:
            comment = f"[{unit}] {meaning}" if unit else meaning
            out.commented(f"# {key} = {_toml_value(_GCODE_EXAMPLE.get(key, zeros))}", comment)
        out.comment("")
        out.comment(offsets_comment)
        out.comment("[gcode.work_offsets]")
        out.comment(f"G54 = {_toml_value(zeros)}")
        out.comment(f"{_toml_key('G59.1')} = {_toml_value(zeros)}")
        return
    table = dict(table)
    offsets = table.pop("work_offsets", None)
    out.line("[gcode]")
    _plain_table(out, table, keys, "[gcode]")
    if offsets is not None:
        out.blank()
        out.comment(offsets_comment)
        out.line("[gcode.work_offsets]")
        for name, value in offsets.items():
            out.line(f"{_toml_key(name)} = {_toml_value(value)}")


def _explain_controller(out: "_Writer", kind: str) -> None:
    out.comment(f"type {kind!r}: {_CONTROLLER_TITLES[kind]}. Keys of each axis's table:")
    for key, unit, meaning in CONTROLLER_KEYS[kind]:
        out.comment(f"  {key}: " + (f"[{unit}] " if unit else "") + meaning)
    if kind == "tf":
        out.comment("  written by `precontour identify` from a servo log; optional at the "
                    "controller's level: base, the controller the drives run")


def _plain_table(out: "_Writer", table: dict, keys, where: str) -> None:
    """Entries of ``table`` in the order of ``keys``; optional keys it lacks commented out."""
    documented = {key for key, _, _ in keys}
    unknown = [key for key in table if key not in documented]
    if unknown:
        raise MachineFileError(f"{where} {unknown[0]}: no description in the template tables")
    for key, unit, meaning in keys:
        comment = f"[{unit}] {meaning}" if unit else meaning
        if key in table:
            out.entry(key, table[key], comment)
        else:
            out.commented(f"# {key} = ...", comment)


class _Writer:
    def __init__(self):
        self.lines: list[str] = []

    def line(self, text: str) -> None:
        self.lines.append(text)

    def blank(self) -> None:
        self.lines.append("")

    def comment(self, text: str) -> None:
        indent = " " * (len(text) - len(text.lstrip()))
        self.lines += textwrap.wrap(text, WIDTH, initial_indent="# ",
                                    subsequent_indent="# " + indent + "  ") or ["#"]

    def entry(self, key: str, value, comment: str) -> None:
        self.commented(f"{_toml_key(key)} = {_toml_value(value)}", comment)

    def commented(self, text: str, comment: str) -> None:
        """``text`` with ``comment`` after it at COMMENT_COLUMN, or on the line before it
        when both would not fit in WIDTH."""
        line = text.ljust(COMMENT_COLUMN - 1) + f" # {comment}"
        if len(line) <= WIDTH:
            self.lines.append(line)
        else:
            self.comment(comment)
            self.lines.append(text)

    def text(self) -> str:
        return "\n".join(self.lines) + "\n"
