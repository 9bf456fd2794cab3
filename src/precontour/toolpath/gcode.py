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
  space; under G91 its words are machine positions, as a Haas control moves, said once);
  G28/G30 rapid through the given point to the machine file's reference position
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
  the modal state of M70-M73; no loop runs more than
  :data:`~._gcode_language.MAX_LOOP_ITERATIONS` times and no calls nest deeper than
  :data:`~._gcode_language.MAX_CALL_DEPTH` (a runaway ends with an error on its line); the
  ``line`` of a move is the line executing (inside a subroutine, its own);
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

import math
import re
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType

import numpy as np

from ..errors import ForeignSyntaxError, InputError, ProgramError
from ..machine.gcode import GcodeSettings
from ..machine.tools import checked_tool_lengths, read_tool_table
from ._common import INCH, ReadReport, finish, read_text
from ._dialects import REPOST, SINUMERIK, foreign_construct, program_language
from ._gcode_codes import (ARC_CHORD_TOLERANCE, ARC_RADIUS_RTOL, ARC_RADIUS_TOLERANCE, AXIS_WORDS,
                           PASSTHROUGH_G, SINUMERIK_SUFFIXES, _AXIS_WORD_CODES, _CYCLES,
                           _CYCLE_WORDS, _FLOW_M, _Frame, _KNOWN_G, _KNOWN_M, _LENGTH_G,
                           _MODAL_GROUPS, _MOTION, _M_WORDS, _NON_MODAL, _PASSTHROUGH_WORDS,
                           _PLANES, _STOP_M, _TILT_G, _TOOL_LENGTH_WORDS, _Table, _UNSUPPORTED_G,
                           _WORK_OFFSET_G, _ZERO, _degrees, _g_name)
from ._gcode_cycles import CycleBlocks
from ._gcode_language import LanguageBlocks
from ._gcode_lines import LineReading
from ._gcode_motion import MotionBlocks
from ._gcode_offsets import OffsetBlocks
from ._gcode_tcp import TcpBlocks
from ._ngc import MAX_PARAMETER
from ._sinumerik_blocks import SinumerikBlocks
from .program import Program, ProgrammedMoves, Stop


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


@dataclass(slots=True, eq=False)
class _Block:
    """One block while :meth:`_Reader.execute` runs it: its words and what its phases work out
    (the codes in tenths, the non-modal code, the M numbers and the words they read, what
    the axis words are, the words an output program keeps)."""

    words: list
    traori: bool
    trafoof: bool
    raw: str
    comments: list
    values: dict[str, float] = field(default_factory=dict)
    spelled: dict[str, str] = field(default_factory=dict)
    g_codes: list[tuple[int, str]] = field(default_factory=list)
    m_codes: list[tuple[int, str]] = field(default_factory=list)
    codes: set[int] = field(default_factory=set)
    g_word: dict[int, str] = field(default_factory=dict)
    non_modal: int | None = None
    m_numbers: set[int] = field(default_factory=set)
    m_words: set[str] = field(default_factory=set)
    m_switch: set[int] = field(default_factory=set)
    moves_axes: bool = False
    kept: list[str] = field(default_factory=list)
    evaluated: bool = False
    scale: float = 1.0
    dwell: bool = False
    motion_here: int | None = None
    previous_motion: int | None = None
    centre_only: bool = False
    is_cycle: bool = False
    is_arc: bool = False


class _Reader(LineReading, LanguageBlocks, OffsetBlocks, TcpBlocks, MotionBlocks,
              CycleBlocks, SinumerikBlocks):
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

    # ------------------------------------------------------------------ one block
    # A block is executed in RS274/NGC's phases, as LinuxCNC's interpreter does: its words
    # read and checked, the modes set in the order of execution, the words that depend on
    # the codes checked, the block's action, then stops, subprogram calls and what an output
    # program keeps (:class:`_Block` carries the block between them).
    def execute(self, words, traori, trafoof, raw, comments) -> bool:
        """Execute one block of ``words`` (letter, value, number as written, word as
        written); True after the program end (M2/M30)."""
        block = self.read_block(words, traori, trafoof, raw, comments)
        self.check_codes(block)
        self.set_modes(block)
        self.check_block_words(block)
        self.act(block)
        return self.after_block(block)

    def read_block(self, words, traori, trafoof, raw, comments) -> _Block:
        """The block's words by letter, its G and M codes (tenths), each word at most once."""
        block = _Block(words=words, traori=traori, trafoof=trafoof, raw=raw, comments=comments)
        values, spelled = block.values, block.spelled
        for letter, value, _, word in words:
            if letter == "G":
                block.g_codes.append((int(round(value * 10)), word))
            elif letter == "M":
                block.m_codes.append((int(round(value * 10)), word))
            elif letter in ("N", "O"):
                continue
            elif letter in values:
                self.fail(f"word {letter} appears twice in the block", word)
            else:
                if not math.isfinite(value):
                    self.fail(f"value is not finite in {word!r}", word)
                values[letter] = value
                spelled[letter] = word
        return block

    def check_codes(self, block: _Block) -> None:
        """Check the block's G and M codes and its words against them; what an output program
        keeps of it (:attr:`_Block.kept`)."""
        spelled, raw = block.spelled, block.raw
        # G codes: check, then apply the modes in execution order (RS274/NGC).
        seen_groups = {}
        for code, word in block.g_codes:
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
        codes = block.codes = {code for code, _ in block.g_codes}
        g_word = block.g_word = {code: word for code, word in block.g_codes}
        block.non_modal = next((code for code in _NON_MODAL if code in codes), None)
        m_codes, m_numbers = block.m_codes, block.m_numbers
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
        m_words = block.m_words = set().union(
            *(_M_WORDS.get(n, "PQ" if 100 <= n <= 199 else "") for n in m_numbers))
        if m_numbers & {70, 71, 72, 73}:
            self.modal_state(m_numbers, m_codes)
        for letter in spelled:
            if letter in self.axis_index or letter in "@^":
                block.moves_axes = True
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
        if block.non_modal in _AXIS_WORD_CODES and block.moves_axes and any(
                code in _MOTION for code in codes):
            motion_word = next(g_word[c] for c in codes if c in _MOTION)
            self.fail(f"{_g_name(block.non_modal)} and {motion_word} both use the axis words "
                      "of the block", motion_word)
        kept = block.kept  # words an output program keeps, as written, in their order
        for letter, value, number, _ in block.words:
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
        block.evaluated = any(spelled != letter + number
                              for letter, _, number, spelled in block.words)

    def set_modes(self, block: _Block) -> None:
        """The block's modes, in RS274/NGC's order of execution: feed mode, F (in the units
        before this block's G20/G21), units, plane, TCP switches, tool length, work offset,
        path control, distance modes, motion mode, retract mode."""
        codes, values, spelled, g_word = block.codes, block.values, block.spelled, block.g_word
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
        block.scale = INCH if self.inch else 1.0
        block.dwell = 40 in codes
        for code in (170, 180, 190):
            if code in codes:
                self.plane = _PLANES[code]
        # the site's M codes (LinuxCNC's remapped M428/M429, modal group 10) act before the
        # tool length codes G43.4/G43.5/G49 in RS274/NGC's order of execution
        m_switch = block.m_switch = block.m_numbers & (self.tcp_on | self.tcp_off)
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
        self.tool_change(values, spelled, block.m_numbers)
        self.haas_modes(codes, g_word, values, spelled)
        if codes & _LENGTH_G:
            self.select_length(values, spelled, g_word[min(codes & _LENGTH_G)])
        if 434 in codes or 435 in codes:
            self.tcp_sources.add("G43.4")
        if 490 in codes:
            self.tcp_sources.discard("G43.4")
            self.tcp_sources.discard("G234")
        if block.traori:
            self.tcp_sources.add("TRAORI")
        if block.trafoof:
            self.tcp_sources.discard("TRAORI")
        if self.tilt is not None and (m_switch or block.traori or block.trafoof or 434 in codes
                                      or 435 in codes):
            self.fail("a TCP switch with G68.2 or CYCLE800 active: cancel it with G69 or "
                      "CYCLE800() first",
                      next((w for c, w in block.m_codes if c // 10 in m_switch), None)
                      or g_word.get(434) or g_word.get(435))
        self.set_tcp(bool(self.tcp_sources))
        if 490 in codes:
            self.set_length(math.nan)     # after the switch: G49 ends TCP at the old length
        non_modal = block.non_modal
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
            self.path_tolerance = values["P"] * block.scale if "P" in values else math.nan
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
        block.previous_motion = self.motion
        if 800 in codes:
            self.motion = None            # G80: no motion mode (the cycles end)
            self.cycle_start = None
            self.cancelled = True
        for code in codes:
            if code in _MOTION:
                block.motion_here = _MOTION[code]
        if block.motion_here is not None:
            self.motion = block.motion_here
            if block.motion_here not in _CYCLES:
                self.cycle_start = None   # the next cycle's G98 height is taken anew
        if 980 in codes:
            self.retract_initial = True
        if 990 in codes:
            self.retract_initial = False

    def check_block_words(self, block: _Block) -> None:
        """The word checks that depend on the block's codes and the modes now set: what the
        axis words are (a tilted plane's origin, a tool length, a cycle's holes, an arc's
        end), and who reads I J K R P Q; a G68.2 / G53.1 / G69 block is executed here."""
        codes, spelled, g_word = block.codes, block.spelled, block.g_word
        motion_here = block.motion_here
        arc_words = [spelled[k] for k in ("IJK" if 100 in codes else "IJKR") if k in spelled]
        if codes & _TILT_G:
            if any(code in _MOTION for code in codes) or block.non_modal is not None:
                self.fail("G68.2, G53.1 and G69 take a block of their own",
                          g_word[min(codes & _TILT_G)])
            self.tilted_plane(codes, block.values, spelled, block.scale, g_word)
            block.moves_axes = False     # G68.2's X Y Z are its origin
            arc_words = []
        elif self.tilt is not None and block.moves_axes:
            rotary = [spelled[a] for a in self.axes[3:] if a in spelled]
            if rotary:
                self.fail(f"rotary axis word {rotary[0]!r} with G68.2 active: G53.1 turns the "
                          "rotary axes to the plane", rotary[0])
        if codes & _TOOL_LENGTH_WORDS:
            if any(code in _MOTION for code in codes) and block.moves_axes:
                word = g_word[min(codes & _TOOL_LENGTH_WORDS)]
                self.fail(f"{word} and a motion both use the axis words of the block", word)
            block.moves_axes = False    # the words are the tool length offset (not applied)
        moves_axes = block.moves_axes
        block.centre_only = not moves_axes and any(k in spelled for k in "IJK")
        block.is_cycle = (self.motion in _CYCLES and (moves_axes or motion_here in _CYCLES)
                          and block.non_modal is None)
        cycle_words = _CYCLE_WORDS[self.motion] if block.is_cycle else ""
        block.is_arc = is_arc = (
            self.motion in (2, 3) and (moves_axes or motion_here in (2, 3) or block.centre_only)
            and (block.non_modal is None or block.dwell and motion_here is not None))
        if block.dwell and is_arc and "P" in spelled:
            self.fail("G4 P and an arc's turns P in one block", spelled["P"])
        arc_words = [w for w in arc_words if w[0] not in cycle_words]
        if arc_words and not is_arc:
            self.fail(f"word {arc_words[0]!r} is read only with G2/G3"
                      + (" and G87" if arc_words[0][0] in "IJK" else " and canned cycles"),
                      arc_words[0])
        p_readers = (block.dwell or 640 in codes or is_arc or 541 in codes or 100 in codes
                     or "P" in cycle_words or 682 in codes)
        if "P" in spelled and not (p_readers or "P" in block.m_words):
            self.fail(f"unsupported word {spelled['P']!r} (P is read with G4, G10, G54.1, "
                      "G64, G2/G3, G82/G86/G89, M62-M66)", spelled["P"])
        if "Q" in spelled and not (640 in codes or "Q" in block.m_words
                                   or "Q" in cycle_words):
            self.fail(f"unsupported word {spelled['Q']!r} (Q is read with G64, G73/G83, M61, "
                      "M66-M68)", spelled["Q"])

    def act(self, block: _Block) -> None:
        """The block's action: a dwell (before the block's motion), a non-modal code, a
        canned cycle or a move."""
        values, spelled, scale, g_word = block.values, block.spelled, block.scale, block.g_word
        non_modal, moves_axes = block.non_modal, block.moves_axes
        if block.dwell:
            # RS274/NGC: the dwell before the block's motion; with a motion code the axis
            # words are that motion's, else Fanuc's X is the time
            seconds = values.get("P")
            if block.motion_here is None:
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
            if block.motion_here is not None and moves_axes:
                self.move(values, spelled, scale, block.g_codes)
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
        elif block.is_cycle:
            if self.dwo_base is not None:
                self.dwo_origin(spelled)
            self.cycle(values, spelled, scale, block.previous_motion, g_word)
        elif moves_axes or block.is_arc and block.centre_only:
            if self.dwo_base is not None:
                self.dwo_origin(spelled)
            # (G2/G3 with a centre and no axis words: a full circle, as in LinuxCNC)
            self.move(values, spelled, scale, block.g_codes)

    def after_block(self, block: _Block) -> bool:
        """Stops (M0, M1, M6, M2/M30), M98/M99, and the block's line for an output program;
        True after the program end."""
        end = False
        m_codes, m_numbers, spelled = block.m_codes, block.m_numbers, block.spelled
        for code, word in m_codes:
            kind = _STOP_M.get(code // 10)
            if kind is not None:
                self.stops.append(Stop(self.n_moves, self.row, kind))
                end = end or kind == "end"
        if 98 in m_numbers and 99 in m_numbers:
            self.fail("M98 and M99 in one block", spelled.get("P"))
        if 98 in m_numbers:
            self.subprogram(block.values, spelled, next(w for c, w in m_codes if c == 980))
        elif 99 in m_numbers:
            self.subprogram_return(next(w for c, w in m_codes if c == 990))
        if block.kept or block.comments:
            motion_words = (block.moves_axes or block.dwell or "F" in spelled
                            or any(code not in PASSTHROUGH_G for code in block.codes)
                            or block.traori or block.trafoof or block.m_switch
                            or block.evaluated)
            if motion_words:
                text = " ".join(block.kept + [f"({c.strip()})" for c in block.comments
                                              if c.strip()])
            else:
                text = block.raw
            if text:
                self.passthrough.append((self.row, text))
        return end

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
