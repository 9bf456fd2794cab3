"""What a machine file says about how its controller reads G-code: the optional ``[gcode]``
table, parsed into :class:`GcodeSettings`.

These are the controller's stored data that a program refers to without giving them: the
reference positions of G28 and G30 (LinuxCNC's parameters 5161-5169 and 5181-5189), the
work offsets of G54-G59.3 and Fanuc's G54.1 P1-P300 (LinuxCNC's parameters 5221 and on), and
the M codes with which the site switches tool centre point (TCP) mode on and off (LinuxCNC's
trunnion configurations remap M428 to their TCP kinematics and M429 to identity kinematics).
Positions are machine axes in the machine file's units, mm and rad, in the order of the
kinematics' axis names (X Y Z A C, or X Y Z B C on a B-C machine)::

    [gcode]
    g28 = [0.0, 0.0, 50.0, 0.0, 0.0]
    g30 = [-100.0, 0.0, 50.0, 0.0, 0.0]
    tcp_on = ["M428"]
    tcp_off = ["M429"]

    [gcode.work_offsets]
    G54 = [120.0, -35.5, 200.0, 0.0, 0.0]
    "G59.1" = [0.0, 0.0, 150.0, 0.0, 0.0]
    "G54.1 P7" = [10.0, 0.0, 0.0, 0.0, 0.0]

Every key is optional. Without ``g28``/``g30`` the reader takes the machine origin (all axes
0, the parameters' values in a fresh LinuxCNC), without a work offset zero, and says so once;
``tcp_on``/``tcp_off`` default to LinuxCNC's M428/M429 (``[]``: none).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Mapping

from ._config import ConfigTable

__all__ = ["GcodeSettings", "WORK_OFFSETS", "parse_gcode_settings", "work_offset_name"]

#: The work offsets G54-G59.3, in LinuxCNC's order (coordinate systems 1-9).
WORK_OFFSETS = ("G54", "G55", "G56", "G57", "G58", "G59", "G59.1", "G59.2", "G59.3")
#: Fanuc's additional work offsets G54.1 P1 ... P300.
MAX_EXTENDED_OFFSET = 300

_EXTENDED = re.compile(r"G54\.1\s*P(\d+)")
_M_CODE = re.compile(r"M0*(\d{1,4})")
#: M codes with a meaning of their own (stops, spindle, tool, coolant, overrides, I/O, modal
#: state, subprograms): not available as a TCP switch.
RESERVED_M = frozenset([0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 19, 30, 48, 49, 50, 51, 52, 53, 60, 61,
                        62, 63, 64, 65, 66, 67, 68, 70, 71, 72, 73, 98, 99])
#: LinuxCNC's remapped TCP switches (configs/sim/axis/vismach/5axis/table-rotary-tilting).
DEFAULT_TCP_ON = (428,)
DEFAULT_TCP_OFF = (429,)


def work_offset_name(key: str) -> str | None:
    """The canonical name of a work offset key (``"G55"``, ``"G59.1"``, ``"G54.1 P7"``), or
    None if ``key`` names none."""
    text = key.strip().upper()
    if text in WORK_OFFSETS:
        return text
    match = _EXTENDED.fullmatch(text)
    if match and 1 <= int(match.group(1)) <= MAX_EXTENDED_OFFSET:
        return f"G54.1 P{int(match.group(1))}"
    return None


@dataclass(frozen=True)
class GcodeSettings:
    """The controller data a G-code program refers to (machine axes, mm and rad).

    Attributes
    ----------
    g28, g30 : tuple of 5 floats, or None
        Reference positions of G28 and G30; None: not given (the reader takes all axes 0).
    work_offsets : Mapping[str, tuple of 5 floats]
        Work offsets by name (``"G54"`` ... ``"G59.3"``, ``"G54.1 P1"`` ...); an offset not
        given is zero.
    tcp_on, tcp_off : tuple of int
        M code numbers that switch TCP mode on and off.
    """

    g28: tuple[float, ...] | None = None
    g30: tuple[float, ...] | None = None
    work_offsets: Mapping[str, tuple[float, ...]] = field(
        default_factory=lambda: MappingProxyType({}))
    tcp_on: tuple[int, ...] = DEFAULT_TCP_ON
    tcp_off: tuple[int, ...] = DEFAULT_TCP_OFF


def parse_gcode_settings(table: ConfigTable | None, axis_names: tuple[str, ...]
                         ) -> GcodeSettings:
    """Read the ``[gcode]`` table (None: no table, the defaults)."""
    if table is None:
        return GcodeSettings()
    g28 = _position(table, "g28", axis_names)
    g30 = _position(table, "g30", axis_names)
    offsets = {}
    offsets_table = table.get_table("work_offsets", required=False)
    if offsets_table is not None:
        for key in offsets_table.keys():
            if isinstance(offsets_table.data[key], dict):
                raise offsets_table.error(key, "a dotted key: write names with a dot in "
                                               'quotes ("G59.1" = [...])')
            name = work_offset_name(key)
            if name is None:
                raise offsets_table.error(key, "not a work offset; use G54 ... G59, G59.1, "
                                               "G59.2, G59.3 or G54.1 P1 ... P300")
            if name in offsets:
                raise offsets_table.error(key, f"{name} is given twice")
            offsets[name] = _position(offsets_table, key, axis_names)
        offsets_table.finish()
    tcp_on = _m_codes(table, "tcp_on", DEFAULT_TCP_ON)
    tcp_off = _m_codes(table, "tcp_off", DEFAULT_TCP_OFF)
    both = sorted(set(tcp_on) & set(tcp_off))
    if both:
        raise table.error("tcp_off", f"M{both[0]} is in tcp_on too")
    table.finish()
    return GcodeSettings(g28=g28, g30=g30, work_offsets=MappingProxyType(offsets),
                         tcp_on=tcp_on, tcp_off=tcp_off)


def _m_codes(table: ConfigTable, key: str, default: tuple[int, ...]) -> tuple[int, ...]:
    value = table._get(key, None)
    if value is None:
        return default
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        raise table.error(key, f'must be a list of M codes such as ["M428"], got {value!r}')
    numbers = []
    for text in value:
        match = _M_CODE.fullmatch(text.strip().upper())
        if match is None:
            raise table.error(key, f"{text!r} is not an M code (M followed by its number)")
        number = int(match.group(1))
        if number in RESERVED_M:
            raise table.error(key, f"M{number} has a meaning of its own; a TCP switch needs "
                                   "a code of its own (e.g. a remapped M100-M199 or M428)")
        numbers.append(number)
    return tuple(dict.fromkeys(numbers))


def _position(table: ConfigTable, key: str, axis_names) -> tuple[float, ...] | None:
    value = table._get(key, None)   # the machine package's own checked reader
    if value is None:
        return None
    names = " ".join(axis_names)
    if (not isinstance(value, list) or len(value) != len(axis_names)
            or any(isinstance(v, bool) or not isinstance(v, (int, float))
                   or not math.isfinite(v) for v in value)):
        raise table.error(key, f"must be a list of {len(axis_names)} finite numbers, the "
                               f"machine axes {names} (mm, rad), got {value!r}")
    return tuple(float(v) for v in value)
