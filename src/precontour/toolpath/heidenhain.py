"""Reader for Heidenhain TNC conversational (Klartext, ``.h``) programs, into the same
:class:`~precontour.toolpath.program.Program` the G-code reader gives.

How: each Heidenhain block is translated into the words of one RS274/NGC block and executed
by the G-code reader's interpreter (:class:`~precontour.toolpath.gcode._Reader`), on the
block's own line. The kinematics, the tool centre point (TCP) conversion, the arcs and their
chords, the feeds and block times, the stops, the tilted working plane (G68.2 / G53.1 / G69)
and every check after the words are the G-code reader's, not a copy: a Heidenhain program and
its G-code equivalent give the same moves. What is Heidenhain's own is worked out here before
the words are made: the block syntax, incremental words per axis (``IX``), the circle centre
``CC`` and the tangential arc ``CT``, ``Q`` parameters, the datum shift, the spatial angles of
``PLANE SPATIAL``, the vector ``TX TY TZ`` of ``LN``, ``M126``. The words are always absolute
(G90) coordinates, so that the reader's modal state only ever holds one distance mode. The
error words the reader names are the Heidenhain words as written (``X+Q1``, ``M128``,
``FUNCTION TCPM``).

Read, as the TNC 640 user's manual (Klartext programming) describes it:

- ``BEGIN PGM name MM|INCH`` (INCH: coordinates in inches, feeds in 1/10 inch/min) and
  ``END PGM`` (the end of the program); block numbers, ``;`` comments, ``* text`` section
  headings, a trailing ``*`` block end, ``/`` block delete (skipped), ``~`` continued lines;
- ``BLK FORM`` (the blank, ignored);
- ``TOOL CALL n Z S.. F.. DL.. DR..`` (or a tool name in quotes): a tool change (stop
  "tool change") with the spindle speed kept as a pass-through word; ``F`` is the feed of
  ``FAUTO``; ``DL`` is refused unless 0. The tool length comes from the machine file's
  kinematics (:meth:`_Heidenhain.tool_call` is where a tool table is to be applied);
- ``L`` with ``X Y Z`` and the machine's rotary axis letters, absolute or incremental
  (``IX``), numbers or ``Q`` parameters (``X+Q1``, ``X-Q1``), ``R0``, ``F`` (mm/min, modal),
  ``FMAX`` / ``F MAX`` (this block a rapid), ``FAUTO`` (the ``TOOL CALL`` feed), M functions;
  ``M91`` (coordinates of this block in the machine system: G53); ``M126`` / ``M127`` (the
  turn axis takes the shorter way: an absolute angle is taken modulo 360 degrees nearest
  where the axis is);
- arcs in the working plane XY (tool axis Z): ``CC X Y`` (the centre, absolute or ``IX IY``
  from the last position; ``CC`` alone: the last position), ``C X Y DR+|DR-`` (about CC,
  DR+ counter-clockwise: G3, DR- G2), ``CR X Y R+|R- DR+|DR-`` (R+ the arc of at most 180
  degrees, R- the longer one: G-code's R), ``CT X Y`` (the arc tangent to the end of the
  previous contour block);
- ``M128`` / ``M129`` and ``FUNCTION TCPM F TCP AXIS POS PATHCTRL AXIS`` [``REFPNT TIP-TIP``]
  / ``FUNCTION RESET TCPM``: tool centre point mode (as G43.4 / G49: X Y Z the tool tip, the
  rotary axes as programmed and interpolated linearly);
- ``LN X Y Z [NX NY NZ] TX TY TZ`` in TCP mode: the tool tip and the tool vector; the rotary
  axes are solved through the machine's kinematics (``inverse``), C on the branch nearest
  where it is. The surface normal ``NX NY NZ`` only serves 3D tool compensation, which a
  program with ``R0`` and no delta does not use: it is read and not applied;
- ``CYCL DEF 7.0 DATUM SHIFT`` with ``7.1 X..`` ``7.2 Y..`` ``7.3 Z..`` (absolute from the
  preset, which is the machine file's G54 work offset, or incremental ``IX`` from the last
  shift; an axis not given keeps its shift);
- ``CYCL DEF 32.0 TOLERANCE`` / ``32.1 T..``: the path tolerance (G64 P; ``32.1`` without T
  ends it); ``32.2`` (HSC mode) is ignored;
- ``PLANE SPATIAL SPA SPB SPC`` (rotations about the fixed X, then Y, then Z axis, about the
  current datum) with ``TURN`` (the rotary axes turn the tool onto the plane's Z, linear axes
  standing, as G53.1), or ``STAY`` (they stay; a later ``L A+Q120 C+Q122`` -- the angles the
  PLANE function stores in Q120-Q122 -- turns them, as G53.1); ``SEQ+`` / ``SEQ-`` is checked
  against the solution G53.1 chose; ``TABLE ROT`` / ``COORD ROT`` and ``FMAX`` / ``F`` of the
  positioning are accepted (the rotary axes are solved for the tool direction only, as
  G53.1 does); ``PLANE RESET STAY`` / ``TURN`` (TURN: the rotary axes back to 0);
- ``Q`` parameters: ``Qn = expression`` and ``FN 0:`` ... ``FN 4:`` (assign, add, subtract,
  multiply, divide), expressions of numbers and ``Q`` parameters with ``+ - * /`` and
  parentheses;
- M functions kept as pass-through words (spindle, coolant; M30 / M2 end the program).

Everything else -- labels and calls (``LBL``, ``CALL LBL``, ``CALL PGM``), machining cycles
(``CYCL DEF 200`` ...), ``FN 9`` jumps and other FN functions, polar coordinates (``LP``,
``CP``), ``RND`` / ``CHF``, radius compensation ``RL`` / ``RR``, other PLANE functions and
``MOVE``, arcs outside the XY plane, ``M140``, ``M92`` -- is a
:class:`~precontour.errors.ProgramError` naming the file, the line, the whole construct and
what to do.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from ..errors import InputError, ProgramError
from ..machine.gcode import GcodeSettings
from ._common import INCH, read_text
from ._heidenhain_contour import ContourBlocks, _format
from .gcode import (ARC_CHORD_TOLERANCE, _axis_letters, _kinematics, _Reader,
                    program_report)
from .program import Program, Stop

__all__ = ["read_heidenhain", "read_heidenhain_report", "read_heidenhain_program",
           "spatial_rotation", "euler_zxz_angles"]

#: What to do with a construct this reader does not read.
ADVICE = "post-process without it (straight and circular contour blocks, L C CC CR CT LN)"
#: Q parameters the PLANE function sets to the rotary axis angles (A, B, C).
PLANE_ANGLES = {120: "A", 121: "B", 122: "C"}
#: Tolerance (degrees) of a sign check of the tilt axis against SEQ.
_SEQ_SLACK = 1e-9

_NUMBER = r"(?:\d+(?:[.,]\d*)?|[.,]\d+)"
# one word: a name (FQ3 is F and Q3), then a signed number, a signed Q parameter, or a lone sign (DR+)
_WORD = re.compile(r"((?:[A-PR-Z]|Q(?!\d))+)\s*([+-]?\s*(?:Q\d+|" + _NUMBER + r")|[+-](?![\d.,Q]))?")
_BLOCK_NUMBER = re.compile(r"\d+(?:\s+|$)")
_ASSIGN = re.compile(r"(?:FN\s*(\d+)\s*:\s*)?Q(\d+)\s*=\s*(.+)$", re.IGNORECASE)
_TOOL_CALL = re.compile(r"TOOL\s+CALL\s*(\d+|\"[^\"]*\"|'[^']*')?\s*(.*)$", re.IGNORECASE)
_CYCL7 = re.compile(r"CYCL\s+DEF\s+7\.(\d)\s*(.*)$", re.IGNORECASE)
_CYCL32 = re.compile(r"CYCL\s+DEF\s+32\.(\d)\s*(.*)$", re.IGNORECASE)
_CONTOUR = re.compile(r"(LN|L|CC|CR|CT|C)(?![A-Z])\s*(.*)$")

#: Constructs refused, as (pattern, what it is); the construct named is the match.
_REFUSED = (
    (re.compile(r"CYCL\s+DEF\s+\d+(?:\.\d+)?(?: [A-Z][A-Z-]*(?![\w]))*"),
     "a machining cycle"),
    (re.compile(r"CYCL\s+CALL(?:\s+\w+)?", re.I), "a cycle call"),
    (re.compile(r"CALL\s+(?:LBL|PGM)\s*\S*", re.I), "a call of a label or program"),
    (re.compile(r"LBL\s*\S+", re.I), "a label"),
    (re.compile(r"FN\s*\d+\s*:\s*\w*", re.I), "a Q-parameter function"),
    (re.compile(r"PLANE\s+\w+", re.I), "a PLANE function"),
    (re.compile(r"FUNCTION\s+[\w ]+", re.I), "a FUNCTION block"),
    (re.compile(r"TCH\s+PROBE\s+\d+", re.I), "a touch probe cycle"),
    (re.compile(r"TOOL\s+DEF\s*\S*", re.I), "a tool pre-selection"),
    (re.compile(r"(?:LP|CP|RND|CHF|APPR\s+\w+|DEP\s+\w+)(?![A-Z])", re.I),
     "a contour element"),
)


def read_heidenhain_program(path: str | Path, machine, *, block_delete: bool = True,
                            arc_tolerance: float = ARC_CHORD_TOLERANCE) -> Program:
    """Read a Heidenhain conversational program into machine-axis moves (see the module
    docstring).

    Parameters
    ----------
    path : str or Path
        The program (``.h``).
    machine : Machine or str
        The machine (or a built-in name / machine file): its kinematics converts TCP tool
        tips and tool vectors to machine axes; its axis letters are the program's.
    block_delete : bool
        Skip blocks starting with ``/``.
    arc_tolerance : float
        Largest distance between an arc and its chords, mm.

    Returns
    -------
    Program

    Raises
    ------
    ProgramError
        One line naming the file, line and construct, for the first problem in the program.
    """
    kinematics = _kinematics(machine)
    if not (np.isfinite(arc_tolerance) and arc_tolerance > 0):
        raise InputError(f"arc tolerance must be positive, got {arc_tolerance!r}",
                         field="arc_tolerance")
    source = str(path)
    text = read_text(path)
    settings = getattr(machine, "gcode", None) or GcodeSettings()
    reader = _Reader(source, kinematics, _axis_letters(machine), False, block_delete,
                     arc_tolerance, settings)
    return _Heidenhain(reader, block_delete).run(text)


def read_heidenhain_report(path: str | Path, machine, *, block_delete: bool = True):
    """:func:`read_heidenhain_program` seen as a tool path (a
    :class:`~precontour.toolpath.ReadReport`, as :func:`~precontour.toolpath.read_gcode_report`
    gives for G-code)."""
    if isinstance(machine, (str, Path)):
        from ..machine.machine_file import load_machine
        machine = load_machine(machine)
    program = read_heidenhain_program(path, machine, block_delete=block_delete)
    return program_report(program, _kinematics(machine), format="heidenhain")


def read_heidenhain(path: str | Path, machine, *, block_delete: bool = True):
    """The program's points as a :class:`~precontour.toolpath.ToolPath`."""
    return read_heidenhain_report(path, machine, block_delete=block_delete).toolpath


def spatial_rotation(spa: float, spb: float, spc: float) -> np.ndarray:
    """Rotation of ``PLANE SPATIAL SPA SPB SPC`` (degrees): about the fixed X axis by SPA,
    then the fixed Y axis by SPB, then the fixed Z axis by SPC, ``Rz(SPC) Ry(SPB) Rx(SPA)``;
    its columns are the tilted plane's X, Y and Z (tool axis) in the workpiece frame."""
    a, b, c = np.radians([spa, spb, spc])
    rx = np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])
    ry = np.array([[math.cos(b), 0, math.sin(b)], [0, 1, 0], [-math.sin(b), 0, math.cos(b)]])
    rz = np.array([[math.cos(c), -math.sin(c), 0], [math.sin(c), math.cos(c), 0], [0, 0, 1]])
    return rz @ ry @ rx


def euler_zxz_angles(rotation: np.ndarray) -> tuple[float, float, float]:
    """(I, J, K) in degrees with ``Rz(I) Rx(J) Rz(K) = rotation``: G68.2's Euler angles of a
    rotation (J in [0, 180]; K = 0 where J is 0 or 180 and only I + K or I - K is defined)."""
    r = np.asarray(rotation, dtype=float)
    sj = math.hypot(r[0, 2], r[1, 2])
    j = math.atan2(sj, r[2, 2])
    if sj > 1e-12:
        i = math.atan2(r[0, 2], -r[1, 2])
        k = math.atan2(r[2, 0], r[2, 1])
    else:
        i = math.atan2(r[1, 0], r[0, 0])   # Rz(I) (J = 0) or Rz(I) diag(1, -1, -1) (J = 180)
        k = 0.0
    return math.degrees(i), math.degrees(j), math.degrees(k)


class _Heidenhain(ContourBlocks):
    """The Heidenhain state of the program while it is read; the motion state is the G-code
    reader's (``self.g``)."""

    def __init__(self, reader: _Reader, block_delete: bool):
        self.g = reader
        reader.language_note = ""     # the G-code reader's refusals: no language guessing
        self.block_delete = block_delete
        self.source = reader.source
        self.axes = reader.axes
        self.index = reader.axis_index
        self.inch = False
        self.feed = None              # the last F (program units per minute)
        self.auto_feed = None         # TOOL CALL F, for FAUTO
        self.centre = None            # CC: absolute (x, y), mm, in the reader's frame
        self.tangent = None           # direction at the end of the last contour block
        self.q = {}                   # Q parameters
        self.shift = [0.0, 0.0, 0.0]  # CYCL DEF 7 datum shift, mm
        self.shift_pending = None     # (construct, line) of a shift given under a PLANE
        self.preset = list(reader.offsets.get("G54", (0.0,) * 5))
        self.tcp = False
        self.plane = None             # the active PLANE: (text, SEQ sign or 0)
        self.plane_turned = False
        self.shortest = False         # M126
        self.row = 0
        self.text = ""

    # ------------------------------------------------------------------ errors
    def fail(self, message, construct=None):
        raise ProgramError(message, source=self.source, row=self.row, field=construct)

    def refuse(self, construct, what):
        self.fail(f"{what} ({construct}) is not read by precontour; {ADVICE}", construct)

    # ------------------------------------------------------------------ program
    def run(self, text: str) -> Program:
        lines = text.splitlines()
        self.g.lines = lines
        n, pc = len(lines), 0
        while pc < n:
            start = pc
            block = lines[pc]
            while block.rstrip().endswith("~") and pc + 1 < n:   # a block on several lines
                pc += 1
                block = block.rstrip()[:-1] + " " + lines[pc]
            pc += 1
            self.row = self.g.row = start + 1
            if self.block(block):
                break
        return self.g.finish()

    def block(self, raw: str) -> bool:
        """Execute one block; True at the end of the program."""
        s = raw.strip()
        if not s:
            return False
        if s[0] == "/":
            if self.block_delete:
                self.g.skipped["/"] += 1
                return False
            s = s[1:].lstrip()
        number = _BLOCK_NUMBER.match(s)
        if number is not None:
            s = s[number.end():]
        comment = None
        if ";" in s:
            s, comment = s.split(";", 1)
            comment = comment.strip()
        s = s.strip()
        if s.endswith("*") and not s.startswith("*"):
            s = s[:-1].rstrip()           # a block end
        self.text = s
        if s.startswith("*"):             # a section heading
            comment = s[1:].strip(" -") or comment
            s = ""
        if not s:
            if comment:
                self.g.passthrough.append((self.row, _comment(comment)))
            return False
        upper = s.upper()
        comments = [comment] if comment else []
        if upper.startswith("BEGIN PGM"):
            return self.begin(upper)
        if upper.startswith("END PGM"):
            self.g.stops.append(Stop(self.g.n_moves, self.row, "end"))
            return True
        if upper.startswith("BLK FORM"):
            self.g.skipped["BLK FORM"] += 1
            return False
        if upper.startswith("TOOL CALL"):
            return self.tool_call(s, comments)
        if upper.startswith("CYCL DEF 7.") or upper.startswith("CYCL DEF 7 "):
            return self.datum_shift(s)
        if upper.startswith("CYCL DEF 32."):
            return self.tolerance(s, comments)
        if upper.startswith("FUNCTION"):
            return self.function(s)
        if upper.startswith("PLANE"):
            return self.plane_function(s)
        assignment = _ASSIGN.match(s)
        if assignment is not None and (upper.startswith("Q") or upper.startswith("FN")):
            return self.assign(assignment)
        contour = _CONTOUR.match(s)
        if contour is not None and not upper.startswith(("CYCL", "CALL")):
            return self.contour(contour.group(1), contour.group(2), comments)
        if re.fullmatch(r"(?:M\d+\s*)+", upper):
            return self.execute(self.m_words(self.words(s)), comments)
        for pattern, what in _REFUSED:
            match = pattern.match(s)
            if match is not None:
                self.refuse(match.group().strip(), what)
        self.fail(f"{s.split()[0]!r} is no Heidenhain conversational block this reader knows; "
                  f"{ADVICE}", s.split()[0])

    def begin(self, upper: str) -> bool:
        unit = upper.split()[-1]
        if unit not in ("MM", "INCH"):
            self.fail("BEGIN PGM needs its unit, MM or INCH, at the end", upper)
        self.inch = unit == "INCH"
        self.execute([("G", 20.0 if self.inch else 21.0, "20" if self.inch else "21",
                       "BEGIN PGM")], [], keep=False)
        return False

    # ------------------------------------------------------------------ words
    def words(self, text: str) -> list[tuple[str, str | None]]:
        """(name, value as written) of each word of a block's arguments; ``F MAX`` is
        ``FMAX``."""
        out, pos, s = [], 0, text.strip().upper()
        while pos < len(s):
            if s[pos].isspace():
                pos += 1
                continue
            match = _WORD.match(s, pos)
            if match is None or match.end() == pos:
                bad = s[pos:].split()[0]
                self.fail(f"cannot read {bad!r} (a word is a letter or name and a signed "
                          "number or Q parameter)", bad)
            name, value = match.group(1), match.group(2)
            if name == "F" and value is None and s[match.end():].lstrip().startswith("MAX"):
                name = "FMAX"
                pos = s.index("MAX", match.end()) + 3
            else:
                pos = match.end()
            out.append((name, None if value is None else value.replace(" ", "")))
        return out

    def value(self, name: str, written: str | None) -> float:
        """The number of a word: a signed number or a signed Q parameter."""
        if written is None or written in "+-":
            self.fail(f"{name} needs a value", name)
        sign = -1.0 if written.startswith("-") else 1.0
        body = written.lstrip("+-")
        if body[:1] in "Qq":
            return sign * self.parameter(int(body[1:]), f"{name}{written}")
        return sign * float(body.replace(",", "."))

    def parameter(self, n: int, word: str) -> float:
        if n not in self.q:
            if n in PLANE_ANGLES:
                self.fail(f"Q{n} (the {PLANE_ANGLES[n]} angle a PLANE function computes) is "
                          "read only in the L block that turns the rotary axes after PLANE "
                          "... STAY", word)
            self.fail(f"Q{n} is used before it is set", word)
        return self.q[n]

    def m_words(self, words) -> list:
        """The M functions of a block as G-code words; those this reader acts on itself
        (M91, M126, M127, M128, M129) are taken out, the unsupported refused."""
        out = []
        for name, written in words:
            if name != "M":
                continue
            number = int(self.value("M", written))
            word = f"M{number}"
            if number in (126, 127):
                self.shortest = number == 126
            elif number in (128, 129):
                self.switch_tcp(number == 128, word)
            elif number == 91:
                pass                      # read by the L block
            elif number in (92, 140, 114, 144, 112, 124, 120):
                self.fail(f"{word} ({_M_MEANING[number]}) is not read by precontour; "
                          f"{ADVICE}", word)
            else:
                out.append(("M", float(number), str(number), word))
        return out

    def execute(self, words, comments, keep=True, text=None) -> bool:
        """Execute G-code words on this block's line; True at the program end."""
        raw = text if text is not None else " ".join(
            w[0] + w[2] for w in words if w[0] in "MSTGF")
        if not raw and comments and keep:
            raw = " ".join(_comment(c) for c in comments)   # an M block read away (M127)
        return self.g.execute(words, False, False, raw, comments if keep else [])

    # ------------------------------------------------------------------ blocks
    def tool_call(self, s: str, comments) -> bool:
        match = _TOOL_CALL.match(s)
        tool, rest = match.group(1), match.group(2)
        words = self.words(rest)
        axis = next((name for name, value in words if value is None
                     and name in ("X", "Y", "Z")), None)
        if axis not in (None, "Z"):
            self.fail(f"TOOL CALL with tool axis {axis}: only the tool axis Z is read", axis)
        out = []
        for name, written in words:
            if name == "S":
                number = self.value(name, written)
                out.append(("S", number, _format(number), f"S{written}"))
            elif name == "F":
                self.auto_feed = self.value(name, written)
            elif name in ("DL", "DR", "DR2"):
                if self.value(name, written) != 0.0:
                    self.fail(f"TOOL CALL {name}{written}: a tool length or radius delta is "
                              "not applied; post-process with DL+0 (the tool length is the "
                              "machine file's)", f"{name}{written}")
            elif (name, written) != (axis, None):
                self.fail(f"TOOL CALL word {name}{written or ''!s} is not read",
                          f"{name}{written or ''}")
        if tool is not None:
            self.tool_call_hook(tool)
            if tool.isdigit():
                out.insert(0, ("T", float(tool), tool, f"TOOL CALL {tool}"))
            else:
                comments = [f"TOOL CALL {tool}"] + list(comments)
            out.append(("M", 6.0, "6", "TOOL CALL"))
        return self.execute(out, comments)

    def tool_call_hook(self, tool: str) -> None:
        """Where a tool table's length for ``tool`` (a number or a quoted name) is to be
        applied; today the machine file's kinematics carries the one tool length."""

    def datum_shift(self, s: str) -> bool:
        """CYCL DEF 7.0 DATUM SHIFT; 7.1, 7.2, ... one axis each (X Y Z, absolute from the
        preset or incremental from the last shift), applied as the active work offset."""
        match = _CYCL7.match(s)
        if match is None:
            self.refuse(s, "a datum shift without its part number")
        part, rest = match.group(1), match.group(2)
        if part == "0":
            return False
        words = self.words(rest)
        if len(words) != 1 or words[0][0] not in ("X", "Y", "Z", "IX", "IY", "IZ"):
            self.fail(f"CYCL DEF 7.{part} {rest.strip()}: one of X Y Z (or IX IY IZ) is read "
                      "(a datum table number or a rotary axis is not)", f"CYCL DEF 7.{part}")
        name, written = words[0]
        axis = "XYZ".index(name[-1])
        value = self.value(name, written) * (INCH if self.inch else 1.0)
        self.shift[axis] = self.shift[axis] + value if name.startswith("I") else value
        if self.plane is not None:
            # under a PLANE function the shift would be in the tilted frame: it is taken only
            # where the plane ends (a post resets the datum before PLANE RESET), and a move
            # before that is refused
            self.shift_pending = f"CYCL DEF 7.{part}", self.row
            return False
        self.apply_shift(axis)
        return False

    def apply_shift(self, axis: int, word: str = "CYCL DEF 7") -> None:
        """The datum shift of ``axis`` as the active work offset (G10 L2 P0)."""
        offset = self.preset[axis] + self.shift[axis]
        letter = self.axes[axis]
        value = offset / (INCH if self.inch else 1.0)
        self.execute([("G", 10.0, "10", word), ("L", 2.0, "2", "L2"), ("P", 0.0, "0", "P0"),
                      (letter, value, _format(value), word)], [], keep=False)

    def end_plane(self) -> None:
        """G69, and a datum shift given under the plane takes effect."""
        self.g.execute([("G", 69.0, "69", "PLANE")], False, False, "G69", [])
        self.plane = None
        if self.shift_pending is not None:
            for axis in range(3):
                self.apply_shift(axis, self.shift_pending[0])
            self.shift_pending = None

    def tolerance(self, s: str, comments) -> bool:
        """CYCL DEF 32 TOLERANCE: 32.1 T.. is the path tolerance (G64 P)."""
        match = _CYCL32.match(s)
        part, rest = match.group(1), match.group(2)
        if part in ("0", "2"):
            return False
        if part != "1":
            self.refuse(s, "a tolerance cycle part")
        words = [(n, w) for n, w in self.words(rest.replace(":", " ")) if n != "HSC"]
        tol = [self.value(n, w) for n, w in words if n == "T"]
        extra = [n for n, _ in words if n != "T"]
        if extra:
            self.fail(f"CYCL DEF 32.1 word {extra[0]} is not read (only T, the tolerance)",
                      extra[0])
        words = [("G", 64.0, "64", "CYCL DEF 32.1")]
        if tol:
            words.append(("P", tol[0], _format(tol[0]), f"T{tol[0]:g}"))
        return self.execute(words, comments, keep=False)

    def function(self, s: str) -> bool:
        parts = s.upper().split()
        if parts[:3] == ["FUNCTION", "RESET", "TCPM"] and len(parts) == 3:
            self.switch_tcp(False, "FUNCTION RESET TCPM")
            return False
        if parts[:2] == ["FUNCTION", "TCPM"]:
            options = " ".join(parts[2:])
            allowed = ("F TCP AXIS POS PATHCTRL AXIS", "F TCP AXIS POS PATHCTRL AXIS REFPNT "
                       "TIP-TIP")
            if options not in allowed:
                self.fail(f"FUNCTION TCPM {options}: only F TCP AXIS POS PATHCTRL AXIS (the "
                          "tool tip feed, rotary axes as axis positions interpolated linearly) "
                          "is read; post-process with it", "FUNCTION TCPM")
            self.switch_tcp(True, "FUNCTION TCPM")
            return False
        self.refuse(" ".join(s.split()[:2]), "a FUNCTION block")

    def switch_tcp(self, on: bool, word: str) -> None:
        if self.plane is not None:
            self.fail(f"{word} with a PLANE function active is not read; post-process with "
                      "PLANE RESET before it", word)
        if on != self.tcp:
            self.g.execute([("G", 43.4 if on else 49.0, "43.4" if on else "49", word)],
                           False, False, word, [])
            self.tcp = on

    def assign(self, match) -> bool:
        fn, n, expression = match.group(1), int(match.group(2)), match.group(3)
        expression = expression.strip()
        if fn is not None and fn not in ("0", "1", "2", "3", "4"):
            self.refuse(f"FN {fn}:", "a Q-parameter function")
        # FN 1-4 (add, subtract, multiply, divide) write their operator in the expression
        self.q[n] = self.expression(expression)
        return False

    def expression(self, text: str) -> float:
        """The value of a Q-parameter expression: numbers, Qn, + - * / and ( )."""
        tokens = re.findall(r"Q\d+|\d+(?:[.,]\d*)?|[.,]\d+|[-+*/()]|\S", text.upper())
        pos = 0

        def peek():
            return tokens[pos] if pos < len(tokens) else None

        def take():
            nonlocal pos
            pos += 1
            return tokens[pos - 1]

        def atom():
            token = peek()
            if token in ("+", "-"):
                take()
                return -atom() if token == "-" else atom()
            if token == "(":
                take()
                value = total()
                if take() != ")":
                    self.fail(f"unbalanced ( in {text!r}", text)
                return value
            if token is None:
                self.fail(f"incomplete expression {text!r}", text)
            take()
            if token[0] == "Q":
                return self.parameter(int(token[1:]), token)
            try:
                return float(token.replace(",", "."))
            except ValueError:
                self.fail(f"cannot read {token!r} in {text!r} (only numbers, Q parameters, + - "
                          "* / and parentheses are read)", token)

        def product():
            value = atom()
            while peek() in ("*", "/"):
                if take() == "*":
                    value *= atom()
                else:
                    divisor = atom()
                    if divisor == 0.0:
                        self.fail(f"division by zero in {text!r}", text)
                    value /= divisor
            return value

        def total():
            value = product()
            while peek() in ("+", "-"):
                value = value + product() if take() == "+" else value - product()
            return value

        value = total()
        if pos != len(tokens):
            self.fail(f"cannot read {' '.join(tokens[pos:])!r} in {text!r}", tokens[pos])
        return value

    # ------------------------------------------------------------------ PLANE
    def plane_function(self, s: str) -> bool:
        parts = s.upper().split()
        kind = parts[1] if len(parts) > 1 else ""
        if kind == "RESET":
            options = parts[2:]
            turn = self.positioning(options, "PLANE RESET")
            self.end_plane()
            if turn:
                words = [("G", 0.0, "0", "PLANE RESET TURN")] + [
                    (letter, 0.0, "0", "PLANE RESET TURN") for letter in self.axes[3:]]
                self.execute(words, [], keep=False)
            return False
        if kind != "SPATIAL":
            self.refuse(" ".join(parts[:2]), "a PLANE function other than SPATIAL and RESET")
        if self.tcp:
            self.fail("PLANE SPATIAL in tool centre point mode is not read; post-process with "
                      "M129 or FUNCTION RESET TCPM before it", "PLANE SPATIAL")
        words = self.words(" ".join(s.split()[2:]))
        angles = {n: self.value(n, w) for n, w in words if n in ("SPA", "SPB", "SPC")}
        options = [n + (w or "") for n, w in words if n not in ("SPA", "SPB", "SPC")]
        turn = self.positioning(options, "PLANE SPATIAL")
        seq = next((1 if o == "SEQ+" else -1 for o in options if o in ("SEQ+", "SEQ-")), 0)
        i, j, k = euler_zxz_angles(spatial_rotation(angles.get("SPA", 0.0),
                                                    angles.get("SPB", 0.0),
                                                    angles.get("SPC", 0.0)))
        if self.plane is not None:
            self.end_plane()
        self.g.execute([("G", 68.2, "68.2", "PLANE SPATIAL"), ("I", i, _format(i), "SPA"),
                        ("J", j, _format(j), "SPB"), ("K", k, _format(k), "SPC")],
                       False, False, "G68.2", [])
        self.plane = (" ".join(s.split()[:2]), seq)
        if turn:
            self.turn_to_plane({}, "PLANE SPATIAL TURN")
        return False

    def positioning(self, options, what) -> bool:
        """True for TURN, False for STAY; the other options checked."""
        turn = stay = False
        for option in options:
            if option == "TURN":
                turn = True
            elif option == "STAY":
                stay = True
            elif option == "MOVE":
                self.fail(f"{what} MOVE (the rotary axes turn about a point held on the tool) "
                          "is not read; post-process with TURN or STAY", "MOVE")
            elif option in ("MB0", "MB+0", "FMAX", "TABLE", "ROT", "COORD", "SEQ+", "SEQ-") \
                    or option.startswith("F") and option[1:].lstrip("+").replace(".", "", 1) \
                    .isdigit():
                continue
            elif option.startswith("MB"):
                self.fail(f"{what} {option} (a retraction before tilting) is not read; "
                          "post-process the retraction as an L block", option)
            else:
                self.fail(f"{what} option {option} is not read", option)
        if turn == stay:
            self.fail(f"{what} needs TURN or STAY", what)
        return turn

    def turn_to_plane(self, targets, word) -> None:
        """The rotary axes turn the tool onto the plane's Z (G53.1); an L block's rotary
        words must be the PLANE function's own angles, Q120-Q122."""
        numbers = {letter: n for n, letter in PLANE_ANGLES.items()}
        for letter in self.axes[3:]:
            if letter in targets:
                incremental, _, spelled = targets[letter]
                expected = f"{letter}+Q{numbers[letter]}"
                if incremental or spelled.replace(" ", "").upper() != expected:
                    self.fail(f"rotary axis word {spelled} under PLANE SPATIAL: only the PLANE "
                              f"function's angle ({expected}) is read", spelled)
        self.g.execute([("G", 53.1, "53.1", word)], False, False, "G53.1", [])
        tilt = self.g.prog[3]
        seq = self.plane[1] if self.plane else 0
        if seq and tilt * seq < -_SEQ_SLACK:
            self.fail(f"SEQ{'+' if seq > 0 else '-'} asks for the other tilt solution than the "
                      f"one within travel nearest C ({self.axes[3]} = {tilt:.6g} deg); "
                      "post-process without SEQ or with the other sign", f"SEQ{'+-'[seq < 0]}")
        for n, letter in PLANE_ANGLES.items():
            if letter in self.index:
                self.q[n] = self.g.prog[self.index[letter]]


def _comment(text: str) -> str:
    """A comment as an output G-code line: ( ) without nested parentheses."""
    return "(" + text.replace("(", "[").replace(")", "]") + ")"


_M_MEANING = {92: "coordinates of the machine manufacturer's datum",
              140: "retraction along the tool axis",
              114: "automatic compensation of the tool geometry with tilting axes",
              144: "the tool's offset in the kinematics",
              112: "contour transition arcs",
              124: "contour filter",
              120: "look-ahead of radius-compensated contours"}
