"""The canonical moves of LinuxCNC's own RS274/NGC interpreter, for the reader's tests.

Run by the Python that LinuxCNC's package installs its modules for (``/usr/bin/python3`` on
Debian), not the project's: ``python3 linuxcnc_reference.py PROGRAM [INI]``. It parses
PROGRAM with LinuxCNC's interpreter through its ``gcode`` module (the one AXIS draws its
preview with; the same interpreter library as the ``rs274`` program, whose printout rounds
to 4 decimals) and prints one JSON object: the canonical STRAIGHT_TRAVERSE, STRAIGHT_FEED and
ARC_FEED calls in full double precision with the source line executing, feed mode and
programmed F, and the interpreter's error if it stops on one.

Units: the module hands lengths in inches; they are given back in mm (x 25.4), angles in
degrees. Positions are absolute as LinuxCNC's motion planner gets them: the canonical
coordinates rotated by the XY rotation and shifted by the G92 and work offsets (what its
canonical layer, ``emccanon.cc``, does). INI (optional) is an INI file with ``[RS274NGC]``
REMAP lines (a site's M codes) and its SUBROUTINE_PATH.

Tool data: in LinuxCNC 2.9 the module reads tools from a running LinuxCNC's shared tool
table, so T, M6, M61 and H words end this process when none runs; they are blanked in a copy
of the program first (they do not move the axes; the project does not apply tool lengths).
"""

import json
import math
import os
import re
import sys
import tempfile

import gcode  # LinuxCNC's

MM = 25.4
_VALUE = r"\s*(?:\d+|#\s*\d+|#\s*<[^>]*>|\[[^\]]*\])"
_TOOL_WORDS = re.compile(r"(?<![A-Za-z_<#\[])([tT]" + _VALUE + r"|[mM]\s*0*6(?![\d.])|[mM]\s*0*61\s*"
                         r"[qQ]" + _VALUE + r"|[hH]" + _VALUE + ")")
_COMMENT = re.compile(r"\([^)]*\)|;.*")


def blank_tool_words(text):
    """The program with its tool words blanked (comments kept), line for line."""
    out = []
    for line in text.splitlines():
        parts, last = [], 0
        for match in _COMMENT.finditer(line):
            parts.append(_TOOL_WORDS.sub(lambda m: " " * len(m.group()),
                                         line[last:match.start()]))
            parts.append(match.group())
            last = match.end()
        parts.append(_TOOL_WORDS.sub(lambda m: " " * len(m.group()), line[last:]))
        out.append("".join(parts))
    return "\n".join(out) + "\n"


class Canon:
    """The callbacks LinuxCNC's interpreter makes; motion is recorded."""

    def __init__(self, parameter_file):
        self.parameter_file = parameter_file
        self.moves = []
        self.dwells = []
        self.line = 0
        self.rate = 0.0
        self.inch = False
        self.g5x = [0.0] * 9
        self.g92 = [0.0] * 9
        self.rotation = 0.0
        self.plane = 1

    def __getattr__(self, name):
        if name.startswith("__"):
            raise AttributeError(name)
        return lambda *args: None

    # what the interpreter asks
    def get_external_length_units(self):
        return 1.0          # a millimetre machine: its stored parameters are in mm

    def get_external_angular_units(self):
        return 1.0

    def get_axis_mask(self):
        return 0x3F         # X Y Z A B C

    def get_block_delete(self):
        return True

    def check_abort(self):
        return False

    def get_tool(self, tool):
        return (tool,) + (0.0,) * 12 + (0,)

    # what it tells
    def next_line(self, state):
        # the modes a line code carries are those after the previous block (LinuxCNC
        # writes them at the end of each block): the units serve only for a rotary-only
        # move's rate (degrees per minute, which the module does not scale)
        self.line = state.sequence_number
        self.inch = state.units == 200

    def dwell(self, seconds):
        self.dwells.append(dict(after=len(self.moves), seconds=seconds, line=self.line))

    def set_feed_rate(self, rate):
        # the canonical rate: F (G94) or LinuxCNC's length x F (G93), in inches per minute
        # (the module divides mm by 25.4)
        self.rate = rate

    def set_g5x_offset(self, index, x, y, z, a, b, c, u=0.0, v=0.0, w=0.0):
        self.g5x = [x * MM, y * MM, z * MM, a, b, c, u * MM, v * MM, w * MM]

    def set_g92_offset(self, x, y, z, a, b, c, u=0.0, v=0.0, w=0.0):
        self.g92 = [x * MM, y * MM, z * MM, a, b, c, u * MM, v * MM, w * MM]

    def set_xy_rotation(self, theta):
        self.rotation = theta

    def set_plane(self, plane):
        self.plane = plane

    def absolute(self, p):
        """Canonical coordinates (mm, deg) -> absolute: G92, rotation, work offset."""
        p = [v + o for v, o in zip(p, self.g92)]
        if self.rotation:
            t = math.radians(self.rotation)
            p[0], p[1] = (p[0] * math.cos(t) - p[1] * math.sin(t),
                          p[0] * math.sin(t) + p[1] * math.cos(t))
        return [v + o for v, o in zip(p, self.g5x)]

    def record(self, kind, end, **extra):
        self.moves.append(dict(kind=kind, line=self.line, end=end[:6], rate=self.rate,
                               inch=self.inch, **extra))

    def straight_traverse(self, x, y, z, a, b, c, u, v, w):
        self.record("traverse", self.absolute([x * MM, y * MM, z * MM, a, b, c, u, v, w]))

    def straight_feed(self, x, y, z, a, b, c, u, v, w):
        self.record("feed", self.absolute([x * MM, y * MM, z * MM, a, b, c, u, v, w]))

    def arc_feed(self, first_end, second_end, first_axis, second_axis, rotation,
                 axis_end_point, a, b, c, u, v, w):
        # canonical plane axes (emccanon.cc): XY -> (X, Y, Z), YZ -> (Y, Z, X), XZ -> (Z, X, Y)
        order = {1: (0, 1, 2), 2: (1, 2, 0), 3: (2, 0, 1)}[self.plane]
        end, centre = [0.0] * 9, [0.0] * 9
        end[order[0]], end[order[1]], end[order[2]] = (first_end * MM, second_end * MM,
                                                       axis_end_point * MM)
        end[3:6] = [a, b, c]
        centre[order[0]], centre[order[1]] = first_axis * MM, second_axis * MM
        shifted = self.absolute(centre)
        centre = [shifted[i] if i in order[:2] else math.nan for i in range(3)]
        self.record("arc", self.absolute(end), centre=centre, rotation=rotation,
                    plane={1: 17, 2: 19, 3: 18}[self.plane])


def main():
    path = sys.argv[1]
    ini = sys.argv[2] if len(sys.argv) > 2 else ""
    with open(path, encoding="utf-8", errors="replace") as f:
        text = blank_tool_words(f.read())
    with tempfile.TemporaryDirectory() as folder:
        if ini:
            # a fresh parameter file: the interpreter writes G10's offsets back at the end
            with open(ini) as f:
                settings = re.sub(r"(?m)^PARAMETER_FILE\s*=.*$",
                                  "PARAMETER_FILE = " + os.path.join(folder, "ini.var"),
                                  f.read())
            os.environ["INI_FILE_NAME"] = os.path.join(folder, "settings.ini")
            with open(os.environ["INI_FILE_NAME"], "w") as f:
                f.write(settings)
        copy = os.path.join(folder, os.path.basename(path))
        with open(copy, "w") as f:
            f.write(text)
        canon = Canon(os.path.join(folder, "linuxcnc.var"))
        result, last_line = gcode.parse(copy, canon, ["G21", "G90"], "")
    error = None if result <= gcode.MIN_ERROR else gcode.strerror(result)
    json.dump({"moves": canon.moves, "dwells": canon.dwells, "error": error,
               "error_line": last_line}, sys.stdout)


if __name__ == "__main__":
    main()
