"""Reader for G-code programs as CAM post-processors write them (RS274/NGC, Fanuc, LinuxCNC,
Haas, Sinumerik TRAORI), into a :class:`~precontour.toolpath.program.Program` in machine axes.

What is read, block by block with the usual modal state:

- motion G0, G1, G2/G3 (arcs in the G17/G18/G19 plane by I J K or R, full circles, P turns,
  helix: the normal axis and the rotary axes move linearly along the arc; the start and end
  radius may differ by :data:`ARC_RADIUS_TOLERANCE` mm or :data:`ARC_RADIUS_RTOL` of the
  radius, whichever is larger, and the radius then changes linearly with the angle, as in
  LinuxCNC); arcs are subdivided into chords within :data:`ARC_CHORD_TOLERANCE`;
- feeds G93 (inverse time: a block takes 1/F min, F on every feed block) and G94 (per minute:
  the XYZ length, or the rotary degrees of a rotary-only move, divided by F), switched freely;
- G90/G91, G90.1/G91.1 (arc centres absolute / incremental), G20/G21, modal motion and
  coordinates, ``N`` numbers, ``( )`` and ``;`` comments, ``/`` block delete, ``%``, ``O``
  program numbers;
- tool centre point (TCP) mode, switched per block: G43.4/G43.5 ... G49, Haas's G234 ... G49
  (or G43), TRAORI ... TRAFOOF, the site's own M or G codes (the machine file's
  ``[gcode] tcp_on``/``tcp_off``, by default LinuxCNC's remapped M428 ... M429; the off code
  ends every TCP mode, G49 only G43.4's and G234's), Haas's dynamic work offset G254 ... G255
  (X Y Z in the work frame turned with the rotary axes: a TCP mode whose rotary moves turn the
  table with the linear axes held, as for 3+2 positioning; not with G234 or G43.4), or
  from the start with ``tcp=True``: X Y Z are then the tool tip in the workpiece frame, the
  rotary axes are taken as programmed and the linear axes follow from the machine's
  kinematics; at a switch the position is carried over through the kinematics (LinuxCNC
  re-reads it from the machine), so modal axes keep the physical point;
- stops: G4 dwell (P or X seconds), M0, M1, M6 (tool change), M2/M30 (end; later lines are
  not read);
- coordinates as LinuxCNC keeps them: the absolute position is the words plus the work offset
  (G54-G59.3, Fanuc's G54.1 P1-P300; from the machine file's ``[gcode.work_offsets]``, else
  zero, said once) and the G92 offset (G92, G92.1, G92.2, G92.3); G10 L2/L20 Pn set a work
  offset; G53 moves in machine coordinates (in TCP mode: the machine axes, a move in joint
  space; under G91 its words are machine positions, as a Haas control moves, said once); G28/G30 rapid through the given point to the machine file's reference position
  (``[gcode] g28``/``g30``, else the machine origin, said once) for the given axes (all
  without axis words), in machine coordinates; G28.1/G30.1 store the current position;
  tool lengths: the machine file's kinematics carries one (``tool_offset``); with a tool
  table (the machine file's ``[tools]``, or ``tool_table=``) the length of the tool that G43 H,
  G43.4 H, G234 H select (no H: the tool of the last T M6 or M61 Q) turns TCP tool tips into
  machine axes, a tool the table lacks said once; the axis words of moves outside TCP are
  machine axes as written, whatever the length;
- LinuxCNC's language (:mod:`._ngc`): numbered and named parameters (``#1``, ``#<depth>``,
  global ``#<_name>``, LinuxCNC's predefined ``#<_x>`` ... and stored ``#5161`` ...),
  expressions with its operators, precedence and functions, polar coordinates (``@`` radius,
  ``^`` angle), O-word subroutines (``sub``/``endsub``/``call`` with arguments ``#1``-``#30``,
  ``return`` with a value in ``#<_value>``), ``if``/``elseif``/``else``/``endif``,
  ``while``/``endwhile``, ``do``/``while``, ``repeat``/``endrepeat``, ``break``/``continue``,
  Fanuc subprograms in the same file (``M98 P<n> [L<count>]`` to ``O<n>`` ... ``M99``) and
  the modal state of M70-M73; no loop runs more than :data:`MAX_LOOP_ITERATIONS` times and
  no calls nest deeper than :data:`MAX_CALL_DEPTH` (a runaway ends with an error on its
  line); the ``line`` of a move is the line executing (inside a subroutine, its own);
- kept for an output program (:attr:`Program.passthrough`): comments, T, S, H, D words, M3-M9,
  M61 Q, M62-M68 with their P E L Q words, G17-G19, G40, G43, G43.1/G43.2 (their axis words
  are the tool length, not applied), G49, G61, G64, G80, G97; any other M code is kept too, with a
  one-line notice; a line with parameters keeps its values. G64 P (path tolerance) and
  G61/G61.1 (exact path: 0) are also kept per move for the timing.
- canned cycles G73, G81-G83, G85-G87, G89 expanded into moves as LinuxCNC 2.9 does
  (:mod:`._cycles`): G98/G99 retract (G99, LinuxCNC's default, without either), R, Q pecks,
  P dwells, L repeats, G91 increments, polar holes, sticky words, G80; in any plane;
- Fanuc's tilted working plane ``G68.2 X Y Z I J K`` (Euler angles about Z, X, Z), G53.1
  (the rotary axes turn the tool onto the plane's Z, in joint space, on the solution within
  travel: :mod:`._swivel`) and G69: the program's coordinates are the plane's, its moves tool
  tip positions (as TCP moves);
- Sinumerik 840D programs (``.mpf``, or a program whose first lines show the language):
  variables, frames, ``SUPA``, ``CYCLE800``, ``CYCLE832``, blending modes ... as
  :mod:`._sinumerik_blocks` says;
- :attr:`Program.programmed`: the moves as programmed (straight moves and whole arcs with
  their centres, feeds as given), as LinuxCNC's canonical interface receives them.

Everything else -- subroutines in other files, Fanuc macros (G65, IF/GOTO/WHILE-DO),
G10 L1/L10/L11 (tool tables), cutter compensation, spindle-synchronized motion (tapping
G74/G84, G33, G76), G88 (a manual retract), G68 rotation, G68.2 P1-P3, G95, HAL pins
(``#<_hal[...]>``) -- is one :class:`~precontour.errors.ProgramError` naming the file, line
and word. A line in another controller's language (Sinumerik 840D's constructs it does not read,
``CYCLE81(...)``, ``ORIVECT``; Heidenhain conversational; Haas's ``G234``, ``G254``) is a
:class:`~precontour.errors.ForeignSyntaxError` naming the construct as written and the
language (:mod:`._dialects`); a refused construct that is none of these says which language
the program looks like, when one of its lines shows one.
"""

from __future__ import annotations

import math
import re
from collections import Counter
from dataclasses import replace
from pathlib import Path
from types import MappingProxyType

import numpy as np
import pyarrow as pa

from ..errors import ForeignSyntaxError, InputError, ProgramError
from ..machine.gcode import MAX_EXTENDED_OFFSET, WORK_OFFSETS, GcodeSettings
from ..machine.tools import checked_tool_lengths, read_tool_table
from ._common import INCH, ReadReport, finish, read_text
from ._cycles import PECK_CLEARANCE_INCH, cycle_moves
from ._dialects import REPOST, SINUMERIK, foreign_construct, program_language
from ._sinumerik_blocks import SinumerikBlocks
from ._swivel import rotary_travel, swivel
from ._ngc import (MAX_PARAMETER, NgcError, OWord, StructureError, compile_line, format_number,
                   needs_macro_reader, scan_structure)
from .program import Program, ProgrammedMoves, Stop

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
#: Most times one loop may run, and deepest calls may nest (runaway guards).
MAX_LOOP_ITERATIONS = 1_000_000
MAX_CALL_DEPTH = 100
#: LinuxCNC's parameter slots of the axes (5161 + slot: X Y Z A B C U V W).
_SLOTS = {0: "X", 1: "Y", 2: "Z", 3: "A", 4: "B", 5: "C"}
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

__all__ = ["read_program", "read_gcode", "read_gcode_report", "AXIS_WORDS",
           "ARC_CHORD_TOLERANCE", "ARC_RADIUS_TOLERANCE", "ARC_RADIUS_RTOL", "PASSTHROUGH_G"]


def read_program(path: str | Path, machine, *, tcp: bool = False,
                 block_delete: bool = True,
                 arc_tolerance: float = ARC_CHORD_TOLERANCE,
                 tool_table=None) -> Program:
    """Read a G-code program into machine-axis moves (see the module docstring).

    Parameters
    ----------
    path : str or Path
        The program.
    machine : Machine or str
        The machine (or a built-in name / machine file): its kinematics'
        ``forward(q) -> (P, O)`` converts TCP tool tips to machine axes.
    tcp : bool
        The program starts in TCP mode (for controllers that switch it with M codes the
        machine file does not name); G49 and TRAFOOF do not end it, the machine file's TCP-off
        M code (by default LinuxCNC's M429) does.
    block_delete : bool
        Skip blocks starting with ``/``.
    arc_tolerance : float
        Largest distance between an arc and its chords, mm.
    tool_table : str, Path or Mapping[int, float], optional
        Tool lengths (mm) by tool number: a LinuxCNC tool table file (``.tbl``) or a mapping;
        it replaces the machine file's ``[tools]``. The length of the tool that ``G43 H``,
        ``G43.4 H``, ``G234 H`` select (without H: the tool of the last ``T.. M6`` or
        ``M61 Q``) turns the tool tips of TCP moves into machine axes; a tool the table lacks
        is said once and takes the machine file's ``tool_offset``.

    Returns
    -------
    Program

    Raises
    ------
    ProgramError
        One line naming the file, line and word, for the first problem in the program.
    """
    kinematics = _kinematics(machine)
    if not (np.isfinite(arc_tolerance) and arc_tolerance > 0):
        raise InputError(f"arc tolerance must be positive, got {arc_tolerance!r}",
                         field="arc_tolerance")
    source = str(path)
    text = read_text(path)
    axes = _axis_letters(machine)
    settings = getattr(machine, "gcode", None) or GcodeSettings()
    if tool_table is None:
        lengths = getattr(machine, "tools", None) or {}
    elif isinstance(tool_table, (str, Path)):
        lengths = read_tool_table(tool_table)
    else:
        lengths = checked_tool_lengths(tool_table, field="tool_table")
    reader = _Reader(source, kinematics, axes, tcp, block_delete, arc_tolerance, settings)
    reader.tool_lengths = dict(lengths)
    return reader.run(text)


class _Reader(SinumerikBlocks):
    """The modal state of the program while it is read, block by block."""

    def __init__(self, source, kinematics, axes, tcp, block_delete, arc_tolerance,
                 settings=GcodeSettings()):
        self.source, self.kinematics, self.axes = source, kinematics, axes
        self.axis_index = {a: i for i, a in enumerate(axes)}
        number = r"([-+]?(?:\d+\.?\d*|\.\d+))"
        self.plain = re.compile(r"(?:N\d+)?(?:G0?([01])(?![\d.]))?"
                                + "".join(f"(?:{a}{number})?" for a in axes)
                                + f"(?:F{number})?")
        self.block_delete, self.arc_tolerance = block_delete, arc_tolerance
        self.tcp_all = tcp
        self.tcp = tcp
        # what holds TCP mode on: "option" (tcp=True), "G43.4" (G43.4/G43.5, ended by G49),
        # "TRAORI" (ended by TRAFOOF), "M" (the site's TCP-on M code; its TCP-off code ends
        # every one: the controller switches its kinematics)
        self.tcp_sources = {"option"} if tcp else set()
        self.tcp_on, self.tcp_off = frozenset(settings.tcp_on), frozenset(settings.tcp_off)
        # the site's G-code TCP switches (the machine file's tcp_on/tcp_off G codes, tenths)
        self.tcp_on_g = frozenset(settings.tcp_on_g)
        self.tcp_off_g = frozenset(settings.tcp_off_g)
        # tool lengths: the table (tool number -> mm), the tool in the spindle (T .. M6,
        # M61 Q) and the one selected, the length in use (NaN: the machine file's
        # tool_offset), the kinematics of each length, the tools said to be missing
        self.tool_lengths = {}
        self.next_tool = self.tool = None
        self.length = math.nan
        self.base_kinematics = kinematics
        self.length_kinematics = {}
        self.said_tools = set()
        self.said_g53_incremental = False
        self.dwo_base = None          # G254: the work offset it turns with the table
        self.motion = None
        self.plane = _PLANES[170]
        self.inch = False
        self.incremental = False
        self.arc_absolute = False
        self.inverse_time = False
        self.feed = math.nan          # G94 feed, mm/min
        # absolute programmed coordinates (tip + rotary in TCP mode, else machine axes), mm
        # and deg: the words plus the work and G92 offsets; NaN: not known yet
        self.prog = [math.nan] * 5
        # partial positions at TCP switches before every axis was known (see resolve)
        self.deferred = []
        # machine-file data in the reader's units (mm, deg)
        self.offsets = {name: _degrees(v) for name, v in settings.work_offsets.items()}
        self.reference = {280: None if settings.g28 is None else _degrees(settings.g28),
                          300: None if settings.g30 is None else _degrees(settings.g30)}
        self.work_offset = "G54"
        self.g5x = list(self.offsets.get("G54", _ZERO))
        self.g92 = list(_ZERO)
        self.g92_stored = list(_ZERO)
        self.said_offsets = self.said_reference = False
        # the language: parameters, call frames, compiled lines, the O-word structure
        self.params = [0.0] * (MAX_PARAMETER + 1)
        self.globals = {}
        self.frames = [_Frame("main", "", 0)]
        self.compiled = {}
        self.structure = None
        self.jump = None             # the next line after M98/M99
        self.value = self.value_returned = 0.0
        self.saved_state = None      # M70 / M73
        # canned cycles: G98 (back to the height before the cycles) or G99 (to R, LinuxCNC's
        # default), the height the cycles began at, the sticky words of the last cycle
        self.retract_initial = False
        self.cycle_start = None
        self.tilt = None             # G68.2: (origin, rotation) of the plane's frame
        self.pframe = None           # Sinumerik's TRANS/ROT ...: (origin, rotation)
        self.tilt_offsets = None
        self.cycle_words = {}
        self.cancelled = False
        self.start = None
        self.start_line = 0
        self.start_tcp = tcp
        self.start_length = math.nan
        # per move: programmed end (mm, deg), rapid, duration, feed, line, tcp, tolerance;
        # per programmed move: kind, end, centre, plane, turns, G93, F, line, tcp, first move
        self.moves = _Table()
        self.programmed = _Table()
        self.path_tolerance = math.nan   # G64 P (mm); 0 after G61/G61.1; NaN: not given
        self.n_moves = 0
        self.stops, self.passthrough, self.notices = [], [], []
        self.skipped = Counter()
        self.unknown_m = set()
        self.pending = []
        self.row = 0
        self.lines = ()
        self.language_note = None     # what refusals add about the program's language
        self.sinumerik = False        # the program is Sinumerik's (its constructs are read)
        self.sinumerik_setup()

    # ------------------------------------------------------------------ errors
    def fail(self, message, word=None):
        raise ProgramError(message, source=self.source, row=self.row, field=word)

    def refuse(self, message, word=None, line=None):
        """Fail on a construct the reader does not know (an unknown word, code or name):
        named as another controller's syntax when it is one (in ``line``, as written), else
        ``message``, with the language the program looks like when one of its lines shows
        one (a ``G60`` among Sinumerik lines)."""
        self.refuse_foreign(line)
        self.fail(message + self.program_language_note(), word)

    def refuse_foreign(self, line):
        """Fail if ``line`` (a line the reader cannot read) holds another controller's
        syntax: the refusal names it as written and the language."""
        foreign = foreign_construct(line) if line else None
        if foreign is not None:
            raise ForeignSyntaxError(foreign.message(), source=self.source, row=self.row,
                                     field=foreign.construct)

    def program_language_note(self) -> str:
        """``; the program looks like ...`` when a line of the program shows another
        controller's language, else ``""`` (worked out once, at the first refusal)."""
        if self.language_note is None:
            found = program_language(self.lines)
            self.language_note = "" if found is None else (
                f"; the program looks like {found[1].language} ({found[1].construct!r} on "
                f"line {found[0] + 1}): {REPOST}")
        return self.language_note

    # ------------------------------------------------------------------ program
    def run(self, text: str) -> Program:
        lines = self.lines = text.splitlines()
        found = program_language(lines)
        self.sinumerik = (Path(self.source).suffix.lower() in SINUMERIK_SUFFIXES
                          or found is not None and found[1].language == SINUMERIK)
        self.structure = self.scan(lines)
        self.prepared = [None] * len(lines)
        owords = self.structure.owords
        pc, n = 0, len(lines)
        while pc < n:
            self.row = pc + 1
            oword = owords.get(pc)
            if oword is not None:
                self.flush()
                pc = self.control(pc, oword)
                if pc is None:
                    break
                continue
            if self.block(pc, lines[pc]):
                break
            if self.jump is not None:
                pc, self.jump = self.jump, None
                continue
            pc += 1
        else:
            if self.frames[-1].kind != "main":
                frame = self.frames[-1]
                self.fail(f"the program ends inside subprogram {frame.name} (called on line "
                          f"{frame.return_pc}): M99 is missing")
        self.flush()
        return self.finish()

    def scan(self, lines):
        """The O-word structure of the program (subroutines, branches, loops, labels)."""
        codes = [None] * len(lines)
        for index, raw in enumerate(lines):
            if _MAYBE_OWORD.match(raw):
                self.row = index + 1     # the line a comment error names
                codes[index] = self.code_of(raw)[0]
        try:
            return scan_structure(codes)
        except StructureError as exc:
            raise ProgramError(exc.message, source=self.source, row=exc.index + 1,
                               field=exc.word) from None

    def block(self, pc: int, raw: str) -> bool:
        """Execute one line; True after the program end (M2/M30). Plain motion blocks
        (``[N..] [G0|G1] axis words [F..]`` in the machine's axis order) are collected and
        executed together by :meth:`flush`. What a line is, is worked out once (loops and
        subroutines run lines again)."""
        prepared = self.prepared[pc]
        if prepared is None:
            prepared = self.prepared[pc] = self.prepare(raw)
        kind = prepared[0]
        if kind == _PLAIN:
            if self.start is not None:
                self.pending.append((self.row, prepared[1], raw))
                return False
            prepared = self.prepared[pc] = self.prepare(raw, plain=False)
        self.flush()
        return self._run_prepared(prepared)

    def prepare(self, raw: str, plain: bool = True):
        """What kind of line ``raw`` is, and what executing it needs."""
        if plain and "(" not in raw and ";" not in raw:
            code = raw.upper().translate(_BLANKS)
            if code and code[0] not in "%/":
                match = self.plain.fullmatch(code)
                if match is not None:
                    return (_PLAIN, match.groups())
        s = raw.lstrip()
        if s[:1] == "/" and self.block_delete:
            return (_SKIP, True)
        if self.sinumerik:
            parsed = self.sinumerik_prepare(raw)
            if parsed is not None:
                return (_SINUMERIK, *parsed, raw.strip())
        code, comments = self.code_of(raw)
        if not code:
            return (_COMMENT, raw.strip()) if comments else (_SKIP, False)
        traori = trafoof = False
        if "TRA" in code:
            code, n_on = _TRAORI.subn("", code)
            code, n_off = re.subn("TRAFOOF", "", code)
            traori, trafoof = n_on > 0, n_off > 0
        fanuc = _FANUC_MACRO.match(code)
        if fanuc:
            self.fail("Fanuc macro statements (IF GOTO, WHILE DO END) are not supported; "
                      "LinuxCNC's O-word if and while are", fanuc.group())
        if code[:1] == "#" and not comments and needs_macro_reader(code):
            compiled = self.compile(code, raw)
            if not compiled.words:
                return (_SETTINGS, code)
        return (_GENERAL, code, traori, trafoof, raw.strip(), comments)

    def flush(self):
        """Execute the collected plain blocks at once; if any of them needs a word-by-word
        look (an error to report), all are executed one by one instead."""
        pending, self.pending = self.pending, []
        if pending and not self.plain_blocks(pending):
            row = self.row
            for pending_row, _, raw in pending:
                self.row = pending_row
                self.general(raw)
            self.row = row

    def plain_blocks(self, pending) -> bool:
        """Vectorized :meth:`general` for plain blocks: False (nothing changed) if one of them
        needs the general path."""
        if self.dwo_base is not None:
            return False    # G254 turns the work offset block by block (dwo_origin)
        rows = np.array([row for row, _, _ in pending], dtype=np.int64)
        columns = list(zip(*(groups for _, groups, _ in pending)))
        # pyarrow's C++ parser: about ten times faster than float() on each word
        values = np.stack([pa.array(column, type=pa.string()).cast(pa.float64())
                           .to_numpy(zero_copy_only=False) for column in columns])
        motion = _ffill(values[0], math.nan if self.motion is None else float(self.motion))
        if not np.isin(motion, (0.0, 1.0)).all():
            return False
        scale = INCH if self.inch else 1.0
        words = values[1:6].T.copy()
        words[:, :3] *= scale
        f_word = values[6]
        if (f_word <= 0).any():
            return False
        given = ~np.isnan(words)
        if self.tilt is not None and given[:, 3:].any():
            return False    # rotary words under G68.2: the word-by-word path says why
        prog = np.array(self.prog, dtype=float)
        if self.incremental:
            target = prog + np.cumsum(np.where(given, words, 0.0), axis=0)
        else:
            offset = np.add(self.g5x, self.g92)
            target = np.column_stack([_ffill(words[:, i] + offset[i], prog[i])
                                      for i in range(5)])
        if not (np.abs(target) <= MAX_COORDINATE).all():
            return False
        moving = given.any(axis=1)
        feed_rows = motion == 1.0
        if self.inverse_time:
            if np.isnan(f_word[moving & feed_rows]).any():
                return False
            feed = np.full(len(rows), self.feed)
        else:
            feed = _ffill(f_word * scale, self.feed)
            if np.isnan(feed[moving & feed_rows]).any():
                return False
        if moving.any():
            end = target[moving]
            start = np.concatenate([prog[None, :], end[:-1]])
            xyz = np.linalg.norm(end[:, :3] - start[:, :3], axis=1)
            rot = np.linalg.norm(end[:, 3:] - start[:, 3:], axis=1)
            rapid = motion[moving] == 0.0
            with np.errstate(divide="ignore", invalid="ignore"):
                if self.inverse_time:
                    duration = 60.0 / f_word[moving]
                    feed_s = np.full(end.shape[0], math.nan)
                else:
                    duration = 60.0 * np.where(xyz > 0, xyz, rot) / feed[moving]
                    feed_s = feed[moving] / 60.0
            duration[rapid] = math.nan
            feed_s[rapid] = math.nan
            k = end.shape[0]
            f_programmed = f_word[moving] if self.inverse_time else feed[moving]
            programmed = (np.where(rapid, 0, 1).astype(np.int8), end,
                          np.full((k, 3), math.nan), np.zeros(k, np.int8), np.zeros(k, np.int64),
                          np.full(k, self.inverse_time), np.where(rapid, math.nan, f_programmed),
                          rows[moving], np.full(k, self.tcp),
                          self.n_moves + np.arange(k, dtype=np.int64))
            self.add_many(end, rapid, duration, feed_s, rows[moving], programmed)
        self.motion = int(motion[-1])
        if not self.inverse_time:
            self.feed = float(feed[-1])
        return True

    def code_of(self, raw: str):
        """(code, comments) of a line: the code upper case without blanks and comments
        (None for a line that is skipped: empty, ``%``, or block-deleted)."""
        written = self.code_as_written(raw)
        if written is None:
            return None, []
        text, comments = written
        return text.upper().translate(_BLANKS), comments

    def code_as_written(self, raw: str):
        """(text, comments) of a line: the part that holds its code as written, comments
        blanked out in their places (so that a refusal can name a construct as written); None
        for a line that is skipped."""
        s = raw.strip()
        if not s or s[0] == "%":
            return None
        if s[0] == "/":
            if self.block_delete:
                return None
            s = s[1:]
        comments = []
        if ";" in s:
            # a ';' outside a ( ) comment makes the rest of the line a comment
            depth = 0
            for i, c in enumerate(s):
                if c == "(":
                    depth += 1
                elif c == ")":
                    depth -= 1
                elif c == ";" and depth <= 0:
                    s, rest = s[:i], s[i + 1:]
                    break
            else:
                rest = None
        else:
            rest = None
        if "(" in s or ")" in s:
            comments = _COMMENT.findall(s)
            s = _COMMENT.sub(lambda comment: " " * len(comment.group()), s)
            if "(" in s or ")" in s:
                self.refuse("unbalanced or nested '(' comment: close each comment with ')' "
                            "on its line, with no '(' inside", None, raw)
        if rest is not None:
            comments.append(rest)
        return s, comments

    def general(self, raw: str) -> bool:
        """Execute one line word by word (every construct, every error)."""
        prepared = self.prepare(raw, plain=False)
        return self._run_prepared(prepared)

    def _run_prepared(self, prepared) -> bool:
        """Act on a line as :meth:`prepare` classified it: skipped, kept as a comment, a
        settings line, or words to execute (their result)."""
        kind = prepared[0]
        if kind == _SKIP:
            if prepared[1]:
                self.skipped["/"] += 1
            return False
        if kind == _COMMENT:
            self.passthrough.append((self.row, prepared[1]))
            return False
        if kind == _SETTINGS:
            self.evaluate(prepared[1])
            return False
        if kind == _SINUMERIK:
            return self.sinumerik_block(*prepared[1:])
        _, code, traori, trafoof, text, comments = prepared
        words = (self.evaluate(code, text) if needs_macro_reader(code)
                 else self.tokens(code, text))
        return self.execute(words, traori, trafoof, text, comments)

    def tokens(self, code: str, line: str) -> list[tuple[str, float, str, str]]:
        """The words of a line's ``code``; a refusal names what ``line`` holds instead."""
        if "=" in code:
            at = code.find("=")
            self.refuse("'=' sets a parameter only after one (#1 = 5, #<depth> = -2)",
                        _word_at(code, max(at - 1, 0)), line)
        words, pos = [], 0
        for match in _WORD.finditer(code):
            if match.start() != pos:
                break
            number = match.group(2)
            words.append((match.group(1), float(number), number, match.group()))
            pos = match.end()
        if pos != len(code):
            self.refuse(*self.unreadable(line, code, pos, words), line)
        return words

    def unreadable(self, line: str, code: str, pos: int, words) -> tuple[str, str | None]:
        """(message, word) of a line's code that is no word from ``pos`` on (after ``words``):
        a name (``FINISH``, ``OFinal ToolPath``), a letter without its number, a malformed
        number, or another character."""
        char = code[pos]
        if char.isascii() and char.isalpha():
            name = self.name_at(line, code, pos)
            if name is not None:
                return _unknown_name(name), name
            bad = _word_at(code, pos)
            return f"cannot parse number {bad!r}", bad
        if char in "0123456789.+-" and words:
            bad = _word_at(code, pos - len(words[-1][3]))
            return f"cannot parse number {bad!r}", bad
        return f"cannot parse {_word_at(code, pos)!r}", None

    def name_at(self, line: str, code: str, pos: int) -> str | None:
        """The name written in ``line`` where ``code[pos]``, a letter, stands, when more letters
        follow it there (``FINISH``, ``OFinal ToolPath``: a program name after O is the rest
        of the line); None for a letter whose number is missing (``X`` in ``X Y1``), or when
        the code and the text cannot be lined up (a character whose upper case is longer)."""
        text, _ = self.code_as_written(line)
        places = [i for i, c in enumerate(text) if c not in _BLANK_CHARS]
        if "".join(text[i] for i in places).upper() != code:
            return None
        start = places[pos]
        name = _NAME.match(text, start)
        if name is None or len(name.group()) < 2:
            return None
        return text[start:].strip() if text[start] in "oO" else name.group()

    # ------------------------------------------------------------------ parameters
    def evaluate(self, code: str, line: str | None = None) -> list[tuple[str, float, str, str]]:
        """The words of a line with parameters and expressions, evaluated; its parameter
        settings take effect after every value of the line is read (LinuxCNC)."""
        compiled = self.compile(code, line)
        try:
            words = []
            for letter, value, spelled, literal in compiled.words:
                number = value(self)
                if not math.isfinite(number):
                    self.fail(f"value is not finite in {spelled!r}", spelled)
                words.append((letter, number, literal or format_number(number), spelled))
            settings = [(target if not callable(target) else target(self), value(self), text)
                        for target, value, text in compiled.settings]
        except NgcError as exc:
            self.fail(exc.message, exc.word)
        for target, number, text in settings:
            self.set_parameter(target, number, text)
        return words

    def compile(self, code: str, line: str | None = None):
        """The compiled code of a line (once per distinct code); a line that does not compile
        and is another controller's syntax (``line`` as written) is refused as such."""
        compiled = self.compiled.get(code)
        if compiled is None:
            try:
                compiled = compile_line(code)
            except NgcError as exc:
                self.refuse_foreign(line)
                self.fail(exc.message, exc.word)
            self.compiled[code] = compiled
        return compiled

    # the parameter context of compiled expressions (see _ngc)
    def number(self, n: int) -> float:
        system = self.system_parameter(n)
        return self.params[n] if system is None else system

    def named(self, name: str) -> float:
        value = self.named_value(name)
        if value is None:
            if name.startswith(("_HAL[", "_INI[")):
                raise NgcError(f"#<{name.lower()}> reads {'a HAL pin' if name[1] == 'H' else 'the INI file'} "
                               "of a running LinuxCNC, which precontour does not have",
                               f"#<{name}>")
            raise NgcError(f"named parameter #<{name.lower()}> is not defined", f"#<{name}>")
        return value

    def exists(self, name: str) -> bool:
        return self.named_value(name) is not None

    def named_value(self, name: str):
        if name.startswith("_"):
            value = self.predefined(name)
            return self.globals.get(name) if value is None else value
        return self.frames[-1].locals.get(name)

    def set_parameter(self, target, value, text):
        if isinstance(target, str):
            if target.startswith("_"):
                if self.predefined(target) is not None:
                    self.fail(f"#<{target.lower()}> is read-only", text)
                self.globals[target] = value
            else:
                self.frames[-1].locals[target] = value
            return
        if not 1 <= target <= MAX_PARAMETER:
            self.fail(f"parameter #{target} is out of range (#1 ... #{MAX_PARAMETER})", text)
        if self.system_parameter(target) is not None:
            self.fail(f"parameter #{target} is the controller's stored position or offset "
                      "data: set it with G10, G28.1/G30.1 or G92", text)
        self.params[target] = value

    def program_position(self) -> list[float]:
        """The current position in program coordinates and units (work and G92 offsets
        taken off), NaN where not known."""
        scale = INCH if self.inch else 1.0
        return [(p - o - g) / (scale if i < 3 else 1.0)
                for i, (p, o, g) in enumerate(zip(self.prog, self.g5x, self.g92))]

    def system_parameter(self, n: int):
        """LinuxCNC's stored parameters that precontour keeps itself (None for the others):
        5161-5169 G28 and 5181-5189 G30 positions, 5211-5219 the G92 offset, 5220 the work
        offset number, 5221-5409 the work offsets, 5420-5428 the current position."""
        if not 5161 <= n <= 5428:
            return None

        def axis_value(vector, slot):
            # the machine's axis in LinuxCNC's slot (0 for the axes it does not have)
            i = self.axis_index.get(_SLOTS.get(slot))
            return 0.0 if i is None else float(vector[i])

        if 5161 <= n <= 5169 or 5181 <= n <= 5189:
            reference = self.reference.get(280 if n < 5180 else 300) or _ZERO
            return axis_value(reference, (n - 5161) % 20)
        if 5211 <= n <= 5219:
            return axis_value(self.g92, n - 5211)
        if n == 5220:
            return float(WORK_OFFSETS.index(self.work_offset) + 1
                         if self.work_offset in WORK_OFFSETS else 1)
        if 5221 <= n <= 5409:
            k, slot = divmod(n - 5221, 20)
            if slot > 9:
                return None
            if slot == 9:
                return 0.0   # the rotation R (G10 L2 R is refused)
            return axis_value(self.offsets.get(WORK_OFFSETS[k], _ZERO), slot)
        if 5420 <= n <= 5428:
            value = axis_value(self.program_position(), n - 5420)
            return value if math.isfinite(value) else 0.0
        return None

    def predefined(self, name: str):
        """LinuxCNC's predefined named parameters (#<_x>, #<_metric>, ...), None if not one."""
        if len(name) == 2 and name[1] in "XYZABCUVW":
            letter = name[1]
            if letter not in self.axis_index:
                return 0.0
            value = self.program_position()[self.axis_index[letter]]
            return value if math.isfinite(value) else 0.0
        if name == "_VALUE":
            return self.value
        if name == "_VALUE_RETURNED":
            return self.value_returned
        if name == "_LINE":
            return float(self.row)
        if name == "_CALL_LEVEL":
            return float(len(self.frames) - 1)
        flag = {"_METRIC": not self.inch, "_IMPERIAL": self.inch,
                "_ABSOLUTE": not self.incremental, "_INCREMENTAL": self.incremental,
                "_INVERSE_TIME": self.inverse_time, "_UNITS_PER_MINUTE": not self.inverse_time,
                "_TASK": False}.get(name)
        if flag is not None:
            return 1.0 if flag else 0.0
        if name == "_FEED":
            feed = self.feed / (INCH if self.inch else 1.0)
            return feed if math.isfinite(feed) else 0.0
        if name == "_MOTION_MODE":
            return float(-1 if self.motion is None else self.motion * 10)
        if name == "_PLANE":
            return float({(0, 1, 2): 170, (2, 0, 1): 180, (1, 2, 0): 190}[self.plane])
        if name == "_COORD_SYSTEM":
            if self.work_offset not in WORK_OFFSETS:
                return 541.0
            return float(int(round(float(self.work_offset[1:]) * 10)))
        return None

    # ------------------------------------------------------------------ control flow
    def control(self, pc: int, oword: OWord):
        """Execute an O-word line; the index of the next line to run (None: program end)."""
        st = self.structure
        key = oword.keyword
        frame = self.frames[-1]
        if key == "SUB":
            return st.subs[oword.label][1] + 1         # a definition: skip it
        if key in ("ENDSUB", "RETURN"):
            if frame.kind != "sub" or key == "ENDSUB" and frame.name != oword.label:
                self.fail(f"o{oword.label.lower()} {key.lower()} outside a call of "
                          f"o{st.sub_of.get(pc, oword.label).lower()}", oword.text)
            if oword.args:
                self.value, self.value_returned = self.condition(oword, 0), 1.0
            else:
                self.value_returned = 0.0
            return self.leave()
        if key == "CALL":
            return self.call(pc, oword)
        if key in ("IF", "ELSEIF"):
            if key == "ELSEIF":                          # reached from a branch that ran
                return st.branches[pc][1] + 1
            at = pc
            while True:
                line = st.owords[at]
                if line.keyword == "ENDIF":
                    return at + 1
                if line.keyword == "ELSE":
                    return at + 1
                if self.condition(line, 0, at) != 0.0:
                    return at + 1
                at = st.branches[at][0]
        if key == "ELSE":
            return st.branches[pc][1] + 1
        if key == "ENDIF":
            return pc + 1
        kind, first, last = st.loops[pc]
        if key == "WHILE" and kind == "WHILE" or key == "ENDWHILE":
            if self.condition(st.owords[first], 0, first) != 0.0:
                self.iterate(frame, first)
                return first + 1
            frame.iterations.pop(first, None)
            return last + 1
        if key == "DO":
            return pc + 1
        if key == "WHILE":                               # the end of a do-while
            if self.condition(oword, 0) != 0.0:
                self.iterate(frame, first)
                return first + 1
            frame.iterations.pop(first, None)
            return last + 1
        if key == "REPEAT":
            count = self.condition(oword, 0)
            count = round(count) if abs(count - round(count)) <= 1e-4 else math.floor(count)
            if count <= 0:
                return last + 1
            frame.repeats[first] = count
            return pc + 1
        if key == "ENDREPEAT":
            left = frame.repeats.get(first, 1) - 1
            if left > 0:
                frame.repeats[first] = left
                self.iterate(frame, first)
                return first + 1
            frame.repeats.pop(first, None)
            frame.iterations.pop(first, None)
            return last + 1
        if key == "BREAK":
            frame.repeats.pop(first, None)
            frame.iterations.pop(first, None)
            return last + 1
        if key == "CONTINUE":
            # the next iteration: a while or a do-while tests its condition, a repeat counts
            return last if kind != "WHILE" else first
        raise AssertionError(key)  # pragma: no cover - every keyword is handled above

    def condition(self, oword: OWord, k: int, at=None) -> float:
        """The value of the ``k``-th bracket of an O-word line (its condition or count)."""
        if at is not None:
            self.row = at + 1
        if len(oword.args) <= k:
            self.fail(f"o{oword.label.lower()} {oword.keyword.lower()} needs its value in "
                      "[ ]", oword.text)
        try:
            return oword.args[k](self)
        except NgcError as exc:
            self.fail(exc.message, exc.word or oword.text)

    def iterate(self, frame, first):
        count = frame.iterations.get(first, 0) + 1
        if count > MAX_LOOP_ITERATIONS:
            self.row = first + 1
            oword = self.structure.owords[first]
            self.fail(f"o{oword.label.lower()} {oword.keyword.lower()} ran {MAX_LOOP_ITERATIONS} "
                      "times: a runaway loop?", oword.text)
        frame.iterations[first] = count

    def call(self, pc: int, oword: OWord):
        """``oN call [a] [b] ...``: #1, #2, ... are the arguments in the subroutine (the
        caller's #1-#30 come back after it), its named parameters are its own."""
        sub = self.structure.subs.get(oword.label)
        if sub is None:
            name = oword.label.lower()
            where = (f" (LinuxCNC looks for {name[1:-1]}.ngc in its SUBROUTINE_PATH; precontour "
                     "reads one file)" if name.startswith("<") else "")
            self.fail(f"subroutine o{name} is not defined in this file{where}", oword.text)
        if len(oword.args) > 30:
            self.fail("a call passes at most 30 arguments (#1 ... #30)", oword.text)
        try:
            args = [fn(self) for fn in oword.args]
        except NgcError as exc:
            self.fail(exc.message, exc.word or oword.text)
        self.enter(_Frame("sub", oword.label, pc + 1, saved=self.params[1:31]))
        self.params[1:31] = args + [0.0] * (30 - len(args))
        return sub[0] + 1

    def enter(self, frame):
        if len(self.frames) > MAX_CALL_DEPTH:
            self.fail(f"calls nested more than {MAX_CALL_DEPTH} deep: a runaway recursion?")
        self.frames.append(frame)

    def leave(self):
        frame = self.frames.pop()
        if frame.saved is not None:
            self.params[1:31] = frame.saved
        if frame.auto_restore is not None:      # M73 in the subroutine
            self.restore_state(frame.auto_restore)
        return frame.return_pc

    def modal_state(self, m_numbers, m_codes):
        """M70 save the modal state, M71 forget it, M72 restore it, M73 save it and restore
        it when the subroutine returns (LinuxCNC): units, distance modes, feed mode and rate,
        plane, path tolerance."""
        word = next(w for c, w in m_codes if c // 10 in (70, 71, 72, 73))
        if len(m_numbers & {70, 71, 72, 73}) > 1:
            self.fail("two of M70-M73 in one block", word)
        state = (self.inch, self.incremental, self.arc_absolute, self.inverse_time, self.feed,
                 self.plane, self.path_tolerance)
        if 70 in m_numbers:
            self.saved_state = state
        elif 71 in m_numbers:
            self.saved_state = None
        elif 72 in m_numbers:
            if self.saved_state is None:
                self.fail("M72 without a state saved by M70", word)
            self.restore_state(self.saved_state)
        else:
            if self.frames[-1].kind != "sub":
                self.fail("M73 is for a subroutine (it restores the state when it returns)",
                          word)
            self.frames[-1].auto_restore = state

    def restore_state(self, state):
        (self.inch, self.incremental, self.arc_absolute, self.inverse_time, self.feed,
         self.plane, self.path_tolerance) = state

    def subprogram(self, values, spelled, m_word):
        """Fanuc's M98 P<program> L<count> (also P<count><4-digit program>): jump to the
        line ``O<program>``; M99 comes back. Parameters are shared with the caller."""
        if "P" not in values:
            self.fail("M98 needs the subprogram number P", m_word)
        number = values["P"]
        count = values.get("L", 1.0)
        if number != int(number) or number < 0:
            self.fail(f"M98 {spelled['P']}: not a program number", spelled["P"])
        if count != int(count) or count < 0:
            self.fail(f"M98 {spelled['L']}: not a repeat count", spelled["L"])
        number, count = int(number), int(count)
        labels = self.structure.labels
        if number not in labels and number >= 10000 and number % 10000 in labels:
            count, number = number // 10000, number % 10000   # Fanuc: P<count><program>
        if number not in labels:
            self.fail(f"M98: there is no O{number} (its subprogram) in this file",
                      spelled["P"])
        if count == 0:
            return
        self.enter(_Frame("m98", f"O{number}", self.row, locals=self.frames[-1].locals,
                          start=labels[number], left=count))
        self.jump = labels[number] + 1

    def subprogram_return(self, m_word):
        frame = self.frames[-1]
        if frame.kind != "m98":
            self.fail("M99 outside a subprogram: in the main program it would restart it "
                      "without end (Fanuc); end the program with M30", m_word)
        frame.left -= 1
        if frame.left > 0:
            self.jump = frame.start + 1
            return
        self.frames.pop()
        self.jump = frame.return_pc

    def execute(self, words, traori, trafoof, raw, comments) -> bool:
        values: dict[str, float] = {}
        spelled: dict[str, str] = {}
        g_codes: list[tuple[int, str]] = []
        m_codes: list[tuple[int, str]] = []
        for letter, value, _, word in words:
            if letter == "G":
                g_codes.append((int(round(value * 10)), word))
            elif letter == "M":
                m_codes.append((int(round(value * 10)), word))
            elif letter in ("N", "O"):
                continue
            elif letter in values:
                self.fail(f"word {letter} appears twice in the block", word)
            else:
                if not math.isfinite(value):
                    self.fail(f"value is not finite in {word!r}", word)
                values[letter] = value
                spelled[letter] = word
        # G codes: check, then apply the modes in execution order (RS274/NGC).
        seen_groups = {}
        motion_here = None
        for code, word in g_codes:
            if code in _UNSUPPORTED_G:
                self.fail(_UNSUPPORTED_G[code], word)
            if code not in _KNOWN_G and code not in self.tcp_on_g | self.tcp_off_g:
                self.refuse(f"unsupported G code {_g_name(code)}", word, raw)
            for group_index, group in enumerate(_MODAL_GROUPS):
                if code in group:
                    if group_index in seen_groups:
                        self.fail(f"two codes of one modal group ({seen_groups[group_index]}, "
                                  f"{_g_name(code)}) in one block", word)
                    seen_groups[group_index] = _g_name(code)
        codes = {code for code, _ in g_codes}
        g_word = {code: word for code, word in g_codes}
        non_modal = next((code for code in _NON_MODAL if code in codes), None)
        m_numbers = set()
        for code, word in m_codes:
            if code % 10:
                self.refuse(f"unsupported M code {word}", word, raw)
            number = code // 10
            m_numbers.add(number)
            if number in self.tcp_on or number in self.tcp_off:
                switches = [w for c, w in m_codes if c // 10 in self.tcp_on | self.tcp_off]
                if len(switches) > 1:
                    self.fail(f"two TCP switches ({', '.join(switches)}) in one block",
                              switches[1])
            elif number not in _KNOWN_M and number not in self.unknown_m:
                self.unknown_m.add(number)
                self.notices.append(f"{self.source}, line {self.row}: M{number} is not a code "
                                    "precontour knows; kept as a pass-through line")
            self.skipped[f"M{number}"] += 1
        # the words an M code of this block reads (M61 Q, M62-M68 P E L Q, M98 P L)
        m_words = set().union(*(_M_WORDS.get(n, "PQ" if 100 <= n <= 199 else "")
                                for n in m_numbers))
        if m_numbers & {70, 71, 72, 73}:
            self.modal_state(m_numbers, m_codes)
        moves_axes = False
        for letter in spelled:
            if letter in self.axis_index or letter in "@^":
                moves_axes = True
            elif (letter not in "FIJKRPQL" and letter not in _PASSTHROUGH_WORDS
                  and letter not in m_words):
                self.refuse(f"unsupported word {spelled[letter]!r} (axes are "
                            f"{' '.join(self.axes)})", spelled[letter], raw)
        if 541 in codes and "P" not in spelled:
            self.fail("G54.1 needs the number of its work offset, P1 ... P300", g_word[541])
        if "L" in spelled and not (100 in codes or "L" in m_words or self.motion in _CYCLES
                                   or any(_MOTION.get(c) in _CYCLES for c in codes)):
            self.fail(f"unsupported word {spelled['L']!r} (L is read with G10, canned cycles, "
                      "M98)", spelled["L"])
        if "E" in spelled and "E" not in m_words:
            self.fail(f"unsupported word {spelled['E']!r} (E is read with M66-M68)",
                      spelled["E"])
        if non_modal in _AXIS_WORD_CODES and moves_axes and any(
                code in _MOTION for code in codes):
            motion_word = next(g_word[c] for c in codes if c in _MOTION)
            self.fail(f"{_g_name(non_modal)} and {motion_word} both use the axis words of the "
                      "block", motion_word)
        kept = []  # words an output program keeps, as written, in their order
        for letter, value, number, _ in words:
            if letter == "G":
                code = int(round(value * 10))
                if code in PASSTHROUGH_G:
                    kept.append(letter + number)
                    self.skipped[_g_name(code)] += 1
            elif letter == "M" and int(round(value)) in self.tcp_on | self.tcp_off | _FLOW_M:
                continue  # interpreted, not kept (TCP switches as G43.4; subprograms; state)
            elif letter == "M" or letter in _PASSTHROUGH_WORDS or letter in m_words:
                if letter != "M":
                    self.skipped[letter] += 1
                # H goes with G43; with G43.4/G43.5 (TCP, not kept) it would stand alone
                if letter != "H" or 430 in codes or 432 in codes:
                    kept.append(letter + number)
            elif letter in self.axis_index and codes & _TOOL_LENGTH_WORDS:
                kept.append(letter + number)
        # a line with parameters or expressions is kept with its values
        evaluated = any(spelled != letter + number for letter, _, number, spelled in words)

        # RS274/NGC's order: feed mode, F (in the units before this block's G20/G21), ...
        if 930 in codes:
            self.inverse_time = True
        if 940 in codes:
            self.inverse_time = False
            self.feed = math.nan
        f_word = self.block_f = values.get("F")
        if f_word is not None:
            if not f_word > 0:
                self.fail(f"feed must be positive, got {spelled['F']}", spelled["F"])
            if not self.inverse_time:
                self.feed = f_word * (INCH if self.inch else 1.0)
        # ... then units
        if 200 in codes:
            self.inch = True
        if 210 in codes:
            self.inch = False
        scale = INCH if self.inch else 1.0
        dwell = 40 in codes
        for code in (170, 180, 190):
            if code in codes:
                self.plane = _PLANES[code]
        # the site's M codes (LinuxCNC's remapped M428/M429, modal group 10) act before the
        # tool length codes G43.4/G43.5/G49 in RS274/NGC's order of execution
        m_switch = m_numbers & (self.tcp_on | self.tcp_off)
        if m_switch & self.tcp_on:
            self.tcp_sources.add("M")
        if m_switch & self.tcp_off:
            self.tcp_sources.clear()
        # the site's G codes (the machine file's tcp_on/tcp_off) act like its M codes
        g_switch = codes & (self.tcp_on_g | self.tcp_off_g)
        if g_switch & self.tcp_on_g:
            self.tcp_sources.add("M")
        if g_switch & self.tcp_off_g:
            self.tcp_sources.clear()
        self.tool_change(values, spelled, m_numbers)
        self.haas_modes(codes, g_word, values, spelled)
        if codes & _LENGTH_G:
            self.select_length(values, spelled, g_word[min(codes & _LENGTH_G)])
        if 434 in codes or 435 in codes:
            self.tcp_sources.add("G43.4")
        if 490 in codes:
            self.tcp_sources.discard("G43.4")
            self.tcp_sources.discard("G234")
        if traori:
            self.tcp_sources.add("TRAORI")
        if trafoof:
            self.tcp_sources.discard("TRAORI")
        if self.tilt is not None and (m_switch or traori or trafoof or 434 in codes
                                      or 435 in codes):
            self.fail("a TCP switch with G68.2 or CYCLE800 active: cancel it with G69 or "
                      "CYCLE800() first",
                      next((w for c, w in m_codes if c // 10 in m_switch), None)
                      or g_word.get(434) or g_word.get(435))
        self.set_tcp(bool(self.tcp_sources))
        if 490 in codes:
            self.set_length(math.nan)     # after the switch: G49 ends TCP at the old length
        if self.tilt is not None and (non_modal in (100, 280, 300, 920, 921, 922, 923)
                                      or non_modal == 530 and not self.supa
                                      or set(_WORK_OFFSET_G) & codes):
            code = non_modal if non_modal in g_word else min(set(_WORK_OFFSET_G) & codes)
            self.fail(f"{_g_name(code)} with G68.2 active: cancel it with G69 first",
                      g_word[code])
        for code in _WORK_OFFSET_G:
            if code in codes:
                self.select_work_offset(code, values, spelled)
        if 640 in codes:
            self.path_tolerance = values["P"] * scale if "P" in values else math.nan
        if 610 in codes or 611 in codes:
            self.path_tolerance = 0.0
        if 900 in codes:
            self.incremental = False
        if 910 in codes:
            self.incremental = True
        if 901 in codes:
            self.arc_absolute = True
        if 911 in codes:
            self.arc_absolute = False
        previous_motion = self.motion
        if 800 in codes:
            self.motion = None            # G80: no motion mode (the cycles end)
            self.cycle_start = None
            self.cancelled = True
        for code in codes:
            if code in _MOTION:
                motion_here = _MOTION[code]
        if motion_here is not None:
            self.motion = motion_here
            if motion_here not in _CYCLES:
                self.cycle_start = None   # the next cycle's G98 height is taken anew
        if 980 in codes:
            self.retract_initial = True
        if 990 in codes:
            self.retract_initial = False

        # word checks that depend on the codes
        arc_words = [spelled[k] for k in ("IJK" if 100 in codes else "IJKR") if k in spelled]
        if codes & _TILT_G:
            if any(code in _MOTION for code in codes) or non_modal is not None:
                self.fail("G68.2, G53.1 and G69 take a block of their own",
                          g_word[min(codes & _TILT_G)])
            self.tilted_plane(codes, values, spelled, scale, g_word)
            moves_axes = False     # G68.2's X Y Z are its origin
            arc_words = []
        elif self.tilt is not None and moves_axes:
            rotary = [spelled[a] for a in self.axes[3:] if a in spelled]
            if rotary:
                self.fail(f"rotary axis word {rotary[0]!r} with G68.2 active: G53.1 turns the "
                          "rotary axes to the plane", rotary[0])
        if codes & _TOOL_LENGTH_WORDS:
            if any(code in _MOTION for code in codes) and moves_axes:
                word = g_word[min(codes & _TOOL_LENGTH_WORDS)]
                self.fail(f"{word} and a motion both use the axis words of the block", word)
            moves_axes = False    # the words are the tool length offset (not applied)
        centre_only = not moves_axes and any(k in spelled for k in "IJK")
        is_cycle = (self.motion in _CYCLES and (moves_axes or motion_here in _CYCLES)
                    and non_modal is None)
        cycle_words = _CYCLE_WORDS[self.motion] if is_cycle else ""
        is_arc = (self.motion in (2, 3) and (moves_axes or motion_here in (2, 3) or centre_only)
                  and (non_modal is None or dwell and motion_here is not None))
        if dwell and is_arc and "P" in spelled:
            self.fail("G4 P and an arc's turns P in one block", spelled["P"])
        arc_words = [w for w in arc_words if w[0] not in cycle_words]
        if arc_words and not is_arc:
            self.fail(f"word {arc_words[0]!r} is read only with G2/G3"
                      + (" and G87" if arc_words[0][0] in "IJK" else " and canned cycles"),
                      arc_words[0])
        p_readers = (dwell or 640 in codes or is_arc or 541 in codes or 100 in codes
                     or "P" in cycle_words or 682 in codes)
        if "P" in spelled and not (p_readers or "P" in m_words):
            self.fail(f"unsupported word {spelled['P']!r} (P is read with G4, G10, G54.1, "
                      "G64, G2/G3, G82/G86/G89, M62-M66)", spelled["P"])
        if "Q" in spelled and not (640 in codes or "Q" in m_words or "Q" in cycle_words):
            self.fail(f"unsupported word {spelled['Q']!r} (Q is read with G64, G73/G83, M61, "
                      "M66-M68)", spelled["Q"])

        if dwell:
            # RS274/NGC: the dwell before the block's motion; with a motion code the axis
            # words are that motion's, else Fanuc's X is the time
            seconds = values.get("P")
            if motion_here is None:
                if seconds is None:
                    seconds = values.get("X")
                extra = [spelled[a] for a in self.axes if a in spelled and a != "X"]
                if "P" in values and "X" in values:
                    extra.insert(0, spelled["X"])
                if extra:
                    self.fail(f"axis word {extra[0]!r} in a dwell (G4) block", extra[0])
            if seconds is None or not seconds >= 0:
                self.fail("dwell (G4) needs a time P (seconds) >= 0", g_word[40])
            self.stops.append(Stop(self.n_moves, self.row, "dwell", float(seconds)))
            if motion_here is not None and moves_axes:
                self.move(values, spelled, scale, g_codes)
        elif non_modal in (280, 300):
            self.reference_return(non_modal, values, spelled, scale, g_word[non_modal])
        elif non_modal in (281, 301):
            self.store_reference(non_modal, g_word[non_modal])
        elif non_modal == 100:
            self.set_work_offset(values, spelled, scale, g_word[100])
        elif non_modal in (920, 921, 922, 923):
            self.axis_offsets(non_modal, values, spelled, scale, g_word[non_modal])
        elif non_modal == 530:
            if self.motion not in (0, 1):
                self.fail("G53 (move in machine coordinates) needs G0 or G1", g_word[530])
            if self.incremental and moves_axes and not self.said_g53_incremental:
                # LinuxCNC refuses G53 under G91; Haas (and posts for it: NX writes G91 G28
                # Z0. then G53 G00 Z0.) moves to the machine position the words give
                self.said_g53_incremental = True
                self.notices.append(f"{self.source}, line {self.row}: G53 under G91: its axis "
                                    "words are taken as machine positions (absolute), as a "
                                    "Haas control moves; LinuxCNC refuses G53 under G91")
            if moves_axes:
                self.machine_move(self.motion == 0, values, spelled, scale)
        elif is_cycle:
            if self.dwo_base is not None:
                self.dwo_origin(spelled)
            self.cycle(values, spelled, scale, previous_motion, g_word)
        elif moves_axes or is_arc and centre_only:
            if self.dwo_base is not None:
                self.dwo_origin(spelled)
            # (G2/G3 with a centre and no axis words: a full circle, as in LinuxCNC)
            self.move(values, spelled, scale, g_codes)

        end = False
        for code, word in m_codes:
            kind = _STOP_M.get(code // 10)
            if kind is not None:
                self.stops.append(Stop(self.n_moves, self.row, kind))
                end = end or kind == "end"
        if 98 in m_numbers and 99 in m_numbers:
            self.fail("M98 and M99 in one block", spelled.get("P"))
        if 98 in m_numbers:
            self.subprogram(values, spelled, next(w for c, w in m_codes if c == 980))
        elif 99 in m_numbers:
            self.subprogram_return(next(w for c, w in m_codes if c == 990))
        if kept or comments:
            motion_words = moves_axes or dwell or "F" in spelled or any(
                code not in PASSTHROUGH_G for code in codes) or traori or trafoof or m_switch \
                or evaluated
            if motion_words:
                text = " ".join(kept + [f"({c.strip()})" for c in comments if c.strip()])
            else:
                text = raw
            if text:
                self.passthrough.append((self.row, text))
        return end

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

    # ------------------------------------------------------------------ coordinates
    def convert(self, pos, from_tcp: bool, to_tcp: bool) -> list[float]:
        """A complete position (mm, deg) from one frame to the other: the tool tip in the
        workpiece frame (TCP) or the machine axes."""
        if from_tcp == to_tcp:
            return list(pos)
        q = np.array(pos, dtype=float)
        q[3:] = np.radians(q[3:])
        if from_tcp:
            xyz = self.kinematics.linear_axes(q[None, :3], q[None, 3:])
        else:
            xyz, _ = self.kinematics.forward(q[None, :])
        return [*map(float, np.asarray(xyz).reshape(3)), *pos[3:]]

    def set_tcp(self, on: bool):
        if on == self.tcp:
            return
        if all(math.isfinite(v) for v in self.prog):
            self.prog = self.from_workpiece(self.convert(self.to_workpiece(self.prog),
                                                         self.tcp, on))
        else:
            # the linear axes' meaning changes; they follow from this partial position once
            # the unknown axes are taken as 0 (see resolve)
            self.deferred.append((list(self.prog), self.tcp))
            self.prog = [math.nan] * 3 + self.prog[3:]
        self.tcp = on

    def resolve(self, target=None):
        """Take the axes never programmed as 0 (before the first feed move): in the frame they
        were unknown in, carried through the TCP switches since; one notice names them."""
        chain = self.deferred + [(list(self.prog), self.tcp)]
        first = chain[0][0]
        missing = [self.axes[i] for i in range(5) if not math.isfinite(first[i])]
        full = [0.0 if not math.isfinite(v) else v for v in first]
        for (_, frame), (pos, next_frame) in zip(chain[:-1], chain[1:]):
            full = self.convert(full, frame, next_frame)
            full = [v if math.isfinite(v) else f for v, f in zip(pos, full)]
        self.deferred = []
        if missing:
            self.notices.append(f"{self.source}, line {self.row}: axes {' '.join(missing)} "
                                "were not programmed before the first feed move; taken as 0")
        self.prog = list(full)
        if target is not None:
            target = [t if math.isfinite(t) else r for t, r in zip(target, full)]
        return target

    def machine_axes(self, prog: np.ndarray, tcp: np.ndarray, length: np.ndarray
                     ) -> np.ndarray:
        """Machine axes (mm, rad) of programmed coordinates (mm, deg) in either mode; TCP
        tips through the kinematics of each move's tool length (NaN: the file's)."""
        q = np.array(prog, dtype=float)
        q[:, 3:] = np.radians(q[:, 3:])
        if tcp.any():
            key = np.where(np.isnan(length), -np.inf, length)
            for value in np.unique(key[tcp]):
                rows = tcp & (key == value)
                kinematics = self.kinematics_of(math.nan if value == -np.inf else value)
                q[rows, :3] = kinematics.linear_axes(q[rows, :3], q[rows, 3:])
        return q

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

    # ------------------------------------------------------------------ motion
    def target(self, values, spelled, scale):
        """The end point of the block's axis words (absolute coordinates, mm and deg): G90
        words are in the work coordinates (work offset and G92 offset added), G91 words add
        to the position; an axis without a word stays."""
        target = list(self.prog)
        for i, letter in enumerate(self.axes):
            if letter in values:
                value = values[letter] * (scale if i < 3 else 1.0)
                if self.incremental:
                    if not math.isfinite(target[i]):
                        if value == 0.0:
                            continue  # no motion on an axis not known yet (G91 G28 Z0)
                        self.fail(f"incremental (G91) move of axis {letter} before its "
                                  "position is known", spelled[letter])
                    value += target[i]
                else:
                    value += self.g5x[i] + self.g92[i]
                if not abs(value) <= MAX_COORDINATE:
                    self.fail(f"coordinate {spelled[letter]!r} is out of range", spelled[letter])
                target[i] = value
        if "@" in values or "^" in values:
            target[0], target[1] = self.polar(values, spelled, scale)
        return target

    def polar(self, values, spelled, scale):
        """LinuxCNC's polar coordinates: X Y from a radius @ and an angle ^ (degrees) about
        the work origin, in any plane; G91 adds them to the current radius and angle."""
        word = spelled.get("@", spelled.get("^"))
        if "X" in values or "Y" in values:
            self.fail("polar coordinates (@ ^) and X or Y in one block", word)
        x, y = self.program_position()[:2]
        if not (math.isfinite(x) and math.isfinite(y)):
            self.fail("polar coordinates (@ ^) before the X and Y position is known", word)
        radius, angle = math.hypot(x, y), math.degrees(math.atan2(y, x))
        if self.incremental:
            radius += values.get("@", 0.0)
            angle += values.get("^", 0.0)
        else:
            radius = values.get("@", radius)
            angle = values.get("^", angle)
        angle = math.radians(angle)
        return (radius * math.cos(angle) * scale + self.g5x[0] + self.g92[0],
                radius * math.sin(angle) * scale + self.g5x[1] + self.g92[1])

    def tilted_plane(self, codes, values, spelled, scale, g_word):
        """Fanuc's tilted working plane. ``G68.2 X Y Z I J K``: the program's coordinates are
        those of a frame with its origin at X Y Z (work coordinates) turned by the Euler
        angles I, J, K (degrees; about Z, then the new X, then the new Z); its moves are tool
        tip positions (as in TCP mode) with the rotary axes where they stand. ``G53.1``: the
        rotary axes turn (a rapid in joint space) until the tool is along the frame's +Z
        (:func:`._swivel.swivel`: the solution within travel, of two the one whose C is
        nearest where it stands). ``G69``: back to the work coordinates."""
        if 682 in codes:
            word = g_word[682]
            if values.get("P", 0.0) != 0.0:
                self.fail(f"G68.2 {spelled['P']}: only the Euler-angle form (P0: I J K about "
                          "Z, X, Z) is supported", spelled["P"])
            extra = [spelled[a] for a in self.axes[3:] if a in spelled]
            if extra:
                self.fail(f"axis word {extra[0]!r} in a G68.2 block", extra[0])
            origin = [values.get(a, 0.0) * scale for a in self.axes[:3]]
            rotation = _euler_zxz(values.get("I", 0.0), values.get("J", 0.0),
                                  values.get("K", 0.0))
            self.enter_tilt(origin, rotation, word, "G68.2")
        if 531 in codes:
            word = g_word[531]
            if self.tilt is None:
                self.fail("G53.1 needs a tilted working plane (G68.2)", word)
            self.align_tool(word)
        if 690 in codes:
            self.leave_tilt()

    def enter_tilt(self, origin, rotation, word, name, cancel="G69"):
        """A tilted working plane (G68.2, CYCLE800): its ``origin`` (work coordinates, mm)
        and ``rotation`` (columns: the plane's axes); the position becomes the tool tip in
        the plane's frame."""
        if self.tilt is not None:
            self.fail(f"{name} again before {cancel} (a tilted plane on a tilted plane is "
                      "not supported)", word)
        if self.tcp_sources:
            self.fail(f"{name} in TCP mode is not supported", word)
        known = all(math.isfinite(v) for v in self.prog)
        if not known and (name == "G68.2" or self.start is not None):
            self.fail(f"{name} before the position of every axis is known", word)
        origin = np.add(origin, np.add(self.g5x, self.g92)[:3])
        self.tcp_sources.add("G68.2")
        if known:
            self.set_tcp(True)                   # the position as a tool tip
            tip = np.array(self.prog[:3])
            self.prog = [*map(float, (tip - origin) @ rotation), *self.prog[3:]]
        else:
            # before the first move (a swivel after the tool change): the tip in the plane
            # becomes known from the plane's moves
            self.tcp, self.deferred = True, []
            self.prog = [math.nan] * 3 + self.prog[3:]
        self.tilt = (origin, rotation)
        self.tilt_offsets = (self.g5x, self.g92)
        self.g5x, self.g92 = list(_ZERO), list(_ZERO)   # in the frame's origin now

    def align_tool(self, word, prefer=0):
        """G53.1 (and CYCLE800's swivel): the rotary axes turn, a rapid in joint space, until
        the tool is along the plane's +Z; of the two branches the one within travel (then
        ``prefer``, see :func:`._swivel.swivel`), said when the preferred one is not."""
        origin, rotation = self.tilt
        tip = origin + rotation @ np.array(self.prog[:3])
        current = np.radians(self.prog[3:])
        known = np.isfinite(tip).all() and np.isfinite(current).all()
        chosen = swivel(self.kinematics, np.nan_to_num(tip), rotation[:, 2],
                        np.nan_to_num(current), prefer)
        if chosen.passed_over is not None:
            a, c = self.axes[3:]
            (pa, pc), (ca, cc) = np.degrees(chosen.passed_over), np.degrees(chosen.rotary)
            low, high = np.degrees(rotary_travel(self.kinematics)[0])
            self.notices.append(
                f"{self.source}, line {self.row}: {word}: {a}{pa:.6g} {c}{pc:.6g} is outside "
                f"the travel ({a} [{low:g}, {high:g}] deg); the other solution {a}{ca:.6g} "
                f"{c}{cc:.6g} turns the tool onto the same plane")
        if not known:
            # before the first move: the axes are where the plane's first moves put them
            self.prog = self.prog[:3] + [*map(math.degrees, chosen.rotary)]
            return
        linear = self.kinematics.linear_axes(tip[None, :], current[None, :])[0]
        target = [*map(float, linear), *map(math.degrees, chosen.rotary)]
        if self.start is not None:
            self.add(target, True, math.nan, math.nan, tcp=False)
        new_tip, _ = self.kinematics.forward(np.array([*target[:3],
                                                       *np.radians(target[3:])]))
        self.prog = [*map(float, (np.asarray(new_tip).reshape(3) - origin) @ rotation),
                     *target[3:]]

    def leave_tilt(self):
        """G69 (CYCLE800()): back to the work coordinates."""
        if self.tilt is None:
            return
        origin, rotation = self.tilt
        tip = origin + rotation @ np.array(self.prog[:3])
        self.prog = [*map(float, tip), *self.prog[3:]]
        self.g5x, self.g92 = self.tilt_offsets
        self.tilt = None
        self.tcp_sources.discard("G68.2")
        self.set_tcp(bool(self.tcp_sources))

    def cycle(self, values, spelled, scale, previous, g_word):
        """A canned-cycle block (G73, G81-G83, G85-G87, G89), expanded into moves as LinuxCNC
        does (:mod:`._cycles`): the hole at the block's X Y (G91: every repeat L moves by
        them), R the retract plane, the bottom on the plane's normal axis; R, the bottom, P,
        Q, I J K carry over while the same cycle continues."""
        code = self.motion
        word = g_word.get(next((c for c in g_word if _MOTION.get(c) == code), None),
                          f"G{code}")
        a, b, n = self.plane
        axis, first, second = self.axes[n], self.axes[a], self.axes[b]
        if self.inverse_time:
            self.fail("canned cycles need feed per minute (G94), not inverse time (G93)", word)
        if not math.isfinite(self.feed):
            self.fail("canned cycle without a feed rate: program F (G94, per minute)", word)
        if "G43.4" in self.tcp_sources:
            self.fail("canned cycles under G43.4/G43.5 (tool centre point) are not supported",
                      word)
        rotary = [spelled[a] for a in self.axes[3:] if a in spelled]
        if rotary:
            self.fail(f"the rotary axes may not move in a canned cycle ({rotary[0]})", rotary[0])
        polar = "@" in values or "^" in values
        if polar and self.plane != _PLANES[170]:
            self.fail("polar coordinates (@ ^) in a canned cycle need the XY plane (G17)",
                      spelled.get("@", spelled.get("^")))
        same = previous == code
        sticky = self.cycle_words if same else {}
        given = dict(sticky)
        for letter, key in (("R", "R"), (axis, "Z"), ("P", "P"), ("Q", "Q"), ("I", "I"),
                            ("J", "J"), ("K", "K")):
            if letter in values:
                given[key] = values[letter]
        needs = {"R": "R (the retract plane)", "Z": f"{axis} (the bottom)"}
        if code in (82, 86, 89):
            needs["P"] = "P (the dwell, s)"
        if code in (73, 83):
            needs["Q"] = "Q (the peck depth)"
        if code == 87:
            needs.update(I="I", J="J", K="K")
        for key, what in needs.items():
            if key not in given:
                self.fail(f"G{code} needs {what} when the cycle begins", word)
        repeats = values.get("L", 1.0)
        if repeats != int(repeats) or repeats < 1:
            self.fail(f"canned cycle repeats {spelled.get('L')!r} must be a whole number >= 1 "
                      "(LinuxCNC refuses L0)", spelled.get("L", word))
        if code in (73, 83) and not given["Q"] > 0:
            self.fail(f"G{code} needs a peck depth Q > 0", spelled.get("Q", word))
        if code in (82, 86, 89) and not given["P"] >= 0:
            self.fail(f"G{code} needs a dwell P >= 0", spelled.get("P", word))
        current = list(self.prog)
        unknown = [self.axes[i] for i in (a, b, n) if not math.isfinite(current[i])]
        if unknown:
            self.fail(f"canned cycle before the position of axis {unknown[0]} is known", word)
        offset = [o + g for o, g in zip(self.g5x, self.g92)]
        height = current[n]
        if self.cycle_start is None:
            self.cycle_start = height
        initial = self.cycle_start
        if self.incremental:
            r = given["R"] * scale + initial
            bottom = r + given["Z"] * scale
        else:
            r = given["R"] * scale + offset[n]
            bottom = given["Z"] * scale + offset[n]
        if r < bottom:
            self.fail(f"the retract plane R is below the bottom {axis} of the cycle", word)
        holes = self.cycle_holes(values, spelled, scale, int(repeats), first, second, a, b,
                                 offset)
        if initial < r:
            # the preliminary move: up to R where the cycles begin below it
            up = list(current)
            up[n] = r
            self.go(up, True, spelled)
            current, initial, height = up, r, r
        clear = initial if self.retract_initial else r
        back_bore = None
        if code == 87:
            top = given["K"] * scale + (bottom if self.incremental else offset[n])
            back_bore = (given["I"] * scale, given["J"] * scale, top)
        peck_clearance = PECK_CLEARANCE_INCH * INCH
        moves = cycle_moves(code, self.plane, current, holes, r=r, bottom=bottom, clear=clear,
                            current=height, dwell=given.get("P", 0.0),
                            peck=given.get("Q", 0.0) * scale, peck_clearance=peck_clearance,
                            back_bore=back_bore)
        for kind, point in moves:
            if kind == "dwell":
                self.stops.append(Stop(self.n_moves, self.row, "dwell", float(point)))
                continue
            # the other axes where they are (a first feed move may just have made them known)
            target = list(self.prog)
            for i in (a, b, n):
                target[i] = point[i]
            self.go(target, kind == "rapid", spelled)
        self.cycle_words = {k: v for k, v in given.items() if k in "RZPQIJK"}

    def cycle_holes(self, values, spelled, scale, repeats, first, second, a, b, offset):
        """The hole of each repeat in the plane (absolute): G90 at the words (or where the
        axes are), G91 the words added once per repeat; polar @ ^ about the work origin."""
        x, y = self.prog[a], self.prog[b]
        if "@" in values or "^" in values:
            # in program coordinates (the work origin), as LinuxCNC's CYCLE_MACRO
            px, py = (x - offset[a]) / scale, (y - offset[b]) / scale
            holes = []
            if not self.incremental:
                radius = values.get("@", math.hypot(px, py))
                theta = math.radians(values["^"]) if "^" in values else math.atan2(py, px)
                px, py = radius * math.cos(theta), radius * math.sin(theta)
                holes = [(px, py)] * repeats
            else:
                for _ in range(repeats):
                    if px == 0.0 and py == 0.0:
                        self.fail("incremental polar coordinates at the origin have no "
                                  "direction", spelled.get("@", spelled.get("^")))
                    if "@" in values:
                        radius = math.hypot(px, py) + values["@"]
                        theta = math.atan2(py, px)
                        px, py = radius * math.cos(theta), radius * math.sin(theta)
                    if "^" in values:
                        radius = math.hypot(px, py)
                        theta = math.atan2(py, px) + math.radians(values["^"])
                        px, py = radius * math.cos(theta), radius * math.sin(theta)
                    holes.append((px, py))
            return [(hx * scale + offset[a], hy * scale + offset[b]) for hx, hy in holes]
        if not self.incremental:
            x = values[first] * scale + offset[a] if first in values else x
            y = values[second] * scale + offset[b] if second in values else y
            return [(x, y)] * repeats
        dx = values.get(first, 0.0) * scale
        dy = values.get(second, 0.0) * scale
        return [(x + dx * (k + 1), y + dy * (k + 1)) for k in range(repeats)]

    def move(self, values, spelled, scale, g_codes):
        if self.motion is None:
            word = next((spelled[a] for a in self.axes if a in spelled), None)
            if self.cancelled:
                self.fail("axis words after G80 without a motion code (G0, G1, G2, G3)", word)
            self.fail("axis words before any motion code (G0, G1, G2, G3)", word)
        target = self.target(values, spelled, scale)
        arc = self.motion in (2, 3)
        if self.start is None:
            target = self.first_move(target, self.motion == 0, arc, g_codes)
            if target is None:
                return
        if arc:
            self.arc(target, values, spelled, scale)
        else:
            self.go(target, self.motion == 0, spelled)

    def first_move(self, target, rapid, arc=False, g_codes=()):
        """Before the start: None where the move only positions (a rapid, or the block that
        completes the axes: the machine starts from its end), else the target of the first
        feed move with the axes not known yet taken as 0."""
        if all(math.isfinite(v) for v in target):
            if arc:
                self.fail("the first block that sets all axes is an arc: its start point is "
                          "unknown; position with G0 first", g_codes[0][1] if g_codes else None)
            self.prog = list(target)
            self.deferred = []
            self.begin(self.row)
            return None
        if rapid:
            self.prog = list(target)
            return None
        target = self.resolve(target)
        self.begin(self.row)
        return target

    def go(self, target, rapid, spelled):
        """A straight move to ``target`` (absolute coordinates in the current mode)."""
        if self.start is None:
            target = self.first_move(target, rapid)
            if target is None:
                return
        duration, feed = math.nan, math.nan
        if not rapid:
            duration, feed = self.timing(self.prog, target, 1, spelled)
        self.add(target, rapid, duration, feed)

    def begin(self, row):
        self.start = list(self.to_workpiece(self.prog)) if self.framed else list(self.prog)
        self.start_line = row
        self.start_tcp = self.tcp
        self.start_length = self.length

    def timing(self, start, end, n_pieces, spelled, length=None):
        """(duration s, feed mm/s) of each of ``n_pieces`` equal pieces of a feed move."""
        if self.inverse_time:
            if "F" not in spelled:
                self.fail("inverse-time feed (G93) needs F on every G1/G2/G3 block", "F")
            return 60.0 / self.block_f / n_pieces, math.nan
        if not math.isfinite(self.feed):
            self.fail("feed move without a feed rate: program F (G94, per minute)",
                      f"G{self.motion}")
        if length is None:
            length = math.dist(start[:3], end[:3])
        if length <= 0.0:
            length = math.dist(start[3:], end[3:])  # rotary only: F in degrees per minute
        return 60.0 * length / self.feed / n_pieces, self.feed / 60.0

    def programmed_feed(self, rapid):
        """F as programmed for a move: mm/min in G94, 1/min in G93, NaN for a rapid."""
        if rapid:
            return math.nan
        return self.block_f if self.inverse_time else self.feed

    @property
    def framed(self) -> bool:
        """A frame turns or shifts the program's coordinates (G68.2, CYCLE800, Sinumerik's
        TRANS/ROT/ATRANS/AROT)."""
        return self.tilt is not None or self.pframe is not None

    def to_workpiece(self, points):
        """Points in the program's coordinates -> the coordinates of the current mode: the
        programmable frame (Sinumerik's TRANS/ROT ...) applied, then the tilted plane's
        (G68.2, CYCLE800: to the workpiece frame, the tool tip as a TCP move); without either,
        the points themselves."""
        if not self.framed:
            return points
        points = np.array(points, dtype=float)
        for frame in (self.pframe, self.tilt):
            if frame is not None:
                origin, rotation = frame
                points[..., :3] = origin + points[..., :3] @ rotation.T
        return points

    def from_workpiece(self, position):
        """The inverse of :meth:`to_workpiece` for one position."""
        position = list(position)
        for frame in (self.tilt, self.pframe):
            if frame is not None:
                origin, rotation = frame
                position[:3] = map(float, (np.array(position[:3]) - origin) @ rotation)
        return position

    def add(self, target, rapid, duration, feed, tcp=None):
        # machine axes (tcp given: G53, G53.1) are no program coordinates
        end = self.to_workpiece(target).tolist() if tcp is None and self.framed \
            else list(target)
        tcp = self.tcp if tcp is None else tcp
        self.programmed.append((0 if rapid else 1, end, _NO_CENTRE, 0, 0,
                                self.inverse_time, self.programmed_feed(rapid), self.row, tcp,
                                self.n_moves))
        self.moves.append((end, rapid, duration, feed, self.row, tcp, self.path_tolerance,
                           self.length))
        self.prog = list(target)
        self.n_moves += 1

    def add_many(self, ends, rapid, duration, feed, lines, programmed):
        """Append k moves at once (arrays of k rows; scalars are broadcast), with their
        programmed moves (the columns of :attr:`programmed`, or one arc's row)."""
        k = ends.shape[0]
        self.prog = ends[-1].tolist()
        if self.framed:
            ends = self.to_workpiece(ends)
            if isinstance(programmed, tuple) and not isinstance(programmed[0], np.ndarray):
                # an arc: its end, and its centre as a point (all three axes) of the plane
                kind, end, centre, *rest = programmed
                programmed = (kind, self.to_workpiece(end).tolist(),
                              self.to_workpiece(centre).tolist(), *rest)
            else:
                programmed = (programmed[0], ends, *programmed[2:])
        self.moves.extend((np.asarray(ends, dtype=float),
                           np.broadcast_to(np.asarray(rapid, dtype=bool), (k,)),
                           np.broadcast_to(np.asarray(duration, dtype=float), (k,)),
                           np.broadcast_to(np.asarray(feed, dtype=float), (k,)),
                           np.broadcast_to(np.asarray(lines, dtype=np.int64), (k,)),
                           np.full(k, self.tcp), np.full(k, self.path_tolerance),
                           np.full(k, self.length)))
        if isinstance(programmed, tuple) and not isinstance(programmed[0], np.ndarray):
            self.programmed.append(programmed)
        else:
            self.programmed.extend(programmed)
        self.n_moves += k

    def arc(self, target, values, spelled, scale):
        a, b, n = self.plane
        centre_words = ("IJK"[a], "IJK"[b])
        start = self.prog
        sa, sb, ea, eb = start[a], start[b], target[a], target[b]
        if "R" in values:
            if any(w in spelled for w in "IJK"):
                self.fail("an arc is given by R or by I J K, not both", spelled["R"])
            radius = values["R"] * scale
            chord = math.hypot(ea - sa, eb - sb)
            if chord == 0.0:
                self.fail("an R arc cannot be a full circle (start = end); use I J K",
                          spelled["R"])
            h2 = radius * radius - 0.25 * chord * chord
            if h2 < 0.0:
                if 0.5 * chord - abs(radius) > max(ARC_RADIUS_TOLERANCE,
                                                   ARC_RADIUS_RTOL * abs(radius)):
                    self.fail(f"arc radius {abs(radius):g} mm is shorter than half the chord "
                              f"({0.5 * chord:g} mm)", spelled["R"])
                h2 = 0.0
            h = math.sqrt(h2) / chord
            # centre on the left of the chord for a counter-clockwise short arc
            side = (1.0 if self.motion == 3 else -1.0) * (1.0 if radius > 0 else -1.0)
            ca = 0.5 * (sa + ea) - side * h * (eb - sb)
            cb = 0.5 * (sb + eb) + side * h * (ea - sa)
        else:
            offsets = [values.get(w) for w in centre_words]
            if offsets[0] is None and offsets[1] is None:
                self.fail(f"arc without centre: G{self.motion} in this plane needs "
                          f"{centre_words[0]}/{centre_words[1]} or R",
                          f"G{self.motion}")
            oa, ob = ((o or 0.0) * scale for o in offsets)
            ca, cb = (oa, ob) if self.arc_absolute else (sa + oa, sb + ob)
            normal_word = "IJK"[n]
            if normal_word in spelled:
                self.fail(f"word {spelled[normal_word]!r} is not in the arc's plane",
                          spelled[normal_word])
        r0 = math.hypot(sa - ca, sb - cb)
        r1 = math.hypot(ea - ca, eb - cb)
        if r0 == 0.0:
            self.fail("arc radius is zero (the centre is the start point)", f"G{self.motion}")
        if abs(r1 - r0) > max(ARC_RADIUS_TOLERANCE, ARC_RADIUS_RTOL * r0):
            self.fail(f"arc start and end radii differ by {abs(r1 - r0):.6g} mm (start "
                      f"{r0:.6g}, end {r1:.6g}; tolerance {ARC_RADIUS_TOLERANCE:g} mm or "
                      f"{ARC_RADIUS_RTOL:g} of the radius)", f"G{self.motion}")
        theta0 = math.atan2(sb - cb, sa - ca)
        theta1 = math.atan2(eb - cb, ea - ca)
        ccw = self.motion == 3
        sweep = (theta1 - theta0) % (2 * math.pi) if ccw else -((theta0 - theta1) % (2 * math.pi))
        if math.hypot(ea - sa, eb - sb) <= 1e-12 * max(1.0, r0):
            sweep = 2 * math.pi if ccw else -2 * math.pi
        turns = values.get("P")
        if turns is not None:
            if turns != int(turns) or turns < 1:
                self.fail(f"arc turns {spelled['P']!r} must be a whole number >= 1",
                          spelled["P"])
            sweep += math.copysign(2 * math.pi * (turns - 1), sweep)
        r_max = max(r0, r1)
        tol = min(self.arc_tolerance, 0.5 * r_max)
        step = 2.0 * math.acos(1.0 - tol / r_max)
        n_chords = max(1, math.ceil(abs(sweep) / step - 1e-9))
        if abs(sweep) > math.pi / 2:
            n_chords = max(n_chords, math.ceil(abs(sweep) / (math.pi / 2)))
        if n_chords > MAX_ARC_CHORDS:
            self.fail(f"arc needs {n_chords} chords (more than {MAX_ARC_CHORDS}) within "
                      f"{self.arc_tolerance:g} mm", f"G{self.motion}")
        u = np.arange(1, n_chords + 1) / n_chords
        angle = theta0 + sweep * u
        radius = r0 + (r1 - r0) * u
        points = np.array(start, dtype=float) + u[:, None] * (np.array(target) - start)
        points[:, a] = ca + radius * np.cos(angle)
        points[:, b] = cb + radius * np.sin(angle)
        points[-1] = target
        helix = math.hypot(0.5 * (r0 + r1) * abs(sweep), target[n] - start[n])
        duration, feed = self.timing(start, target, n_chords, spelled, length=helix)
        centre = [math.nan] * 3
        centre[a], centre[b] = ca, cb
        if self.framed:
            centre[n] = start[n]   # a point of the tilted plane, given in all three axes
        rotation = (1 if ccw else -1) * int(turns or 1)
        plane = {(0, 1, 2): 17, (2, 0, 1): 18, (1, 2, 0): 19}[self.plane]
        self.add_many(points, False, duration, feed, self.row,
                      (2, list(target), centre, plane, rotation, self.inverse_time,
                       self.programmed_feed(False), self.row, self.tcp, self.n_moves))

    # ------------------------------------------------------------------ result
    def check_tilt(self, tilt: np.ndarray, lines: np.ndarray) -> None:
        """The tilt axis (A, or B on a B-C machine) stays within its travel."""
        low, high = _tilt_travel(self.kinematics)
        slack = 1e-9
        out = (tilt < low - slack) | (tilt > high + slack)
        if out.any():
            k = int(np.flatnonzero(out)[0])
            letter = self.axes[3]
            raise ProgramError(f"{letter} = {math.degrees(tilt[k]):.6g} deg is outside the tilt "
                               f"axis's travel [{math.degrees(low):g}, {math.degrees(high):g}] "
                               "deg", source=self.source, row=int(lines[k]), field=letter)

    def finish(self) -> Program:
        if self.start is None or not self.n_moves:
            raise ProgramError("no motion: no move after a block that sets all axes "
                               f"({' '.join(self.axes)})", source=self.source)
        ends, rapid, duration, feed, lines, tcp, tolerance, length = self.moves.columns(
            (float, bool, float, float, np.int64, bool, float, float))
        programmed = ProgrammedMoves(*self.programmed.columns(
            (np.int8, float, float, np.int8, np.int64, bool, float, np.int64, bool, np.int64)))
        q = self.machine_axes(ends, tcp, length)
        start = self.machine_axes(np.array([self.start]), np.array([self.start_tcp]),
                                  np.array([self.start_length]))[0]
        bad = ~np.isfinite(q).all(axis=1)
        if bad.any() or not np.isfinite(start).all():
            k = int(np.flatnonzero(bad)[0]) if bad.any() else 0
            raise ProgramError("the kinematics gives no machine axes for this tool tip",
                               source=self.source, row=int(lines[k]))
        self.check_tilt(q[:, 3], lines)
        return Program(start=start, start_line=self.start_line, q=q,
                       rapid=rapid, duration=duration, feed=feed, line=lines, tcp_move=tcp,
                       stops=tuple(self.stops), passthrough=tuple(self.passthrough),
                       source=self.source, tcp=bool(tcp.any() or self.tcp_all),
                       axes=self.axes, notices=tuple(self.notices),
                       skipped=MappingProxyType(dict(self.skipped)),
                       path_tolerance=tolerance, programmed=programmed)


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


def _axis_letters(machine) -> tuple[str, ...]:
    axes = getattr(getattr(machine, "kinematics", None), "axes", None)
    if axes is None:
        drives = getattr(machine, "drives", None)
        if drives:
            axes = tuple(getattr(d, "axis", a) for d, a in zip(drives, AXIS_WORDS))
    axes = tuple(axes or AXIS_WORDS)
    return axes if len(axes) == 5 else AXIS_WORDS


def _kinematics(machine):
    if isinstance(machine, (str, Path)):
        from ..machine.machine_file import load_machine
        machine = load_machine(machine)
    kinematics = getattr(machine, "kinematics", None)
    if kinematics is None or not hasattr(kinematics, "forward"):
        raise InputError("reading G-code needs a machine whose kinematics has forward(q); "
                         f"got {type(machine).__name__}", field="machine")
    return kinematics


# ---------------------------------------------------------------------- ToolPath view


def read_gcode(path: str | Path, machine, *, block_delete: bool = True, tcp: bool = False,
               tool_table=None):
    """The program's points (start and every move end, arcs subdivided) as a
    :class:`~precontour.toolpath.ToolPath`; see :func:`read_gcode_report`."""
    return read_gcode_report(path, machine, block_delete=block_delete, tcp=tcp,
                             tool_table=tool_table).toolpath


def read_gcode_report(path: str | Path, machine, *, block_delete: bool = True,
                      tcp: bool = False, tool_table=None) -> ReadReport:
    """:func:`read_program` seen as a tool path: P, O (direct kinematics) of the start and
    every move end, the feed (mm/s) of the move ending at each point (G93 blocks: tip chord
    length over block time; NaN for rapids), lines, rapid flags, machine axes."""
    if isinstance(machine, (str, Path)):
        from ..machine.machine_file import load_machine
        machine = load_machine(machine)
    program = read_program(path, machine, tcp=tcp, block_delete=block_delete,
                           tool_table=tool_table)
    return program_report(program, _kinematics(machine))


def program_report(program: Program, kinematics, format: str = "gcode") -> ReadReport:
    """A :class:`~precontour.toolpath.program.Program` seen as a tool path (see
    :func:`read_gcode_report`); also the view of the other NC languages' readers."""
    q = program.points
    P, O = kinematics.forward(q)
    feed = np.concatenate([[np.nan], program.feed])
    timed = np.isnan(feed[1:]) & ~program.rapid
    if timed.any():
        chord = np.linalg.norm(np.diff(P, axis=0), axis=1)
        with np.errstate(divide="ignore", invalid="ignore"):
            feed[1:][timed] = chord[timed] / program.duration[timed]
        feed[1:][timed & ~(feed[1:] > 0)] = np.nan
    lines = np.concatenate([[program.start_line], program.line])
    rapid = np.concatenate([[True], program.rapid])
    return finish(P, O, feed, lines=lines, source=program.source, format=format,
                  empty="no motion", rapid=rapid, skipped=program.skipped, axes=q)
