"""Machine descriptions: load a TOML file (or a built-in machine) into frozen dataclasses.

A machine file has a ``[kinematics]`` table (``type`` picks a module of
:mod:`precontour.machine.kinematics`), one ``[drives.<axis>]`` table per axis X Y Z A C with an
optional ``friction`` table, and named ``[controllers.<name>]`` tables whose ``type`` picks a
parser from :data:`precontour.machine.controllers.CONTROLLER_TYPES`. Every value is checked; unknown and
missing keys are errors naming the file, table and key. Units: mm, rad, s; drive parameters SI.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from types import MappingProxyType
from typing import Mapping

from ._config import ConfigTable
from .controllers import CONTROLLER_TYPES, Controller
from .drives import AXES, Drive, Friction
from ..errors import MachineFileError
from .kinematics import KINEMATICS_TYPES

BUILTIN_MACHINES: tuple[str, ...] = ("zhang2013",)


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

    def controller(self, name: str) -> Controller:
        try:
            return self.controllers[name]
        except KeyError:
            raise MachineFileError(
                f"unknown controller {name!r}; this machine has {', '.join(self.controllers)}",
                source=self.source) from None

    def drive(self, axis: str) -> Drive:
        return self.drives[AXES.index(axis)]


def load_machine(spec: str | Path) -> Machine:
    """Load a built-in machine by name (``"zhang2013"``) or a machine file by path."""
    spec_str = str(spec)
    if spec_str in BUILTIN_MACHINES:
        return parse_machine(builtin_machine_text(spec_str),
                             source=f"<built-in machine {spec_str}>")
    path = Path(spec_str)
    if not path.exists():
        raise MachineFileError(
            f"no such machine file, and not a built-in machine ({', '.join(BUILTIN_MACHINES)})",
            source=spec_str)
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise MachineFileError(f"cannot read machine file: {exc}", source=spec_str) from None
    return parse_machine(text, source=spec_str)


def builtin_machine_text(name: str = "zhang2013") -> str:
    """TOML text of a built-in machine: a template for writing your own machine file."""
    if name not in BUILTIN_MACHINES:
        raise MachineFileError(f"unknown built-in machine {name!r}; choose one of "
                               f"{', '.join(BUILTIN_MACHINES)}")
    return resources.files("precontour.machine.data").joinpath(f"{name}.toml").read_text()


def parse_machine(text: str, source: str = "<string>") -> Machine:
    """Parse the TOML text of a machine file; see the module docstring for the format."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise MachineFileError(f"malformed TOML: {exc}", source=source) from None
    top = ConfigTable(data, source, "")
    name = top.get_str("name", default="unnamed")
    description = top.get_str("description", default="")
    servo_period = top.get_float("servo_period", default=0.001, above=0.0)

    kin_table = top.get_table("kinematics")
    kin_type = kin_table.get_str("type", choices=tuple(KINEMATICS_TYPES))
    kinematics = KINEMATICS_TYPES[kin_type](kin_table)
    kin_table.finish()

    drives_table = top.get_table("drives")
    drives = tuple(_parse_drive(axis, drives_table.get_table(axis)) for axis in AXES)
    drives_table.finish()

    controllers_table = top.get_table("controllers")
    controllers: dict[str, Controller] = {}
    for ctrl_name in controllers_table.keys():
        table = controllers_table.get_table(ctrl_name)
        kind = table.get_str("type", choices=tuple(CONTROLLER_TYPES))
        controllers[ctrl_name] = CONTROLLER_TYPES[kind](ctrl_name, table)
    controllers_table.finish()
    if not controllers:
        raise controllers_table.error(None, "a machine needs at least one controller")
    top.finish()
    return Machine(name=name, kinematics=kinematics, drives=drives,
                   controllers=MappingProxyType(controllers), servo_period=servo_period,
                   description=description, source=source)


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
        position_min=table.get_float("position_min", required=False),
        position_max=table.get_float("position_max", required=False),
    )
    if (drive.position_min is not None and drive.position_max is not None
            and not drive.position_min < drive.position_max):
        raise table.error("position_max", f"must be > position_min ({drive.position_min:g}), "
                                          f"got {drive.position_max:g}")
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
