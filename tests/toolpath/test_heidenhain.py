"""Tests of the Heidenhain conversational reader (precontour.toolpath.heidenhain): positions
computed by hand from the TNC user's manual's rules, the same program in G-code read by the
G-code reader, refusals, and two programs in the style of real posts planned within the
corner tolerance."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from precontour.errors import InputError, ProgramError
from precontour.machine.machine_file import load_machine
from precontour.toolpath import read_program, read_toolpath_report, toolpath_format
from precontour.toolpath._gcode_codes import _euler_zxz
from precontour.toolpath.heidenhain import euler_zxz_angles, spatial_rotation
from precontour.trajectory import program_trajectory, summarize

DATA = Path(__file__).parent / "data"
INCH = 25.4


@pytest.fixture(scope="module")
def ac():
    return load_machine("linuxcnc-xyzac-trt")


@pytest.fixture(scope="module")
def bc():
    return load_machine("linuxcnc-xyzbc-trt")


def write(tmp_path, text, name="prog.h"):
    path = tmp_path / name
    path.write_text(text)
    return path


def program(tmp_path, machine, body, unit="MM"):
    lines = [f"BEGIN PGM T {unit}"] + body + [f"END PGM T {unit}"]
    text = "".join(f"{i} {line}\n" for i, line in enumerate(lines))
    return read_program(write(tmp_path, text), machine)


CONTOUR = ["TOOL CALL 1 Z S8000", "L Z+50 A+0 C+0 R0 FMAX M3", "L X+10 Y+0 R0 FMAX",
           "L Z-2 F200", "L X+20 F500", "CC X+20 Y+10", "C X+30 Y+10 DR+",
           "CR X+40 Y+20 R+10 DR-", "CT X+50 Y+40", "L IX+5 IY-5", "Q1 = 7.5",
           "FN 0: Q2 = +2", "FN 1: Q3 = +Q1 + +0.5", "L X+Q3 Y-Q2", "L Z+50 FMAX ; retract"]


def test_contour_blocks_as_computed_by_hand(ac, tmp_path):
    """L, C about CC, CR, CT, incremental words and Q parameters: the end points and centres
    worked out from the manual's rules (DR+ counter-clockwise; R+ the arc below 180 degrees;
    CT tangent to the previous block; IX from the last position)."""
    moves = program(tmp_path, ac, CONTOUR).programmed
    ends = moves.end[:, :3]
    expected = [(10, 0, -2), (20, 0, -2), (30, 10, -2), (40, 20, -2), (50, 40, -2),
                (55, 35, -2), (8, -2, -2), (8, -2, 50)]
    np.testing.assert_allclose(ends, expected, atol=1e-12)
    assert moves.kind.tolist() == [1, 1, 2, 2, 2, 1, 1, 0]
    # C: about CC (20, 10), counter-clockwise; CR X40 Y20 R+10 DR-: the short clockwise arc
    # from (30, 10) is about (40, 10); CT: tangent +X at (40, 20) (the top of that circle,
    # clockwise), to (50, 40): centre on x = 40 at s = |d|^2 / (2 d.n) = 500 / 40 above
    np.testing.assert_allclose(moves.centre[2:5, :2], [(20, 10), (40, 10), (40, 32.5)],
                               atol=1e-12)
    assert moves.turns[2:5].tolist() == [1, -1, 1]
    assert moves.feed[:2].tolist() == [200.0, 500.0]


def test_the_same_program_as_g_code(ac, tmp_path):
    """The contour and the same moves written in G-code give the same machine axes."""
    heidenhain = program(tmp_path, ac, CONTOUR)
    gcode = write(tmp_path, "G21 G17 G90\nT1 M6 S8000\nG0 Z50 A0 C0 M3\nX10 Y0\nG1 Z-2 F200\n"
                            "X20 F500\nG3 X30 Y10 I0 J10\nG2 X40 Y20 R10\nG3 X50 Y40 I0 J12.5\n"
                            "G1 X55 Y35\nX8 Y-2\nG0 Z50\nM30\n", "prog.ngc")
    reference = read_program(gcode, ac)
    np.testing.assert_allclose(heidenhain.q, reference.q, atol=1e-12)
    np.testing.assert_allclose(heidenhain.duration, reference.duration, rtol=1e-12)
    assert heidenhain.rapid.tolist() == reference.rapid.tolist()


def test_inch_program(ac, tmp_path):
    """BEGIN PGM ... INCH: coordinates in inches, F in 1/10 inch per minute."""
    prog = program(tmp_path, ac, ["L X+0 Y+0 Z+0 A+0 C+0 R0 FMAX", "L X+2 F100"], "INCH")
    np.testing.assert_allclose(prog.q[-1, 0], 2 * INCH)
    np.testing.assert_allclose(prog.duration[-1], 60 * 2 / 10.0)   # 2 in at 10 in/min


def test_datum_shift_and_tilted_plane_by_hand(ac, tmp_path):
    """CYCL DEF 7 moves the datum; PLANE SPATIAL SPA+30 turns the frame about the fixed X
    axis at that datum, TURN turns the rotary axes onto it: a point (5, 0, 10) of the plane
    is datum + Rx(30) (5, 0, 10) in the workpiece, the tool along Rx(30) Z."""
    prog = program(tmp_path, ac, [
        "CYCL DEF 7.0 DATUM SHIFT", "CYCL DEF 7.1 X+10", "CYCL DEF 7.2 Y+20",
        "CYCL DEF 7.3 IZ+0", "L X+0 Y+0 Z+100 A+0 C+0 R0 FMAX",
        "PLANE SPATIAL SPA+30 SPB+0 SPC+0 TURN FMAX", "L X+5 Y+0 Z+10 R0 FMAX",
        "L Z+0 F300", "PLANE RESET STAY"])
    P, O = ac.kinematics.forward(prog.q)
    c, s = math.cos(math.radians(30)), math.sin(math.radians(30))
    np.testing.assert_allclose(P[1], (10 + 5, 20 - 10 * s, 10 * c), atol=1e-9)
    np.testing.assert_allclose(P[2], (15, 20, 0), atol=1e-9)
    np.testing.assert_allclose(O[1:], [(0, -s, c)] * 2, atol=1e-12)


def test_spatial_angles_as_euler_angles():
    """PLANE SPATIAL's rotation about the fixed X, Y, Z axes, as G68.2's Z-X-Z Euler angles:
    a round trip through the G-code reader's own rotation, degenerate tilts included."""
    rng = np.random.default_rng(1)
    cases = [tuple(v) for v in rng.uniform(-180, 180, (20, 3))]
    cases += [(0, 0, 30), (0, 0, 0), (180, 0, 40), (0, 180, 0), (90, 0, 180)]
    for spa, spb, spc in cases:
        rotation = spatial_rotation(spa, spb, spc)
        np.testing.assert_allclose(_euler_zxz(*euler_zxz_angles(rotation)), rotation,
                                   atol=1e-12)
    # SPB+30: the tool axis tilts from Z towards +X (right hand about Y)
    np.testing.assert_allclose(spatial_rotation(0, 30, 0)[:, 2], (0.5, 0, math.cos(math.pi / 6)))


def test_tcp_and_tool_vectors(bc, tmp_path):
    """M128 ... M129 and FUNCTION TCPM: X Y Z the tool tip; LN's vector TX TY TZ sets the
    rotary axes, and the tip and the tool direction come back through the kinematics."""
    prog = program(tmp_path, bc, [
        "L X+0 Y+0 Z+50 B+0 C+0 R0 FMAX", "M128", "L X+10 Y+5 Z+0 B+20 C+30 F1000",
        "LN X+20 Y+0 Z+0 NX+0 NY+0 NZ+1 TX+0.5 TY+0 TZ+0.8660254",
        "LN X+30 Y+0 Z+0 TX+0 TY+0.5 TZ+0.8660254", "M129",
        "FUNCTION TCPM F TCP AXIS POS PATHCTRL AXIS", "L X+0 Y+0 Z+5 B+0 C+0 FMAX",
        "FUNCTION RESET TCPM"])
    P, O = bc.kinematics.forward(prog.q)
    np.testing.assert_allclose(P, [(10, 5, 0), (20, 0, 0), (30, 0, 0), (0, 0, 5)], atol=1e-9)
    np.testing.assert_allclose(O[1], (0.5, 0, 0.8660254), atol=1e-7)
    np.testing.assert_allclose(O[2], (0, 0.5, 0.8660254), atol=1e-7)
    np.testing.assert_allclose(np.degrees(prog.q[0, 3:]), (20, 30))
    assert prog.tcp_move.all()


def test_m126_takes_the_shorter_way(ac, tmp_path):
    prog = program(tmp_path, ac, ["L X+0 Y+0 Z+0 A+0 C+350 R0 FMAX", "L C+10 FMAX M126",
                                  "L C+350 FMAX M127"])
    np.testing.assert_allclose(np.degrees(prog.q[:, 4]), (370, 350))


def test_m91_is_a_move_in_machine_coordinates(ac, tmp_path):
    prog = program(tmp_path, ac, ["CYCL DEF 7.0 DATUM SHIFT", "CYCL DEF 7.1 X+100",
                                  "L X+0 Y+0 Z+0 A+0 C+0 R0 FMAX", "L X+5 F100",
                                  "L X+0 R0 FMAX M91"])
    np.testing.assert_allclose(prog.q[:, 0], (105, 0))


def test_format_and_report(ac, tmp_path):
    path = write(tmp_path, "0 BEGIN PGM T MM\n1 L X+0 Y+0 Z+0 A+0 C+0 R0 FMAX\n"
                           "2 L X+1 F60\n3 END PGM T MM\n")
    assert toolpath_format(path) == "heidenhain"
    report = read_toolpath_report(path, machine=ac)
    assert report.format == "heidenhain"
    np.testing.assert_allclose(report.toolpath.feed[1:], [1.0])
    with pytest.raises(InputError, match="applies to G-code programs"):
        read_program(path, ac, tcp=True)


@pytest.mark.parametrize("line, construct, match", [
    ("CYCL DEF 208 BORE MILLING~\n  Q200=1 ;SET-UP CLEARANCE", "CYCL DEF 208 BORE MILLING",
     "a machining cycle"),
    ("CALL LBL 1 ; RESET WORKING PLANE", "CALL LBL 1", "a call of a label"),
    ("LBL 1", "LBL 1", "a label"),
    ("L X+5 RL F100", "RL", "radius compensation RL is not read"),
    ("CP IPA+90 DR+", "CP", "a contour element"),
    ("L M140 MB MAX", "M140", "retraction along the tool axis"),
    ("PLANE SPATIAL SPA+0 SPB+30 SPC+0 MOVE DIST50 FMAX", "MOVE", "MOVE .* not read"),
    ("PLANE EULER EULPR+0 EULNU+30 EULROT+0 TURN", "PLANE EULER", "PLANE function other"),
    ("FN 9: IF +Q1 EQU +1 GOTO LBL 2", "FN 9: IF", "a Q-parameter function"),
    ("FUNCTION TCPM F CONT AXIS SPAT PATHCTRL VECTOR", "FUNCTION TCPM", "only F TCP AXIS POS"),
    ("CC X+0 Z+5", "Z+5", "only circle centres in the XY plane"),
    ("L X+Q7", "X+Q7", "Q7 is used before it is set"),
])
def test_refusals_name_the_construct_and_line(ac, tmp_path, line, construct, match):
    text = "0 BEGIN PGM T MM\n1 L X+0 Y+0 Z+0 A+0 C+0 R0 FMAX\n2 " + line + "\n"
    with pytest.raises(ProgramError) as info:
        read_program(write(tmp_path, text), ac)
    message = str(info.value)
    assert message.startswith(f"{tmp_path / 'prog.h'}, line 3, word {construct!r}: ")
    assert re.search(match, message)


def test_seq_is_checked_against_the_solution(ac, tmp_path):
    """SEQ- asks for the negative tilt; the reader's G53.1 turns A to +30 for SPA-30 on this
    machine (its nearest solution within travel): refused by name, not silently other."""
    with pytest.raises(ProgramError, match=r"line 3, word 'SEQ-': SEQ- asks for the other"):
        program(tmp_path, ac, ["L X+0 Y+0 Z+50 A+0 C+0 R0 FMAX",
                               "PLANE SPATIAL SPA-30 SPB+0 SPC+0 TURN SEQ- FMAX"])


def point_to_path(points, path):
    """Distance from each point to the polyline through ``path``'s rows."""
    a, ab = path[:-1], np.diff(path, axis=0)
    den = np.einsum("ij,ij->i", ab, ab)
    out = np.empty(len(points))
    for i, p in enumerate(points):
        rel = p - a
        with np.errstate(divide="ignore", invalid="ignore"):
            u = np.where(den > 0, np.clip(np.einsum("ij,ij->i", rel, ab) / den, 0, 1), 0.0)
        out[i] = np.linalg.norm(rel - u[:, None] * ab, axis=1).min()
    return out


@pytest.mark.parametrize("name, machine_name, n_moves", [
    ("heidenhain_bc_tcpm.h", "linuxcnc-xyzbc-trt", 77),
    ("heidenhain_ac_3plus2.h", "linuxcnc-xyzac-trt", 130),
])
def test_post_style_programs_plan_through_their_points(name, machine_name, n_moves):
    """Programs in the style of two posts (see data/README.md) read, and their planned
    trajectories pass their programmed tool tips within the corner tolerance (0.01 mm) and
    the tool orientations there within 1 mrad."""
    machine = load_machine(machine_name)
    prog = read_program(DATA / name, machine)
    assert prog.n_moves == n_moves and not prog.notices
    traj = program_trajectory(prog, machine)
    assert summarize(traj, machine).within_limits
    P, O = machine.kinematics.forward(prog.points)
    Pt, Ot = machine.kinematics.forward(traj.q)
    assert point_to_path(P, Pt).max() <= 0.01
    nearest = [int(np.linalg.norm(Pt - p, axis=1).argmin()) for p in P]
    angle = np.arccos(np.clip(np.einsum("ij,ij->i", O, Ot[nearest]), -1.0, 1.0))
    assert angle.max() <= 1e-3
