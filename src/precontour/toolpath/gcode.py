"""Reader for G-code programs in machine axes (X Y Z in mm or inch, A C in degrees).

Each ``G0``/``G1`` block gives machine-axis positions q = [X, Y, Z, A, C]; a missing axis
word keeps its previous value (axes never programmed start at 0), and the motion mode is
modal. The machine's direct kinematics turns q into tool tip and orientation. Supported:
``G90``/``G91`` (absolute default), ``G20``/``G21`` (mm default; inch lengths and feeds are
converted), ``G94`` feed ``F`` per minute (to mm/s), ``G4`` dwell, comments ``( )`` and
``;``, ``N`` numbers, ``%`` lines, ``O`` program numbers and block delete ``/`` (such blocks
are skipped by default). Codes that do not change the axis commands (plane selection,
compensation and cycle cancels, work offsets, path modes, ``G43`` tool length, which the
machine's kinematics is taken to include) and the words ``M S T H D`` are counted in
``ReadReport.skipped``. Arcs, inverse-time and per-revolution feed, canned cycles, tool-centre
point / tilted-plane modes, parameters and every other code are errors naming the line.
"""

from __future__ import annotations

import io
import re
from collections import Counter
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv

from ..errors import InputError, ToolPathError
from ._common import INCH, ReadReport, finish, read_text

#: Machine-axis words, in the order of q.
AXIS_WORDS = ("X", "Y", "Z", "A", "C")

#: G codes read and ignored: they do not change the axis commands the program gives.
IGNORED_G = frozenset(["G17", "G18", "G19", "G40", "G43", "G49", "G54", "G55", "G56", "G57",
                       "G58", "G59", "G61", "G64", "G80"])

#: Words other than G, F and the axes that are read and ignored.
IGNORED_WORDS = frozenset("NOMSTHD")

#: Largest magnitude of a word's number other than a block number N (mm, inch, degrees,
#: mm/min, s): 1 km, about 2,800 turns, and beyond anything a machine or its feed could do.
MAX_WORD_VALUE = 1e6

_UNSUPPORTED_G = {
    "G2": "circular interpolation (G2) is not supported; output linear G1 moves",
    "G3": "circular interpolation (G3) is not supported; output linear G1 moves",
    "G93": "inverse-time feed (G93) is not supported; output G94 feeds in mm/min",
    "G95": "feed per revolution (G95) is not supported; output G94 feeds in mm/min",
    "G43.4": "tool centre point control (G43.4) gives tool-tip coordinates, not machine "
             "axes; write the tip path as CL data (CSV or APT) instead",
    "G43.5": "tool centre point control (G43.5) gives tool-tip coordinates, not machine "
             "axes; write the tip path as CL data (CSV or APT) instead",
    "G68.2": "tilted working plane (G68.2) is not supported",
}

_CODE_NAMES = {0: "G0", 10: "G1", 20: "G2", 30: "G3", 40: "G4", 200: "G20", 210: "G21",
               900: "G90", 910: "G91", 930: "G93", 940: "G94", 950: "G95"}
#: G codes (in tenths, G43.4 -> 434) that share a modal group: two in one block is an error.
_MODAL_GROUPS = ((0, 10, 20, 30), (900, 910), (200, 210), (930, 940, 950))

_COMMENTS = re.compile(r"\([^()\n]*\)|;[^\n]*")
_PERCENT = re.compile(r"\n%[^\n]*")
_DELETED = re.compile(r"\n/[^\n]*")
_DROP_BLANKS = str.maketrans("", "", " \t\r\f\v")
_NUMBER_CHAR = np.zeros(256, dtype=bool)
_NUMBER_CHAR[np.frombuffer(b"0123456789.+-", dtype=np.uint8)] = True
# a line not starting with a word, or a letter not followed by a plain number
_BAD = re.compile(r"^(?![A-Z\n]|$)|[A-Z](?![-+]?(?:\d+\.?\d*|\.\d+)(?=[A-Z\n]|$))", re.M)

__all__ = ["read_gcode", "read_gcode_report", "AXIS_WORDS", "IGNORED_G", "IGNORED_WORDS"]


def read_gcode(path: str | Path, machine, *, block_delete: bool = True):
    """Read a G-code program into a :class:`~precontour.toolpath.ToolPath`.

    Parameters
    ----------
    path : str or Path
        G-code file in machine axes (see the module docstring).
    machine : Machine or str
        The machine (or a built-in machine name / machine file for
        :func:`~precontour.machine.machine_file.load_machine`); ``machine.kinematics.forward(q)`` maps
        axis positions to tool tip and orientation.
    block_delete : bool
        Skip blocks starting with ``/`` (block-delete switch on).

    Returns
    -------
    ToolPath
        P (M, 3) mm and unit O (M, 3) in the workpiece frame, feed (M,) mm/s (NaN for
        ``G0`` moves and before the first ``F``).
    """
    return read_gcode_report(path, machine, block_delete=block_delete).toolpath


def read_gcode_report(path: str | Path, machine, *, block_delete: bool = True) -> ReadReport:
    """Like :func:`read_gcode`, returning the :class:`ReadReport`, whose ``axes`` holds the
    machine-axis positions q (M, 5) [mm, mm, mm, rad, rad] of the points.

    The whole program is tokenized at once (regular expressions over the text, numbers
    parsed by pyarrow) and the modal state is carried from block to block with array
    forward-fills, so the cost is linear in the file size with no per-block Python work.

    Raises
    ------
    ToolPathError
        One line naming the file, line and word: an unparseable number or text, an
        unsupported G code or word, two codes of one modal group or a repeated word in a
        block, axis words before any ``G0``/``G1``, no motion at all, and the checks common
        to all readers. Problems are checked kind by kind (syntax, repeated words, codes,
        modes, motion); within a kind the first line is reported.
    """
    source = str(path)
    kinematics = _kinematics(machine)
    text = read_text(path).replace("\r\n", "\n").replace("\r", "\n")
    skipped: Counter[str] = Counter()

    # Blanks go first so that the line-start patterns below begin with a literal newline,
    # which the regex engine searches for quickly; a newline is prepended for line 1.
    text = "\n" + text.translate(_DROP_BLANKS)
    if "(" in text or ")" in text or ";" in text:
        text = _COMMENTS.sub("", text)
        paren = re.search(r"[()]", text)
        if paren:
            raise ToolPathError("unbalanced or nested '(' comment", source=source,
                                row=_line_at(text, paren.start()) - 1)
    if "%" in text:
        text = _PERCENT.sub("\n", text)
    if "/" in text:
        if block_delete:
            text, deleted = _DELETED.subn("\n", text)
            if deleted:
                skipped["/"] = deleted
        else:
            text = text.replace("\n/", "\n")
    text = text[1:]
    if not text.isascii():
        bad = next(i for i, ch in enumerate(text) if not ch.isascii())
        raise ToolPathError(f"cannot parse {text[bad]!r}", source=source,
                            row=_line_at(text, bad))
    text = text.upper()

    # Tokens: letter, value and 0-based line of every word, in file order. The text may
    # hold only letters, number characters and newlines, every line must start with a
    # letter, and every letter must be followed by a number; the regex that words the
    # message runs only when the fast byte-level checks fail.
    chars = np.frombuffer(text.encode("ascii"), dtype=np.uint8)
    is_letter = (chars >= ord("A")) & (chars <= ord("Z"))
    newline = chars == ord("\n")
    starts = np.flatnonzero(newline) + 1
    starts = np.concatenate([[0], starts[starts < chars.size]]) if chars.size else starts
    ok = (np.all(is_letter | newline | _NUMBER_CHAR[chars])
          and np.all(is_letter[starts] | newline[starts]))
    letter = chars[is_letter]
    value = None
    if ok:
        digits = chars.copy()
        digits[is_letter] = ord("\n")  # one number per line for the CSV parser
        value = _parse_numbers(digits[~newline].tobytes(), letter.size)
    if value is None:
        _raise_syntax(text, source)
    marks = newline[is_letter | newline]
    n_lines = int(newline.sum()) + 1
    line = np.cumsum(marks)[~marks]
    # Numbers too long for a double, and coordinates no machine has (1 km): refused here, by
    # line, before they overflow the kinematics or the trajectory's sample count.
    huge = ~(np.abs(value) <= MAX_WORD_VALUE) & (letter != ord("N"))
    if huge.any():
        k = int(np.flatnonzero(huge)[0])
        raise ToolPathError(f"number out of range (|{chr(letter[k])}| > {MAX_WORD_VALUE:g})",
                            source=source, row=int(line[k]) + 1, field=chr(letter[k]))

    state = _Blocks(text, line, letter, value, n_lines, source)
    state.check_words(skipped)
    codes = state.g_codes(skipped)
    for group in _MODAL_GROUPS:
        state.at_most_one(np.isin(codes, group), "G")

    is_g = letter == ord("G")
    motion = state.per_line(is_g & np.isin(codes, (0, 10)), codes)         # 0, 10 or NaN
    dwell = state.per_line(is_g & (codes == 40), codes) == 40
    distance = state.ffill(state.per_line(is_g & np.isin(codes, (900, 910)), codes), 900)
    units = state.ffill(state.per_line(is_g & np.isin(codes, (200, 210)), codes), 210)
    scale = np.where(units == 200, INCH, 1.0)
    f_word = state.per_line(letter == ord("F"))
    has_f = ~np.isnan(f_word)
    if np.any(f_word[has_f] <= 0):
        row = int(np.flatnonzero(has_f & ~(f_word > 0))[0])
        state.fail(row, f"feed must be positive, got F{f_word[row]:g}", "F")
    feed = state.ffill(f_word * scale / 60.0, np.nan)
    p_word = state.per_line(letter == ord("P"))
    both = dwell & ~np.isnan(motion)
    stray_p = ~np.isnan(p_word) & ~dwell
    state.fail_first([(both, "dwell (G4) and a motion code in one block", "G"),
                      (stray_p, "unsupported word {word} (P is read only with G4)", "P")])
    motion = state.ffill(motion, -1.0)

    axis_values = np.column_stack([state.per_line(letter == ord(a)) for a in AXIS_WORDS])
    # G4's X word is the dwell time, not a position
    moving = (~np.isnan(axis_values)).any(axis=1) & ~dwell
    state.fail_first([(moving & (motion < 0), "axis words before any motion code (G0 or G1)",
                       "G")])

    rows = np.flatnonzero(moving)
    v = axis_values[rows]
    v[:, :3] *= scale[rows, None]
    q = _positions(v, distance[rows] == 910)
    q[:, 3:] = np.radians(q[:, 3:])
    _check_tilt(q[:, 3], kinematics, rows, state)
    rapid = motion[rows] == 0
    P, O = kinematics.forward(q)
    return finish(P, O, np.where(rapid, np.nan, feed[rows]), lines=rows + 1, source=source,
                  format="gcode", empty="no motion (no G0/G1 block with an axis word)",
                  rapid=rapid, skipped=skipped, axes=q)


def _check_tilt(a: np.ndarray, kinematics, rows: np.ndarray, state: "_Blocks") -> None:
    """The tilt axis A stays within +-180 degrees and the machine's A travel, if it has one."""
    low = getattr(kinematics, "a_min", None)
    high = getattr(kinematics, "a_max", None)
    low = -np.pi if low is None else max(low, -np.pi)
    high = np.pi if high is None else min(high, np.pi)
    slack = 1e-9
    out = (a < low - slack) | (a > high + slack)
    if out.any():
        k = int(np.flatnonzero(out)[0])
        state.fail(int(rows[k]), f"A = {np.degrees(a[k]):.6g} deg is outside the tilt axis's "
                                 f"travel [{np.degrees(low):g}, {np.degrees(high):g}] deg", "A")


def _positions(v: np.ndarray, incremental: np.ndarray) -> np.ndarray:
    """Axis positions after each motion block from its words ``v`` (NaN: not given) and
    distance mode; an axis keeps its value when not given, and starts at 0."""
    present = ~np.isnan(v)
    inc = present & incremental[:, None]
    absolute = present & ~incremental[:, None]
    # position = (last absolute value - increments up to it) + increments up to now
    summed = np.cumsum(np.where(inc, v, 0.0), axis=0)
    base = np.where(absolute, v - summed, np.nan)
    k = np.arange(v.shape[0])[:, None]
    last = np.maximum.accumulate(np.where(absolute, k, -1), axis=0)
    base = np.where(last >= 0, np.take_along_axis(base, np.maximum(last, 0), axis=0), 0.0)
    return np.where(absolute, v, base + summed)


def _parse_numbers(rows: bytes, n: int) -> np.ndarray | None:
    """Parse ``n`` numbers, one per line; None if any is malformed or missing."""
    if n == 0:
        return np.empty(0)
    try:
        table = pacsv.read_csv(
            io.BytesIO(rows),
            read_options=pacsv.ReadOptions(column_names=["v"]),
            convert_options=pacsv.ConvertOptions(column_types={"v": pa.float64()},
                                                 null_values=[]))
    except pa.ArrowInvalid:
        return None
    values = table.column("v").to_numpy(zero_copy_only=False)
    return values if values.size == n else None


def _raise_syntax(text: str, source: str):
    """Locate and word the first syntax error of cleaned text."""
    bad = _BAD.search(text)
    if bad is None:  # the byte checks and the grammar disagree; never return wrong data
        raise ToolPathError("cannot parse the program", source=source)
    row = _line_at(text, bad.start())
    word = re.match(r"[^\n]*", text[bad.start():]).group()
    if bad.group():  # a letter with a bad number
        word = re.match(r"[A-Z][^A-Z\n]*", word).group()
        raise ToolPathError(f"cannot parse number {word!r}", source=source, row=row,
                            field=word[0])
    raise ToolPathError(f"cannot parse {word!r}", source=source, row=row)


def _line_at(text: str, position: int) -> int:
    return text.count("\n", 0, position) + 1


class _Blocks:
    """Per-block (line) views of the word tokens, and errors naming the first bad line."""

    def __init__(self, text, line, letter, value, n_lines, source):
        self.text, self.line, self.letter, self.value = text, line, letter, value
        self.n_lines, self.source = n_lines, source
        allowed = np.frombuffer(("GFP" + "".join(AXIS_WORDS) + "".join(sorted(IGNORED_WORDS)))
                                .encode(), dtype=np.uint8)
        self.unknown = ~np.isin(letter, allowed)
        self.codes = np.where(letter == ord("G"), np.rint(value * 10.0), np.nan)

    def word(self, row: int, letter: str) -> str:
        """The first word with ``letter`` on 0-based line ``row``, as written (cleaned)."""
        text = self.text.split("\n", row + 1)[row]
        match = re.search(letter + r"[^A-Z]*", text)
        return repr(match.group()) if match else letter

    def fail(self, row: int, message: str, field: str | None = None):
        raise ToolPathError(message.format(word=self.word(row, field or "?")),
                            source=self.source, row=row + 1, field=field)

    def fail_first(self, candidates):
        """Raise for the first line flagged by any (mask per line, message, field)."""
        best = None
        for mask, message, field in candidates:
            hits = np.flatnonzero(mask)
            if hits.size and (best is None or hits[0] < best[0]):
                best = (int(hits[0]), message, field)
        if best is not None:
            self.fail(*best)

    def per_line(self, mask: np.ndarray, values: np.ndarray | None = None) -> np.ndarray:
        """Value of the (single) masked token of each line, NaN where there is none."""
        out = np.full(self.n_lines, np.nan)
        out[self.line[mask]] = (self.value if values is None else values)[mask]
        return out

    @staticmethod
    def ffill(per_line: np.ndarray, initial: float) -> np.ndarray:
        """Carry each line's value forward over lines without one (modal state)."""
        k = np.where(np.isnan(per_line), -1, np.arange(per_line.size))
        k = np.maximum.accumulate(k)
        return np.where(k >= 0, per_line[np.maximum(k, 0)], initial)

    def at_most_one(self, mask: np.ndarray, field: str):
        counts = np.bincount(self.line[mask], minlength=self.n_lines)
        if (counts > 1).any():
            row = int(np.flatnonzero(counts > 1)[0])
            tokens = np.flatnonzero(mask & (self.line == row))
            if field == "G":
                names = [_CODE_NAMES.get(int(c), "G?") for c in self.codes[tokens]]
                self.fail(row, f"two codes of one modal group ({', '.join(names)}) in one "
                               "block", "G")
            self.fail(row, f"word {field} appears twice in the block", field)

    def check_words(self, skipped: Counter):
        """Reject unknown words (after any G-code error on an earlier or the same line) and
        repeated value words; count the ignored ones."""
        for ch in (*AXIS_WORDS, "F", "P"):
            self.at_most_one(self.letter == ord(ch), ch)
        for ch in IGNORED_WORDS:
            mask = self.letter == ord(ch)
            if ch == "N" or not mask.any():
                continue
            if ch == "M":
                codes, counts = np.unique(self.value[mask], return_counts=True)
                skipped.update({f"M{_code(c)}": int(k) for c, k in zip(codes, counts)})
            else:
                skipped[ch] += int(mask.sum())

    def g_codes(self, skipped: Counter) -> np.ndarray:
        """G code numbers in tenths (G43.4 -> 434; NaN for other words), after rejecting
        unsupported codes and unknown words, whichever comes first in the file."""
        is_g = self.letter == ord("G")
        codes = self.codes
        ignored = {int(_code10(g)) for g in IGNORED_G}
        known = {0, 10, 40, 200, 210, 900, 910, 940} | ignored
        bad_g = is_g & ~np.isin(codes, sorted(known))
        candidates = []
        g_rows = np.full(self.n_lines, False)
        if bad_g.any():
            t = int(np.flatnonzero(bad_g)[0])
            name = "G" + _code(self.value[t])
            message = _UNSUPPORTED_G.get(name, f"unsupported G code {name}")
            g_rows[self.line[t]] = True
            candidates.append((g_rows, message.replace("{", "{{").replace("}", "}}"), "G"))
        if self.unknown.any():
            t = int(np.flatnonzero(self.unknown)[0])
            rows = np.full(self.n_lines, False)
            rows[self.line[t]] = True
            ch = chr(self.letter[t])
            # a G-code error on the same line explains more (e.g. G2 before its I J words)
            rows &= ~g_rows
            candidates.append((rows, "unsupported word {word} (axes are "
                               f"{' '.join(AXIS_WORDS)})", ch))
        self.fail_first(candidates)
        ign = is_g & np.isin(codes, sorted(ignored))
        if ign.any():
            values, counts = np.unique(codes[ign], return_counts=True)
            skipped.update({f"G{_code(c / 10.0)}": int(k) for c, k in zip(values, counts)})
        return codes


def _code10(name: str) -> float:
    return round(float(name[1:]) * 10.0)


def _code(value) -> str:
    """Canonical spelling of a G or M number: ``01`` -> ``1``, ``43.40`` -> ``43.4``."""
    number = float(value)
    return f"{number:g}" if number == int(number) else f"{number:.10g}"


def _kinematics(machine):
    if isinstance(machine, (str, Path)):
        from ..machine.machine_file import load_machine
        machine = load_machine(machine)
    kinematics = getattr(machine, "kinematics", None)
    if kinematics is None or not hasattr(kinematics, "forward"):
        raise InputError("reading G-code needs a machine whose kinematics has forward(q); "
                         f"got {type(machine).__name__}", field="machine")
    return kinematics
