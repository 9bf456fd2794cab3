"""Sinumerik 840D programs as five-axis posts write them, read by the G-code reader; and the
choice of the swivel solution within travel (G53.1, CYCLE800). Expected numbers are worked
by hand from Siemens's definitions (frames: p = t + R p'; ROT with several angles in RPY
order; CYCLE800 axis by axis) and the machine's direct kinematics."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from precontour.errors import ForeignSyntaxError, ProgramError
from precontour.machine.machine_file import load_machine
from precontour.toolpath import read_program

DATA = Path(__file__).parent / "data"


@pytest.fixture(scope="module")
def xyzac():
    # A tilts within [-100, 50] deg
    return load_machine("linuxcnc-xyzac-trt")


def rx(degrees):
    c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def rz(degrees):
    c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def ends(program, kinematics):
    """Tool tip, orientation and rotary axes (deg) at the end of each line's last move."""
    tips, orientations = kinematics.forward(program.q)
    last = {int(line): k for k, line in enumerate(program.line)}
    return {line: (tips[k], orientations[k], np.degrees(program.q[k, 3:]))
            for line, k in last.items()}


def write(tmp_path, text, name="part.mpf"):
    path = tmp_path / name
    path.write_text(text)
    return path


# --------------------------------------------------------------------------- the two posts


def test_nx_style_program(xyzac):
    """data/sinumerik_nx_style.mpf: DEF and variables, SUPA homes, T="name", MSG, CYCLE832,
    TRAORI with rotary words, AC/IC/DC values, an arc with an absolute centre, a 3+2 section
    under TRANS + AROT."""
    kin = xyzac.kinematics
    program = read_program(DATA / "sinumerik_nx_style.mpf", xyzac)
    at = ends(program, kin)
    # SUPA X=_X_HOME Y=_Y_HOME A=_A_HOME C=_C_HOME (line 11) after SUPA Z=_Z_HOME: machine
    # axes 0 0 120 0 0
    assert program.start_line == 11
    np.testing.assert_allclose(program.start, [0, 0, 120, 0, 0], atol=1e-12)
    # TRAORI: the programmed tips and rotary axes
    for line, tip, rotary in ((20, [20, -10, 30], [-20, 30]), (23, [22.5, -8.2, 4.1],
                                                                  [-21.5, 31.2]),
                              (25, [27.5, -4.6, 2.6], [-24.5, 33.6])):
        np.testing.assert_allclose(at[line][0], tip, atol=1e-9)
        np.testing.assert_allclose(at[line][2], rotary, atol=1e-9)
    assert program.tcp_move[program.line == 23].all()
    # F=R1+2000 (R1 is 0): 25 mm in 60 * 25 / 2000 s
    assert program.duration[program.line == 22].sum() == pytest.approx(60 * 25 / 2000)
    # G2 X32.5 Y-4.6 I=AC(30.) J=AC(-4.6): a half circle about (30, -4.6), radius 2.5,
    # clockwise from (27.5, -4.6): through (30, -2.1)
    arc = kin.forward(program.q[program.line == 26])[0]
    np.testing.assert_allclose(np.hypot(arc[:, 0] - 30, arc[:, 1] + 4.6), 2.5, atol=1e-9)
    assert arc[:, 1].max() == pytest.approx(-2.1, abs=1e-9)
    # A=DC(-20.) from -24.5, C=IC(-3.6) from 33.6
    np.testing.assert_allclose(at[27][2], [-20, 30], atol=1e-9)
    # CYCLE832(_camtolerance, ...) with _camtolerance=0.01: the corner tolerance, said once
    assert (program.path_tolerance[(program.line >= 20) & (program.line <= 37)] == 0.01).all()
    assert sum("CYCLE832" in n for n in program.notices) == 1
    # TRANS X10 Y5, AROT X-30: p = (10, 5, 0) + Rx(-30) p'
    origin, rotation = np.array([10.0, 5.0, 0.0]), rx(-30)
    for line, local in ((34, [0, 0, 30]), (35, [0, 0, 2]), (36, [12, 4, 2])):
        np.testing.assert_allclose(at[line][0], origin + rotation @ local, atol=1e-9)
        # A30 C0 turns the tool along the frame's Z
        np.testing.assert_allclose(at[line][1], rotation[:, 2], atol=1e-12)
    # after TRANS (cleared) and G60: SUPA in machine axes, exact stop
    np.testing.assert_allclose(program.q[-1], [0, 0, 120, 0, 0], atol=1e-12)
    assert (program.path_tolerance[program.line >= 42] == 0).all()
    # the constructs are kept as comments for an output program
    kept = dict(program.passthrough)
    assert kept[12] == 'N120 M6 (T="BALL_6")' and kept[13] == "N130 (MSG, VARIABLE_CONTOUR)"


def test_autodesk_style_program(xyzac):
    """data/sinumerik_autodesk_style.mpf: a 3+2 face under CYCLE800 (axis by axis, X Y Z,
    A = -30 about X, _DIR -1), an arc by CR=, CYCLE800() and SUPA, then TRAORI."""
    kin = xyzac.kinematics
    program = read_program(DATA / "sinumerik_autodesk_style.mpf", xyzac)
    at = ends(program, kin)
    rotation = rx(-30)
    # the first moves in the plane: G0 X5 Y0 (line 14), G0 Z15 (line 16) start the program
    assert program.start_line == 16
    np.testing.assert_allclose(kin.forward(program.start)[0], rotation @ [5, 0, 15],
                               atol=1e-9)
    # _DIR -1: of A -30 C -180 and A 30 C 0, the one with the lower A (both within travel)
    np.testing.assert_allclose(np.degrees(program.start[3:]), [-30, -180], atol=1e-9)
    for line, local in ((17, [5, 0, 0]), (18, [15, 0, 0]), (19, [25, 0, 0])):
        np.testing.assert_allclose(at[line][0], rotation @ local, atol=1e-9)
        np.testing.assert_allclose(at[line][1], rotation[:, 2], atol=1e-12)
    # G3 X25. Y0. CR=5.: a half circle of radius 5 about (20, 0) in the plane, through y -5
    arc = kin.forward(program.q[program.line == 19])[0] @ rotation
    np.testing.assert_allclose(np.hypot(arc[:, 0] - 20, arc[:, 1]), 5, atol=1e-9)
    np.testing.assert_allclose(arc[:, 2], 0, atol=1e-9)
    assert -5 <= arc[:, 1].min() <= -5 + 1e-3      # the chord ends within the arc tolerance
    assert (program.path_tolerance[(program.line >= 17) & (program.line <= 20)] == 0.02).all()
    # CYCLE800() then G0 SUPA Z0.: machine Z 0, the rotary axes where the swivel left them
    np.testing.assert_allclose(program.q[program.line == 23][-1, 2:],
                               [0, *np.radians([-30, -180])], atol=1e-12)
    assert not program.tcp_move[program.line == 23].any()
    # TRAORI: tips and rotary axes as programmed
    np.testing.assert_allclose(at[29][0], [10, 2, 1], atol=1e-9)
    np.testing.assert_allclose(at[30][2], [-15, 25], atol=1e-9)


@pytest.mark.parametrize("name", ["sinumerik_nx_style.mpf", "sinumerik_autodesk_style.mpf"])
def test_sinumerik_programs_plan_within_the_limits(xyzac, name):
    from precontour.trajectory import program_trajectory, summarize
    program = read_program(DATA / name, xyzac)
    assert summarize(program_trajectory(program, xyzac), xyzac).within_limits


# --------------------------------------------------------------------------- constructs


def test_variables_r_parameters_and_expressions(xyzac, tmp_path):
    text = ("N10 DEF REAL _D=4, _W\nN20 DEF INT _K\nR1=2 R2=R1*3+1 _W=SQRT(POT(3)+POT(4))\n"
            "_K=7 DIV 2\nN30 G0 X0 Y0 Z10 A0 C0\nN40 G1 X=R2 Y=_W*_D Z=-(_K+SIN(30)) F=R1*500\n"
            "N50 X=ATAN2(1,1) Y=TRUNC(-2.7) Z=ROUND(2.5)\n")
    program = read_program(write(tmp_path, text), xyzac)
    np.testing.assert_allclose(program.q[0, :3], [7, 20, -3.5], atol=1e-12)
    np.testing.assert_allclose(program.q[1, :3], [45, -2, 3], atol=1e-12)
    assert program.duration[0] == pytest.approx(60 * math.dist([0, 0, 10], [7, 20, -3.5]) / 1000)


def test_blending_modes_and_exact_stop(xyzac, tmp_path):
    text = ("N10 G0 X0 Y0 Z10 A0 C0\nCTOL=0.05\nG642 G1 X1 F100\nG64 X2\nG60 X3\nG641 X4\n"
            "G9 X5\nX6\nG64 X7\n")
    program = read_program(write(tmp_path, text), xyzac)
    np.testing.assert_array_equal(program.path_tolerance,
                                  [0.05, np.nan, 0, 0.05, 0, 0.05, np.nan])


def test_rot_with_several_angles_turns_z_then_y_then_x(xyzac, tmp_path):
    """ROT X Y Z: RPY order (Z, the new Y, the new X); ATRANS in the turned frame; ROT RPL=
    in the working plane (G17: about Z)."""
    text = ("G0 X0 Y0 Z0 A0 C0\nTRAORI\nROT X10 Y20 Z30\nATRANS X1\nG1 X1 Y2 Z3 F100\n"
            "ROT RPL=90\nG1 X1 Y0 Z0\nROT\nG1 X1 Y2 Z3\nTRAFOOF\n")
    program = read_program(write(tmp_path, text), xyzac)
    tips = xyzac.kinematics.forward(program.q)[0]
    ry = np.array([[math.cos(math.radians(20)), 0, math.sin(math.radians(20))], [0, 1, 0],
                   [-math.sin(math.radians(20)), 0, math.cos(math.radians(20))]])
    rotation = rz(30) @ ry @ rx(10)
    np.testing.assert_allclose(tips[0], rotation @ [1, 0, 0] + rotation @ [1, 2, 3], atol=1e-9)
    np.testing.assert_allclose(tips[1], [0, 1, 0], atol=1e-9)
    np.testing.assert_allclose(tips[2], [1, 2, 3], atol=1e-9)


def test_m17_and_ret_end_the_program(xyzac, tmp_path):
    program = read_program(write(tmp_path, "G0 X0 Y0 Z0 A0 C0\nG1 X1 F100\nM17\nG1 X9\n"), xyzac)
    assert program.n_moves == 1 and program.stops[-1].kind == "end"


# --------------------------------------------------------------------------- item 7: travel


def test_g53_1_takes_the_branch_within_travel(xyzac, tmp_path):
    """J-60: the branch nearest C0 is A = +60, outside A's travel [-100, 50]; A = -60 with
    C turned half a turn reaches the same plane, and a notice says so."""
    text = "G0 X0 Y0 Z50 A0 C0\nG68.2 X0 Y0 Z0 I0 J-60 K0\nG53.1\nG1 Z10 F100\nG69\n"
    program = read_program(write(tmp_path, text, "tilt.ngc"), xyzac)
    a, c = np.degrees(program.q[0, 3:])
    assert a == pytest.approx(-60) and abs(c) == pytest.approx(180)
    plane_z = np.array([0.0, math.sin(math.radians(60)), math.cos(math.radians(60))])
    np.testing.assert_allclose(xyzac.kinematics.forward(program.q)[1][1], plane_z, atol=1e-12)
    note = [n for n in program.notices if "G53.1" in n]
    assert len(note) == 1 and re.search(r"line 3: G53\.1: A60 C0 is outside the travel \(A "
                                        r"\[-100, 50\] deg\); the other solution A-60 C-?180",
                                        note[0]), note


def test_cycle800_direction_gives_way_to_the_travel(xyzac, tmp_path):
    """_DIR +1 asks for the higher A (+60), out of travel: A -60 is taken, said once; the
    same plane with _DIR -1 takes A -60 without a word."""
    text = ("G0 X0 Y0 Z50 A0 C0\nCYCLE800(0,\"TC1\",0,57,0,0,0,60,0,0,0,0,0,{})\nG1 Z10 F100\n"
            "CYCLE800()\n")
    for direction, said in ((1, True), (-1, False)):
        program = read_program(write(tmp_path, text.format(direction)), xyzac)
        assert np.degrees(program.q[0, 3]) == pytest.approx(-60)
        assert any("is outside the travel" in n for n in program.notices) == said


def test_g53_1_keeps_the_nearest_branch_within_travel(xyzac, tmp_path):
    text = "G0 X0 Y0 Z50 A0 C0\nG68.2 X0 Y0 Z0 I0 J30 K0\nG53.1\nG69\n"
    program = read_program(write(tmp_path, text, "tilt.ngc"), xyzac)
    np.testing.assert_allclose(np.degrees(program.q[0, 3:]), [-30, 0], atol=1e-9)
    assert not any("travel" in n for n in program.notices)


# --------------------------------------------------------------------------- refusals


@pytest.mark.parametrize("line, construct, message", [
    ("N20 ORIVECT", "ORIVECT", r"the orientation interpolated on a great circle"),
    ("N20 G1 X1 A3=0.5 B3=0 C3=1", "A3=0.5", r"the tool orientation as a vector"),
    ('N20 CYCLE800(1,"TC1",0,64,0,0,0,0,30,0,0,0,0,1)', "CYCLE800(...)",
     r"swivel mode solid angle, _MODE=64"),
    ('N20 CYCLE800(1,"TC1",1,57,0,0,0,0,30,0,0,0,0,1)', "CYCLE800(...)",
     r"an additive swivel, _ST=1"),
    ("N20 CYCLE81(10,0,1,-5)", "CYCLE81(10,0,1,-5)", r"a cycle call"),
    ("N20 SCALE X2", "SCALE", r"a scaling frame"),
])
def test_refused_sinumerik_constructs_are_named(xyzac, tmp_path, line, construct, message):
    path = write(tmp_path, f"N10 G0 X0 Y0 Z10 A0 C0\n{line}\nN30 G1 X1 F100\n")
    with pytest.raises(ForeignSyntaxError) as info:
        read_program(path, xyzac)
    error = info.value
    assert (error.row, error.field) == (2, construct)
    assert str(error).startswith(f"{path}, line 2") and repr(construct) in str(error)
    assert re.search(message, str(error)), str(error)
    assert "\n" not in str(error)


@pytest.mark.parametrize("line, word, message", [
    ("N20 G1 X=_NOPE F100", "X=_NOPE", r"variable _NOPE is not defined \(DEF REAL _NOPE\)"),
    ("N20 G1 X=DC(5) F100", "X=DC(5)", r"DC\(\) is for a rotary axis, not X"),
    ("N20 TRANS X10 G1", "G1", r"TRANS takes a block of its own with X Y Z"),
    ("N20 G1 X=R1/R2 F100", "X=R1/R2", r"division by zero"),
])
def test_sinumerik_errors_name_the_word(xyzac, tmp_path, line, word, message):
    path = write(tmp_path, f"N10 G0 X0 Y0 Z10 A0 C0\n{line}\n")
    with pytest.raises(ProgramError) as info:
        read_program(path, xyzac)
    assert (info.value.row, info.value.field) == (2, word)
    assert re.search(message, str(info.value)), str(info.value)
