"""The program's own blocks with corrected end points (precontour.cnc.blocks).

A controller's trace is made here by interpolating the program's end points the way LinuxCNC's
planner sums block displacements (each block's progress a smooth ramp over its time, blends
overlapping); a correction that blocks can carry exactly (hats of chosen end-point
corrections at that timing) must come back as those corrections, and the rewritten program,
read by an independent G-code parser (gcodeparser) and by precontour's reader, must differ from
the original only in the corrected axis words, by the corrections.
"""

from __future__ import annotations

import numpy as np
import pytest
from gcodeparser import GcodeParser
from hypothesis import given, settings
from hypothesis import strategies as st

from precontour import load_machine
from precontour.cnc import ControllerTrace, correct_program
from precontour.cnc import blocks
from precontour.cnc.blocks import MIN_BLOCK, block_starts, fit_end_points
from precontour.toolpath import read_program

DEG = np.array([1.0, 1.0, 1.0, np.pi / 180, np.pi / 180])


def _program(n_blocks=40, *, incremental=False, inch=False, extra="") -> tuple[str, np.ndarray,
                                                                               np.ndarray]:
    """A G94 program of straight moves along a gentle five-axis curve: (text, start, ends) in
    program units (mm or inches, degrees)."""
    u = np.linspace(0.0, 1.0, n_blocks + 1)
    points = np.column_stack([20 + 30 * u, 10 + 8 * np.sin(2 * u), 5 + 2 * u ** 2,
                              10 * np.sin(u), 40 * u])
    scale = np.array([1 / 25.4 if inch else 1.0] * 3 + [1.0, 1.0])
    words = points * scale
    lines = ["%", "(a test program)", "G20" if inch else "G21", "G90 G94",
             "G0 X{:.4f} Y{:.4f} Z{:.4f} A{:.4f} C{:.4f}".format(*words[0])]
    if incremental:
        lines.append("G91")
    previous = words[0]
    for k, p in enumerate(words[1:]):
        shown = p - previous if incremental else p
        comment = " (block %d)" % k if k % 7 == 3 else ""
        lines.append("G1 X{:.4f} Y{:.4f} Z{:.4f} A{:.4f} C{:.4f} F600".format(*shown) + comment)
        previous = p
    lines += [extra, "M2", "%"] if extra else ["M2", "%"]
    return "\n".join(lines) + "\n", points[0], points[1:]


def _trace(text, path, machine, *, period=1e-3, block_time=0.025, overlap=0.006):
    """A planner-like trace of the program's moves: each block's displacement added with a
    smooth progress ramp over its time (blends overlapping by ``overlap``), the line column
    switching at each block's start; positions in program coordinates (mm, degrees)."""
    program = read_program(path, machine)
    moves = program.programmed
    start = np.degrees(program.start)
    start[:3] = program.start[:3]
    ends = moves.end
    count = moves.n_moves
    rest = 0.1
    n = int((rest * 2 + count * block_time + overlap) / period)
    t = np.arange(n) * period
    w = np.tile(start, (n, 1))
    line = np.full(n, moves.line[0] - 1)
    previous = start
    for k in range(count):
        t0 = rest + k * block_time
        t1 = t0 + block_time + overlap
        s = np.clip((t - t0) / (t1 - t0), 0.0, 1.0)
        s = s * s * (3 - 2 * s)
        w += s[:, None] * (ends[k] - previous)
        line[t >= t0] = moves.line[k]
        previous = ends[k]
    return ControllerTrace(t=t, command=w * DEG, line=line, source="synthetic"), moves, start


def _ramp(k):
    """0 at the first block (its start point, the approach's end, is kept), rising smoothly
    over ten blocks: a correction the penalties on chord changes leave alone."""
    return (np.sin(0.5 * np.pi * np.clip(k / 10, 0, 1)) ** 2)[:, None]


@pytest.fixture(scope="module")
def machine():
    return load_machine("zhang2013")


def _hats(trace, moves, start, correction):
    """The displacement the corrected end points add at the trace's timing, computed the
    way the trace was made (sum of the blocks' progress times their chord changes)."""
    w = trace.command / DEG
    out = np.zeros_like(w)
    previous_end, previous_corr = start, np.zeros(5)
    for k in range(moves.n_moves):
        d = moves.end[k] - previous_end
        span = np.linalg.norm(d)
        s = np.clip(((w - previous_end) @ d) / span ** 2, 0, 1) if span > 0 else 0
        out += np.asarray(s)[:, None] * (correction[k] - previous_corr)
        previous_end, previous_corr = moves.end[k], correction[k]
    return out


def test_a_correction_blocks_can_carry_comes_back_as_the_end_points(tmp_path, machine,
                                                                    monkeypatch):
    text, _, _ = _program()
    path = tmp_path / "p.ngc"
    path.write_text(text)
    trace, moves, start = _trace(text, path, machine)
    k = np.arange(moves.n_moves)
    wanted = np.column_stack([2e-3 * np.sin(k / 6), 1e-3 * np.cos(k / 5), 1.5e-3 * np.sin(k / 9),
                              5e-3 * np.sin(k / 7), 8e-3 * np.cos(k / 8)]) * _ramp(k)
    commands = trace.command + _hats(trace, moves, start, wanted) * DEG
    with monkeypatch.context() as free:
        # without the penalties on chord changes and corners: the exact least-squares fit
        free.setattr(blocks, "CHORD_CHANGE", np.inf)
        free.setattr(blocks, "CORNER", np.inf)
        exact = correct_program(path, machine, trace, commands)
    assert exact.lines.tolist() == moves.line.tolist()
    assert np.abs(exact.correction - wanted).max() < 1e-6 * np.abs(wanted).max()
    assert np.all(exact.residual_rms < 1e-6 * exact.needed_rms)
    # with them, a smooth correction is biased by a few per cent at most (measured: 6.5 %
    # of the largest correction, where C's correction grows fastest over the first blocks)
    result = correct_program(path, machine, trace, commands)
    assert np.abs(result.correction - wanted).max() < 0.1 * np.abs(wanted).max()
    assert np.all(result.residual_rms < 0.1 * result.needed_rms)


def test_rewritten_program_differs_only_in_the_corrected_axis_words(tmp_path, machine):
    text, _, _ = _program()
    path = tmp_path / "p.ngc"
    path.write_text(text)
    trace, moves, start = _trace(text, path, machine)
    k = np.arange(moves.n_moves)
    wanted = np.column_stack([3e-3 * np.sin(k / 6)] * 3 + [4e-3 * np.sin(k / 7)] * 2) * _ramp(k)
    commands = trace.command + _hats(trace, moves, start, wanted) * DEG
    result = correct_program(path, machine, trace, commands)
    out = tmp_path / "out.ngc"
    out.write_text(result.text)
    before = GcodeParser(text, include_comments=True).lines
    after = GcodeParser(result.text, include_comments=True).lines
    assert len(before) == len(after)
    by_line = dict(zip(result.lines.tolist(), result.correction))
    source_lines = text.splitlines()
    rewritten = result.text.splitlines()
    assert len(source_lines) == len(rewritten)
    for number, (old, new) in enumerate(zip(source_lines, rewritten), 1):
        if number not in by_line:
            assert old == new
            continue
        a = GcodeParser(old, include_comments=True).lines[0]
        b = GcodeParser(new, include_comments=True).lines[0]
        assert a.command == b.command
        assert a.params["F"] == b.params["F"]
        assert a.comment == b.comment
        for slot, letter in enumerate("XYZAC"):
            assert b.params[letter] == pytest.approx(a.params[letter] + by_line[number][slot],
                                                     abs=6e-5)
    # precontour's reader sees the corrected end points
    corrected = read_program(out, machine).programmed
    assert np.allclose(corrected.end - moves.end, np.vstack([by_line[n] for n in moves.line]),
                       atol=6e-5)


@pytest.mark.parametrize("incremental, inch", [(True, False), (False, True), (True, True)])
def test_incremental_and_inch_programs_get_the_same_end_points(tmp_path, machine,
                                                              incremental, inch):
    text, _, _ = _program(incremental=incremental, inch=inch)
    path = tmp_path / "p.ngc"
    path.write_text(text)
    trace, moves, start = _trace(text, path, machine)
    k = np.arange(moves.n_moves)
    wanted = np.column_stack([3e-3 * np.sin(k / 6)] * 5) * _ramp(k)
    commands = trace.command + _hats(trace, moves, start, wanted) * DEG
    result = correct_program(path, machine, trace, commands)
    out = tmp_path / "out.ngc"
    out.write_text(result.text)
    corrected = read_program(out, machine).programmed
    change = corrected.end - moves.end
    decimals = 1e-5 * (25.4 if inch else 1.0)
    expected = np.zeros_like(change)
    expected[np.isin(moves.line, result.lines)] = result.correction
    # incremental words accumulate their rounding
    assert np.abs(change - expected).max() < (moves.n_moves if incremental else 1) * decimals
    assert np.abs(expected).max() > 1e-3


def test_lines_with_expressions_and_short_blocks_keep_their_words(tmp_path, machine):
    text, _, _ = _program()
    lines = text.splitlines()
    target = next(i for i, s in enumerate(lines) if s.startswith("G1")) + 10
    words = lines[target].split()
    lines[target] = " ".join([words[0], f"X[{words[1][1:]}+0]"] + words[2:])
    short = target + 5
    p = [float(w[1:]) for w in lines[short - 1].split()[1:6]]
    lines[short] = "G1 X{:.4f} Y{:.4f} Z{:.4f} A{:.4f} C{:.4f} F600".format(
        p[0] + 0.5 * MIN_BLOCK, *p[1:])
    text = "\n".join(lines) + "\n"
    path = tmp_path / "p.ngc"
    path.write_text(text)
    trace, moves, start = _trace(text, path, machine)
    commands = trace.command + np.full(trace.command.shape, 2e-3) * DEG
    result = correct_program(path, machine, trace, commands)
    out = result.text.splitlines()
    assert out[target] == lines[target]
    assert out[short] == lines[short]
    assert result.fixed == 1
    assert target + 1 not in result.lines and short + 1 not in result.lines


def test_block_starts_follow_the_line_column():
    line = np.array([0, 0, 5, 5, 6, 6, 6, 9, 9, 5])
    assert block_starts(line, np.array([5, 6, 8, 9, 5])).tolist() == [2, 4, -1, 7, 9]


@settings(max_examples=200, deadline=None)
@given(st.lists(st.integers(0, 5), min_size=1, max_size=60),
       st.lists(st.integers(0, 6), min_size=1, max_size=12))
def test_block_starts_are_a_forward_scan(column, lines):
    """Against the plain scan: each block's first sample at or after the previous block's."""
    column, lines = np.array(column), np.array(lines)
    expected, position = [], 0
    for number in lines:
        hits = np.flatnonzero(column[position:] == number)
        if hits.size:
            position += int(hits[0])
            expected.append(position)
        else:
            expected.append(-1)
    assert block_starts(column, lines).tolist() == expected


def test_fit_is_linear_in_the_samples():
    """Each hat is built over its own window: the basis of a long trace has a bounded number
    of entries per sample."""
    n_blocks, per = 3000, 20
    n = n_blocks * per
    ends = np.zeros((n_blocks, 5))
    ends[:, 0] = np.arange(1, n_blocks + 1, dtype=float)
    t = np.arange(n)
    w = np.zeros((n, 5))
    w[:, 0] = t / per
    windows = np.column_stack([np.maximum(np.arange(n_blocks) * per - per, 0),
                               np.minimum(np.arange(n_blocks) * per + 2 * per, n)])
    dw = np.zeros((n, 5))
    dw[:, 1] = 1e-3 * np.sin(t / 500)
    correction, fitted = fit_end_points(w, dw, ends, np.zeros(5), windows,
                                        np.ones(n_blocks, bool), np.full(5, 100.0))
    assert np.abs(fitted[:, 1] - dw[:, 1])[per * 5:-per * 5].max() < 1e-5
