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
``tcp_on``/``tcp_off`` default to LinuxCNC's M428/M429 (``[]``: none). They may also name G
codes (``tcp_on = ["M428", "G43.7"]``): a site's own G code that switches TCP on or off, which
acts as its M codes do. The reader knows G43.4/G43.5 and Haas's G234 (on) and G49 (off)
itself; naming them is allowed and changes nothing; a G code with another meaning to the
reader (:data:`RESERVED_G`) is refused.
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
_G_CODE = re.compile(r"G0*(\d{1,3})(?:\.(\d))?")
#: M codes with a meaning of their own (stops, spindle, tool, coolant, overrides, I/O, modal
#: state, subprograms): not available as a TCP switch.
RESERVED_M = frozenset([0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 19, 30, 48, 49, 50, 51, 52, 53, 60, 61,
                        62, 63, 64, 65, 66, 67, 68, 70, 71, 72, 73, 98, 99])
#: LinuxCNC's remapped TCP switches (configs/sim/axis/vismach/5axis/table-rotary-tilting).
DEFAULT_TCP_ON = (428,)
DEFAULT_TCP_OFF = (429,)
#: G codes (in tenths: G43.4 -> 434) the G-code reader itself reads as TCP on, and off.
BUILTIN_TCP_ON_G = frozenset([434, 435, 2340])
BUILTIN_TCP_OFF_G = frozenset([490])
#: G codes (tenths) with a meaning of their own to the G-code reader
#: (:mod:`precontour.toolpath.gcode`; a test keeps the two lists in step): not available as
#: a site's TCP switch.
RESERVED_G = frozenset([0, 10, 20, 30, 40, 100, 170, 180, 190, 200, 210, 280, 281, 300, 301,
                        400, 430, 431, 432, 530, 531, 540, 541, 550, 560, 570, 580, 590, 591, 592,
                        593, 610, 611, 640, 682, 690, 730, 800, 810, 820, 830, 850, 860, 870,
                        890, 900, 901, 910, 911, 920, 921, 922, 923, 930, 940, 970, 980, 990,
                        2540, 2550])


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
    tcp_on_g, tcp_off_g : tuple of int
        The site's own G codes (in tenths, G43.7 -> 437) that switch TCP mode on and off.
    """

    g28: tuple[float, ...] | None = None
    g30: tuple[float, ...] | None = None
    work_offsets: Mapping[str, tuple[float, ...]] = field(
        default_factory=lambda: MappingProxyType({}))
    tcp_on: tuple[int, ...] = DEFAULT_TCP_ON
    tcp_off: tuple[int, ...] = DEFAULT_TCP_OFF
    tcp_on_g: tuple[int, ...] = ()
    tcp_off_g: tuple[int, ...] = ()


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
    tcp_on, tcp_on_g = _switch_codes(table, "tcp_on", DEFAULT_TCP_ON, BUILTIN_TCP_ON_G)
    tcp_off, tcp_off_g = _switch_codes(table, "tcp_off", DEFAULT_TCP_OFF, BUILTIN_TCP_OFF_G)
    both = sorted(set(tcp_on) & set(tcp_off))
    if both:
        raise table.error("tcp_off", f"M{both[0]} is in tcp_on too")
    both_g = sorted(set(tcp_on_g) & set(tcp_off_g))
    if both_g:
        raise table.error("tcp_off", f"{_g_name(both_g[0])} is in tcp_on too")
    table.finish()
    return GcodeSettings(g28=g28, g30=g30, work_offsets=MappingProxyType(offsets),
                         tcp_on=tcp_on, tcp_off=tcp_off, tcp_on_g=tcp_on_g,
                         tcp_off_g=tcp_off_g)


def _switch_codes(table: ConfigTable, key: str, default: tuple[int, ...],
                  builtin_g: frozenset[int]) -> tuple[tuple[int, ...], tuple[int, ...]]:
    """(M code numbers, G codes in tenths) of ``tcp_on``/``tcp_off``; the G codes the reader
    reads as this switch itself (``builtin_g``) are accepted and left out."""
    value = table._get(key, None)
    if value is None:
        return default, ()
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        raise table.error(key, 'must be a list of M or G codes such as ["M428"] or ["G234"], '
                               f"got {value!r}")
    numbers, g_codes = [], []
    for text in value:
        code = text.strip().upper()
        match = _M_CODE.fullmatch(code)
        if match is not None:
            number = int(match.group(1))
            if number in RESERVED_M:
                raise table.error(key, f"M{number} has a meaning of its own; a TCP switch needs "
                                       "a code of its own (e.g. a remapped M100-M199 or M428)")
            numbers.append(number)
            continue
        match = _G_CODE.fullmatch(code)
        if match is None:
            raise table.error(key, f"{text!r} is not an M or G code (M or G followed by its "
                                   "number, G43.4)")
        tenths = int(match.group(1)) * 10 + int(match.group(2) or 0)
        if tenths in builtin_g:
            continue        # read as this switch already
        if tenths in RESERVED_G or tenths in BUILTIN_TCP_ON_G | BUILTIN_TCP_OFF_G:
            raise table.error(key, f"{_g_name(tenths)} has a meaning of its own to the reader; "
                                   "a TCP switch needs a code of its own")
        g_codes.append(tenths)
    return tuple(dict.fromkeys(numbers)), tuple(dict.fromkeys(g_codes))


def _g_name(tenths: int) -> str:
    return f"G{tenths // 10}" if tenths % 10 == 0 else f"G{tenths // 10}.{tenths % 10}"


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
