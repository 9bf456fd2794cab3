"""G-code and halstreamer writers: read back by an independent G-code parser (``gcodeparser``
from PyPI) and by a line parser that follows LinuxCNC's ``streamer_usr.c``."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from precontour.errors import InputError
from precontour.toolpath.writers import (DEFAULT_TOL_LINEAR, DEFAULT_TOL_ROTARY, ProgramInfo,
                                         gcode_tolerances, decimate, gcode_program,
                                         halstreamer_lines, streamer_depth)

gcodeparser = pytest.importorskip("gcodeparser")

TS = 0.001


def _commands(n=3000, seed=0):
    """Smooth five-axis commands with a few sharp features and a final hold."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * TS
    phases = rng.uniform(0, 2 * np.pi, 5)
    q = np.column_stack([
        40 * np.sin(2.1 * t + phases[0]) + 3 * np.abs(np.sin(7 * t)),
        25 * np.cos(1.3 * t + phases[1]),
        -10 + 2 * t,
        0.4 * np.sin(1.7 * t + phases[3]),
        0.9 * t + 0.05 * np.sin(11 * t),
    ])
    q[-300:] = q[-300]
    return t, q


def _read_back(text):
    """Independent reading: start point from G0, then each G1 (inverse-time F) or G4 (P s) as
    a straight move in time. Returns block end times and positions (mm, rad)."""
    lines = gcodeparser.parse_gcode_lines(text, include_comments=False)
    times, points = [], []
    mode93 = False
    now = 0.0
    for item in lines:
        letter, number = item.command
        params = item.params
        if (letter, number) == ("G", 93):
            mode93 = True
        elif (letter, number) == ("G", 94):
            mode93 = False
        elif (letter, number) == ("G", 0):
            assert not times, "one G0, to the start"
            times.append(now)
            points.append([params[a] for a in "XYZAC"])
        elif (letter, number) == ("G", 1):
            assert mode93 and "F" in params
            now += 60.0 / params["F"]
            points.append([params.get(a, points[-1][i]) for i, a in enumerate("XYZAC")])
            times.append(now)
        elif (letter, number) == ("G", 4):
            now += params["P"]
            points.append(points[-1])
            times.append(now)
    points = np.array(points, dtype=float)
    points[:, 3:] = np.radians(points[:, 3:])
    return np.array(times), points


def _interpolate(times, points, t):
    return np.column_stack([np.interp(t, times, points[:, i]) for i in range(5)])


def test_written_gcode_reproduces_commands_within_tolerance():
    t, q = _commands()
    program = gcode_program(t, q)
    times, points = _read_back(program.text)
    assert len(times) == program.n_blocks + 1
    assert times[-1] == pytest.approx(t[-1], abs=1e-9)
    deviation = np.abs(_interpolate(times, points, t) - q).max(axis=0)
    tol = np.array([DEFAULT_TOL_LINEAR] * 3 + [DEFAULT_TOL_ROTARY] * 2)
    assert np.all(deviation <= tol), deviation
    # It decimates: smooth commands need far fewer blocks than samples, and none is shorter
    # than the servo period.
    assert program.n_blocks < t.size / 3
    assert np.diff(times).min() >= TS * (1 - 1e-9)
    # The tolerance is used: tightening it tenfold needs more blocks.
    finer = gcode_program(t, q, tolerance=gcode_tolerances(1e-4, 1e-6))
    assert finer.n_blocks > program.n_blocks


def test_gcode_header_and_modes():
    t, q = _commands(500)
    info = ProgramInfo(machine="zhang2013", controller="pid-low", method="contour",
                       source="part (v2).ngc")
    text = gcode_program(t, q, info=info).text
    head = text.split("G0 ")[0]
    for word in ("zhang2013", "pid-low", "contour", "part [v2].ngc"):
        assert word in head
    lines = text.splitlines()
    g0 = next(i for i, s in enumerate(lines) if s.startswith("G0 "))
    g93 = lines.index("G93")
    first_g1 = next(i for i, s in enumerate(lines) if s.startswith("G1 "))
    assert g0 < g93 < first_g1
    assert "G90" in lines[g0 - 1] or any("G90" in s for s in lines[:g0])
    assert all("F" in s for s in lines if s.startswith("G1 "))
    assert lines[-2] == "M2" and text.count("M2") == 1


def test_a_hold_becomes_a_dwell():
    t = np.arange(1000) * TS
    q = np.zeros((1000, 5))
    q[:500, 0] = np.linspace(0, 5, 500)
    q[500:, 0] = 5
    text = gcode_program(t, q).text
    assert "G4 P0.5\n" in text
    times, points = _read_back(text)
    assert times[-1] == pytest.approx(t[-1])


def test_passthrough_lines_stay_at_their_places():
    t, q = _commands(2000)
    line = np.repeat(np.arange(10, 30), 100)  # source line of each sample
    passthrough = [(2, "T1 M6"), (3, "M3 S12000"), (14, "M8"), (14, "(roughing done)"),
                   (40, "M30")]
    program = gcode_program(t, q, passthrough=passthrough, line=line)
    lines = program.text.splitlines()
    g0 = next(i for i, s in enumerate(lines) if s.startswith("G0 "))
    assert lines.index("T1 M6") < lines.index("M3 S12000") < g0
    # Every motion block before "M8" ends at a sample of line <= 14, every one after starts
    # with samples of later lines.
    motion = [i for i, s in enumerate(lines) if s.startswith(("G1 ", "G4 "))]
    position = lines.index("M8")
    assert lines[position + 1] == "(roughing done)"
    kept = program.kept
    block_of_line = {li: b for b, li in enumerate(motion)}
    before = [block_of_line[i] for i in motion if i < position]
    after = [block_of_line[i] for i in motion if i > position]
    assert line[kept[max(before) + 1]] <= 14
    assert line[kept[min(after)] + 1] > 14
    assert lines[-2] == "M30" and "M2" not in lines
    times, points = _read_back(program.text)
    assert np.all(np.abs(_interpolate(times, points, t) - q)
                  <= np.array([DEFAULT_TOL_LINEAR] * 3 + [DEFAULT_TOL_ROTARY] * 2))


def _brute_force_ok(t, q, tol, i, j):
    frac = (t[i:j + 1] - t[i]) / (t[j] - t[i])
    line = q[i] + frac[:, None] * (q[j] - q[i])
    return bool(np.all(np.abs(line - q[i:j + 1]) <= tol * (1 + 1e-12)))


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 10_000), st.integers(5, 120), st.floats(0.01, 2.0))
def test_decimate_against_brute_force(seed, n, tol):
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(0.5, 1.5, n))
    q = np.cumsum(rng.normal(size=(n, 2)), axis=0)
    must = rng.uniform(size=n) < 0.05
    kept = decimate(t, q, np.array([tol, 2 * tol]), must)
    tolerance = np.array([tol, 2 * tol])
    assert kept[0] == 0 and kept[-1] == n - 1
    assert set(np.flatnonzero(must)) <= set(kept)
    for a, b in zip(kept[:-1], kept[1:]):
        assert _brute_force_ok(t, q, tolerance, a, b)
        # Greedy and maximal: one sample further would break the tolerance, unless the
        # block had to end at a kept sample.
        if b + 1 < n and not must[b]:
            assert not _brute_force_ok(t, q, tolerance, a, b + 1)


def test_tolerance_must_exceed_rounding():
    with pytest.raises(InputError, match="tol"):
        gcode_tolerances(1e-6, 1e-5)
    with pytest.raises(InputError, match="tol"):
        gcode_tolerances(1e-3, float("nan"))


def _streamer_read(text, n_pins):
    """Lines as streamer_usr.c reads them: '#' in column 0 is a comment; fields are
    whitespace separated and converted like strtod."""
    rows = []
    for raw in text.splitlines(keepends=True):
        if raw.startswith("#"):
            continue
        fields = raw.split()
        assert len(fields) == n_pins and raw.endswith("\n")
        rows.append([float(f) for f in fields])
    return np.array(rows)


def test_halstreamer_file():
    t, q = _commands(2500)
    text = "".join(halstreamer_lines(q, TS, info=ProgramInfo(machine="zhang2013"), chunk=700))
    assert f"loadrt streamer depth={streamer_depth(TS)} cfg=fffff" in text
    assert "0.001 s" in text and "1000000 ns" in text
    rows = _streamer_read(text, 5)
    assert rows.shape == q.shape
    np.testing.assert_array_equal(rows[:, :3], q[:, :3])
    np.testing.assert_allclose(np.radians(rows[:, 3:]), q[:, 3:], rtol=1e-15, atol=1e-15)
    assert streamer_depth(TS) == 2000 and math.isclose(streamer_depth(0.0005), 4000)


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 10_000), st.integers(2, 400), st.floats(1e-4, 1e-2), st.floats(1e-6, 1e-3))
def test_any_commands_round_trip_within_tolerance(seed, n, tol_linear, tol_rotary):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * TS
    q = np.cumsum(rng.normal(scale=[0.01, 0.01, 0.01, 1e-4, 1e-4], size=(n, 5)), axis=0)
    tolerance = gcode_tolerances(tol_linear, tol_rotary)
    program = gcode_program(t, q, tolerance=tolerance)
    times, points = _read_back(program.text)
    assert times[-1] == pytest.approx(t[-1], abs=1e-9)
    assert np.all(np.abs(_interpolate(times, points, t) - q) <= tolerance)


def test_tcp_switches_become_comments_in_a_machine_axis_program():
    from precontour.toolpath.writers import machine_axes_passthrough

    lines = ((1, "M428 ;TCP:xyzac"), (2, "S600 M3"), (3, "G43.4 H1 (tcp on)"), (4, "T2 M6"),
             (5, "TRAORI"), (6, "M429"), (7, "G49"), (8, "M30"), (9, "(G43.4 in a comment)"))
    # a program without TCP keeps everything
    assert machine_axes_passthrough(lines, tcp=False) == lines
    kept = dict(machine_axes_passthrough(lines, tcp=True, tcp_all=True))
    for line in (1, 3, 5, 6, 7):
        assert kept[line].startswith("(precontour: left out") and kept[line].endswith(")")
        assert kept[line].count("(") == 1 and kept[line].count(")") == 1
    assert (kept[2], kept[4], kept[8], kept[9]) == ("S600 M3", "T2 M6", "M30",
                                                    "(G43.4 in a comment)")
    # switched by G43.4 in the program (not --tcp): other M codes are the program's own
    kept = dict(machine_axes_passthrough(lines, tcp=True, tcp_all=False))
    assert kept[1] == "M428 ;TCP:xyzac" and kept[3].startswith("(precontour: left out")


def test_b_c_machine_program_uses_b_words_and_reads_back():
    from precontour import load_machine
    from precontour.toolpath import read_program
    from precontour.toolpath.writers import gcode_program

    machine = load_machine("linuxcnc-xyzbc-trt")
    t = np.arange(200) * 1e-3
    s = t / t[-1]
    q = np.column_stack([10 * s, -5 * s, 20 + 0 * s, np.radians(-30 * s), np.radians(90 * s)])
    text = gcode_program(t, q, axis_names=machine.axis_names).text
    motion = [line for line in text.splitlines() if line.startswith(("G0 ", "G1 "))]
    assert motion and all(" B" in line and " A" not in line for line in motion)
    assert "machine axes X Y Z mm, B C degrees" in text
    import pathlib
    import tempfile
    with tempfile.TemporaryDirectory() as folder:
        path = pathlib.Path(folder) / "bc.ngc"
        path.write_text(text)
        program = read_program(path, machine)
    np.testing.assert_allclose(program.q[-1], q[-1], rtol=0, atol=1e-5)


def test_header_counts_the_blocks_that_move_a_rotary_axis():
    """The header names the planner behaviour the program needs and how many blocks move a
    rotary axis (LinuxCNC 2.9 stretches those; docs/linuxcnc.md)."""
    t = np.arange(600) * TS
    q = np.zeros((600, 5))
    q[:, 0] = 40 * np.sin(np.linspace(0, 3, 600))  # X moves throughout
    q[200:400, 3] = np.linspace(0, 0.3, 200)       # A moves in the middle third only
    q[400:, 3] = 0.3
    program = gcode_program(t, q, axis_names=("X", "Y", "Z", "B", "C"))
    times, points = _read_back(program.text.replace(" B", " A"))
    moving = np.any(np.diff(np.round(np.degrees(points[:, 3:]), 6), axis=0) != 0, axis=1)
    assert program.rotary_blocks == moving.sum() > 0
    assert program.rotary_blocks < program.n_blocks
    head = " ".join(line.strip("()") for line in program.text.split("G21")[0].splitlines())
    assert (f"move B or C, here {program.rotary_blocks} of {program.n_blocks}" in head
            and "60/F s" in head and "stream" in head)
    assert all(len(line) <= 100 for line in program.text.splitlines())
