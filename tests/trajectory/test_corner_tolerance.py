"""Corner blends within the corner tolerance, and TCP rotary-only moves holding the tool tip,
measured independently of the planner: brute-force distances between the programmed points
and the polyline through the trajectory's samples (every point against every segment), and
from every sample to the programmed polyline. Measured where the tolerance applies: at the
tool tip (the direct kinematics of the planned joint commands) for TCP programs, in the linear
axes otherwise. On synthetic corners and dense G93 blocks, and on excerpts of LinuxCNC's
five-axis demos (real CAM output; data/README.md in tests/toolpath). The whole programs are
measured by ``scripts/measure_corners.py`` (docs/gcode.md)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from precontour.machine.machine_file import load_machine
from precontour.toolpath import read_program
from precontour.trajectory import program_trajectory, summarize

DEMOS = Path("/usr/share/doc/linuxcnc/examples/sample-configs/sim/axis/vismach/5axis/"
             "table-rotary-tilting/demos")
#: The default corner tolerance, mm (``--corner-tol``).
TOLERANCE = 0.01


@pytest.fixture(scope="module")
def machine():
    return load_machine("zhang2013")


@pytest.fixture(scope="module")
def trt():
    return load_machine("linuxcnc-xyzac-trt")


def point_to_path(points, path):
    """Distance from each point to the polyline through ``path``'s rows: every point against
    every segment."""
    a, ab = path[:-1], np.diff(path, axis=0)
    den = np.einsum("ij,ij->i", ab, ab)
    out = np.empty(len(points))
    for i, p in enumerate(points):
        rel = p - a
        with np.errstate(divide="ignore", invalid="ignore"):
            u = np.where(den > 0, np.clip(np.einsum("ij,ij->i", rel, ab) / den, 0, 1), 0.0)
        out[i] = np.linalg.norm(rel - u[:, None] * ab, axis=1).min()
    return out


def path_to_polyline(x, points):
    """Distance from each row of ``x`` to the polyline through ``points``: every row against
    every segment."""
    d = np.full(len(x), np.inf)
    for a, b in zip(points[:-1], points[1:]):
        ab = b - a
        den = ab @ ab
        u = np.clip(((x - a) @ ab) / den, 0, 1) if den > 0 else np.zeros(len(x))
        d = np.minimum(d, np.linalg.norm(x - (a + u[:, None] * ab), axis=1))
    return d


def program_text(tmp_path, text, name="prog.ngc"):
    path = tmp_path / name
    path.write_text(text)
    return path


def excerpt(tmp_path, name, lines, first_lines=0):
    """Lines ``lines`` (1-based, inclusive range) of a LinuxCNC demo, after its first
    ``first_lines`` lines (the header: TCP switch, feed mode)."""
    path = DEMOS / name
    if not path.is_file():
        pytest.skip(f"LinuxCNC's demos are not installed ({DEMOS})")
    text = path.read_text().splitlines()
    body = text[:first_lines] + text[lines[0] - 1:lines[1]]
    return program_text(tmp_path, "\n".join(body) + "\n", name)


def corner_distances(program, traj, machine):
    """Programmed points (TCP: tips) to the trajectory (TCP: its tips), and the trajectory's
    samples to the programmed polyline, mm."""
    if program.tcp_move.all():
        points, path = machine.kinematics.forward(program.points)[0], traj.P
        np.testing.assert_allclose(machine.kinematics.forward(traj.q)[0], path, atol=1e-12)
    else:
        assert not program.tcp_move.any()
        points, path = program.points[:, :3], traj.q[:, :3]
    return point_to_path(points, path), path_to_polyline(path, points)


SYNTHETIC = {
    # 90, 104, 22, 157 and 170 degree corners, then small zig-zags
    "corners": "G1 X20 F{f}\nY20\nX40 Y25\nX60 Y20\nX0 Y0 Z5\nX1 Y0.1\nX2 Y0\nX3 Y0.1\n",
    # a quarter circle of radius 10 mm in 100 chords of 0.157 mm, in inverse time
    "dense G93": "G93\n" + "".join(
        f"G1 X{10 * math.sin(t):.5f} Y{10 - 10 * math.cos(t):.5f} F{{g}}\n"
        for t in np.linspace(0, math.pi / 2, 101)[1:]),
}


@pytest.mark.parametrize("feed", [600, 3000, 12000])
@pytest.mark.parametrize("name", sorted(SYNTHETIC))
def test_programmed_points_within_the_tolerance_on_corners(machine, tmp_path, name, feed):
    # G93 F of a chord of 0.157 mm at ``feed`` mm/min
    text = "G0 X0 Y0 Z0 A0 C0\n" + SYNTHETIC[name].format(f=feed, g=feed / 0.15708)
    program = read_program(program_text(tmp_path, text), machine)
    for tolerance in (TOLERANCE, 0.05):
        traj = program_trajectory(program, machine, tolerance=tolerance)
        to_points, to_path = corner_distances(program, traj, machine)
        assert to_points.max() <= tolerance
        assert to_path.max() <= tolerance
        assert summarize(traj, machine).within_limits


def test_programmed_points_within_the_tolerance_on_dense_tcp_g93(machine, tmp_path):
    # the tool tip on a quarter circle in 0.157 mm chords while the table turns, in TCP
    text = "G43.4 H1\nG0 X0 Y0 Z0 A-20 C0\nG93\n" + "".join(
        f"G1 X{10 * math.sin(t):.5f} Y{10 - 10 * math.cos(t):.5f} A{-20 - 10 * t:.4f} "
        f"C{30 * t:.4f} F19100\n" for t in np.linspace(0, math.pi / 2, 101)[1:])
    program = read_program(program_text(tmp_path, text), machine)
    traj = program_trajectory(program, machine)
    to_points, to_path = corner_distances(program, traj, machine)
    assert to_points.max() <= TOLERANCE and to_path.max() <= TOLERANCE
    assert summarize(traj, machine).within_limits


def test_boat_head_within_the_tolerance(trt, tmp_path):
    # LinuxCNC's boat (A-C, TCP by M428), its first roughing levels: 10 mm/s short blocks
    # whose corners follow each other within a filter window (before: 10.2 um at line 210)
    path = excerpt(tmp_path, "boat-xyzac.ngc", (1, 215))
    program = read_program(path, trt, tcp=True)
    traj = program_trajectory(program, trt)
    to_points, to_path = corner_distances(program, traj, trt)
    assert to_points.max() <= TOLERANCE and to_path.max() <= TOLERANCE
    assert summarize(traj, trt).within_limits


def test_impeller_rapids_within_the_tolerance(trt, tmp_path):
    # LinuxCNC's impeller: a run of 19 TCP rapids turning C by about 3 degrees each, between
    # feed blocks (before: 11.7 um at a rapid's end, line 4405)
    path = excerpt(tmp_path, "impeller-7bl-xyzac.ngc", (4380, 4425), first_lines=5)
    program = read_program(path, trt, tcp=True)
    assert program.rapid.sum() == 19
    traj = program_trajectory(program, trt)
    to_points, to_path = corner_distances(program, traj, trt)
    assert to_points.max() <= TOLERANCE and to_path.max() <= TOLERANCE
    assert summarize(traj, trt).within_limits


def rotary_only_rows(program, traj, machine, line):
    """Samples of ``line`` (a TCP rotary-only move) and their distance from the tool tip
    polyline of the moves around it."""
    tips = machine.kinematics.forward(program.points)[0]
    k = int(np.flatnonzero(program.line == line)[0])
    np.testing.assert_allclose(tips[k + 1], tips[k], atol=1e-9)   # the tip stays put
    assert np.abs(program.points[k + 1, 3:] - program.points[k, 3:]).max() > 0.05
    rows = np.flatnonzero(traj.line == line)
    near = tips[max(k - 3, 0):k + 5]
    return rows, path_to_polyline(traj.P[rows], near), tips[k + 1]


@pytest.mark.parametrize("motion", ["G1", "G0"])
def test_tcp_rotary_only_move_holds_the_tip(machine, tmp_path, motion):
    # the tip 50 mm off the C axis; the table turns C by 120 and A by 30 degrees with the tip
    # at one point: as a TCP controller does, the joints follow the kinematics of the
    # (filtered) tip and rotary axes, so the tip stays there (filtering X Y Z on their own
    # cut the chord of their circle: before, the tip left the path by 0.23 mm in G0 here, and
    # stood 0.37 um off the point mid-move in G1)
    feed = " F3000" if motion == "G1" else ""
    text = ("G43.4 H1\nG0 X50 Y0 Z10 A0 C0\nG1 Z0 F600\n"
            f"{motion} A-30 C120{feed}\nG1 X60 F600\nG49\n")
    program = read_program(program_text(tmp_path, text), machine)
    traj = program_trajectory(program, machine)
    rows, off, point = rotary_only_rows(program, traj, machine, 4)
    assert rows.size > 100
    assert off.max() <= TOLERANCE
    # away from its ends (where the corner to the next leg blends), at the point itself
    inner = rows[rows.size // 4: -rows.size // 4]
    assert np.linalg.norm(traj.P[inner] - point, axis=1).max() < 1e-9
    assert summarize(traj, machine).within_limits


def test_boat_rotary_only_rapids_hold_the_tip(trt, tmp_path):
    # boat-xyzac lines 377-378: after Z5.0, 'A0.' then 'A-5.546 C-25.605' turn the table by
    # 129 degrees in C with the tip above the part (TCP rapids); before, the tip left the
    # programmed path by 5.5 um there, and by 6.2 um at line 1860
    path = excerpt(tmp_path, "boat-xyzac.ngc", (1, 380))
    program = read_program(path, trt, tcp=True)
    traj = program_trajectory(program, trt)
    for line in (377, 378):
        rows, off, _ = rotary_only_rows(program, traj, trt, line)
        assert rows.size > 50
        assert off.max() < 1e-6
    assert summarize(traj, trt).within_limits


def test_a_corner_still_outside_becomes_a_stop(machine, tmp_path, monkeypatch):
    # dense G93 chords at 200 mm/s: their blends add up (before the check: 11.6 times the
    # tolerance). Without slow-down passes, the corners found outside become stops, which the
    # path passes through exactly.
    import precontour.trajectory.program as timing

    text = "G0 X0 Y0 Z0 A0 C0\n" + SYNTHETIC["dense G93"].format(g=12000 / 0.15708)
    program = read_program(program_text(tmp_path, text), machine)
    slowed = program_trajectory(program, machine)
    monkeypatch.setattr(timing, "CORNER_PASSES", 0)
    stopped = program_trajectory(program, machine)
    to_points, to_path = corner_distances(program, stopped, machine)
    assert to_points.max() <= TOLERANCE and to_path.max() <= TOLERANCE
    assert summarize(stopped, machine).within_limits
    exact = np.flatnonzero(to_points < 1e-9)
    assert exact.size > 2   # start, end and at least one stop on the way
    assert stopped.duration > slowed.duration
    np.testing.assert_allclose(stopped.q[-1], program.q[-1], atol=1e-12)
