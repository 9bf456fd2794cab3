"""Tool orientation at corners (``orientation_tolerance``, ``--corner-ori-tol``): at every
programmed point the plan passes a pose whose tool tip is within the corner tolerance and
whose orientation is within the orientation tolerance of the programmed ones, at once.
Measured independently of the planner, on the samples' direct kinematics: for each
programmed point, over the segments between consecutive samples (tip and orientation
interpolated linearly), the stretch where the tip is within the corner tolerance, and the
least orientation error on it.

LinuxCNC's boats (A-C and B-C) and impeller are planned whole (1-3 s each): before this
tolerance, the orientation where the tip was within 0.01 mm of a point before a rotary-only
move was up to 27 mrad off the programmed one (boat A-C, line 376: the rotation had started
before the tip got there; 33.5 mrad where the tip was within 0.7 um)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import cKDTree

from precontour.defaults import DEFAULT_CORNER_ORIENTATION_TOLERANCE, GCODE_TOL_ROTARY
from precontour.machine.machine_file import load_machine
from precontour.toolpath import read_program
from precontour.trajectory import program_trajectory, summarize

DEMOS = Path("/usr/share/doc/linuxcnc/examples/sample-configs/sim/axis/vismach/5axis/"
             "table-rotary-tilting/demos")
#: The default corner tolerance, mm (``--corner-tol``).
TOLERANCE = 0.01
#: The issue's target for the orientation at programmed points, rad.
TARGET = 1e-3


def pose_errors(points, orientations, P, O, tolerance=TOLERANCE):
    """Per programmed point (tip ``points``, orientation ``orientations``), the least angle
    (rad) between the planned and programmed orientation where the planned tip (``P``, ``O``
    the samples) is within ``tolerance`` of the point, and whether it ever is. Segments
    between samples whose tip comes within ``tolerance`` + 0.5 mm are measured exactly."""
    tree = cKDTree(P)
    near = tree.query_ball_point(points, tolerance + 0.5)
    angle = np.full(len(points), np.inf)
    for i, found in enumerate(near):
        if not found:
            continue
        k = np.asarray(found)
        k = np.unique(np.clip(np.concatenate([k, k - 1]), 0, len(P) - 2))
        a, b = P[k] - points[i], P[k + 1] - P[k]
        c, d = O[k] - orientations[i], O[k + 1] - O[k]
        bb, ab, aa = (b * b).sum(1), (a * b).sum(1), (a * a).sum(1)
        # the u in [0, 1] where |a + u b| <= tolerance: an interval
        root = np.sqrt(np.maximum(ab * ab - bb * (aa - tolerance**2), 0.0))
        with np.errstate(divide="ignore", invalid="ignore"):
            lo = np.where(bb > 0, (-ab - root) / bb, 0.0)
            hi = np.where(bb > 0, (-ab + root) / bb, 1.0)
            u = np.where((d * d).sum(1) > 0, -(c * d).sum(1) / (d * d).sum(1), 0.0)
        lo, hi = np.clip(lo, 0, 1), np.clip(hi, 0, 1)
        u = np.clip(u, lo, hi)
        tip = np.linalg.norm(a + u[:, None] * b, axis=1)
        chord = np.linalg.norm(c + u[:, None] * d, axis=1)
        ok = (tip <= tolerance * (1 + 1e-9)) & (lo <= hi)
        if ok.any():
            angle[i] = 2.0 * np.arcsin(min(1.0, chord[ok].min() / 2.0))
    return angle


def measure(name, machine_name, **options):
    path = DEMOS / name
    if not path.is_file():
        pytest.skip(f"LinuxCNC's demos are not installed ({DEMOS})")
    machine = load_machine(machine_name)
    program = read_program(path, machine, tcp=True)
    traj = program_trajectory(program, machine, **options)
    tips, orientations = machine.kinematics.forward(program.points)
    return pose_errors(tips, orientations, traj.P, traj.O), traj, machine


def test_the_default_is_the_rotary_decimation_tolerance():
    assert DEFAULT_CORNER_ORIENTATION_TOLERANCE == GCODE_TOL_ROTARY == 1e-5


@pytest.mark.parametrize("name, machine_name", [
    ("boat-xyzac.ngc", "linuxcnc-xyzac-trt"),
    ("boat-xyzbc.ngc", "linuxcnc-xyzbc-trt"),
    ("impeller-7bl-xyzac.ngc", "linuxcnc-xyzac-trt")])
def test_linuxcnc_programs_keep_the_orientation_at_every_point(name, machine_name):
    # Measured: the worst point just under 0.010 mrad on all three (the tolerance), the tip
    # within 0.01 mm at that moment. Without the orientation tolerance: 27.4 (boat A-C, line 376,
    # before the rotary-only 'A0.'), 27.0 (boat B-C) and 2.3 mrad (impeller).
    angle, traj, machine = measure(name, machine_name)
    assert np.isfinite(angle).all()          # every point has its tip within the tolerance
    assert angle.max() <= DEFAULT_CORNER_ORIENTATION_TOLERANCE * (1 + 1e-6)
    assert angle.max() <= TARGET
    assert summarize(traj, machine).within_limits


def test_without_the_orientation_tolerance_the_rotation_starts_early():
    # the observation, kept as the reason for the tolerance: boat A-C without it
    angle, _, _ = measure("boat-xyzac.ngc", "linuxcnc-xyzac-trt", orientation_tolerance=None)
    assert angle.max() > 10 * TARGET


def program_text(tmp_path, text, name="prog.ngc"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_an_excerpt_within_any_orientation_tolerance(tmp_path):
    # boat A-C, its first 560 lines (the roughing levels, the rotary-only rapids of lines
    # 377-378, five-axis blocks by lines 470-560): each tolerance is kept, and a looser one
    # plans faster
    text = (DEMOS / "boat-xyzac.ngc")
    if not text.is_file():
        pytest.skip(f"LinuxCNC's demos are not installed ({DEMOS})")
    path = program_text(tmp_path, "\n".join(text.read_text().splitlines()[:560]) + "\n")
    machine = load_machine("linuxcnc-xyzac-trt")
    program = read_program(path, machine, tcp=True)
    tips, orientations = machine.kinematics.forward(program.points)
    durations = []
    for tolerance in (1e-5, 1e-4, 1e-3):
        traj = program_trajectory(program, machine, orientation_tolerance=tolerance)
        angle = pose_errors(tips, orientations, traj.P, traj.O)
        assert np.isfinite(angle).all()
        assert angle.max() <= tolerance * (1 + 1e-6)
        durations.append(traj.duration)
    assert durations[0] > durations[1] > durations[2]


@pytest.mark.parametrize("bad", [0.0, -1e-5, math.inf, math.nan])
def test_the_orientation_tolerance_is_checked(tmp_path, bad):
    machine = load_machine("zhang2013")
    program = read_program(program_text(tmp_path, "G1 X10 F600\nG1 Y10\n"), machine)
    with pytest.raises(ValueError, match=r"^orientation_tolerance must be positive and "
                                         r"finite \(or None\), got "):
        program_trajectory(program, machine, orientation_tolerance=bad)


def test_cli_option_in_trajectory_and_run(capsys):
    from precontour.cli import build_parser, main

    parser = build_parser()
    base = {"trajectory": ["trajectory", "p.ngc", "-o", "t.csv"],
            "run": ["run", "p.ngc", "--machine", "zhang2013", "--controller", "pid-low",
                    "-o", "o.ngc"]}
    for command, argv in base.items():
        assert parser.parse_args(argv).corner_ori_tol == DEFAULT_CORNER_ORIENTATION_TOLERANCE
        assert parser.parse_args(argv + ["--corner-ori-tol", "0.001"]).corner_ori_tol == 0.001
        with pytest.raises(SystemExit):
            parser.parse_args(argv + ["--corner-ori-tol", "0"])
        assert capsys.readouterr().err.strip().splitlines()[-1] == (
            f"precontour {command}: error: argument --corner-ori-tol: must be a positive "
            "number, got '0'")
        with pytest.raises(SystemExit):
            main([command, "--help"])
        text = " ".join(capsys.readouterr().out.split())
        assert "--corner-ori-tol RAD" in text and "(default 1e-05 rad" in text


def test_cli_option_reaches_the_planner(tmp_path, capsys):
    from precontour.cli import main
    from precontour.tables import read_columns

    text = (DEMOS / "boat-xyzac.ngc")
    if not text.is_file():
        pytest.skip(f"LinuxCNC's demos are not installed ({DEMOS})")
    program = program_text(tmp_path, "\n".join(text.read_text().splitlines()[:560]) + "\n")
    durations = []
    for value in ("1e-5", "1"):
        out = tmp_path / f"t{value}.csv"
        assert main(["trajectory", str(program), "--machine", "linuxcnc-xyzac-trt", "--tcp",
                     "--corner-ori-tol", value, "-o", str(out)]) == 0
        t = read_columns(out, ["t"])["t"]
        durations.append(t[-1] - t[0])
    capsys.readouterr()
    # 1 rad bounds nothing here: the corners are blended for the tip only, which is faster
    assert durations[1] < durations[0]
