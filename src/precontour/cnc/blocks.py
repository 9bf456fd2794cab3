"""The program's own blocks with corrected end points, at the controller's timing.

A controller re-times new blocks, but keeps the timing of its own blocks moved by microns
(measured on LinuxCNC 2.9: every one of 443 impeller lines started within one servo period
after a smooth +-10 um / 100 urad change of the end points). So the compensation is handed
back as the program itself, every line as written, with only the axis words of its straight
feed moves changed.

Which end points: the controller interpolates between them, so the end points are chosen so
that its interpolation fits the needed correction over each whole block, not sampled at the
block ends. At the trace's timing the controller's position is (LinuxCNC's planner sums the
displacements of the blocks it blends)

    w(t) = P_0 + sum_k s_k(t) (P_k - P_(k-1)),

with s_k(t) the progress of block k (0 before it, 1 after it, both blocks progressing in a
blend). With the timing kept, moving the end points by dP_k moves the position by

    dw(t) = sum_k (s_k(t) - s_(k+1)(t)) dP_k,

a hat function per end point. The correction dw(t) needed (the compensated commands minus the
traced ones, in the program's coordinates: machine axes, or tool tip and rotary axes for tool
centre point moves) is fitted by these hats in least squares over every sample of the
program (:func:`fit_end_points`). s_k(t) is measured from the trace: the projection of the
traced position on the block's chord, within the samples the controller spends around the
block (its ``line`` column).

What is corrected: straight feed moves (G1) that are alone on their line and whose axis words
are plain numbers. Rapids (G0) keep their end points (they do not cut); arcs (G2/G3) keep
theirs too (an arc's end point and centre are tied: moved alone the arc changes radius),
and so do moves on lines written with expressions or parameters: their corrections are 0 and
the fit spreads the correction over the neighbours. A zero-length move keeps its
predecessor's correction. Absolute (G90) and incremental (G91) words, millimetres (G21) and
inches (G20) are kept as written; a word the line did not have is added where its axis is
corrected.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import sparse
from scipy.sparse import linalg as sparse_linalg

from ..errors import InputError
from .trace import ControllerTrace, degrees_per_unit

__all__ = ["CorrectedProgram", "correct_program", "fit_end_points", "block_starts"]

#: Weight of a degree against a millimetre when the progress along a block is measured
#: (1 deg ~ 1.7 mm at 100 mm from the axis): the chord's direction in five coordinates.
DEGREE_WEIGHT = 1.0
#: Tikhonov weight of the end-point corrections, relative to the mean of the normal
#: matrix's diagonal: keeps end points that no sample constrains (a zero-length or a
#: one-sample block) at the neighbours' correction instead of undetermined.
RIDGE = 1e-6
#: Change of a block's chord on one axis (its end-point correction minus its predecessor's),
#: as a fraction of what the axis covers at its speed limit in the time the block needs at
#: its most loaded axis's, that costs as much as leaving the whole correction unfitted over
#: the block: corrections that would load an axis more or less by much more are not made.
CHORD_CHANGE = 0.02
#: The same for the corner a correction adds between two blocks (the second difference of
#: the corrections), as a fraction of what the axis covers at its speed limit in the block's
#: time. Without it, learned corrections zigzagged over consecutive blocks (+-3-6 % of their
#: length) and LinuxCNC's blending slowed by 1-3.6 ms a block: blocks of the paper path's
#: G-code ended up to 32 periods late. Measured there (simulated drives, four learning
#: iterations): 0.003 kept every block within one period (mean tip error 1.11 um, from
#: 2.62 uncompensated), 0.005 let them drift 4 periods, 0.002 cost accuracy (1.25 um).
CORNER = 0.003
#: Blocks shorter than this (mm of X Y Z, or degrees for a rotary-only block) keep their
#: end points: LinuxCNC's planner times short blocks by their length (a block's speed is
#: held to about sqrt(a L / 2)), so that a correction of a few per cent of a block that
#: short moves every later block (measured on the paper path's G-code, whose blocks start
#: from rest 2.5, 7.5, 15.6 ... um long: corrected down to 0.1 mm every block ended within
#: one servo period of the uncompensated run's, corrected throughout up to 3 periods later).
MIN_BLOCK = 0.1
#: Least decimals written for a corrected word: 0.1 um in mm, 1e-5 in inches and degrees.
DECIMALS = {"mm": 4, "inch": 5, "deg": 5}

_WORD = re.compile(r"([A-Za-z])\s*([-+]?(?:\d+\.?\d*|\.\d+))")


@dataclass(frozen=True)
class CorrectedProgram:
    """The program with corrected end points.

    Attributes
    ----------
    text : str
        The program, every line as written but the corrected moves' axis words.
    lines : ndarray of int, shape (K,)
        Source line of each corrected move.
    correction : ndarray, shape (K, 5)
        Its end point's correction in the program's coordinates, mm and degrees.
    fixed : int
        Straight feed moves kept as written (expressions, several moves on a line).
    residual_rms, needed_rms : ndarray, shape (5,)
        RMS over the samples the corrected blocks span of the correction they leave out and
        of the correction needed, per coordinate (mm, degrees): how much of it they carry.
    """

    text: str
    lines: np.ndarray
    correction: np.ndarray
    fixed: int
    residual_rms: np.ndarray
    needed_rms: np.ndarray


def program_coordinates(kinematics, q: np.ndarray, tcp: np.ndarray) -> np.ndarray:
    """The program's coordinates of machine axes ``q`` (N, 5; mm, rad): the machine axes in mm
    and degrees, or, where ``tcp``, the tool tip (workpiece frame) and the rotary axes."""
    w = q * degrees_per_unit()
    if np.any(tcp):
        tip, _ = kinematics.forward(q[tcp])
        w[tcp, :3] = tip
    return w


def block_starts(line: np.ndarray, lines: np.ndarray) -> np.ndarray:
    """For each of ``lines`` (the program's moves in order), the first sample at which the
    trace's ``line`` column reaches it after the previous one's (-1 where it never does):
    when the controller starts executing the block, i.e. ends the one before. Linear in the
    samples: the column is walked as its runs of equal values."""
    line = np.asarray(line)
    starts = np.full(len(lines), -1, dtype=np.int64)
    if line.size == 0:
        return starts
    run_start = np.flatnonzero(np.concatenate([[True], line[1:] != line[:-1]]))
    run_value = line[run_start]
    # for each line number, the runs where it stands, in order
    order = np.argsort(run_value, kind="stable")
    values, first = np.unique(run_value[order], return_index=True)
    where = {int(v): order[f:l] for v, f, l in zip(values, first,
                                                    np.append(first[1:], order.size))}
    position = 0            # the run the previous block started in
    for k, number in enumerate(np.asarray(lines)):
        runs = where.get(int(number))
        if runs is None:
            continue
        i = np.searchsorted(runs, position)
        if i < runs.size:
            starts[k] = run_start[runs[i]]
            position = runs[i]
    return starts


def _progress(w: np.ndarray, begin: np.ndarray, end: np.ndarray, lo: int,
              hi: int) -> np.ndarray | None:
    """s(t) of one block from ``begin`` to ``end`` over samples [lo, hi) (0 before them, 1
    after them), or None for a block of zero length."""
    weights = np.where(np.arange(5) < 3, 1.0, DEGREE_WEIGHT)
    d = (end - begin) * weights
    length2 = float(d @ d)
    if length2 <= 1e-24:
        return None
    part = ((w[lo:hi] - begin) * weights) @ d / length2
    return np.maximum.accumulate(np.clip(part, 0.0, 1.0)) if part.size else part


def _block_time(ends: np.ndarray, start: np.ndarray, k: int, speeds: np.ndarray) -> float:
    """Time move ``k`` needs at its most loaded axis's speed limit, s."""
    previous = start if k == 0 else ends[k - 1]
    return float(np.max(np.abs(ends[k] - previous) / speeds))


def _local(s: np.ndarray | None, lo: int, hi: int, a: int, b: int) -> np.ndarray:
    """Progress given on [lo, hi) as values on [a, b) (0 before lo, 1 from hi)."""
    out = np.zeros(b - a)
    if s is None:
        return out
    idx = np.arange(a, b)
    out[idx >= hi] = 1.0
    inside = (idx >= lo) & (idx < hi)
    out[inside] = s[idx[inside] - lo]
    return out


def fit_end_points(w: np.ndarray, dw: np.ndarray, ends: np.ndarray, start: np.ndarray,
                   windows: np.ndarray, free: np.ndarray,
                   speeds: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """End-point corrections (K, 5) whose hats fit ``dw`` (N, 5) in least squares.

    ``w`` (N, 5): the traced positions in program coordinates; ``ends`` (K, 5): the moves'
    end points, ``start`` (5,) the point before the first; ``windows`` (K, 2): the samples
    [lo, hi) the controller spends around each move (increasing); ``free`` (K,): the moves
    whose end point may move (the others keep 0); ``speeds`` (5,): the axes' speed limits
    in the same units per s. Returns the corrections and the fitted dw. Each hat is built
    over its own window only, so the work is linear in the samples."""
    n, count = w.shape[0], ends.shape[0]
    # progress of each move; a zero-length move's end is its predecessor's
    owner = np.arange(count)
    progress: list[np.ndarray | None] = []
    begin = start
    for k in range(count):
        s = _progress(w, begin, ends[k], int(windows[k, 0]), int(windows[k, 1]))
        progress.append(s)
        if s is None and k > 0:
            owner[k] = owner[k - 1]
        begin = ends[k]
    # hat of end point k: s_k - s_(k+1), nonzero from s_k's start to s_(k+1)'s end, summed
    # into the unknown that owns it
    unknown = {k: j for j, k in enumerate(sorted({int(owner[k]) for k in range(count)
                                                  if free[owner[k]]}))}
    rows, cols, vals = [], [], []
    for k in range(count):
        j = unknown.get(int(owner[k]))
        if j is None:
            continue
        lo, hi = int(windows[k, 0]), int(windows[k, 1])
        a = lo
        b = max(hi, int(windows[k + 1, 1])) if k + 1 < count else hi
        hat = _local(progress[k], lo, hi, a, b)
        if k + 1 < count:
            hat -= _local(progress[k + 1], int(windows[k + 1, 0]), int(windows[k + 1, 1]),
                          a, b)
        nz = np.flatnonzero(np.abs(hat) > 1e-12)
        rows.append(a + nz)
        cols.append(np.full(nz.size, j))
        vals.append(hat[nz])
    correction = np.zeros((count, 5))
    if not unknown:
        return correction, np.zeros_like(dw)
    size = len(unknown)
    basis = sparse.csr_matrix((np.concatenate(vals), (np.concatenate(rows),
                                                      np.concatenate(cols))),
                              shape=(n, size))
    gram = (basis.T @ basis).tocsc()
    rhs = np.asarray(basis.T @ dw)
    # The change of each unknown's chord (its correction minus its predecessor's), per
    # coordinate, against the time the block needs at its most loaded axis's speed limit: the
    # controller keeps a block's timing while no axis needs noticeably more or less of it
    # (its speed on short blocks is limited by their length and the axes' limits).
    order = sorted(unknown, key=unknown.get)
    block_time = np.array([_block_time(ends, start, k, speeds) for k in order])
    samples = np.asarray(gram.diagonal()).ravel()
    needed = np.sqrt(np.mean(dw ** 2, axis=0)) + 1e-15
    difference = sparse.diags([np.ones(size), -np.ones(size - 1)], [0, -1], format="csc")
    # the corner a correction adds between two blocks (its second difference against the
    # chord): the controller slows for corners (LinuxCNC blends them within G64's tolerance)
    bend = sparse.diags([np.ones(size), -2.0 * np.ones(size - 1), np.ones(size - 2)],
                        [0, -1, -2], format="csc")
    solved = np.zeros((size, 5))
    at_speed = np.maximum(block_time, np.max(block_time) * 1e-6 + 1e-12)
    for c in range(5):
        weight = samples * (needed[c] / (CHORD_CHANGE * speeds[c] * at_speed)) ** 2
        corner = samples * (needed[c] / (CORNER * speeds[c] * at_speed)) ** 2
        normal = (gram + difference.T @ sparse.diags(weight) @ difference
                  + bend.T @ sparse.diags(corner) @ bend)
        ridge = RIDGE * float(normal.diagonal().mean() or 1.0)
        normal = (normal + ridge * sparse.identity(size, format="csc")).tocsc()
        solved[:, c] = sparse_linalg.splu(normal).solve(rhs[:, c])
    fitted = basis @ solved
    for k in range(count):
        j = unknown.get(int(owner[k]))
        if j is not None:
            correction[k] = solved[j]
    return correction, fitted


@dataclass
class _Line:
    """One source line's axis words: letter -> (span of the number, value, decimals)."""

    words: dict
    plain: bool


def _scan(text: str, letters: str) -> _Line:
    code, plain, words = [], True, {}
    depth = 0
    for ch in text:
        if ch == "(":
            depth += 1
        elif ch == ")":
            depth = max(depth - 1, 0)
        elif ch == ";" and depth == 0:
            break
        code.append(ch if depth == 0 and ch != ")" else " ")
    code = "".join(code)
    for match in _WORD.finditer(code):
        letter = match.group(1).upper()
        if letter in letters:
            number = match.group(2)
            decimals = len(number.split(".")[1]) if "." in number else 0
            words[letter] = (match.span(2), float(number), decimals)
    for letter in letters:  # an axis word with an expression or a parameter
        if re.search(rf"(?i){letter}\s*[\[#]", code):
            plain = False
    return _Line(words=words, plain=plain)


def _modes(lines: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """Per source line (1-based index), after the line: incremental (G91) and inch (G20)."""
    incremental = np.zeros(len(lines) + 1, dtype=bool)
    inch = np.zeros(len(lines) + 1, dtype=bool)
    inc, inches = False, False
    for number, text in enumerate(lines, 1):
        code = re.sub(r"\([^)]*\)", " ", text).split(";")[0].upper()
        for value in re.findall(r"G\s*(\d+(?:\.\d+)?)", code):
            g = float(value)
            if g == 90:
                inc = False
            elif g == 91:
                inc = True
            elif g in (20, 70):
                inches = True
            elif g in (21, 71):
                inches = False
        incremental[number] = inc
        inch[number] = inches
    return incremental, inch


def correct_program(program_path: str | Path, machine, trace: ControllerTrace,
                    commands: np.ndarray, *, tcp: bool = False) -> CorrectedProgram:
    """The program at ``program_path`` with its straight feed moves' end points corrected so
    that, at the timing of ``trace`` (the controller's trace of the program as written), its
    interpolation follows ``commands`` (N, 5; machine axes, mm and rad, at the trace's
    samples) instead of the traced commands."""
    from ..toolpath import read_program

    path = Path(program_path)
    program = read_program(path, machine, tcp=tcp)
    moves = program.programmed
    commands = np.asarray(commands, dtype=float)
    if commands.shape != trace.command.shape:
        raise ValueError(f"commands must have the trace's shape {trace.command.shape}")
    if trace.line is None:
        raise InputError("the trace has no program line column (line): it cannot be matched "
                         "to the program's blocks", source=trace.source, field="line")
    letters = "".join(machine.axis_names)
    text = path.read_text()
    source_lines = text.splitlines(keepends=True)
    plain_lines = [s.rstrip("\r\n") for s in source_lines]

    # which move each sample executes (the last move reached), and its mode
    move_lines = moves.line
    starts = block_starts(trace.line, move_lines)
    reached = starts >= 0
    if not np.any(reached):
        raise InputError("the trace never executes one of the program's moves (its line "
                         "column names none of the program's move lines): a trace of "
                         "another program?", source=trace.source, field="line")
    n = trace.n_samples
    active = np.full(n, -1)
    active[starts[reached]] = np.flatnonzero(reached)
    active = np.maximum.accumulate(active)
    sample_tcp = np.where(active >= 0, moves.tcp[np.maximum(active, 0)], False)
    kin = machine.kinematics
    w = program_coordinates(kin, trace.command, sample_tcp)
    dw = program_coordinates(kin, commands, sample_tcp) - w

    # the samples around each move: from its predecessor's start to its successor's end
    count = moves.n_moves
    filled = np.where(reached, starts, n)
    filled = np.minimum.accumulate(filled[::-1])[::-1]      # unreached: the next one's
    begin_of = np.concatenate([[0], filled[:-1]])          # predecessor's start
    after = np.concatenate([filled[2:], [n, n]])[:count]   # successor's end
    windows = np.column_stack([begin_of, np.maximum(after, begin_of)])

    per_line = np.bincount(move_lines, minlength=len(plain_lines) + 2)
    scans = {}
    free = np.zeros(count, dtype=bool)
    fixed = 0
    for k in range(count):
        if moves.kind[k] != 1 or not reached[k]:
            continue
        number = int(move_lines[k])
        scan = _scan(plain_lines[number - 1], letters) if 0 < number <= len(plain_lines) \
            else None
        if scan is None or not scan.plain or per_line[number] != 1:
            fixed += 1
            continue
        scans[k] = scan
        free[k] = True
    # where the first move starts: the program's start point, in the first move's frame
    start_point = program_coordinates(kin, np.asarray(program.start, dtype=float)[None],
                                      moves.tcp[:1])[0]
    # short blocks keep their end points (see MIN_BLOCK)
    previous = np.vstack([start_point, moves.end[:-1]])
    chord = np.linalg.norm(moves.end[:, :3] - previous[:, :3], axis=1)
    rotary_only = chord < 1e-9
    chord[rotary_only] = np.linalg.norm(moves.end[rotary_only, 3:] - previous[rotary_only, 3:],
                                        axis=1)
    free &= chord >= MIN_BLOCK
    incremental, inch = _modes(plain_lines)
    # in G91 a move kept as written carries the correction of the move before it on: that
    # move's end point is kept too
    kept = ~free & incremental[move_lines]
    free[np.flatnonzero(kept[1:])] = False
    speeds = np.array([d.v_max if d.v_max else np.inf for d in machine.drives]) \
        * degrees_per_unit()
    if not np.all(np.isfinite(speeds)):
        raise InputError("the axes' speed limits (v_max) are needed to keep the blocks' "
                         "timing", source=machine.source or machine.name, field="v_max")
    correction, fitted = fit_end_points(w, dw, moves.end, start_point, windows, free, speeds)
    correction[~free] = 0.0

    # offsets between words and absolute end points, per axis, for words a line lacks
    offsets = np.full(5, np.nan)
    previous = np.zeros(5)
    out = list(source_lines)
    for k in range(count):
        number = int(move_lines[k])
        scale = np.where(np.arange(5) < 3, 25.4 if inch[number] else 1.0, 1.0)
        scan = scans.get(k) or (_scan(plain_lines[number - 1], letters)
                                if 0 < number <= len(plain_lines) else None)
        if scan is not None and not incremental[number]:
            for slot, letter in enumerate(letters):
                if letter in scan.words:
                    offsets[slot] = moves.end[k, slot] - scan.words[letter][1] * scale[slot]
        if free[k]:
            delta = correction[k] - previous if incremental[number] else correction[k]
            out[number - 1] = _rewrite(source_lines[number - 1], scan, delta, scale, letters,
                                       moves.end[k], offsets, bool(incremental[number]),
                                       bool(inch[number]))
        previous = correction[k]
    # the samples the corrected blocks cover
    cover = np.zeros(n + 1)
    np.add.at(cover, windows[free, 0], 1.0)
    np.add.at(cover, windows[free, 1], -1.0)
    program_samples = np.cumsum(cover[:-1]) > 0
    residual = dw[program_samples] - fitted[program_samples]
    rms = lambda a: np.sqrt(np.mean(a ** 2, axis=0)) if a.size else np.zeros(5)  # noqa: E731
    return CorrectedProgram(text="".join(out), lines=move_lines[free],
                            correction=correction[free], fixed=fixed,
                            residual_rms=rms(residual), needed_rms=rms(dw[program_samples]))


def _rewrite(raw: str, scan: _Line, delta: np.ndarray, scale: np.ndarray, letters: str,
             end: np.ndarray, offsets: np.ndarray, incremental: bool, inch: bool) -> str:
    """``raw`` with its axis words moved by ``delta`` (program coordinates, mm and degrees)
    and words added where an axis moves that the line did not name."""
    body = raw.rstrip("\r\n")
    newline = raw[len(body):]
    edits = []      # (start, stop, new text), right to left
    added = []
    for slot, letter in enumerate(letters):
        step = delta[slot] / scale[slot]
        unit = "deg" if slot >= 3 else ("inch" if inch else "mm")
        if letter in scan.words:
            (lo, hi), value, decimals = scan.words[letter]
            if step == 0.0:
                continue
            edits.append((lo, hi, _format(value + step, max(decimals, DECIMALS[unit]))))
        elif step != 0.0 and abs(step) >= 0.5 * 10.0 ** -DECIMALS[unit]:
            if incremental:
                value = step
            elif np.isfinite(offsets[slot]):
                value = (end[slot] + delta[slot] - offsets[slot]) / scale[slot]
            else:
                continue        # no word of this axis yet: its frame is unknown
            added.append(f"{letter}{_format(value, DECIMALS[unit])}")
    for lo, hi, new in sorted(edits, reverse=True):
        body = body[:lo] + new + body[hi:]
    if added:
        code_end = _code_end(body)
        body = body[:code_end].rstrip() + " " + " ".join(added) + \
            (" " + body[code_end:].lstrip() if body[code_end:].strip() else "")
    return body + newline


def _code_end(body: str) -> int:
    """Index where the line's trailing comment starts (``;`` or a final ``(...)``)."""
    semicolon = body.find(";")
    end = len(body) if semicolon < 0 else semicolon
    stripped = body[:end].rstrip()
    if stripped.endswith(")"):
        opening = stripped.rfind("(")
        if opening >= 0:
            return opening
    return end


def _format(value: float, decimals: int) -> str:
    text = f"{value:.{decimals}f}"
    return "0." + "0" * decimals if text.startswith("-") and float(text) == 0.0 else text
