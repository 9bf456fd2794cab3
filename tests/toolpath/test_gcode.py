"""Tests of the G-code program reader (precontour.toolpath.gcode.read_program) and its
tool-path view; numbers are checked against hand-worked values, the circle equation, the
machine's direct kinematics and a sequential reference interpreter."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from precontour.errors import ForeignSyntaxError, InputError, PrecontourError, ProgramError
from precontour.machine.machine_file import load_machine
from precontour.toolpath import read_gcode, read_gcode_report, read_program, read_toolpath
from precontour.toolpath.gcode import ARC_CHORD_TOLERANCE, ARC_RADIUS_TOLERANCE

DATA = Path(__file__).parent / "data"
INCH = 25.4
deg = np.radians


@pytest.fixture(scope="module")
def machine():
    return load_machine("zhang2013")


def write(tmp_path: Path, text: str, name: str = "prog.ngc") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def read(tmp_path, machine, text, **kwargs):
    return read_program(write(tmp_path, text), machine, **kwargs)


# --------------------------------------------------------------------------- everyday text


def test_fixture_program(machine):
    program = read_program(DATA / "program_words.nc", machine)
    assert program.start_line == 7
    np.testing.assert_array_equal(program.start, [0, 0, 150, 0, 0])
    expected_q = [[0, 0, 120, 0, 0], [0, 0, 100, 0, 0],
                  [10.5, -2.25, 100, 0, 0], [10.5, -2.25, 100, deg(5), deg(10)],
                  [12.75, -1.5, 99.5, deg(10), deg(20)], [12.75, -0.75, 99.5, deg(10), deg(20)],
                  [15, -0.75, 99.5, deg(15), deg(30)], [15, -0.75, 99.5, deg(15), deg(30)],
                  [15, -0.75, 150, deg(15), deg(30)]]
    np.testing.assert_allclose(program.q, expected_q, rtol=0, atol=1e-14)
    np.testing.assert_array_equal(program.line, [8, 9, 10, 11, 12, 14, 15, 16, 17])
    np.testing.assert_array_equal(program.rapid, [1, 0, 0, 0, 0, 0, 0, 0, 1])
    # G94: XYZ length / F; a rotary-only move: degrees / F (deg/min); line 16 repeats line 15
    expected_t = [np.nan, 20 / 10, math.hypot(10.5, 2.25) / 10, math.hypot(5, 10) / 20,
                  math.dist((10.5, -2.25, 100), (12.75, -1.5, 99.5)) / 20, 0.75 / 20, 2.25 / 20,
                  0.0, np.nan]
    np.testing.assert_allclose(program.duration, expected_t, rtol=1e-14)
    assert [(s.index, s.line, s.kind) for s in program.stops] == [(0, 5, "tool change"),
                                                                 (9, 19, "end")]
    kept = dict(program.passthrough)
    assert kept[2] == "O1001 (BLADE FINISH - 5X MACHINE AXES)"
    assert kept[4] == "G17 G40 G49 G80"
    assert kept[5] == "N20 T1 M6"
    assert kept[6] == "N30 S12000 M3"
    assert kept[8] == "G43 H1"
    assert kept[3] == "(POST: GENERIC A-C TRUNNION)"
    assert kept[9] == "(plunge)" and kept[14] == "(modal X Z A C)"
    assert kept[18] == "N140 M5" and kept[19] == "N150 M30"
    assert 13 not in kept and program.skipped["/"] == 1
    assert program.notices == () and not program.tcp


def test_toolpath_view_matches_forward_kinematics(machine):
    report = read_gcode_report(DATA / "program_words.nc", machine)
    program = read_program(DATA / "program_words.nc", machine)
    keep = np.r_[True, np.any(np.diff(program.points, axis=0) != 0, axis=1)]
    np.testing.assert_allclose(report.axes, program.points[keep], rtol=0, atol=0)
    P, O = machine.kinematics.forward(program.points[keep])
    np.testing.assert_allclose(report.toolpath.P, P, rtol=0, atol=1e-12)
    np.testing.assert_allclose(report.toolpath.O, O, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(report.toolpath.feed[:3], [np.nan, np.nan, 10.0])
    assert read_toolpath(DATA / "program_words.nc", machine=machine).n_points == keep.sum()


def test_rotate_first_then_position_is_the_start(machine, tmp_path):
    program = read(tmp_path, machine, "G90 G21\nG0 A30 C-45\nG0 X10 Y20 Z50\nG1 X20 F600\n")
    assert program.start_line == 3
    np.testing.assert_allclose(program.start, [10, 20, 50, deg(30), deg(-45)], atol=1e-15)
    np.testing.assert_allclose(program.q, [[20, 20, 50, deg(30), deg(-45)]], atol=1e-15)
    np.testing.assert_allclose(program.duration, [1.0])


def test_feed_move_before_all_axes_known_takes_them_as_zero(machine, tmp_path):
    program = read(tmp_path, machine, "G0 X1 Y2 Z3\nG1 X4 F60\n")
    np.testing.assert_array_equal(program.start, [1, 2, 3, 0, 0])
    assert "line 2: axes A C were not programmed before the first feed move" in program.notices[0]


def _interpret(blocks):
    """Sequential reference interpreter of G90/G91/G20/G21 blocks."""
    q = np.zeros(5)
    inc, scale, out = False, 1.0, []
    for codes, words in blocks:
        inc = True if "G91" in codes else False if "G90" in codes else inc
        scale = INCH if "G20" in codes else 1.0 if "G21" in codes else scale
        for j, name in enumerate("XYZAC"):
            if name in words:
                value = words[name] * (scale if j < 3 else 1.0)
                q[j] = q[j] + value if inc else value
        out.append(q.copy())
    q = np.array(out)
    q[:, 3:] = np.radians(q[:, 3:])
    return q


@pytest.mark.parametrize("seed", range(3))
def test_g90_g91_g20_g21_match_a_sequential_interpreter(machine, tmp_path, seed):
    rng = np.random.default_rng(seed)
    blocks = [((), {"X": 0.0, "Y": 0.0, "Z": 0.0, "A": 0.0, "C": 0.0})]
    text = ["G0 X0 Y0 Z0 A0 C0"]
    for k in range(200):
        codes = [c for c in (rng.choice(["", "G90", "G91"]), rng.choice(["", "G20", "G21"])) if c]
        names = [a for a in "XYZAC" if rng.random() < 0.5] or ["X"]
        words = {a: round(float(rng.uniform(-2, 2)), 4) for a in names}
        blocks.append((codes, words))
        text.append(f"N{k} " + " ".join(codes) + (" G1" if k == 0 else "") + " "
                    + " ".join(f"{a}{v:.4f}" for a, v in words.items()) + " F500")
    program = read(tmp_path, machine, "\n".join(text))
    np.testing.assert_allclose(program.q, _interpret(blocks)[1:], rtol=0, atol=1e-9)


def test_inch_feed_and_crlf_lowercase(machine, tmp_path):
    path = tmp_path / "w.nc"
    path.write_bytes(b"%\r\n(dos file)\r\ng20 g0 x1 y2 z3 a0 c0\r\n\r\ng1 x4 f120\r\n%\r\n")
    program = read_program(path, machine)
    np.testing.assert_allclose(program.q[0, :3], [4 * INCH, 2 * INCH, 3 * INCH])
    np.testing.assert_allclose(program.duration, [3 * INCH / (120 * INCH) * 60])
    np.testing.assert_array_equal(program.line, [5])


def test_dwell_stops_and_block_delete(machine, tmp_path):
    text = ("G0 X0 Y0 Z50 A0 C0 ; start\ng04 p0.5\nG4 X2.0 (Fanuc: X is seconds)\n"
            "/G1 X5 F100\nG1 X10. Y-.5 F 300.\nM0\nX11\nM1\nM30\nG1 X99\n")
    program = read(tmp_path, machine, text)
    assert [(s.index, s.line, s.kind) for s in program.stops] == [
        (0, 2, "dwell"), (0, 3, "dwell"), (1, 6, "program stop"), (2, 8, "optional stop"),
        (2, 9, "end")]
    assert [s.seconds for s in program.stops][:2] == [0.5, 2.0]
    np.testing.assert_array_equal(program.q[:, 0], [10, 11])  # nothing read after M30
    program = read(tmp_path, machine, text, block_delete=False)
    np.testing.assert_array_equal(program.q[:, 0], [5, 10, 11])


def test_unknown_m_codes_are_kept_with_one_notice(machine, tmp_path):
    text = "M100 ;probe on\nG0 X0 Y0 Z0 A0 C0\nM100\nM7 M8\nG1 X1 F60 M9\nM101\n"
    program = read(tmp_path, machine, text)
    assert len(program.notices) == 2
    assert program.notices[0].endswith("prog.ngc, line 1: M100 is not a code precontour "
                                       "knows; kept as a pass-through line")
    assert dict(program.passthrough) == {1: "M100 ;probe on", 3: "M100", 4: "M7 M8", 5: "M9",
                                         6: "M101"}


def test_g93_and_g94_switching(machine, tmp_path):
    text = ("G0 X0 Y0 Z0 A0 C0\nG93 G1 X10 F30\nY5 A10 F120\nG94 G1 X20 F600\n"
            "G3 X30 Y15 R10 \nG93 G2 X20 Y5 I-10 J0 F6\nG94 G0 Z10\nG1 A20 F10\n")
    program = read(tmp_path, machine, text)
    arc = program.line == 5
    arc2 = program.line == 6
    np.testing.assert_allclose(program.duration[:3], [2.0, 0.5, 1.0])
    # quarter circle of radius 10 at 600 mm/min
    np.testing.assert_allclose(program.duration[arc].sum(), 0.5 * math.pi * 10 / 10)
    np.testing.assert_allclose(program.duration[arc2].sum(), 10.0)
    np.testing.assert_allclose(program.feed[arc], 10.0)
    assert np.isnan(program.feed[arc2]).all()
    assert program.rapid[-2] and np.isnan(program.duration[-2])
    np.testing.assert_allclose(program.duration[-1], 10 / 10 * 60)  # 10 deg at 10 deg/min


# --------------------------------------------------------------------------- arcs


def _arc_checks(points, centre, radius, tol=ARC_CHORD_TOLERANCE):
    """Every chord end on the circle, every chord within the chord tolerance of it."""
    r = np.linalg.norm(points - centre, axis=1)
    np.testing.assert_allclose(r, radius, rtol=0, atol=1e-9)
    mid = 0.5 * (points[1:] + points[:-1])
    sag = radius - np.linalg.norm(mid - centre, axis=1)
    assert sag.max() <= tol * (1 + 1e-9)
    assert sag.max() > 0.3 * tol  # not needlessly fine


@pytest.mark.parametrize("plane, words, centre_words, cw_view", [
    ("G17", ("X", "Y", "Z"), ("I", "J"), 1),
    ("G18", ("Z", "X", "Y"), ("K", "I"), 1),
    ("G19", ("Y", "Z", "X"), ("J", "K"), 1),
])
def test_quarter_arcs_in_each_plane_by_ijk_and_r(machine, tmp_path, plane, words, centre_words,
                                                 cw_view):
    a, b, n = ("XYZ".index(w) for w in words)
    # start at (10, 0) in the plane's (first, second) axes, centre at the origin
    start = np.zeros(3)
    start[a] = 10.0
    for code, end_b in (("G2", -10.0), ("G3", 10.0)):
        end = np.zeros(3)
        end[b] = end_b
        coords = " ".join(f"{'XYZ'[i]}{end[i]:g}" for i in range(3))
        for centre in (f"{centre_words[0]}-10 {centre_words[1]}0", "R10"):
            text = (f"G0 X{start[0]:g} Y{start[1]:g} Z{start[2]:g} A0 C0\n{plane} G1 F600\n"
                    f"{code} {coords} {centre}\n")
            program = read(tmp_path, machine, text)
            pts = program.points[:, :3]
            _arc_checks(pts, np.zeros(3), 10.0)
            # a quarter turn, the short way, in the G2/G3 sense of the plane
            angle = np.unwrap(np.arctan2(pts[:, b], pts[:, a]))
            expected = -np.pi / 2 if code == "G2" else np.pi / 2
            np.testing.assert_allclose(angle[-1] - angle[0], expected, atol=1e-12)
            assert np.all(np.diff(angle) * expected > 0)
            np.testing.assert_allclose(pts[:, n], 0.0, atol=0)


def test_g18_g3_direction_viewed_from_plus_y(machine, tmp_path):
    # G3 is counter-clockwise seen from +Y: from X+ it turns through X- (via Z-) before Z+.
    program = read(tmp_path, machine, "G0 X10 Y0 Z0 A0 C0\nG18 G3 X0 Z10 I-10 K0 F600\n")
    pts = program.q[:, [0, 2]]
    _arc_checks(program.points[:, [0, 2]], np.zeros(2), 10.0)
    lowest_z, lowest_x = np.argmin(pts[:, 1]), np.argmin(pts[:, 0])
    np.testing.assert_allclose(pts[lowest_z], [0, -10], atol=0.2)  # within a chord
    np.testing.assert_allclose(pts[lowest_x], [-10, 0], atol=0.2)
    assert lowest_z < lowest_x


def test_negative_r_is_the_long_arc(machine, tmp_path):
    program = read(tmp_path, machine, "G0 X10 Y0 Z0 A0 C0\nG2 X0 Y-10 R-10 F600\n")
    _arc_checks(program.points[:, :3], np.array([10.0, -10.0, 0.0]), 10.0)
    angle = np.unwrap(np.arctan2(program.points[:, 1] + 10, program.points[:, 0] - 10))
    np.testing.assert_allclose(angle[-1] - angle[0], -1.5 * np.pi, atol=1e-12)


def test_full_circle_helix_with_rotary_axes_and_turns(machine, tmp_path):
    text = ("G0 X5 Y0 Z0 A0 C0\nG17 G3 X5 Y0 Z-6 A3 C90 I-5 J0 F60\n"
            "G2 X5 Y0 Z-12 I-5 P2 F60\n")
    program = read(tmp_path, machine, text)
    one, two = program.line == 2, program.line == 3
    pts = program.points
    _arc_checks(pts[:, [0, 1]], np.zeros(2), 5.0)
    turn = np.unwrap(np.arctan2(pts[:, 1], pts[:, 0]))
    first = np.r_[True, one]
    np.testing.assert_allclose(turn[first][-1] - turn[0], 2 * np.pi, atol=1e-12)
    np.testing.assert_allclose(turn[-1] - turn[first][-1], -4 * np.pi, atol=1e-12)
    # the normal axis and the rotary axes move in proportion to the angle
    frac = (turn[first] - turn[0]) / (2 * np.pi)
    np.testing.assert_allclose(pts[first, 2], -6 * frac, atol=1e-12)
    np.testing.assert_allclose(pts[first, 3], deg(3) * frac, atol=1e-12)
    np.testing.assert_allclose(pts[first, 4], deg(90) * frac, atol=1e-12)
    # G94 time: helix length / F
    np.testing.assert_allclose(program.duration[one].sum(),
                               math.hypot(2 * np.pi * 5, 6) / 60 * 60, rtol=1e-12)
    np.testing.assert_allclose(program.duration[two].sum(),
                               math.hypot(4 * np.pi * 5, 6) / 60 * 60, rtol=1e-12)


def test_arc_radius_mismatch_within_and_beyond_tolerance(machine, tmp_path):
    ok = read(tmp_path, machine, "G0 X0 Y0 Z0 A0 C0\nG2 X10.004 Y0 I5 J0 F60\n")
    assert ok.q[-1, 0] == 10.004
    with pytest.raises(ProgramError, match=r"prog.ngc, line 2, word 'G2': arc start and end "
                                           r"radii differ by 0.1 mm \(start 5, end 5.1; "
                                           r"tolerance 0.005 mm"):
        read(tmp_path, machine, "G0 X0 Y0 Z0 A0 C0\nG2 X10.1 Y0 I5 J0 F60\n")
    assert ARC_RADIUS_TOLERANCE == 0.005


# --------------------------------------------------------------------------- TCP


def _tcp_program(prefix, suffix):
    tips = np.array([[10.0, -5.0, 2.0], [12.0, -4.0, 1.5], [15.0, 0.0, 1.0], [14.0, 3.0, 0.5]])
    rot = np.array([[-30.0, 20.0], [-32.0, 60.0], [-35.0, 400.0], [-20.0, 380.0]])
    lines = [prefix, "G93"]
    lines.append(f"G0 X{tips[0, 0]} Y{tips[0, 1]} Z{tips[0, 2]} A{rot[0, 0]} C{rot[0, 1]}")
    for k in range(1, 4):
        lines.append(f"G1 X{tips[k, 0]} Y{tips[k, 1]} Z{tips[k, 2]} A{rot[k, 0]} "
                     f"C{rot[k, 1]} F{10 * k}")
    lines.append(suffix)
    lines.append("G0 X0 Y0 Z100")
    return "\n".join(lines) + "\n", tips, np.radians(rot)


@pytest.mark.parametrize("prefix, suffix, option", [
    ("G43.4 H1", "G49", False), ("TRAORI", "TRAFOOF", False), ("M428", "M429", False),
    ("(TCP by the site's own code)", "G49", True)])
def test_tcp_moves_reach_the_programmed_tips(machine, tmp_path, prefix, suffix, option):
    text, tips, rot = _tcp_program(prefix, suffix)
    program = read(tmp_path, machine, text, tcp=option)
    P, O = machine.kinematics.forward(program.points[:4])
    np.testing.assert_allclose(P, tips, rtol=0, atol=1e-10)
    np.testing.assert_allclose(program.points[:4, 3:], rot, rtol=0, atol=1e-15)  # as programmed
    np.testing.assert_allclose(program.duration[:3], [6.0, 3.0, 2.0])
    assert program.tcp and program.tcp_move[:3].all()
    # no lone H word, no TCP switch in the pass-through lines
    assert all("H1" not in text and "M42" not in text for _, text in program.passthrough)
    if option:  # TCP from the start, and G49 does not end it: the last rapid is a tip too
        np.testing.assert_allclose(machine.kinematics.forward(program.q[-1])[0], [0, 0, 100],
                                   atol=1e-10)
    else:       # after G49/TRAFOOF the words are machine axes again
        np.testing.assert_allclose(program.q[-1], [0, 0, 100, rot[-1, 0], rot[-1, 1]])
        assert not program.tcp_move[-1]


def test_tcp_linear_axes_agree_with_direct_kinematics(machine):
    # the reader's TCP map is the kinematics' own linear_axes(P, rotary)
    rng = np.random.default_rng(5)
    P = rng.uniform(-100, 100, (50, 3))
    rotary = rng.uniform(-3, 3, (50, 2))
    xyz = machine.kinematics.linear_axes(P, rotary)
    tip, _ = machine.kinematics.forward(np.concatenate([xyz, rotary], axis=1))
    np.testing.assert_allclose(tip, P, rtol=0, atol=1e-10)


# --------------------------------------------------------------------------- errors


@pytest.mark.parametrize("text, match", [
    ("", r"prog.ngc: no motion"),
    ("%\n(ONLY SETUP)\nG90 G21\nM3 S1000\nM30\n%\n", r"no motion"),
    ("G0 X0 Y0 Z0 A0 C0\nG93 G1 X1 F10\nX2\n",
     r"line 3, word 'F': inverse-time feed \(G93\) needs F on every G1/G2/G3 block"),
    ("G0 X0 Y0 Z0 A0 C0\nG1 X1\n", r"line 2, word 'G1': feed move without a feed rate"),
    ("G0 X0 Y0 Z0 A0 C0\nG93 G1 X1 F10\nG94 G1 X2\n", r"line 3, word 'G1': feed move without"),
    ("G0 X0\nG95\n", r"line 2, word 'G95': feed per revolution \(G95\) is not supported"),
    ("G0 X0 Y0 Z0 A0 C0\nG2 X2 I1 F10\nG53 Z0\n", r"line 3, word 'G53': G53 .* needs G0 or "
                                                  r"G1"),
    ("G0 X0\nG28 G0 X1\n", r"line 2, word 'G0': G28 and G0 both use the axis words"),
    ("G0 X0\nG28 G53 Z1\n", r"line 2, word 'G53': two codes of one modal group \(G28, G53\)"),
    ("G0 X0\nG10 L1 P1 Z0\n", r"line 2, word 'L1': G10 L1 is not supported \(only G10 L2 and "
                             r"G10 L20 set work offsets"),
    ("G0 X0\nG10 L2 P10 X0\n", r"line 2, word 'P10': G10 L2/L20 needs P0 .* P9"),
    ("G0 X0\nG10 L2 P1 R30\n", r"line 2, word 'R30': G10 R \(a rotated coordinate system\)"),
    ("G0 X0\nG54.1 X1\n", r"line 2, word 'G54.1': G54.1 needs the number of its work "
                          r"offset, P1 ... P300"),
    ("G0 X0\nG54.1 P301\n", r"line 2, word 'P301': G54.1 P301: the extended work offsets"),
    ("G0 X0\nG92\n", r"line 2, word 'G92': G92 needs at least one axis word"),
    ("G0 X0\nG92 Y1\n", r"line 2, word 'Y1': G92 sets axis Y relative to its position, "
                        r"which is not known yet"),
    ("G0 X0\nG28.1\n", r"line 2, word 'G28.1': G28.1 stores the current position, which is "
                       r"not known yet"),
    ("G0 X0\nM61 Q1 L2\n", r"line 2, word 'L2': unsupported word 'L2' \(L is read with G10, canned "
                           r"cycles, M98\)"),
    ("G0 X0\nG81 X1 Z-1 R1\n", r"line 2, word 'G81': canned cycle without a feed rate"),
    ("G0 X0 Y0 Z5 A0 C0\nG81 X1 Z-1 F9\n", r"line 2, word 'G81': G81 needs R \(the retract "
                                          r"plane\) when the cycle begins"),
    ("G0 X0 Y0 Z5 A0 C0\nG83 X1 Z-1 R1 F9\n", r"line 2, word 'G83': G83 needs Q \(the peck "
                                             r"depth\) when the cycle begins"),
    ("G0 X0 Y0 Z5 A0 C0\nG82 X1 Z-1 R1 F9\n", r"line 2, word 'G82': G82 needs P \(the dwell, "
                                             r"s\)"),
    ("G0 X0 Y0 Z5 A0 C0\nG81 X1 R1 F9\n", r"line 2, word 'G81': G81 needs Z \(the bottom\)"),
    ("G0 X0 Y0 Z5 A0 C0\nG81 X1 Z2 R1 F9\n", r"line 2, word 'G81': the retract plane R is below "
                                            r"the bottom Z of the cycle"),
    ("G0 X0 Y0 Z5 A0 C0\nG81 X1 Z-1 R1 L0 F9\n", r"line 2, word 'L0': canned cycle repeats 'L0' "
                                                r"must be a whole number >= 1"),
    ("G0 X0 Y0 Z5 A0 C0\nG83 X1 Z-1 R1 Q0 F9\n", r"line 2, word 'Q0': G83 needs a peck depth "
                                                r"Q > 0"),
    ("G0 X0 Y0 Z5 A0 C0\nG93 G81 X1 Z-1 R1 F9\n", r"line 2, word 'G81': canned cycles need feed "
                                                 r"per minute \(G94\)"),
    ("G0 X0 Y0 Z5 A0 C0\nG81 X1 Z-1 R1 C5 F9\n", r"line 2, word 'C5': the rotary axes may not "
                                                r"move in a canned cycle"),
    ("G0 X0 Y0 Z5 A0 C0\nG43.4 H1\nG81 X1 Z-1 R1 F9\n", r"line 3, word 'G81': canned cycles "
                                                       r"under G43.4/G43.5"),
    ("G0 X0 Y0 Z5 A0 C0\nG84 X1 Z-1 R1 F9\n", r"line 2, word 'G84': tapping cycles \(G84\) follow "
                                             r"the spindle"),
    ("G0 X0 Y0 Z5 A0 C0\nG88 X1 Z-1 R1 P1 F9\n", r"line 2, word 'G88': G88 \(boring with a "
                                                r"manual retract"),
    ("G0 X0 Y0 Z5 A0 C0\nG81 X1 Z-1 R1 F9\nG80\nX2\n", r"line 4, word 'X2': axis words after "
                                                      r"G80 without a motion code"),
    ("G0 X0 Y0 Z5 A0 C0\nG18 G81 Z0 Y-1 R1 @2 F9\n", r"word '@2': polar coordinates "
                                                  r"\(@ \^\) in a canned cycle need the XY "
                                                  r"plane"),
    ("G0 X0 Y0 Z5 A0 C0\nG1 X1 @2 F9\n", r"line 2, word '@2': polar coordinates \(@ \^\) and "
                                        r"X or Y in one block"),
    ("G0 X0 Y0 Z5 A0 C0\nG68.2 X0 Y0 Z0 I0 J10 K0 P1\n", r"line 2, word 'P1': G68.2 P1: only "
                                                       r"the Euler-angle form"),
    ("G0 X0 Y0 Z5 A0 C0\nG53.1\n", r"line 2, word 'G53.1': G53.1 needs a tilted working plane"),
    ("G0 X0 Y0 Z5 A0 C0\nG68.2 X0 Y0 Z0 I0 J10 K0\nG55\n", r"line 3, word 'G55': G55 with "
                                                          r"G68.2 active: cancel it with G69"),
    ("G0 X0 Y0 Z5 A0 C0\nG68.2 X0 Y0 Z0 I0 J10 K0\nG1 A5 F9\n", r"line 3, word 'A5': rotary "
                                                               r"axis word 'A5' with G68.2"),
    ("G0 X0 Y0 Z5 A0 C0\nG68.2 X0 Y0 Z0 I0 J10 K0\nM428\n", r"line 3, word 'M428': a TCP "
                                                           r"switch with G68.2 or CYCLE800 "
                                                           r"active"),
    ("G0 X0 Y0 Z5 A0 C0\nG68.2 X0 Y0 Z0 I0 J10 K0 G1\n", r"line 2, word 'G68.2': G68.2, G53.1 "
                                                       r"and G69 take a block of their own"),
    ("G0 X1\nG68.2 X0 Y0 Z0 I0 J10 K0\n", r"line 2, word 'G68.2': G68.2 before the position "
                                          r"of every axis is known"),
    ("G0 X0\nG41 D1\n", r"line 2, word 'G41': cutter radius compensation"),
    ("G0 X0\nG5.1 X1\n", r"line 2, word 'G5.1': unsupported G code G5.1"),
    ("G0 X0\nG1 B45. F100\n", r"line 2, word 'B45.': unsupported word 'B45.' \(axes are "
                              r"X Y Z A C\)"),
    ("G0 X0\nG1 X1.2.3 F100\n", r"line 2, word 'X1.2.3': cannot parse number 'X1.2.3'"),
    ("G0 X0\nG1 X Y1 F100\n", r"line 2, word 'X': cannot parse number 'X'"),
    ("G0 X0\r\nG1 Y- F100\r\n", r"line 2, word 'Y-': cannot parse number 'Y-'"),
    ("G0 X0\n5 Y1\n", r"line 2: cannot parse '5'"),
    ("G0 X0\nG1 X#<a> F100\n", r"line 2, word '#<A>': named parameter #<a> is not defined"),
    ("G0 X0\nG1 X#<_nope> F100\n", r"line 2, word '#<_NOPE>': named parameter #<_nope> is "
                                  r"not defined"),
    ("G0 X0\n#1 = [1 / [2 - 2]]\n", r"line 2, word '#1=\[1/\[2-2\]\]': division by zero"),
    ("G0 X0\nG0 X[SQRT[-1]]\n", r"line 2, word 'X\[SQRT\[-1\]\]': SQRT\[-1\] is not defined"),
    ("G0 X0\nG0 X[FOO[1]]\n", r"line 2, word 'X\[FOO\[1\]\]': unknown function or operator "
                              r"'FOO'"),
    ("G0 X[1+2\n", r"line 1, word 'X\[1\+2': unclosed '\[' in an expression"),
    ("G0 X0\n#6000 = 1\n", r"line 2, word '#6000': parameter #6000 is out of range"),
    ("G0 X0\n#5221 = 1\n", r"line 2, word '#5221=1': parameter #5221 is the controller's "
                           r"stored position or offset data"),
    ("G0 X0\n#<_x> = 1\n", r"line 2, word '#<_X>=1': #<_x> is read-only"),
    ("G0 X0\n#1\n", r"line 2, word '#1': a parameter outside an expression must be set"),
    ("G0 X0\nX=1\n", r"line 2, word 'X=1': '=' sets a parameter only after one"),
    ("G0 X0\nO100 SUB\n", r"line 2, word 'O100SUB': o100 sub is never closed"),
    ("G0 X0\nO100 CALL\n", r"line 2, word 'O100CALL': subroutine o100 is not defined in this "
                           r"file"),
    ("G0 X0\nO<probe> CALL [1]\n", r"line 2, word 'O<PROBE>CALL': subroutine o<probe> is not "
                                   r"defined in this file \(LinuxCNC looks for probe.ngc in its "
                                   r"SUBROUTINE_PATH; precontour reads one file\)"),
    ("G0 X0\no101 endwhile\n", r"line 2, word 'O101ENDWHILE': o101 endwhile without an open "
                               r"o101 while"),
    ("G0 X0\no1 if [1]\no2 endif\n", r"line 3, word 'O2ENDIF': o2 endif without an open o2 "
                                     r"if"),
    ("G0 X0\no1 break\n", r"line 2, word 'O1BREAK': o1 break outside an o1 while or do loop"),
    ("G0 X0\no1 return\n", r"line 2, word 'O1RETURN': o1 return outside a subroutine"),
    ("G0 X0\no1 if [1] G1\no1 endif\n", r"line 2, word 'O1IF': after O1 if only values in"),
    ("G0 X0\no1 sub\no1 call\no1 endsub\no1 call\n",
     r"line 3: calls nested more than 100 deep: a runaway recursion\?"),
    ("G0 X0\nM98 P100\n", r"line 2, word 'P100': M98: there is no O100 \(its subprogram\) in "
                          r"this file"),
    ("G0 X0\nM99\n", r"line 2, word 'M99': M99 outside a subprogram: in the main program it "
                     r"would restart it"),
    ("G0 X0\nM98 P100\nM30\nO100\nG0 X1\n", r"line 5: the program ends inside subprogram O100 "
                                          r"\(called on line 2\): M99 is missing"),
    ("G0 X0\nM72\n", r"line 2, word 'M72': M72 without a state saved by M70"),
    ("G0 X0\nIF [#1 GT 0] GOTO 10\n", r"line 2, word 'IF\[': Fanuc macro statements \(IF GOTO, "
                                     r"WHILE DO END\) are not supported"),
    ("G0 X0\no1 repeat [2]\no1 break\no1 endrepeat\n", r"line 3, word 'O1BREAK': o1 break "
                                                    r"outside an o1 while or do loop"),
    ("G0 X0\nG65 P9000\n", r"line 2, word 'G65': macro calls \(G65\)"),
    ("X0 Y0 Z10\n", r"line 1, word 'X0': axis words before any motion code"),
    ("G0 G1 X0\n", r"line 1, word 'G1': two codes of one modal group \(G0, G1\) in one block"),
    ("G0 X0\nG91 G90 X1\n", r"line 2, word 'G90': two codes of one modal group \(G91, G90\)"),
    ("G0 X0\nG20 G21 X1\n", r"line 2, word 'G21': two codes of one modal group \(G20, G21\)"),
    ("G0 X0 X1\n", r"line 1, word 'X1': word X appears twice in the block"),
    ("G0 X0\nG1 X1 F100 F200\n", r"line 2, word 'F200': word F appears twice in the block"),
    ("G0 X0\nG1 X1 F100\nG1 Q5 X2\n", r"line 3, word 'Q5': unsupported word 'Q5' \(Q is read "
                                      r"with G64, G73/G83, M61, M66-M68\)"),
    ("G0 X0\nG1 X1 F100 \u00e9\n", r"line 2: cannot parse '\u00c9'"),
    ("G0 X0\nG4 G1 X1\n", r"line 2, word 'G4': dwell \(G4\) needs a time P"),
    ("G0 X0\nG4\n", r"line 2, word 'G4': dwell \(G4\) needs a time P"),
    ("G0 X0\nG4 P1 Y2\n", r"line 2, word 'Y2': axis word 'Y2' in a dwell"),
    ("G0 X0\nG1 X1 (OPEN (NESTED) COMMENT)\n", r"line 2: unbalanced or nested"),
    ("G0 X0\nG1 X1 P2 F10\n", r"line 2, word 'P2': unsupported word 'P2'"),
    ("G0 X0\nG1 X1 I2 F10\n", r"line 2, word 'I2': word 'I2' is read only with G2/G3"),
    ("G0 X0\nG1 X1 F0\n", r"line 2, word 'F0': feed must be positive, got F0"),
    ("G0 X0\nM3.5\n", r"line 2, word 'M3.5': unsupported M code M3.5"),
    ("G0 X0 Y0 Z0 A0 C0\nG91 G1 X1 F10\nG90 G91 X1\n", r"line 3, word 'G91': two codes"),
    ("G91 G0 X1\n", r"line 1, word 'X1': incremental \(G91\) move of axis X before its "
                    r"position is known"),
    ("G0 X0 Y0 Z0 A0 C0\nG2 X10 Y0 F10\n", r"line 2, word 'G2': arc without centre: G2 in "
                                           r"this plane needs I/J or R"),
    ("G0 X0 Y0 Z0 A0 C0\nG2 X0 Y0 R5 F10\n", r"line 2, word 'R5': an R arc cannot be a full "
                                             r"circle"),
    ("G0 X0 Y0 Z0 A0 C0\nG2 X20 Y0 R5 F10\n", r"line 2, word 'R5': arc radius 5 mm is "
                                              r"shorter than half the chord \(10 mm\)"),
    ("G0 X0 Y0 Z0 A0 C0\nG2 X10 Y0 I5 R5 F10\n", r"line 2, word 'R5': an arc is given by R or "
                                                 r"by I J K, not both"),
    ("G0 X0 Y0 Z0 A0 C0\nG2 X10 Y0 I5 K1 F10\n", r"line 2, word 'K1': word 'K1' is not in "
                                                 r"the arc's plane"),
    ("G0 X0 Y0 Z0 A0 C0\nG2 X0 Y0 I0 J0 F10\n", r"line 2, word 'G2': arc radius is zero"),
    ("G0 X0 Y0 Z0 A0 C0\nG2 X10 Y0 I5 P1.5 F10\n", r"line 2, word 'P1.5': arc turns"),
    ("G0 X0 Y0 Z0 A0\nG2 X1 Y1 C0 I1 J0 F10\n", r"line 2, word 'G2': the first block that "
                                                 r"sets all axes is an arc"),
    ("G0 X0 Y0 Z0 A0 C0\nG1 X1e3 F10\n", r"line 2, word 'E3': unsupported word 'E3'"),
    ("G0 X0 Y0 Z0 A0 C0\nG1 X1000000000000 F10\n", r"line 2, word 'X1000000000000': "
                                                   r"coordinate .* is out of range"),
])
def test_program_errors_name_file_line_and_word(machine, tmp_path, text, match):
    path = write(tmp_path, text)
    with pytest.raises(ProgramError, match=match) as info:
        read_program(path, machine)
    assert str(info.value).startswith(str(path))
    assert "\n" not in str(info.value)


def test_real_program_idioms(machine, tmp_path):
    """Lines as the public LinuxCNC trunnion examples write them (re-typed, not copied)."""
    text = ("%\nM428 ;TCP:xyzac\n(PART)\nG00 G17 G40 G90 G94\nZ5\nT1 M6\n"
            "G54 X-49.65 Y-23.015 A0. C0. S630 M03\nG00 Z5.0 M08\nG01 Z-6.625 F300.0\n"
            "X-49.375 F600.0\nG93\nG01 X-34.988 Y-2.0 Z-1.404 F67.8035\nG94\nG00 Z10 M09\n"
            "M429 ;Restore\nM30\n%\n")
    program = read(tmp_path, machine, text, tcp=True)
    assert program.start_line == 7
    kept = dict(program.passthrough)
    assert kept[4] == "G17 G40" and kept[6] == "T1 M6"
    assert kept[7] == "S630 M03" and kept[8] == "M08" and kept[14] == "M09"
    np.testing.assert_allclose(program.duration[1:4],
                               [11.625 / 300 * 60, 0.275 / 600 * 60, 60 / 67.8035], rtol=1e-12)


def test_needs_a_machine_with_kinematics(tmp_path):
    path = write(tmp_path, "G0 X0 Y0 Z0 A0 C0\nG1 X1 F100\n")
    with pytest.raises(InputError, match=r"field 'machine': reading G-code needs a machine"):
        read_gcode(path, None)
    assert read_gcode(path, "zhang2013").n_points == 2


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                  HealthCheck.function_scoped_fixture])
@given(st.text(alphabet=st.sampled_from(list("GMXYZACFIJKRPNOST0123456789.-+ ()%;/#[]=\n"
                                             "\u00e9\t")), max_size=200))
def test_arbitrary_text_raises_only_precontour_errors(machine, tmp_path, text):
    path = tmp_path / "fuzz.ngc"
    path.write_text(text)
    try:
        read_program(path, machine)
        read_program(path, machine, tcp=True)
    except PrecontourError:
        pass


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                  HealthCheck.function_scoped_fixture])
@given(st.binary(max_size=300))
def test_arbitrary_bytes_raise_only_precontour_errors(machine, tmp_path, data):
    path = tmp_path / "fuzz.nc"
    path.write_bytes(data)
    try:
        read_program(path, machine)
    except PrecontourError:
        pass


@pytest.mark.parametrize("modes", ["G90 G21 G94", "G91 G20 G94", "G90 G93", "G91 G21 G93"])
def test_plain_blocks_read_like_the_general_path(machine, tmp_path, modes):
    """Plain motion blocks are executed together, vectorized; the same blocks with their
    words in another order (which takes the word-by-word path) give the same program."""
    rng = np.random.default_rng(len(modes))
    inverse = "G93" in modes
    lines = ["G0 X1 Y2 Z3 A4 C5", modes]
    for k in range(300):
        names = [a for a in "XYZAC" if rng.random() < 0.6] or ["Z"]
        words = [f"{a}{rng.uniform(-3, 3):+.4f}" for a in names]
        if inverse or rng.random() < 0.2:
            words.append(f"F{rng.uniform(10, 900):.2f}")
        code = ["", "G1", "G01", "G0", "G00"][rng.integers(5)] if k else "G1"
        if k == 0 and not inverse:
            words.append("F500")
        lines.append(f"N{k} {code} " + " ".join(words))
    fast = read(tmp_path, machine, "\n".join(lines))
    shuffled = [lines[0], lines[1]] + [" ".join(reversed(line.split())) for line in lines[2:]]
    slow = read(tmp_path, machine, "\n".join(shuffled))
    assert fast.n_moves == slow.n_moves > 250
    for name in ("rapid", "line", "tcp_move"):
        np.testing.assert_array_equal(getattr(fast, name), getattr(slow, name))
    np.testing.assert_allclose(fast.q, slow.q, rtol=0, atol=1e-12)  # G91 sums in another order
    np.testing.assert_allclose(fast.duration, slow.duration, rtol=1e-13)
    np.testing.assert_allclose(fast.feed, slow.feed, rtol=1e-13)


# --------------------------------------------------------------------------- machine data


GCODE_TABLE = """
[gcode]
g28 = [0.0, 0.0, 400.0, 0.0, 0.0]
g30 = [-100.0, 50.0, 380.0, 0.0, 0.5]

[gcode.work_offsets]
G54 = [10.0, 20.0, 30.0, 0.0, 0.0]
G55 = [100.0, 0.0, 0.0, 0.0, 0.5]
"G59.3" = [0.0, -5.0, 0.0, 0.0, 0.0]
"G54.1 P2" = [1.0, 2.0, 3.0, 0.0, 0.0]
"""


@pytest.fixture(scope="module")
def shop_machine():
    from precontour.machine.machine_file import builtin_machine_text, parse_machine
    return parse_machine(builtin_machine_text() + GCODE_TABLE, "shop.toml")


def test_work_offsets_from_the_machine_file(shop_machine, tmp_path):
    # LinuxCNC: absolute position = words + work offset (+ G92); an axis without a word keeps
    # its absolute position when the offset changes
    text = ("G0 X1 Y2 Z3 A0 C0\nG55 G1 X1 F600\nG59.3 G0 Y1\nG54.1 P2 G0 X0 Y0\nG54 Z0\n"
            "C10\nG55 C10\n")
    program = read(tmp_path, shop_machine, text)
    np.testing.assert_allclose(program.start, [11, 22, 33, 0, 0])
    expected = [[101, 22, 33, 0, 0], [101, -4, 33, 0, 0], [1, 2, 33, 0, 0], [1, 2, 30, 0, 0],
                [1, 2, 30, 0, deg(10)], [1, 2, 30, 0, 0.5 + deg(10)]]
    np.testing.assert_allclose(program.q, expected, rtol=0, atol=1e-12)
    assert program.notices == ()
    assert all("G55" not in text and "G54" not in text for _, text in program.passthrough)


def test_work_offsets_not_given_are_identity_said_once(machine, tmp_path):
    program = read(tmp_path, machine, "G55 G0 X1 Y2 Z3 A0 C0\nG1 X2 F60\nG56 X3\nG54.1 P9 X4\n")
    np.testing.assert_allclose(program.q[:, 0], [2, 3, 4])
    assert program.notices == (
        f"{tmp_path / 'prog.ngc'}, line 1: the machine file gives no work offset G55 "
        "([gcode.work_offsets]); work offsets it does not give are taken as zero (identity)",)


def test_g53_moves_in_machine_coordinates(shop_machine, tmp_path):
    text = ("G0 X1 Y2 Z3 A0 C0\nG53 G0 Z350\nG53 G1 X-5 F600\nG1 Y0\nG53 X0 Y0 Z0\n"
            "G1 X5 Y5\n")
    program = read(tmp_path, shop_machine, text)
    np.testing.assert_allclose(program.q[:4], [[11, 22, 350, 0, 0], [-5, 22, 350, 0, 0],
                                               [-5, 20, 350, 0, 0], [0, 0, 0, 0, 0]],
                               rtol=0, atol=1e-12)
    np.testing.assert_array_equal(program.rapid[:4], [True, False, False, False])
    np.testing.assert_allclose(program.duration[1], 16 / 600 * 60)
    # after G53 the words are work coordinates again (G54: +10, +20, +30)
    np.testing.assert_allclose(program.q[-1], [15, 25, 0, 0, 0], atol=1e-12)


def test_g53_in_tcp_mode_is_a_joint_space_move(machine, tmp_path):
    text = ("G43.4 H1\nG0 X10 Y-5 Z2 A-30 C20\nG53 G0 Z450\nG53 G1 A0 C0 F600\nG1 Z1 F60\n"
            "G49\n")
    program = read(tmp_path, machine, text)
    kin = machine.kinematics
    first = kin.linear_axes(np.array([10.0, -5.0, 2.0]), deg(-30), deg(20))
    np.testing.assert_allclose(program.q[0], [*first[:2], 450, deg(-30), deg(20)], atol=1e-9)
    np.testing.assert_allclose(program.q[1], [*first[:2], 450, 0, 0], atol=1e-9)
    np.testing.assert_array_equal(program.tcp_move, [False, False, True])
    # rotary-only G94 move: degrees / F
    np.testing.assert_allclose(program.duration[1], math.hypot(30, 20) / 600 * 60)
    # the TCP move starts from the tip where the joint-space move left it
    tip, _ = kin.forward(program.q[1])
    end, _ = kin.forward(program.q[2])
    np.testing.assert_allclose(end, [tip[0], tip[1], 1.0], atol=1e-9)


def test_g28_and_g30_use_the_machine_file_reference(shop_machine, tmp_path):
    text = ("G0 X1 Y2 Z3 A0 C0\nG91 G28 Z0\nG90 G28 X5\nG30\nG0 X0 Y0 Z0\nG28.1\nG0 X1\n"
            "G28\n")
    program = read(tmp_path, shop_machine, text)
    q = program.q
    np.testing.assert_allclose(q[0], [11, 22, 33, 0, 0])          # G91 Z0: no intermediate move
    np.testing.assert_allclose(q[1], [11, 22, 400, 0, 0])          # then Z to the reference
    np.testing.assert_allclose(q[2], [15, 22, 400, 0, 0])          # intermediate X5 (+ G54)
    np.testing.assert_allclose(q[3], [0, 22, 400, 0, 0])           # then X only
    np.testing.assert_allclose(q[4], [-100, 50, 380, 0, 0.5])      # G30: every axis
    np.testing.assert_allclose(q[5], [10, 20, 30, 0, 0.5])
    np.testing.assert_allclose(q[6], [11, 20, 30, 0, 0.5])
    np.testing.assert_allclose(q[7], [10, 20, 30, 0, 0.5])         # the G28.1 position
    assert program.rapid.all() and program.notices == ()


def test_g28_without_a_reference_takes_the_machine_origin(machine, tmp_path):
    program = read(tmp_path, machine, "G91 G28 Z0\nG90 G0 X1 Y2 A0 C0\nG1 X2 F60\nG28\n")
    assert program.start_line == 2
    np.testing.assert_allclose(program.start, [1, 2, 0, 0, 0])
    np.testing.assert_allclose(program.q[-1], [0, 0, 0, 0, 0])
    assert program.notices == (
        f"{tmp_path / 'prog.ngc'}, line 1: the machine file gives no reference position for "
        "G28 ([gcode] g28); the machine origin (all axes 0) is taken, as in LinuxCNC's "
        "default parameters",)


def test_g10_and_g92_offsets(machine, tmp_path):
    # the numbers of LinuxCNC's rs274 on the same program (absolute = canonical + G5x + G92)
    text = ("G10 L2 P1 X10 Y20 Z30\nG10 L2 P2 X100 C30\nG54 G0 X1 Y2 Z3 A0 C0\n"
            "G55 G1 X1 F600\nG10 L2 P1 X0 Y0 Z0\nG54 G0 X5\nG92 X1\nG10 L20 P2 X0\n"
            "G55 X0 Y0\nG1 X2 F100\nG92.1\nG0 X2\nG92 Y3\nG92.2\nG0 Y1\nG92.3\nG0 Y1\n")
    program = read(tmp_path, machine, text)
    np.testing.assert_allclose(program.start, [11, 22, 33, 0, 0])
    x_y = [[101, 22], [5, 22], [5, 0], [7, 0], [3, 0], [3, 1], [3, -2]]
    np.testing.assert_allclose(program.q[:, :2], x_y, rtol=0, atol=1e-12)
    np.testing.assert_allclose(program.q[0, 4], 0.0, atol=1e-15)   # C kept when G55 adds 30


def test_tcp_on_after_positioning_keeps_the_known_position(machine, tmp_path):
    program = read(tmp_path, machine, "G0 X10. Y0.\nG43.4 H1\nG1 Z-1. F100\nG1 X0\n")
    assert program.notices == (f"{tmp_path / 'prog.ngc'}, line 3: axes Z A C were not "
                               "programmed before the first feed move; taken as 0",)
    np.testing.assert_allclose(program.start, [10, 0, 0, 0, 0])
    tip0, _ = machine.kinematics.forward(program.start)
    tips, _ = machine.kinematics.forward(program.q)
    np.testing.assert_allclose(tips, [[tip0[0], tip0[1], -1], [0, tip0[1], -1]], atol=1e-9)
    assert program.tcp_move.all()


def test_m61_and_io_words_are_kept(machine, tmp_path):
    text = "G0 X0 Y0 Z0 A0 C0\nM61 Q1\nM64 P2\nM66 E0 L0\nM68 E3 Q1.5\nG1 X1 F60\n"
    program = read(tmp_path, machine, text)
    assert dict(program.passthrough) == {2: "M61 Q1", 3: "M64 P2", 4: "M66 E0 L0",
                                         5: "M68 E3 Q1.5"}
    assert program.notices == ()



def test_g97_spindle_rpm_mode_is_kept(machine, tmp_path):
    """Fanuc-style posts start the spindle with ``G97 S.. M3`` (RPM mode, LinuxCNC's default
    too): kept as a pass-through line, no notice."""
    program = read(tmp_path, machine, "G0 X0 Y0 Z0 A0 C0\nG97 S8000 M3\nG1 X1 F60\n")
    assert dict(program.passthrough) == {2: "G97 S8000 M3"}
    assert program.notices == ()


# --------------------------------------------------------------------------- TCP switches


@pytest.fixture(scope="module")
def xyzac():
    return load_machine("linuxcnc-xyzac-trt")


SWITCHKINS_DEMOS = Path("/usr/share/doc/linuxcnc/examples/sample-configs/sim/axis/vismach/"
                        "5axis/table-rotary-tilting/demos")

# LinuxCNC's xyzac_switchkins_test_3.ngc, re-typed: M429 identity kinematics, M428 TCP; its
# "expect" comments give the position LinuxCNC's display shows (machine axes under M429, the
# tool tip in the table frame under M428) after each block
SWITCHKINS_3 = """m429 ;trivkins
G0 X0 Y0 Z0 A0 C0
G0 C90 X10 Y0
G1 F1000 Z2
(debug,A expect: 10   0 2) m1
m428 ;tcp
(debug,C expect:  0 -10 2) m1
g1f1000 z0
(debug,D expect:  0 -10 0) m1
m429 ;trivkins
(debug,F expect: 10 0 0)
G1 X5
m2
"""


def _expectations(program, machine):
    """(line, displayed position) after each move: machine axes, or the tip in TCP mode."""
    tips, _ = machine.kinematics.forward(program.q)
    shown = np.where(program.tcp_move[:, None], tips, program.q[:, :3])
    return dict(zip(program.line.tolist(), shown))


def test_tcp_switched_mid_program_by_m428_m429(xyzac, tmp_path):
    program = read(tmp_path, xyzac, SWITCHKINS_3)
    shown = _expectations(program, xyzac)
    np.testing.assert_allclose(shown[4], [10, 0, 2], atol=1e-12)    # expect A (identity)
    np.testing.assert_allclose(shown[8], [0, -10, 0], atol=1e-12)   # expect C, then D (TCP)
    np.testing.assert_allclose(program.q[-2, :3], [10, 0, 0], atol=1e-12)   # expect F
    np.testing.assert_allclose(program.q[-1, :3], [5, 0, 0], atol=1e-12)    # machine axes again
    np.testing.assert_array_equal(program.tcp_move, [False, False, True, False])
    assert program.tcp and program.notices == ()
    assert dict(program.passthrough)[6] == "(tcp)"
    installed = SWITCHKINS_DEMOS / "xyzac_switchkins_test_3.ngc"
    if installed.exists():
        demo = read_program(installed, xyzac)
        tips, _ = xyzac.kinematics.forward(demo.q)
        np.testing.assert_allclose(tips[-1], [0, -10, 0], atol=1e-12)
        np.testing.assert_allclose(demo.q[-1, :3], [10, 0, 0], atol=1e-12)


def test_tcp_rotary_only_move_after_a_switch_holds_the_tip(xyzac, tmp_path):
    # xyzac_switchkins_test_2.ngc's pattern: after M428 a rotary-only G1 keeps the tip
    text = "M429\nG0 X0 Y0 Z5 A0 C0\nG1 F1000 Z0\nG1 X20 Y0\nM428\nG1 C90\nG1 X20\nG1 Y20\n"
    program = read(tmp_path, xyzac, text)
    tips, _ = xyzac.kinematics.forward(program.q)
    np.testing.assert_allclose(tips[2:], [[20, 0, 0], [20, 0, 0], [20, 20, 0]], atol=1e-12)
    np.testing.assert_allclose(np.degrees(program.q[2:, 4]), 90)


def test_g49_does_not_end_tcp_switched_by_an_m_code(tmp_path):
    # boat-xyzbc.ngc's ending: G43 H1 is the tool length, G49 cancels it, not the TCP of M428
    machine = load_machine("linuxcnc-xyzbc-trt")
    text = ("M428\nG0 X10 Y-5 Z5 B-20 C30\nG43 H1 Z4\nG53 G49 Z30 M09\nG53 Y0 B0 C0\n"
            "G0 X1\nM429\nG0 X2\n")
    program = read(tmp_path, machine, text)
    np.testing.assert_array_equal(program.tcp_move, [True, False, False, True, False])
    first = machine.kinematics.linear_axes(np.array([10.0, -5.0, 4.0]), deg(-20), deg(30))
    np.testing.assert_allclose(program.q[1], [*first[:2], 30, deg(-20), deg(30)], atol=1e-9)
    np.testing.assert_allclose(program.q[2], [first[0], 0, 30, 0, 0], atol=1e-9)
    tip, _ = machine.kinematics.forward(program.q[3])
    np.testing.assert_allclose(tip[0], 1.0, atol=1e-12)
    np.testing.assert_allclose(program.q[4, 0], 2.0, atol=1e-12)


def test_the_sites_own_tcp_codes_from_the_machine_file(tmp_path):
    from precontour.machine.machine_file import builtin_machine_text, parse_machine
    machine = parse_machine(builtin_machine_text() + '[gcode]\ntcp_on = ["M128"]\n'
                            'tcp_off = ["m129"]\n', "heidenhain.toml")
    text = "G0 X0 Y0 Z400 A0 C0\nM128\nG1 X1 F60\nM129\nG1 X2\nM428\n"
    program = read(tmp_path, machine, text)
    np.testing.assert_array_equal(program.tcp_move, [True, False])
    tip, _ = machine.kinematics.forward(program.q[0])
    start_tip, _ = machine.kinematics.forward(program.start)
    np.testing.assert_allclose(tip, start_tip + [1, 0, 0], atol=1e-9)
    assert program.notices == (f"{tmp_path / 'prog.ngc'}, line 6: M428 is not a code "
                               "precontour knows; kept as a pass-through line",)


def test_tcp_option_ends_at_the_programs_own_tcp_off(machine, tmp_path):
    program = read(tmp_path, machine, "G0 X1 Y2 Z3 A0 C0\nG1 X2 F60\nM429\nG1 X3\n", tcp=True)
    np.testing.assert_array_equal(program.tcp_move, [True, False])
    np.testing.assert_allclose(program.q[-1, 0], 3.0)


# --------------------------------------------------------------------------- the language


def _ends_by_line(program):
    pm = program.programmed
    return [(int(line), [round(float(v), 9) + 0.0 for v in end[:3]])
            for line, end in zip(pm.line, pm.end)]


def test_language_program_gives_linuxcncs_numbers(xyzac):
    # the values in the program's comments are what LinuxCNC 2.9's rs274 prints for it
    program = read_program(DATA / "language.ngc", xyzac)
    ends = _ends_by_line(program)
    expected_start = [(9, [7, 0, 10]), (10, [4, 4, 10]), (11, [1, 2, 10]),
                      (12, [-3, -3, -2]), (13, [1, 0, 0]), (14, [3, 1, 5]),
                      (15, [6, 3, 1.5]), (16, [0, 1, 1]), (18, [0, 0, 10]),
                      (19, [-5, -1, -2]),
                      (23, [1, 2, 0]), (31, [3, 1, 5]), (23, [20, 1, -1]), (33, [21, 2, 0]),
                      (43, [12, 0, 0])]
    assert ends[:len(expected_start)] == expected_start
    rest = ends[len(expected_start):]
    # do-while three times, while with continue (#5 = 2) and break (#5 = 5), repeat x3,
    # while [1] left by a break
    assert [e for _, e in rest[:10]] == [[12, 0, -1], [12, 0, -2], [12, 0, -3], [1, 2, -3],
                                         [3, 6, -3], [4, 8, -3], [5, 7, -3], [6, 6, -3],
                                         [7, 5, -3], [9, 5, -3]]
    # M98 P1000 L2, each calling P2000: lines of the subprograms, #7 shared
    assert rest[10:15] == [(97, [9, 5, -4]), (94, [10, 5, -4]), (97, [10, 5, -5]),
                           (94, [20, 5, -5]), (74, [2, 0, 0])]
    arcs = program.programmed.kind == 2
    np.testing.assert_allclose(program.programmed.centre[arcs][:, :2], [[0, 0], [0, 5]],
                               atol=1e-12)
    np.testing.assert_array_equal(program.programmed.turns[arcs], [1, -1])
    # polar @10 ^45, then G91 @1 ^15, then G90 @5; M72 restores G21 G90 after G20 G91
    assert [e for _, e in rest[-6:-1]] == [
        [round(10 * math.cos(math.pi / 4), 9), round(10 * math.sin(math.pi / 4), 9), 0],
        [round(11 * math.cos(math.radians(60)), 9), round(11 * math.sin(math.radians(60)), 9),
         0],
        [2.5, round(5 * math.sin(math.radians(60)), 9), 0],
        [5.04, round(5 * math.sin(math.radians(60)), 9), 0],
        [1, round(5 * math.sin(math.radians(60)), 9), 0]]
    assert program.notices == ()


def test_line_column_is_the_line_executing(machine, tmp_path):
    text = ("G0 X0 Y0 Z0 A0 C0\no10 sub\n  G1 X#1 F60\n  G1 Y#1\no10 endsub\no10 call [1]\n"
            "o10 call [2]\nG1 Z1\n")
    program = read(tmp_path, machine, text)
    np.testing.assert_array_equal(program.line, [3, 4, 3, 4, 8])
    np.testing.assert_allclose(program.q[:, :3], [[1, 0, 0], [1, 1, 0], [2, 1, 0], [2, 2, 0],
                                                  [2, 2, 1]])


def test_parameters_in_passthrough_lines_are_evaluated(machine, tmp_path):
    text = "#1 = 1200\nG0 X0 Y0 Z0 A0 C0\nS#1 M3 (spindle)\nT[#1 / 600] M6\nG1 X1 F60\n"
    program = read(tmp_path, machine, text)
    kept = dict(program.passthrough)
    assert kept[3] == "S1200 M3 (spindle)" and kept[4] == "T2 M6"


def test_a_runaway_loop_ends_with_an_error(machine, tmp_path, monkeypatch):
    import precontour.toolpath._gcode_language as language
    monkeypatch.setattr(language, "MAX_LOOP_ITERATIONS", 1000)
    text = "G0 X0 Y0 Z0 A0 C0\n#1 = 0\no7 while [#1 GE 0]\n  #1 = [#1 + 1]\no7 endwhile\n"
    with pytest.raises(ProgramError, match=r"prog.ngc, line 3, word 'O7WHILE': o7 while ran "
                                           r"1000 times: a runaway loop\?"):
        read(tmp_path, machine, text)
    text = "G0 X0 Y0 Z0 A0 C0\no8 do\n  G91 G1 X0.001 F60\no8 while [1]\n"
    with pytest.raises(ProgramError, match=r"line 2, word 'O8DO': o8 do ran 1000 times"):
        read(tmp_path, machine, text)
    assert language.MAX_LOOP_ITERATIONS == 1000


def test_fanuc_subprogram_repeat_forms(machine, tmp_path):
    text = ("G0 X0 Y0 Z0 A0 C0\nG91\nM98 P20100\nM98 P100 L0\nM98 P100 L2\nG90\nM30\n"
            "O100\nG1 X1 F60\nM99\n")
    program = read(tmp_path, machine, text)
    np.testing.assert_allclose(program.q[:, 0], [1, 2, 3, 4])   # 2 + 0 + 2 calls
    np.testing.assert_array_equal(program.line, [9, 9, 9, 9])


# --------------------------------------------------------------------------- canned cycles


def test_canned_cycles_expand_as_linuxcnc(xyzac):
    # the moves LinuxCNC 2.9's rs274 prints for tests/toolpath/data/cycles.ngc (its lines)
    program = read_program(DATA / "cycles.ngc", xyzac)
    pm = program.programmed

    def moves(line):
        k = pm.line == line
        return [("rapid" if kind == 0 else "feed", [round(float(v), 9) + 0.0 for v in e[:3]])
                for kind, e in zip(pm.kind[k], pm.end[k])]

    assert moves(6) == [("rapid", [1, 1, 20]), ("rapid", [1, 1, 2]), ("feed", [1, 1, -5]),
                        ("rapid", [1, 1, 2])]                       # G99 by default: to R
    assert moves(9) == [("rapid", [3, 3, 20]), ("rapid", [3, 3, 2]), ("feed", [3, 3, -5]),
                        ("rapid", [3, 3, 20])]                      # G98: the start height
    assert [e for _, e in moves(13)] == [[9, 3, 20], [9, 3, 2], [9, 3, -5], [9, 3, 2],
                                         [14, 3, 2], [14, 3, -5], [14, 3, 2],
                                         [19, 3, 2], [19, 3, -5], [19, 3, 2]]   # G91 L3
    assert moves(17) == [("rapid", [10, 10, 20]), ("rapid", [10, 10, 1]),
                         ("feed", [10, 10, -3]), ("rapid", [10, 10, 1]),
                         ("rapid", [10, 10, -2.746]), ("feed", [10, 10, -7]),
                         ("rapid", [10, 10, 1]), ("rapid", [10, 10, -6.746]),
                         ("feed", [10, 10, -10]), ("rapid", [10, 10, 20])]   # G83 pecks
    assert [e[2] for _, e in moves(18)] == [20, 1, -3, -2.746, -7, -6.746, -10, 1]   # G73
    assert moves(20)[-2:] == [("feed", [13, 10, 1]), ("rapid", [13, 10, 20])]   # G85 out
    assert moves(22)[-1] == ("feed", [15, 10, 20])                  # G89 feeds out
    assert [e for _, e in moves(24)] == [[20, 20, 20], [20, 20, 2], [21, 20, 2], [21, 20, -5],
                                         [20, 20, -5], [20, 20, -3], [20, 20, -5],
                                         [21, 20, -5], [21, 20, 20], [20, 20, 20]]   # G87
    assert moves(28) == [("rapid", [20, 20, 12]), ("rapid", [1, 2, 12]), ("feed", [1, 2, -1]),
                         ("rapid", [1, 2, 12])]                     # up to R first
    dwells = [(s.line, s.seconds) for s in program.stops if s.kind == "dwell"]
    assert dwells == [(19, 0.5), (21, 0.2), (22, 0.3)]
    polar = [e for line, e in zip(pm.line, pm.end) if line in (37, 38, 39) and e[2] == -2]
    np.testing.assert_allclose([p[:2] for p in polar],
                               [[10, 0], [-5, 10 * math.sin(math.radians(120))],
                                [-5, -10 * math.sin(math.radians(120))]], atol=1e-12)
    y_axis = moves(44)                                              # G18: drilling along Y
    assert y_axis == [("rapid", [1, 5, 0]), ("rapid", [1, -1, 0]), ("feed", [1, -3, 0]),
                      ("rapid", [1, -1, 0])]


def test_cycle_words_carry_over_and_g80_ends_them(machine, tmp_path):
    text = ("G0 X0 Y0 Z10 A0 C0\nG83 X1 Z-1.5 R1 Q1 F60\nX2\nG80\nG1 X3 F60\n")
    program = read(tmp_path, machine, text)
    pm = program.programmed
    again = pm.line == 3
    # R, Z and Q carry over: pecks of 1 mm from R, back to R, down to 0.254 above the last
    np.testing.assert_allclose(pm.end[again][:, :3],
                               [[2, 0, 1], [2, 0, 0], [2, 0, 1], [2, 0, 0.254], [2, 0, -1],
                                [2, 0, 1], [2, 0, -0.746], [2, 0, -1.5], [2, 0, 1]],
                               atol=1e-12)
    np.testing.assert_allclose(program.q[-1, :3], [3, 0, 1])


# --------------------------------------------------------------------------- G68.2


def test_tilted_working_plane_g68_2_g53_1(xyzac, tmp_path):
    # Fanuc's G68.2 with Euler angles I J K (about Z, the new X, the new Z): here 90, 30, 0,
    # so the plane's X is the workpiece's +Y and its Z leans 30 deg towards +X
    text = ("G21 G90 G94\nG0 X0 Y0 Z40 A0 C0\nG68.2 X10 Y5 Z0 I90 J30 K0\nG53.1\n"
            "G0 X0 Y0 Z20\nG1 Z0 F300\nG1 X5\nG3 X5 Y5 I0 J2.5\nG81 X0 Y0 Z-4 R2\nG80\nG69\n"
            "G0 X0 Y0 Z60\n")
    program = read(tmp_path, xyzac, text)
    kin = xyzac.kinematics
    c30, s30 = math.cos(math.radians(30)), math.sin(math.radians(30))
    x_axis, z_axis = np.array([0.0, 1.0, 0.0]), np.array([s30, 0.0, c30])
    y_axis = np.cross(z_axis, x_axis)
    origin = np.array([10.0, 5.0, 0.0])
    tips, orientations = kin.forward(program.q)
    # G53.1: the rotary axes only, then the tool along the plane's Z for every move after
    np.testing.assert_allclose(program.q[0, :3], program.start[:3], atol=1e-12)
    assert not program.tcp_move[0] and program.tcp_move[1:-1].all()
    np.testing.assert_allclose(orientations[:-1], np.tile(z_axis, (len(tips) - 1, 1)),
                               atol=1e-12)
    pm = program.programmed

    def at(line):
        return tips[pm.first[pm.line == line][-1] + (pm.line == line).sum() - 1]

    np.testing.assert_allclose(tips[1], origin + 20 * z_axis, atol=1e-9)
    np.testing.assert_allclose(at(7), origin + 5 * x_axis, atol=1e-9)
    # the arc is a circle in the tilted plane: centre origin + 5 x + 2.5 y, radius 2.5
    arc = tips[pm.first[pm.line == 8][0]:pm.first[pm.line == 9][0]]
    centre = origin + 5 * x_axis + 2.5 * y_axis
    np.testing.assert_allclose(np.linalg.norm(arc - centre, axis=1), 2.5, atol=1e-9)
    np.testing.assert_allclose((arc - origin) @ z_axis, 0.0, atol=1e-9)
    np.testing.assert_allclose(pm.centre[pm.line == 8][0], centre, atol=1e-12)
    # the cycle drills along the plane's Z
    bottom = tips[pm.first[pm.line == 9][0] + 2]
    np.testing.assert_allclose(bottom, origin - 4 * z_axis, atol=1e-9)
    # G69: machine axes again
    assert not program.tcp_move[-1]
    np.testing.assert_allclose(program.q[-1, :3], [0, 0, 60], atol=1e-12)


# --------------------------------------------------------------------------- a post's program


def test_fanuc_style_trunnion_program(tmp_path):
    """data/fanuc_trunnion.nc, written like a Fanuc five-axis post's output: G28 G91 Z0.
    retracts, G43.4 TCP finishing with an arc and G93 blocks, then 3+2 drilling under
    G68.2/G53.1 with G81 and G83, G53 retract; timed within the machine's limits."""
    from precontour.machine.machine_file import builtin_machine_text, parse_machine
    from precontour.trajectory import program_trajectory, summarize
    machine = parse_machine(builtin_machine_text() + "[gcode]\ng28 = [0.0, 0.0, 500.0, 0.0, 0.0]\n",
                            "shop.toml")
    kin = machine.kinematics
    program = read_program(DATA / "fanuc_trunnion.nc", machine)
    pm = program.programmed
    tips, orientations = kin.forward(program.q)
    assert program.start_line == 15
    np.testing.assert_allclose(kin.forward(program.start)[0], [10, -5, 20], atol=1e-9)
    np.testing.assert_allclose(np.degrees(program.start[3:]), [-20, 30], atol=1e-12)
    # the TCP finish: tool tips as programmed, G93 blocks in 60/F s
    finish = (program.line >= 16) & (program.line <= 23)
    assert program.tcp_move[finish].all()
    last = {line: k for k, line in enumerate(program.line)}
    np.testing.assert_allclose(tips[last[20]], [15.5, -0.5, 0.2], atol=1e-9)
    np.testing.assert_allclose(tips[last[23]], [6, 6, 0], atol=1e-9)
    np.testing.assert_allclose([program.duration[program.line == 22].sum(),
                                program.duration[program.line == 23].sum()], [60 / 40, 60 / 35])
    arc = tips[program.line == 21]
    np.testing.assert_allclose(np.hypot(arc[:, 0] - 13, arc[:, 1] - 1.5), math.hypot(2.5, 2),
                               atol=1e-9)
    # G28 G91 Z0.: machine Z to the machine file's reference, nothing else moves
    np.testing.assert_allclose(program.q[last[26], 2], 500.0)
    np.testing.assert_allclose(program.q[last[26], [0, 1]], program.q[last[24], [0, 1]])
    # 3+2: the tool along the plane's Z (15 deg about X), the holes in the plane's frame
    z_axis = np.array([0.0, math.sin(math.radians(15)), math.cos(math.radians(15))])
    drilling = (program.line >= 34) & (program.line <= 39)
    np.testing.assert_allclose(orientations[drilling], np.tile(z_axis, (drilling.sum(), 1)),
                               atol=1e-12)
    rotation = np.array([[1, 0, 0], [0, z_axis[2], z_axis[1]], [0, -z_axis[1], z_axis[2]]])
    bottoms = [tips[k] for k in range(len(tips)) if pm.kind[np.searchsorted(pm.first, k,
                                                                            "right") - 1] == 1
               and program.line[k] in (36, 37, 38)]
    np.testing.assert_allclose(bottoms, [rotation @ [x, y, -3] for x, y in
                                         ((5, 5), (-5, 5), (-5, -5))], atol=1e-9)
    # G53 G0 Z500.: machine Z; the last G28 G91 Z0. to the reference too
    np.testing.assert_allclose(program.q[last[42], 2], 500.0)
    assert not program.tcp_move[last[42]]
    trajectory = program_trajectory(program, machine)
    assert summarize(trajectory, machine).within_limits


# --------------------------------------------------------------------------- refusals


def _refusal(path, machine):
    with pytest.raises(ProgramError) as info:
        read_program(path, machine)
    assert "\n" not in str(info.value)
    return info.value


# Each refusal names the construct as written, the file, the line (1-based, of the file), and
# what to do; the lines after the refused one are never reached.
@pytest.mark.parametrize("text, line, construct, what", [
    ("G21\nOFinal ToolPath\nG0 X0\n", 2, "OFinal ToolPath",
     r"O takes a program number \(O1000\) or a subroutine name in < > \(o<name> sub\); "
     r"post-process with the program's name in a comment, \(Final ToolPath\), or without it"),
    ("; part\nN10 G17\nN20 DEF REAL _X\nN30 CYCLE81(10,0,1,-5)\n", 4, "CYCLE81(10,0,1,-5)",
     r"is Sinumerik 840D syntax \(a cycle call\), which this reader does not read; "
     r"post-process for LinuxCNC/Fanuc-style G-code$"),
    ("G21\n\nN30 AMIRROR X0\n", 3, "AMIRROR", r"Sinumerik 840D syntax \(a mirroring frame\)"),
    ("0 BEGIN PGM PART MM\n1 BLK FORM 0.1 Z X+0 Y+0 Z-20\n", 1, "BEGIN PGM",
     r"is Heidenhain TNC conversational syntax \(a conversational block\), which this reader "
     r"does not read; post-process for LinuxCNC/Fanuc-style G-code$"),
    ("G21 G90\n_camtolerance=.02\nORIVECT\n", 3, "ORIVECT",
     r"is Sinumerik 840D syntax \(the orientation interpolated on a great circle, not axis by "
     r"axis\), which this reader does not read; post-process without it$"),
])
def test_refusals_name_the_construct_the_line_and_what_to_do(machine, tmp_path, text, line,
                                                             construct, what):
    path = write(tmp_path, text)
    error = _refusal(path, machine)
    assert (error.row, error.field) == (line, construct)
    message = str(error)
    assert message.startswith(f"{path}, line {line}")
    assert repr(construct) in message and re.search(what, message), message


def test_a_foreign_construct_is_named_once_before_its_message(machine, tmp_path):
    path = write(tmp_path, "N10 G17\nN20 SCALE X2\n", "part.mpf")
    error = _refusal(path, machine)
    assert isinstance(error, ForeignSyntaxError)
    assert str(error).startswith(f"{path}, line 2: 'SCALE' is Sinumerik 840D syntax")


@pytest.mark.parametrize("text", ["G21\n(unterminated\nG1 X1\n", "G21\nO100 (sub\nG1 X1\n",
                                  "G21\no(\n"])
def test_an_unterminated_comment_is_refused_on_its_own_line(machine, tmp_path, text):
    """The O-word scan reads some lines before the program runs (an O on line 2 was
    reported as line 0)."""
    error = _refusal(write(tmp_path, text), machine)
    assert error.row == 2
    assert re.search(r", line 2: unbalanced or nested '\(' comment: close each comment with "
                     r"'\)' on its line", str(error)), str(error)


def test_a_comment_that_names_a_construct_is_no_construct(machine, tmp_path):
    """Comments are left out before another language's constructs are looked for."""
    error = _refusal(write(tmp_path, "G0 X0\nG1 X1 Y (TRANS) ; DEF REAL\n"), machine)
    assert type(error) is ProgramError
    assert str(error).endswith("line 2, word 'Y': cannot parse number 'Y'")


# Public programs as their posts write them, read up to their first line in the language.

# github.com/polymech-info/heidenhain-simulator/blob/db5968cb6b6dbf5efb621c8b202c9b8508f2dba3/
# samples/asterix/spot-drill.h, lines 1-3, 11, 14-15 (block numbers 0-2, 10, 13, 14)
HEIDENHAIN_LINES = ["0  BEGIN PGM spot-drill MM ", "1  BLK FORM 0.1 Z  X+0  Y-200  Z-15",
                    "2  BLK FORM 0.2  X+500  Y+0  Z+0", "10 TOOL CALL 7 Z S624",
                    "13 L  X+451.5  Y-25.5 R0 FMAX", "14 L  Z+15 R0 FMAX"]
# Lines as the Siemens SINUMERIK 840D post writes them,
# github.com/AntonTroskin/posts/blob/dc6a9b29535e2d146975b24623a14634d393743b/siemens-840d.cps:
# the header (line 307), a comment (writeComment, line 212; sequence numbers from 10 by 1),
# the tool by name or number (lines 1157-1158), the swivel cycle (line 700), TRAORI (1281).
SINUMERIK_LINES = ["; %_N_PART1_MPF", "N10 ; PART1", 'N11 T="BALL6" D1', "N12 M6",
                   'N13 CYCLE800(0,"TC1",200000,27,0,0,0,0,30,0,0,0,0,0)', "N14 TRAORI"]


@pytest.mark.parametrize("lines, line, construct, language", [
    (HEIDENHAIN_LINES, 1, "BEGIN PGM", "Heidenhain TNC conversational"),
    (HEIDENHAIN_LINES[1:], 1, "BLK FORM", "Heidenhain TNC conversational"),
    (HEIDENHAIN_LINES[3:], 1, "TOOL CALL", "Heidenhain TNC conversational"),
    (HEIDENHAIN_LINES[4:], 1, "L  X+451.5  Y-25.5 R0 FMAX", "Heidenhain TNC conversational"),
    (SINUMERIK_LINES[:5] + ["N15 CYCLE81(10,0,1,-5)"], 6, "CYCLE81(10,0,1,-5)",
     "Sinumerik 840D"),
])
def test_a_program_in_another_language_says_which(machine, tmp_path, lines, line, construct,
                                                  language):
    path = write(tmp_path, "\n".join(lines) + "\n", "part.nc")
    error = _refusal(path, machine)
    assert isinstance(error, ForeignSyntaxError)
    assert (error.row, error.field) == (line, construct)
    assert str(error).startswith(f"{path}, line {line}: {construct!r} is {language} syntax")


def test_a_refusal_says_which_language_the_program_looks_like(machine, tmp_path):
    """A refused construct of no language's own (Sinumerik's G153, machine coordinates
    keeping the base frame) in a program that shows one elsewhere, even after it; a plain
    program's refusal says nothing more."""
    path = write(tmp_path, "N10 G153 G0 X0\nN20 G17\nN30 TRAORI\n", "part.mpf")
    assert str(_refusal(path, machine)) == (
        f"{path}, line 1, word 'G153': unsupported G code G153; the program looks like "
        "Sinumerik 840D ('TRAORI' on line 3): post-process for LinuxCNC/Fanuc-style G-code")
    path = write(tmp_path, "G0 X0\nG1 B45. F100\nN30 MSG(\"TOOL 2\")\n", "part.nc")
    assert str(_refusal(path, machine)).endswith(
        "unsupported word 'B45.' (axes are X Y Z A C); the program looks like Sinumerik 840D "
        "('MSG(\"TOOL 2\")' on line 3): post-process for LinuxCNC/Fanuc-style G-code")
    path = write(tmp_path, "G0 X0\nG60 X1\n", "plain.ngc")
    assert str(_refusal(path, machine)) == f"{path}, line 2, word 'G60': unsupported G code G60"


def test_the_sinumerik_words_the_reader_reads_are_still_read(machine, tmp_path):
    """Nothing read before is refused: TRAORI/TRAFOOF, ; comments, N numbers, % and O."""
    program = read(tmp_path, machine, "%\nO1000\nN10 G0 X0 Y0 Z0 A0 C0 ; start\nN20 TRAORI\n"
                                      "N30 G1 X1 F100\nN40 TRAFOOF\n%\n")
    assert program.start_line == 3 and program.n_moves == 1 and program.tcp_move.all()
