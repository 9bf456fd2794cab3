"""The G-code reader's tables: the G and M codes it reads, keeps or refuses, their modal
groups and words, its limits and patterns, and the small helpers its parts share
(:mod:`.gcode` and the ``_gcode_*`` modules that make up its :class:`~.gcode._Reader`)."""

from __future__ import annotations

import math
import re

import numpy as np


#: Largest distance (mm) between an arc and its chords.
ARC_CHORD_TOLERANCE = 1e-3
#: Start/end radius mismatch of an arc tolerated in mm ...
ARC_RADIUS_TOLERANCE = 5e-3
#: ... or as a fraction of the radius, whichever is larger (LinuxCNC's rule).
ARC_RADIUS_RTOL = 1e-3
#: Largest |coordinate| of a linear axis or tool tip, mm (1 km: no machine's travel), and of a
#: rotary axis, degrees (about 2,800 turns): beyond it a number is a typo or garbage, refused
#: by line before it overflows the kinematics or the trajectory's sample count.
MAX_COORDINATE = 1e6
#: Largest number of chords one arc may be cut into (memory guard against absurd arcs).
MAX_ARC_CHORDS = 1_000_000

#: Machine-axis words of the default machine, in the order of q.
AXIS_WORDS = ("X", "Y", "Z", "A", "C")

# G codes in tenths (G43.4 -> 434).
_MOTION = {0: 0, 10: 1, 20: 2, 30: 3, 730: 73, 810: 81, 820: 82, 830: 83, 850: 85, 860: 86,
           870: 87, 890: 89}
#: The canned cycles read (their motion mode numbers) and the words each reads.
_CYCLES = frozenset([73, 81, 82, 83, 85, 86, 87, 89])
_CYCLE_WORDS = {73: "RLQ", 81: "RL", 82: "RLP", 83: "RLQ", 85: "RL", 86: "RLP",
                87: "RLIJK", 89: "RLP"}
_PLANES = {170: (0, 1, 2), 180: (2, 0, 1), 190: (1, 2, 0)}
#: G codes accepted and kept for an output program (they do not change the axis commands).
PASSTHROUGH_G = frozenset([170, 180, 190, 400, 430, 431, 432, 490, 610, 611, 640, 800, 970])
#: Tool length codes whose axis words are the offset (LinuxCNC's G43.1, G43.2), not a move.
_TOOL_LENGTH_WORDS = frozenset([431, 432])
#: Work offsets G54-G59.3 and G54.1 (Pn), in tenths.
_WORK_OFFSET_G = (540, 550, 560, 570, 580, 590, 591, 592, 593, 541)
#: Non-modal codes (RS274/NGC group 0): at most one per block.
_NON_MODAL = (40, 100, 280, 281, 300, 301, 530, 920, 921, 922, 923)
#: Non-modal codes that read the block's axis words themselves.
_AXIS_WORD_CODES = frozenset([100, 280, 300, 920])
#: Fanuc's tilted working plane: G68.2 (define), G53.1 (tool along its Z), G69 (cancel).
_TILT_G = frozenset([682, 531, 690])
#: Haas's tool centre point control G234 (on until G49, like G43.4; G43 ends it too) and its
#: dynamic work offset G254 / G255 (on / off), in tenths.
_HAAS_TCP_G = 2340
_DWO_ON_G, _DWO_OFF_G = 2540, 2550
_MODE_G = frozenset([200, 210, 434, 435, 900, 901, 910, 911, 930, 940, 980, 990, _HAAS_TCP_G,
                     _DWO_ON_G, _DWO_OFF_G])
_MODAL_GROUPS = (frozenset(_MOTION), frozenset(_PLANES), frozenset([200, 210]),
                 frozenset([980, 990]),
                 frozenset([900, 910]), frozenset([901, 911]), frozenset([930, 940]),
                 frozenset([430, 431, 434, 435, 490, _HAAS_TCP_G]), frozenset(_WORK_OFFSET_G),
                 frozenset(_NON_MODAL), frozenset([610, 611, 640]), frozenset([682, 690]),
                 frozenset([_DWO_ON_G, _DWO_OFF_G]))
#: Codes that apply a tool length (H, else the current tool): G43, G43.4, G43.5, G234.
_LENGTH_G = frozenset([430, 434, 435, _HAAS_TCP_G])
_KNOWN_G = (frozenset(_MOTION) | PASSTHROUGH_G | _MODE_G | frozenset(_WORK_OFFSET_G)
            | frozenset(_NON_MODAL) | _TILT_G)
_UNSUPPORTED_G = {
    950: "feed per revolution (G95) is not supported; use G94 or G93",
    410: "cutter radius compensation (G41) is not supported; post-process with the tool "
         "radius applied",
    420: "cutter radius compensation (G42) is not supported; post-process with the tool "
         "radius applied",
    650: "macro calls (G65) are not supported",
    740: "tapping cycles (G74) follow the spindle (synchronized motion): not supported",
    840: "tapping cycles (G84) follow the spindle (synchronized motion): not supported",
    841: "rigid tapping (G84.1) follows the spindle (synchronized motion): not supported",
    880: "G88 (boring with a manual retract: the operator moves the axes) is not supported",
    760: "threading cycles (G76) follow the spindle (synchronized motion): not supported",
    330: "spindle-synchronized motion (G33) is not supported",
    331: "rigid tapping (G33.1) follows the spindle (synchronized motion): not supported",
    680: "coordinate rotation (G68) is not supported",
}
_STOP_M = {0: "program stop", 1: "optional stop", 6: "tool change", 2: "end", 30: "end"}
#: M codes read (stops, spindle, coolant, overrides, tool number, I/O).
_KNOWN_M = frozenset([0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 30, 48, 49, 50, 51, 52, 53, 61, 62, 63,
                      64, 65, 66, 67, 68, 70, 71, 72, 73, 98, 99])
#: Words that M codes read (LinuxCNC): M61 Q (tool number), M62-M65 P (digital output),
#: M66 P/E L Q (wait for an input), M67/M68 E Q (analog output), M50-M53 P (overrides).
_M_WORDS = {61: "Q", 62: "P", 63: "P", 64: "P", 65: "P", 66: "PELQ", 67: "EQ", 68: "EQ",
            50: "P", 51: "P", 52: "P", 53: "P", 98: "PL"}
#: M codes that steer the reading (subprograms, modal state), not kept for an output program.
_FLOW_M = frozenset([70, 71, 72, 73, 98, 99])
_FANUC_MACRO = re.compile(r"(?:N\d+)?(IF\[|GOTO\d|WHILE\[|END\d|DO\d)")
# kinds of line (see _Reader.prepare)
_PLAIN, _SKIP, _COMMENT, _SETTINGS, _GENERAL, _SINUMERIK = range(6)
#: File name extensions of Sinumerik programs (main programs, subprograms).
SINUMERIK_SUFFIXES = (".mpf", ".spf")
# lines that may be O-word statements (a cheap test before a line's code is worked out)
_MAYBE_OWORD = re.compile(r"\s*/?\s*[oO]")
_PASSTHROUGH_WORDS = frozenset("STHD")
_ZERO = (0.0,) * 5
_NO_CENTRE = (math.nan,) * 3

_WORD = re.compile(r"([A-Z])([-+]?(?:\d+\.?\d*|\.\d+))")
_COMMENT = re.compile(r"\(([^()]*)\)")
_TRAORI = re.compile(r"TRAORI(?:\([^)]*\))?")
_BLANK_CHARS = " \t\r\f\v"
_BLANKS = str.maketrans("", "", _BLANK_CHARS)
#: A name as written: a letter followed by letters, digits or _ (a keyword, a label).
_NAME = re.compile(r"[A-Za-z_$][\w$]*")


class _Table:
    """Columns collected in order, row by row (tuples) or in chunks of arrays."""

    __slots__ = ("rows", "chunks")

    def __init__(self):
        self.rows, self.chunks = [], []

    def append(self, row: tuple):
        self.rows.append(row)

    def extend(self, columns: tuple):
        self.seal()
        self.chunks.append(columns)

    def seal(self):
        if self.rows:
            self.chunks.append(tuple(zip(*self.rows)))
            self.rows = []

    def columns(self, dtypes):
        self.seal()
        return [np.concatenate([np.asarray(chunk[i], dtype=dtype) for chunk in self.chunks])
                if self.chunks else np.zeros(0, dtype) for i, dtype in enumerate(dtypes)]


class _Frame:
    """One level of calls: the main program, an O-word subroutine or an M98 subprogram."""

    __slots__ = ("kind", "name", "return_pc", "saved", "locals", "start", "left", "repeats",
                 "iterations", "auto_restore")

    def __init__(self, kind, name, return_pc, *, saved=None, locals=None, start=0, left=0):
        self.kind, self.name, self.return_pc = kind, name, return_pc
        self.saved = saved                      # the caller's #1-#30
        self.locals = {} if locals is None else locals
        self.start, self.left = start, left     # M98: the label line, calls still to run
        self.repeats, self.iterations = {}, {}  # per loop (first line): counts
        self.auto_restore = None                # M73: the state to restore on return


def _tilt_travel(kinematics) -> tuple[float, float]:
    """The tilt axis's travel (rad): the machine's limits if it has them, within +-180 deg."""
    low, high = getattr(kinematics, "tilt_limits", (None, None))
    return (-math.pi if low is None else max(low, -math.pi),
            math.pi if high is None else min(high, math.pi))


def _euler_zxz(i: float, j: float, k: float) -> np.ndarray:
    """Rotation Rz(i) Rx(j) Rz(k) (degrees): the columns are the tilted frame's axes."""
    def rz(t):
        c, s = math.cos(math.radians(t)), math.sin(math.radians(t))
        return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])

    c, s = math.cos(math.radians(j)), math.sin(math.radians(j))
    rx = np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
    return rz(i) @ rx @ rz(k)


def _degrees(position) -> tuple[float, ...]:
    """A machine-file position (mm, rad) in the reader's units (mm, deg)."""
    return (*map(float, position[:3]), *map(math.degrees, position[3:]))


def _ffill(values: np.ndarray, initial: float) -> np.ndarray:
    """Carry each value forward over the NaNs after it (modal state); ``initial`` before the
    first value."""
    index = np.where(np.isnan(values), -1, np.arange(values.size))
    index = np.maximum.accumulate(index)
    return np.where(index >= 0, values[np.maximum(index, 0)], initial)


def _unknown_name(name: str) -> str:
    """What a refusal says of a name that is no word (a letter and a number) and no construct
    of another language the reader knows of."""
    if name[0] in "oO":
        return ("O takes a program number (O1000) or a subroutine name in < > (o<name> sub); "
                f"post-process with the program's name in a comment, ({name[1:].strip()}), "
                "or without it")
    return "no G-code word (a letter and a number); post-process without it"


def _word_at(code: str, pos: int) -> str:
    """The text from ``pos`` up to the next letter (the bad word as written)."""
    match = re.match(r".[^A-Z]*", code[pos:])
    return match.group() if match else code[pos:]


def _g_name(code: int) -> str:
    return f"G{code // 10}" if code % 10 == 0 else f"G{code // 10}.{code % 10}"
