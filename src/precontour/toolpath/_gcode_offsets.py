"""Coordinate systems and tools in the G-code reader (the reader's :class:`~.gcode._Reader`
mixes this in): work offsets (G54-G59.3, G54.1 Pn, G10 L2/L20), G92 offsets, G28/G30
reference returns and G28.1/G30.1, G53 machine-coordinate moves, tool lengths from the tool
table (T, M6, M61, G43 H), and Haas's G234 and G254/G255 dynamic work offset."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from ..errors import InputError
from ..machine.gcode import MAX_EXTENDED_OFFSET, WORK_OFFSETS
from ._gcode_codes import MAX_COORDINATE, _DWO_OFF_G, _DWO_ON_G, _HAAS_TCP_G, _ZERO, _g_name


class OffsetBlocks:
    """The reader's work offsets, reference positions, machine moves and tools."""

    # ------------------------------------------------------------------ Haas modes, tools
    def haas_modes(self, codes, g_word, values, spelled):
        """Haas's G234 (tool centre point control: as G43.4, on until G49, G43 or the program
        end) and G254 / G255 (dynamic work offset on / off, see :meth:`dwo_origin`); the two
        exclude each other (Haas mill operator's manual, G234 and G254 notes)."""
        if _HAAS_TCP_G in codes:
            if self.dwo_base is not None:
                self.fail("G234 (tool centre point control) with G254 (dynamic work offset) "
                          "on: Haas runs them one at a time; cancel G254 with G255 first",
                          g_word[_HAAS_TCP_G])
            self.tcp_sources.add("G234")
        elif 430 in codes:
            self.tcp_sources.discard("G234")   # G43 ends G234 (one tool length group)
        if _DWO_ON_G in codes:
            on = next((name for name in ("G234", "G43.4", "TRAORI", "M", "option", "G68.2")
                       if name in self.tcp_sources), None)
            if on is not None:
                self.fail("G254 (dynamic work offset) in tool centre point mode "
                          f"({'the TCP switch' if on in ('M', 'option') else on}): Haas runs "
                          "them one at a time; end TCP first", g_word[_DWO_ON_G])
            if self.dwo_base is None:
                self.dwo_base = list(self.g5x)
        if _DWO_OFF_G in codes and self.dwo_base is not None:
            self.g5x, self.dwo_base = self.dwo_base, None

    def dwo_origin(self, spelled):
        """Under G254, before a block's moves: the work offset's linear part turned with the
        rotary axes where they stand. Haas's DWO keeps the program's X Y Z along the machine
        axes (the tool stays along Z: 3+2 positioning) and moves their origin, the work
        offset, with the table about its centres of rotation: the work offset is a machine
        position at B = C = 0, its tool tip is carried by the table to B, C, and the origin
        is the machine position that puts the tip there (the kinematics' inverse). Rotary
        words move the rotary axes only (the linear axes hold, as in the Haas manual's DWO
        example); with linear words in the same block it would be simultaneous motion, which
        DWO does not do."""
        rotary = [spelled[a] for a in self.axes[3:] if a in spelled]
        linear = [spelled[a] for a in self.axes[:3] if a in spelled]
        if rotary and linear:
            self.fail(f"{rotary[0]} and {linear[0]} in one block under G254 (dynamic work "
                      "offset, for 3+2 positioning): move the rotary axes in a block of their "
                      "own, or use G234 (tool centre point control) for simultaneous motion",
                      rotary[0])
        rot = self.prog[3:]
        if not all(math.isfinite(v) for v in rot):
            self.fail("G254 (dynamic work offset) before the rotary axes' positions are "
                      "known: position them first", rotary[0] if rotary else None)
        base = np.array([*self.dwo_base[:3], 0.0, 0.0])
        tip, _ = self.base_kinematics.forward(base)
        origin = self.base_kinematics.linear_axes(np.asarray(tip).reshape(1, 3),
                                                  np.radians([rot]))[0]
        self.g5x = [*map(float, origin), *self.dwo_base[3:]]

    def tool_change(self, values, spelled, m_numbers):
        """T (the next tool), M6 (it goes in the spindle), M61 Q (the tool in the spindle)."""
        if "T" in values:
            number = values["T"]
            if number != int(number) or number < 0:
                self.fail(f"tool number {spelled['T']!r} must be a whole number >= 0",
                          spelled["T"])
            self.next_tool = int(number)
        if 6 in m_numbers and self.next_tool is not None:
            self.tool = self.next_tool
        if 61 in m_numbers and "Q" in values and values["Q"] == int(values["Q"]):
            self.tool = int(values["Q"])

    def select_length(self, values, spelled, word):
        """G43 / G43.4 / G43.5 / G234: the length of tool H, without H of the tool in the
        spindle (LinuxCNC, Haas); a tool the table lacks (or H0, no tool) takes the machine
        file's tool_offset, said once per tool when there is a table."""
        if "H" in values:
            number = values["H"]
            if number != int(number) or number < 0:
                self.fail(f"tool length offset {spelled['H']!r} must be a whole number >= 0",
                          spelled["H"])
            number = int(number)
        else:
            number = self.tool
        length = math.nan
        if number:
            length = self.tool_lengths.get(number, math.nan)
            if math.isnan(length) and self.tool_lengths and number not in self.said_tools:
                self.said_tools.add(number)
                called = spelled.get("H", word)
                default = getattr(self.base_kinematics, "tool_offset", 0.0)
                self.notices.append(f"{self.source}, line {self.row}: tool {number} ({called}) "
                                    "is not in the tool table; its length is the machine "
                                    f"file's tool_offset ({default:g} mm)")
        self.set_length(length)

    def set_length(self, length: float):
        """Use the tool length ``length`` (mm; NaN: the machine file's tool_offset) from now
        on; in TCP mode the machine axes stay where they are and the tip follows."""
        same = (math.isnan(length) and math.isnan(self.length)) or length == self.length
        if same:
            return
        carry = self.tcp and all(math.isfinite(v) for v in self.prog)
        if carry:
            machine = self.convert(self.prog, True, False)
        self.length = length
        self.kinematics = self.kinematics_of(length)
        if carry:
            self.prog = self.convert(machine, False, True)

    def kinematics_of(self, length: float):
        """The machine's kinematics with tool length ``length`` (NaN: as in the file)."""
        if math.isnan(length):
            return self.base_kinematics
        kinematics = self.length_kinematics.get(length)
        if kinematics is None:
            if not hasattr(self.base_kinematics, "tool_offset"):
                raise InputError("a tool table needs kinematics with a tool_offset; "
                                 f"{type(self.base_kinematics).__name__} has none",
                                 source=self.source, field="tool_table")
            kinematics = replace(self.base_kinematics, tool_offset=float(length))
            self.length_kinematics[length] = kinematics
        return kinematics

    def select_work_offset(self, code, values, spelled):
        """G54-G59.3, G54.1 Pn: the machine file's offset, or zero (said once)."""
        if code == 541:
            number = values["P"]
            if number != int(number) or not 1 <= number <= MAX_EXTENDED_OFFSET:
                self.fail(f"G54.1 {spelled['P']}: the extended work offsets are P1 ... "
                          f"P{MAX_EXTENDED_OFFSET}", spelled["P"])
            name = f"G54.1 P{int(number)}"
        else:
            name = _g_name(code)
        self.work_offset = name
        self.g5x = list(self.offsets.get(name, _ZERO))
        if self.dwo_base is not None:
            self.dwo_base = list(self.g5x)   # G254 turns the new offset (dwo_origin)
        if name not in self.offsets and not self.said_offsets:
            self.said_offsets = True
            self.notices.append(f"{self.source}, line {self.row}: the machine file gives no "
                                f"work offset {name} ([gcode.work_offsets]); work offsets it "
                                "does not give are taken as zero (identity)")

    def set_work_offset(self, values, spelled, scale, word):
        """G10 L2 Pn (the offset itself) and G10 L20 Pn (so that the current position has the
        given coordinates), n = 0 (the active one), 1-9 (G54 ... G59.3)."""
        kind = values.get("L")
        if kind not in (2.0, 20.0):
            what = spelled.get("L", "without L")
            self.fail(f"G10 {what} is not supported (only G10 L2 and G10 L20 set work "
                      "offsets; tool tables are not read)", spelled.get("L", word))
        number = values.get("P")
        if number is None or number != int(number) or not 0 <= number <= 9:
            self.fail("G10 L2/L20 needs P0 (the active work offset) ... P9 (G59.3)",
                      spelled.get("P", word))
        if "R" in spelled:
            self.fail("G10 R (a rotated coordinate system) is not supported", spelled["R"])
        name = self.work_offset if number == 0 else WORK_OFFSETS[int(number) - 1]
        offset = list(self.offsets.get(name, _ZERO))
        for i, letter in enumerate(self.axes):
            if letter in values:
                value = values[letter] * (scale if i < 3 else 1.0)
                if kind == 20.0:
                    if not math.isfinite(self.prog[i]):
                        self.fail(f"G10 L20 sets axis {letter} relative to its position, "
                                  "which is not known yet", spelled[letter])
                    value = self.prog[i] - self.g92[i] - value
                offset[i] = value
        self.offsets[name] = tuple(offset)
        if name == self.work_offset:
            self.g5x = offset

    def axis_offsets(self, code, values, spelled, scale, word):
        """G92 (the current position gets the given coordinates), G92.1 and G92.2 (offsets
        off; G92.1 also forgets them), G92.3 (the stored offsets again)."""
        if code == 920:
            given = [a for a in self.axes if a in values]
            if not given:
                self.fail("G92 needs at least one axis word", word)
            for i, letter in enumerate(self.axes):
                if letter in values:
                    if not math.isfinite(self.prog[i]):
                        self.fail(f"G92 sets axis {letter} relative to its position, which is "
                                  "not known yet", spelled[letter])
                    value = values[letter] * (scale if i < 3 else 1.0)
                    self.g92[i] = self.prog[i] - self.g5x[i] - value
            self.g92_stored = list(self.g92)
        elif code == 921:
            self.g92 = list(_ZERO)
            self.g92_stored = list(_ZERO)
        elif code == 922:
            self.g92 = list(_ZERO)
        else:
            self.g92 = list(self.g92_stored)

    def store_reference(self, code, word):
        """G28.1 / G30.1: the current machine position becomes the reference position."""
        q = self.machine_position()
        if not all(math.isfinite(v) for v in q):
            self.fail(f"{word} stores the current position, which is not known yet", word)
        self.reference[code - 1] = tuple(q)

    def reference_return(self, code, values, spelled, scale, word):
        """G28 / G30: a rapid to the given point (if any axis word), then the given axes (all
        without axis words) to the reference position, in machine coordinates."""
        name = _g_name(code)
        reference = self.reference.get(code)
        if reference is None:
            reference = _ZERO
            if not self.said_reference:
                self.said_reference = True
                self.notices.append(
                    f"{self.source}, line {self.row}: the machine file gives no reference "
                    f"position for {name} ([gcode] {name.lower()}); the machine origin (all "
                    "axes 0) is taken, as in LinuxCNC's default parameters")
        given = [i for i, a in enumerate(self.axes) if a in values]
        if given:
            target = self.target(values, spelled, scale)
            self.go(target, True, spelled)
        machine = [math.nan] * 5
        for i in (given or range(5)):
            machine[i] = reference[i]
        self.go_machine(machine, True, spelled)

    def machine_position(self) -> list[float]:
        """The machine axes now (mm, deg), NaN where not known."""
        if not self.tcp:
            return list(self.to_workpiece(self.prog)) if self.framed else list(self.prog)
        if all(math.isfinite(v) for v in self.prog):
            return self.convert(list(self.to_workpiece(self.prog)), True, False)
        return [math.nan] * 3 + self.prog[3:]

    def machine_move(self, rapid, values, spelled, scale):
        """G53: the axis words are machine coordinates (in TCP mode: the machine axes, a move
        in joint space)."""
        machine = [math.nan] * 5
        for i, letter in enumerate(self.axes):
            if letter in values:
                value = values[letter] * (scale if i < 3 else 1.0)
                if not abs(value) <= MAX_COORDINATE:
                    self.fail(f"coordinate {spelled[letter]!r} is out of range", spelled[letter])
                machine[i] = value
        self.go_machine(machine, rapid, spelled)

    def go_machine(self, machine, rapid, spelled):
        """A move to machine axes (mm, deg; NaN: the axis stays), programmed in either mode;
        in TCP mode it runs in joint space and the tip follows from the kinematics."""
        if not self.tcp:
            if self.framed:
                # SUPA under a frame: the frame's coordinates of the machine position
                current = self.machine_position()
                target = [m if math.isfinite(m) else c for m, c in zip(machine, current)]
                self.go(self.from_workpiece(target), rapid, spelled)
                return
            self.go([m if math.isfinite(m) else p for m, p in zip(machine, self.prog)],
                    rapid, spelled)
            return
        current = self.machine_position()
        target = [m if math.isfinite(m) else c for m, c in zip(machine, current)]
        if not all(math.isfinite(v) for v in target):
            # before the start: the tip is not known until the other axes are, as at a TCP
            # switch with unknown axes
            self.deferred.append((list(self.prog), True))
            self.deferred.append((list(target), False))
            self.prog = [math.nan] * 3 + target[3:]
            if rapid:
                return
            self.resolve()
            self.begin(self.row)
            current = self.machine_position()
            target = [m if math.isfinite(m) else c for m, c in zip(machine, current)]
        elif self.start is None:
            if rapid or not all(math.isfinite(v) for v in current):
                self.prog = self.from_workpiece(self.convert(target, False, True))
                self.deferred = []
                self.begin(self.row)
                return
            self.begin(self.row)
        duration, feed = math.nan, math.nan
        if not rapid:
            duration, feed = self.timing(current, target, 1, spelled)
        self.add(target, rapid, duration, feed, tcp=False)
        self.prog = self.from_workpiece(self.convert(target, False, True))
