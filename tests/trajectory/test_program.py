"""Tests of program timing (precontour.trajectory.program.program_trajectory): block times
against 1/F, rapids against the axis limits, stops, TCP tips against the direct kinematics,
every sample within the machine's limits, and the 'line' column."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from precontour.cli import main
from precontour.errors import PrecontourError
from precontour.machine.machine_file import builtin_machine_text, load_machine, parse_machine
from precontour.tables import read_trajectory, trajectory_columns, write_columns
from precontour.toolpath import read_program
from precontour.trajectory import program_trajectory, summarize
from precontour.trajectory.feedplan import axis_limits


@pytest.fixture(scope="module")
def machine():
    return load_machine("zhang2013")


def program_of(tmp_path, machine, text, **kwargs):
    path = tmp_path / "prog.ngc"
    path.write_text(text)
    return read_program(path, machine, **kwargs)


def motion_span(traj):
    """First and last sample index at which the commands move."""
    moving = np.flatnonzero(np.any(np.diff(traj.q, axis=0) != 0, axis=1))
    return moving[0], moving[-1] + 1


def test_block_times_follow_inverse_time_feeds(machine, tmp_path):
    # three collinear G93 blocks: 2 s, 1 s and 5 s
    program = program_of(tmp_path, machine, "G0 X0 Y0 Z0 A0 C0\nG93 G1 X10 F30\nX20 F60\n"
                                            "X22 F12\nM30\n")
    traj = program_trajectory(program, machine, dwell=0.2)
    first, last = motion_span(traj)
    motion = (last - first) * traj.ts
    window = motion - 8.0           # the jerk filters' start-up and run-out
    assert 0.0 <= window <= 0.05
    lag = first * traj.ts + window / 2
    # mid-block the velocity is constant over the filter window: the nominal position exactly
    for t_block, x in ((1.0, 5.0), (2.5, 15.0), (5.5, 21.0)):
        k = int(round((t_block + lag) / traj.ts))
        assert traj.q[k, 0] == pytest.approx(x, abs=1e-9)
        assert traj.line[k] == {5.0: 2, 15.0: 3, 21.0: 4}[x]
    np.testing.assert_array_equal(traj.q[-1], [22, 0, 0, 0, 0])
    assert (traj.n_samples - 1 - last) * traj.ts == pytest.approx(0.2 + 2e-3, abs=1e-12)
    assert traj.line[-1] == 5


def test_rapids_run_at_the_rapid_rate_on_a_straight_line(machine, tmp_path):
    program = program_of(tmp_path, machine, "G0 X0 Y0 Z0 A0 C0\nG0 X100 C1\n")
    traj = program_trajectory(program, machine, dwell=0.0)
    v, a, j = axis_limits(machine)
    first, last = motion_span(traj)
    duration = (last - first) * traj.ts
    assert 100 / v[0] <= duration <= 100 / v[0] / 0.98 + 0.08
    peak = np.abs(np.diff(traj.q[:, 0])).max() / traj.ts
    assert 0.95 * 0.98 * v[0] <= peak <= v[0]
    # a rapid is a straight line in machine axes
    np.testing.assert_allclose(np.degrees(traj.q[:, 4]) * 100, traj.q[:, 0], rtol=0, atol=1e-9)
    assert summarize(traj, machine).within_limits


def test_stops_hold_the_axes_at_rest(machine, tmp_path):
    text = "G0 X0 Y0 Z0 A0 C0\nG1 X5 F600\nG4 P0.5\nG1 X6\nM0\nG1 X7\nM30\n"
    program = program_of(tmp_path, machine, text)
    traj = program_trajectory(program, machine, dwell=0.3)
    held = {line: np.flatnonzero(traj.line == line) for line in (3, 5, 7)}
    for line, seconds in ((3, 0.5), (5, 0.3), (7, 0.3)):
        k = held[line]
        assert k.size == round(seconds / traj.ts)
        assert np.all(np.diff(k) == 1)
        assert np.all(traj.q[k[0] - 1: k[-1] + 1] == traj.q[k[0]])
    assert traj.q[held[3][0], 0] == 5 and traj.q[held[5][0], 0] == 6


def _cam_program():
    """A 3+2 program with rapids, a tool change, arcs in all planes (R and IJK), a full
    circle, a helix, G91 and G20 blocks, as a post-processor writes them."""
    return "\n".join([
        "%", "O0100 (3+2 WITH ARCS)", "G90 G21 G17 G40 G49 G94", "T2 M6", "S8000 M3",
        "G0 A-20. C35.", "G0 X10. Y0. Z50.", "G0 Z2.", "M8", "G1 Z0. F300.", "X20.",
        "G3 X30. Y10. R10.", "G2 X40. Y0. I0. J-10.", "G2 X40. Y0. I-5. J0.",
        "G18 G3 X50. Z0. I5. K0.", "G19 G2 Y10. Z0. J5. K0.", "G17 G3 X50. Y10. Z-2. I0. "
        "J-5. F200.", "G91 G1 X-5. Y-5.", "G90", "G20 G1 X1.5 F10.", "G21", "G0 Z50.",
        "G0 A0. C0.", "M9", "M5", "M30", "%"])


def test_cam_program_within_the_machine_limits(machine, tmp_path):
    program = program_of(tmp_path, machine, _cam_program())
    traj = program_trajectory(program, machine)
    assert summarize(traj, machine).within_limits
    P, O = machine.kinematics.forward(traj.q)
    np.testing.assert_array_equal(traj.P, P)
    np.testing.assert_array_equal(traj.O, O)
    assert set(np.unique(traj.line)) <= (set(program.line) | {s.line for s in program.stops}
                                         | {program.start_line})
    assert np.all(np.diff(traj.line) >= 0)
    # the G2 full circle (line 14) at 300 mm/min stays on its circle, centre (35, 0)
    on = traj.line == 14
    r = np.hypot(traj.q[on, 0] - 35.0, traj.q[on, 1])
    inner = np.abs(r - 5.0)[20:-20]
    assert inner.max() < 2e-3


def test_tcp_program_tips_against_forward_kinematics(machine, tmp_path):
    text = ("G43.4 H1\nG93\nG0 X10 Y-5 Z2 A-30 C20\nG1 X20 Y-5 Z2 A-32 C60 F6\n"
            "G1 X20 Y5 Z1 A-35 C100 F6\nG49\nG0 X0 Y0 Z100\nM30\n")
    program = program_of(tmp_path, machine, text)
    traj = program_trajectory(program, machine)
    assert summarize(traj, machine).within_limits
    first, last = motion_span(traj)
    # 10 s per block; mid-block the tip is on the programmed straight line in the workpiece
    # frame, with the rotary axes halfway (as programmed, no re-branching)
    rows = np.flatnonzero(traj.line == 4)
    k = rows[np.argmin(np.abs(traj.P[rows, 0] - 15.0))]
    np.testing.assert_allclose(traj.P[k], [15, -5, 2], atol=1e-3)
    np.testing.assert_allclose(np.degrees(traj.q[k, 3:]), [-31, 40], atol=1e-3)
    assert (rows.size - 10_000) <= 60 and rows.size >= 9_900


def test_rapid_needs_a_velocity_limit(tmp_path):
    text = builtin_machine_text().replace("v_max = 250.0\n", "", 1)
    machine = parse_machine(text, "slow.toml")
    program = program_of(tmp_path, machine, "G0 X0 Y0 Z0 A0 C0\nG0 X10\n")
    with pytest.raises(PrecontourError, match=r"prog.ngc, line 2: a rapid \(G0\) moves axis X, "
                                              r"which has no velocity limit"):
        program_trajectory(program, machine)


def test_sample_guard(machine, tmp_path):
    program = program_of(tmp_path, machine, "G0 X0 Y0 Z0 A0 C0\nG93 G1 X1 F0.0001\n")
    with pytest.raises(PrecontourError, match=r"would have about 6e\+08 samples"):
        program_trajectory(program, machine)


def test_line_column_round_trip(machine, tmp_path):
    program = program_of(tmp_path, machine, "G0 X0 Y0 Z0 A0 C0\nG1 X5 F600\nG1 Y5\n")
    traj = program_trajectory(program, machine)
    for suffix in (".csv", ".npz", ".parquet"):
        out = write_columns(tmp_path / f"t{suffix}", trajectory_columns(traj))
        back = read_trajectory(out)
        np.testing.assert_array_equal(back.line, traj.line)
        np.testing.assert_array_equal(back.q, traj.q)
    bad = tmp_path / "bad.csv"
    bad.write_text("t,X,Y,Z,A,C,line\n0,0,0,0,0,0,1\n0.001,0,0,0,0,0,1.5\n"
                   + "".join(f"0.00{k},0,0,0,0,0,2\n" for k in range(2, 6)))
    with pytest.raises(PrecontourError, match=r"bad.csv, row 2, field 'line': line number is "
                                              r"not a whole number \(1.5\)"):
        read_trajectory(bad)


def test_cli_trajectory_of_a_program(tmp_path, capsys):
    path = tmp_path / "prog.ngc"
    path.write_text("M428\nG93\nG0 X10 Y-5 Z2 A-30 C20\nG1 X20 Y-5 Z2 A-32 C60 F60\nM30\n")
    out = tmp_path / "traj.csv"
    assert main(["trajectory", str(path), "--tcp", "-o", str(out)]) == 0
    captured = capsys.readouterr()
    assert "M428" not in captured.err   # LinuxCNC's TCP switch, understood
    assert f"program {path}: 1 move(s) (0 rapid), 1 stop(s), 1 pass-through line(s), tool " \
           "centre point mode" in captured.out
    assert out.read_text().splitlines()[0] == "t,X,Y,Z,A,C,Px,Py,Pz,Oi,Oj,Ok,line"
    traj = read_trajectory(out)
    np.testing.assert_allclose(traj.P[-1], [20, -5, 2], atol=1e-9)
    bad = tmp_path / "bad.ngc"
    bad.write_text("G0 X0 Y0 Z0 A0 C0\nG41 D1\n")
    out2 = tmp_path / "bad.csv"
    assert main(["trajectory", str(bad), "-o", str(out2)]) == 2
    err = capsys.readouterr().err.strip()
    assert err == f"precontour: error: {bad}, line 2, word 'G41': cutter radius " \
                  "compensation (G41) is not supported; post-process with the tool radius " \
                  "applied"
    assert not out2.exists()
    csv = tmp_path / "cl.csv"
    csv.write_text("Px,Py,Pz,Oi,Oj,Ok\n0,0,0,0,0,1\n1,0,0,0,0,1\n")
    assert main(["trajectory", str(csv), "--tcp", "-o", str(out2)]) == 2
    assert "--tcp applies to G-code programs only" in capsys.readouterr().err


def _distance_to_polyline(x, points):
    d = np.full(len(x), np.inf)
    for a, b in zip(points[:-1], points[1:]):
        ab = b - a
        u = np.clip(((x - a) @ ab) / (ab @ ab), 0, 1)
        d = np.minimum(d, np.linalg.norm(x - (a + u[:, None] * ab), axis=1))
    return d


def test_corners_blend_within_the_tolerance(machine, tmp_path):
    # corners of 90, 104, 22, 157 and 170 degrees at 50 mm/s, then small zig-zags at 10 mm/s
    text = ("G0 X0 Y0 Z0 A0 C0\nG1 X20 F3000\nY20\nX40 Y25\nX60 Y20\nX0 Y0 Z5\n"
            "X1 Y0.1 F600\nX2 Y0\nX3 Y0.1\n")
    program = program_of(tmp_path, machine, text)
    points = program.points[:, :3]
    free = program_trajectory(program, machine, tolerance=None)
    free_deviation = _distance_to_polyline(free.q[:, :3], points).max()
    assert free_deviation > 0.1
    for tolerance in (0.1, 0.03, 0.001):
        traj = program_trajectory(program, machine, tolerance=tolerance)
        deviation = _distance_to_polyline(traj.q[:, :3], points).max()
        assert deviation <= tolerance
        assert summarize(traj, machine).within_limits
        # no slower than stopping at every corner would be
        assert traj.duration < free.duration + 9 * 0.2
    # a sharp corner within a tight tolerance is a stop: the path passes through it
    traj = program_trajectory(program, machine, tolerance=0.001)
    corner = np.linalg.norm(traj.q[:, :3] - [20, 0, 0], axis=1)
    assert corner.min() < 1e-9


def test_a_reversal_reaches_its_end_point_within_the_tolerance(machine, tmp_path):
    program = program_of(tmp_path, machine, "G0 X0 Y0 Z0 A0 C0\nG1 X20 F3000\nX10\n")
    for tolerance in (0.05, 0.01):
        traj = program_trajectory(program, machine, tolerance=tolerance)
        assert 20 - tolerance <= traj.q[:, 0].max() <= 20


@settings(max_examples=25, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(st.lists(st.tuples(st.sampled_from(["G0", "G1", "G1", "G2", "G3", "G4"]),
                          st.lists(st.floats(-30, 30, allow_nan=False), min_size=5,
                                   max_size=5),
                          st.floats(20, 5000)), min_size=1, max_size=12),
       st.booleans())
def test_random_programs_stay_within_the_limits(machine, tmp_path, blocks, tcp):
    lines = ["G0 X0 Y0 Z0 A-20 C0", "G94"]
    for code, (x, y, z, a, c), feed in blocks:
        if code == "G4":
            lines.append(f"G4 P{abs(x) / 100:.3f}")
        elif code in ("G2", "G3"):
            lines.append(f"{code} X{x:.3f} Y{y:.3f} Z{z:.3f} R{abs(a) + 40:.3f} F{feed:.1f}")
        else:
            lines.append(f"{code} X{x:.3f} Y{y:.3f} Z{z:.3f} A{a - 20:.3f} C{c * 3:.3f} "
                         f"F{feed:.1f}")
    path = tmp_path / "random.ngc"
    path.write_text("\n".join(lines) + "\n")
    try:
        program = read_program(path, machine, tcp=tcp)
    except PrecontourError:
        return
    traj = program_trajectory(program, machine, dwell=0.01)
    assert summarize(traj, machine).within_limits
    np.testing.assert_allclose(traj.q[-1], program.q[-1], rtol=0, atol=1e-9)
    np.testing.assert_allclose(traj.q[0], program.start, rtol=0, atol=1e-12)


def test_program_path_tolerance_g64_p_and_g61(machine, tmp_path):
    corners = "G1 X20 F3000\nY20\nX40 Y25\nX60 Y20\n"
    loose = program_of(tmp_path, machine, "G0 X0 Y0 Z0 A0 C0\nG64 P0.1\n" + corners)
    np.testing.assert_array_equal(loose.path_tolerance, 0.1)
    traj = program_trajectory(loose, machine, tolerance=0.001)
    deviation = _distance_to_polyline(traj.q[:, :3], loose.points[:, :3]).max()
    assert 0.03 < deviation <= 0.1   # the program's G64 P, not the (tighter) default
    exact = program_of(tmp_path, machine, "G0 X0 Y0 Z0 A0 C0\nG61\n" + corners + "G64\nX70\n")
    np.testing.assert_array_equal(exact.path_tolerance, [0, 0, 0, 0, np.nan])
    traj = program_trajectory(exact, machine, tolerance=None)
    for corner in exact.points[1:4, :3]:   # G61: a stop at every corner
        assert np.linalg.norm(traj.q[:, :3] - corner, axis=1).min() < 1e-9
    inch = program_of(tmp_path, machine, "G20 G0 X0 Y0 Z0 A0 C0\nG64 P0.001\nG1 X1 F10\n")
    np.testing.assert_allclose(inch.path_tolerance, [0.0254])


@pytest.mark.parametrize("between", ["X20", "A1", "G4 P0.001\nG1"])
def test_a_corner_across_a_block_at_rest_still_blends_within_tolerance(machine, tmp_path,
                                                                       between):
    text = f"G0 X0 Y0 Z0 A0 C0\nG1 X20 F3000\n{between}\nY20 F3000\n"
    program = program_of(tmp_path, machine, text)
    points = np.array([[0, 0, 0], [20, 0, 0], [20, 20, 0]], dtype=float)
    traj = program_trajectory(program, machine, tolerance=0.02)
    assert _distance_to_polyline(traj.q[:, :3], points).max() <= 0.02


def test_tcp_arc_is_a_circle_of_the_tool_tip(machine, tmp_path):
    text = "G43.4 H1\nG0 X10 Y0 Z5 A-30 C0\nG3 X-10 Y0 A-40 C90 I-10 J0 F300\nG49\n"
    program = program_of(tmp_path, machine, text)
    tips, _ = machine.kinematics.forward(program.points)
    np.testing.assert_allclose(np.hypot(tips[:, 0], tips[:, 1]), 10.0, rtol=0, atol=1e-9)
    np.testing.assert_allclose(tips[:, 2], 5.0, rtol=0, atol=1e-9)
    np.testing.assert_allclose(np.degrees(program.q[-1, 3:]), [-40, 90], atol=1e-12)
    traj = program_trajectory(program, machine)
    on = (traj.line == 3)
    r = np.hypot(traj.P[on, 0], traj.P[on, 1])[50:-50]
    assert np.abs(r - 10.0).max() < 2e-3 and np.abs(traj.P[on, 2][50:-50] - 5).max() < 2e-3
    assert summarize(traj, machine).within_limits
