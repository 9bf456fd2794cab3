"""Machine descriptions: load a TOML file (or a built-in machine) into frozen dataclasses.

A machine file has a ``[kinematics]`` table (``type`` picks a module of
:mod:`precontour.machine.kinematics`), one ``[drives.<axis>]`` table per axis of the machine
(X Y Z A C, X Y Z B C on a B-C machine, X Y Z A B on an A-B table: the kinematics'
``axis_names``) with an optional
``friction`` table and optional travel ``p_min``/``p_max``, and named ``[controllers.<name>]``
tables whose ``type`` picks a parser from :data:`precontour.machine.controllers.CONTROLLER_TYPES`,
an optional ``[gcode]`` table of the controller data G-code programs refer to (G28/G30
reference positions, work offsets; :mod:`precontour.machine.gcode`), and an optional
``[tools]`` table of tool lengths by tool number (:mod:`precontour.machine.tools`).
The tilt drive's travel (slot 3) bounds the tilt sign that inverse kinematics picks, unless
the kinematics table gives its own (``a_min``/``a_max`` of ``ac-trunnion``); on an A-B table
(``xyzab-tdr``) both rotary drives' travels bound the inverse's choice. Every value is
checked; unknown and missing keys are errors naming the file, table and key. Units: mm, rad,
s; drive parameters SI.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Mapping

from ._config import ConfigTable
from .controllers import CONTROLLER_TYPES, Controller, check_closed_loop_bases
from .drives import AXES, Drive, Friction
from ..defaults import BUILTIN_MACHINES, DEFAULT_SERVO_PERIOD
from ..defaults import builtin_machine_text as _builtin_text
from .gcode import GcodeSettings, parse_gcode_settings
from .tools import parse_tools_table
from ..errors import MachineFileError
from ..files import check_input_file
from .kinematics import KINEMATICS_TYPES

# BUILTIN_MACHINES, the names of the built-in machines, is defined in precontour.defaults.


#: Relative tolerance of :meth:`Machine.at_servo_period`.
SERVO_PERIOD_RTOL = 1e-6


@dataclass(frozen=True)
class Machine:
    """A five-axis machine: kinematics, five drives and named controllers."""

    name: str
    kinematics: object
    drives: tuple[Drive, ...]
    controllers: Mapping[str, Controller]
    servo_period: float = 0.001
    description: str = ""
    source: str = ""
    gcode: GcodeSettings = GcodeSettings()
    #: Tool lengths (mm) by tool number, the ``[tools]`` table (empty: none given).
    tools: Mapping[int, float] = field(default_factory=lambda: MappingProxyType({}))

    def controller(self, name: str) -> Controller:
        try:
            return self.controllers[name]
        except KeyError:
            raise MachineFileError(
                f"unknown controller {name!r}; this machine has {', '.join(self.controllers)}",
                source=self.source) from None

    def error_models(self, controller: str | Controller):
        """The closed-loop error models e/X of the five axes (spec section 3) with
        ``controller`` (a name of this machine's controllers, or a controller) closing the
        loops of this machine's drives: what prediction and compensation take."""
        if isinstance(controller, str):
            controller = self.controller(controller)
        return controller.error_models(self.drives)

    def at_servo_period(self, ts: float) -> bool:
        """Whether samples every ``ts`` s are one per servo period, within
        :data:`SERVO_PERIOD_RTOL` (sample periods read back from text time stamps differ from
        it by round-off). The one check of it, for the virtual machine's discrete mode,
        learning, identification, the stream and ``compare``."""
        return abs(ts - self.servo_period) <= SERVO_PERIOD_RTOL * self.servo_period

    @property
    def axis_names(self) -> tuple[str, ...]:
        """The five axis letters in q order: ("X", "Y", "Z", "A", "C"), or B in slot 3 on a
        B-C machine, or ("X", "Y", "Z", "A", "B") on an A-B table: the letters of G-code and
        of the axis columns of trajectory and command files."""
        return tuple(getattr(self.kinematics, "axis_names", AXES))

    def drive(self, axis: str) -> Drive:
        """The drive of axis ``axis`` (a letter of :attr:`axis_names`, or of ``AXES``)."""
        names = self.axis_names
        return self.drives[names.index(axis) if axis in names else AXES.index(axis)]


def load_machine(spec: str | Path) -> Machine:
    """A built-in machine or a machine file.

    Parameters
    ----------
    spec : str or Path
        A built-in machine's name (``"zhang2013"``; ``precontour machines`` lists them) or
        the path of a TOML machine file (docs/machine-file.md).

    Returns
    -------
    Machine
        Kinematics, drives, controllers and servo period, checked.
    """
    spec_str = str(spec)
    if spec_str in BUILTIN_MACHINES:
        return parse_machine(builtin_machine_text(spec_str),
                             source=f"<built-in machine {spec_str}>")
    path = Path(spec_str)
    if not path.exists() and not path.is_symlink():
        raise MachineFileError(
            f"no such machine file, and not a built-in machine ({', '.join(BUILTIN_MACHINES)})",
            source=spec_str)
    check_input_file(path, "machine file", error=MachineFileError)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise MachineFileError(f"cannot read machine file: {exc.strerror or exc}",
                               source=spec_str) from None
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise MachineFileError(f"not UTF-8 text (byte {exc.start}): a machine file is TOML",
                               source=spec_str) from None
    return parse_machine(text, source=spec_str)


def machine_data(spec: str | Path) -> tuple[dict, str]:
    """The raw TOML data of a built-in machine or machine file, and its source name.

    Use it to derive a machine file (change tables, then :func:`machine_file_text`); check the
    result with :func:`parse_machine`.
    """
    spec_str = str(spec)
    if spec_str in BUILTIN_MACHINES:
        text, source = builtin_machine_text(spec_str), f"<built-in machine {spec_str}>"
    else:
        path = Path(spec_str)
        if not path.is_file():
            raise MachineFileError("no such machine file, and not a built-in machine "
                                   f"({', '.join(BUILTIN_MACHINES)})", source=spec_str)
        try:
            text, source = path.read_text(), spec_str
        except (OSError, UnicodeDecodeError) as exc:
            raise MachineFileError(f"cannot read machine file: {exc}", source=spec_str) from None
    try:
        return tomllib.loads(text), source
    except tomllib.TOMLDecodeError as exc:
        raise MachineFileError(f"malformed TOML: {exc}", source=source) from None


def machine_file_text(data: dict, header: str = "") -> str:
    """TOML text of machine data (the inverse of ``tomllib.loads`` for what a machine file
    holds: tables, strings, numbers, booleans, lists of numbers). Tables whose values are all
    plain become inline tables (per-axis gains, friction); floats keep full precision."""
    lines = [f"# {line}" if line else "#" for line in header.splitlines()]
    _write_table(lines, [], data)
    return "\n".join(lines).lstrip("\n") + "\n"


def _is_plain(value) -> bool:
    return not isinstance(value, dict) or all(not isinstance(v, dict) for v in value.values())


def _toml_key(key: str) -> str:
    bare = key and all(c.isalnum() and c.isascii() or c in "-_" for c in key)
    return key if bare else _toml_value(key)


def _toml_value(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        text = repr(value)
        return {"inf": "inf", "-inf": "-inf", "nan": "nan"}.get(text, text)
    if isinstance(value, str):
        escaped = value.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n")
        return f'"{escaped}"'
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{_toml_key(k)} = {_toml_value(v)}" for k, v in value.items()) + " }"
    raise TypeError(f"cannot write {type(value).__name__} to TOML")


def _write_table(lines: list[str], path: list[str], table: dict) -> None:
    # Top-level tables ([kinematics], [drives], ...) are always sections.
    plain = {k: v for k, v in table.items() if _is_plain(v) and (path or not isinstance(v, dict))}
    nested = {k: v for k, v in table.items() if k not in plain}
    if path and plain:
        lines.append("")
        lines.append("[" + ".".join(_toml_key(p) for p in path) + "]")
    for key, value in plain.items():
        lines.append(f"{_toml_key(key)} = {_toml_value(value)}")
    for key, value in nested.items():
        _write_table(lines, path + [key], value)


def builtin_machine_text(name: str = "zhang2013") -> str:
    """TOML text of a built-in machine: a template for writing your own machine file."""
    if name not in BUILTIN_MACHINES:
        raise MachineFileError(f"unknown built-in machine {name!r}; choose one of "
                               f"{', '.join(BUILTIN_MACHINES)}")
    return _builtin_text(name)


def parse_machine(text: str, source: str = "<string>") -> Machine:
    """Parse the TOML text of a machine file; see the module docstring for the format."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise MachineFileError(f"malformed TOML: {exc}", source=source) from None
    top = ConfigTable(data, source, "")
    name = top.get_str("name", default="unnamed")
    description = top.get_str("description", default="")
    servo_period = top.get_float("servo_period", default=DEFAULT_SERVO_PERIOD, above=0.0)

    kin_table = top.get_table("kinematics")
    kin_type = kin_table.get_str("type", choices=tuple(KINEMATICS_TYPES))
    kinematics = KINEMATICS_TYPES[kin_type](kin_table)
    kin_table.finish()
    axis_names = tuple(getattr(kinematics, "axis_names", AXES))

    drives_table = top.get_table("drives")
    drives = tuple(_parse_drive(axis, drives_table.get_table(axis)) for axis in axis_names)
    drives_table.finish()
    tilt = drives[3]
    if hasattr(kinematics, "with_rotary_travel"):   # both rotary axes' travel matter
        kinematics = kinematics.with_rotary_travel((tilt.p_min, tilt.p_max),
                                                   (drives[4].p_min, drives[4].p_max))
    elif hasattr(kinematics, "with_tilt_limits"):
        kinematics = kinematics.with_tilt_limits(tilt.p_min, tilt.p_max)

    controllers_table = top.get_table("controllers")
    controllers: dict[str, Controller] = {}
    for ctrl_name in controllers_table.keys():
        table = controllers_table.get_table(ctrl_name)
        kind = table.get_str("type", choices=tuple(CONTROLLER_TYPES))
        controllers[ctrl_name] = CONTROLLER_TYPES[kind](ctrl_name, table, axis_names)
    controllers_table.finish()
    if not controllers:
        raise controllers_table.error(None, "a machine needs at least one controller")
    check_closed_loop_bases(controllers, lambda ctrl_name, message: MachineFileError(
        f"[controllers.{ctrl_name}] {message}", source=source))
    gcode = parse_gcode_settings(top.get_table("gcode", required=False), axis_names)
    tools = parse_tools_table(top.get_table("tools", required=False))
    top.finish()
    return Machine(name=name, kinematics=kinematics, drives=drives,
                   controllers=MappingProxyType(controllers), servo_period=servo_period,
                   description=description, source=source, gcode=gcode, tools=tools)


def _parse_drive(axis: str, table: ConfigTable) -> Drive:
    friction = None
    friction_table = table.get_table("friction", required=False)
    if friction_table is not None:
        friction = _parse_friction(friction_table)
    drive = Drive(
        axis=axis,
        ka=table.get_float("ka", above=0.0),
        kt=table.get_float("kt", above=0.0),
        rg=table.get_float("rg", above=0.0),
        J=table.get_float("J", above=0.0),
        B=table.get_float("B", minval=0.0),
        friction=friction,
        v_max=table.get_float("v_max", required=False, above=0.0),
        a_max=table.get_float("a_max", required=False, above=0.0),
        j_max=table.get_float("j_max", required=False, above=0.0),
        p_min=table.get_float("p_min", required=False),
        p_max=table.get_float("p_max", required=False),
    )
    if drive.p_min is not None and drive.p_max is not None and not drive.p_min < drive.p_max:
        raise table.error("p_max", f"must be > p_min ({drive.p_min:g}), got {drive.p_max:g}")
    table.finish()
    return drive


def _parse_friction(table: ConfigTable) -> Friction:
    friction = Friction(
        Ts_pos=table.get_float("Ts_pos", minval=0.0),
        W1_pos=table.get_float("W1_pos", above=0.0),
        Tc_pos=table.get_float("Tc_pos", minval=0.0),
        W2_pos=table.get_float("W2_pos", above=0.0),
        Ts_neg=table.get_float("Ts_neg"),
        W1_neg=table.get_float("W1_neg"),
        Tc_neg=table.get_float("Tc_neg"),
        W2_neg=table.get_float("W2_neg"),
    )
    for key in ("Ts_neg", "Tc_neg"):
        if getattr(friction, key) > 0:
            raise table.error(key, f"must be <= 0 (negative-speed side), got {getattr(friction, key):g}")
    for key in ("W1_neg", "W2_neg"):
        if not getattr(friction, key) < 0:
            raise table.error(key, f"must be < 0 (negative-speed side), got {getattr(friction, key):g}")
    table.finish()
    return friction
