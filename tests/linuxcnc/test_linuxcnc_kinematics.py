"""precontour's kinematics against LinuxCNC's own modules: xyzac-trt-kins and xyzbc-trt-kins
with the parameters of the built-in ``linuxcnc-xyzac-trt`` / ``linuxcnc-xyzbc-trt`` machines,
running the head of LinuxCNC's impeller and boat demos, and 5axiskins (head-head) with those
of ``linuxcnc-bridgemill`` and xyzab_tdr_kins (A-B table dual rotary) with those of
``linuxcnc-xyzab-tdr``, each running a program of our own (the bridge mill's demo loops in
o-words, which precontour's reader does not run; the dual rotary's demo sets its work offset
from HAL pins). Each TCP program (M428) runs on a
configuration from ``linuxcnc-config``, and the joint commands LinuxCNC computes are compared
with the library's inverse kinematics (what ``precontour trajectory --tcp`` uses) at every
programmed point and in every servo period."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from precontour import load_machine
from precontour.toolpath import read_program
from precontour.linuxcnc.run import run_gcode

from lcnc_fixtures import config, lcnc  # noqa: F401 (fixtures)

#: mm and degrees: halsampler prints 6 decimals, so agreement shows at the nm level; the
#: target is 1 um / 1 urad (5.7e-5 degrees).
LINEAR_TOL = 1e-5
ANGLE_TOL = 1e-5
#: Dwell after each motion line, so that the joints stand at each programmed point. The task
#: times a G4 on the wall clock, not in servo periods, and a servo thread without real-time
#: rights does not keep wall time under load: an 8 ms dwell lasted only 4 periods once on the
#: boat (docs/linuxcnc.md), and once in CI a 20 ms dwell on the A-B table stood fewer than
#: the 5 periods needed (the cubic interpolator settles in 3). 0.1 s gives five times the
#: slack; the dwells add 1.5-2.4 s to each program.
DWELL = 0.1
#: LinuxCNC's trunnion demo programs, installed with linuxcnc-uspace.
DEMOS = Path("/usr/share/doc/linuxcnc/examples/sample-configs/sim/axis/vismach/5axis/"
             "table-rotary-tilting/demos")
_AXIS_WORD = re.compile(r"(?<![A-Z])[XYZABC]\s*[-+.0-9]")


def _head_with_dwells(source, motion_lines: int, out, speedup: float):
    """The first ``motion_lines`` lines with axis words of ``source``, each followed by a
    dwell, then M2; feeds ``speedup`` times the programmed ones (the geometry is what
    counts here, and LinuxCNC keeps within its limits whatever the feed). Stops before a
    move in machine coordinates (G53: the boat's last two lines): what is compared here is
    the kinematics of the program's moves in work coordinates."""
    kept, count = [], 0
    for line in source.read_text().splitlines():
        code = re.sub(r"\([^)]*\)", "", line).split(";")[0].upper()
        if re.search(r"G0*53(?![0-9.])", code):
            break
        if code.strip() in ("%", "") or re.match(r"\s*M(2|30)\b", code):
            continue
        line = re.sub(r"F\s*([0-9.]+)", lambda m: f"F{float(m.group(1)) * speedup:.6g}", code)
        kept.append(line)
        if _AXIS_WORD.search(code):
            kept.append(f"G4 P{DWELL}")
            count += 1
            if count == motion_lines:
                break
    out.write_text("\n".join(kept + ["M2"]) + "\n")
    return out


def _stationary_point(world, start, target, tol=1e-5, hold=5):
    """First sample from ``start`` on where the planner's position equals ``target`` and
    stays there ``hold`` periods (a dwell)."""
    close = np.all(np.abs(world[start:] - target) < tol, axis=1)
    for i in np.flatnonzero(close):
        if close[i:i + hold].all() and i + hold <= close.size:
            return start + i
    return None


def _why_not_reached(world, start, target, tol=1e-5) -> str:
    """For a point never found standing: how close the planner came after ``start``, and its
    longest stand within ``tol`` (a dwell cut short by a held-up servo thread, or a wrong
    point)."""
    distance = np.abs(world[start:] - target).max(axis=1)
    close = distance < tol
    edges = np.flatnonzero(np.diff(np.r_[0, close.astype(np.int8), 0]))
    longest = int((edges[1::2] - edges[::2]).max()) if edges.size else 0
    return (f"closest {distance.min():.3g} (mm or deg) at sample {start + distance.argmin()}, "
            f"longest stand within {tol:g}: {longest} period(s)")


@pytest.mark.parametrize("machine_name, demo, motion_lines, speedup", [
    ("linuxcnc-xyzac-trt", "impeller-7bl-xyzac.ngc", 24, 4.0),
    ("linuxcnc-xyzbc-trt", "boat-xyzbc.ngc", 12, 4.0),
])
def test_joint_commands_equal_linuxcnc_kinematics(config, tmp_path, machine_name, demo,
                                                  motion_lines, speedup):
    source = DEMOS / demo
    if not source.is_file():
        pytest.skip(f"needs LinuxCNC's demo program {source}")
    program = _head_with_dwells(source, motion_lines, tmp_path / demo, speedup)
    machine = load_machine(machine_name)
    rec = run_gcode(config(machine_name), program)
    assert rec.overruns == 0
    joints = rec.joints
    world = np.column_stack([rec.columns[f"w{i}"] for i in range(5)])

    # at every programmed point: the library's joints (read_program with --tcp, i.e. the
    # kinematics' linear_axes) against LinuxCNC's while it dwells there
    parsed = read_program(program, machine, tcp=True)
    last_move = np.r_[np.flatnonzero(np.diff(parsed.line)), parsed.line.size - 1]
    q = parsed.q[last_move]
    tip, _ = machine.kinematics.forward(q)
    targets = np.column_stack([tip, np.degrees(q[:, 3:])])
    expected = np.column_stack([q[:, :3], np.degrees(q[:, 3:])])
    at, found = 0, []
    for k, target in enumerate(targets):
        n = _stationary_point(world, at, target)
        assert n is not None, (f"point {k} (line {parsed.line[last_move[k]]}) never reached: "
                               + _why_not_reached(world, at, target))
        found.append(joints[n + 4])  # the cubic interpolator has caught up after 3 periods
        at = n
    error = np.abs(np.array(found) - expected)
    assert len(found) >= motion_lines - 2
    assert error[:, :3].max() < LINEAR_TOL, error[:, :3].max(axis=0)
    assert error[:, 3:].max() < ANGLE_TOL, error[:, 3:].max(axis=0)

    # every servo period of the program: LinuxCNC's joints = the cubic interpolator over the
    # library's inverse of the planner's tool tip position, J(n) = (I(n-3) + 4 I(n-2) +
    # I(n-1)) / 6
    inverse = np.column_stack([machine.kinematics.linear_axes(world[:, :3],
                                                              np.radians(world[:, 3]),
                                                              np.radians(world[:, 4])),
                               world[:, 3:]])
    running = np.flatnonzero(rec.columns["line"] > 0)
    n = np.arange(max(running[0], 3), running[-1])
    smoothed = (inverse[n - 3] + 4 * inverse[n - 2] + inverse[n - 1]) / 6
    error = np.abs(joints[n] - smoothed)
    assert n.size > 5000
    assert error[:, :3].max() < LINEAR_TOL, error[:, :3].max(axis=0)
    assert error[:, 3:].max() < ANGLE_TOL, error[:, 3:].max(axis=0)


def _head_head_program(out, points: int = 16) -> Path:
    """A tool centre point program (M428) for the bridge mill: the tip along a closed space
    curve while B sweeps 5..60 deg and C turns 0..300 deg, a dwell at each point."""
    k = np.arange(points) / points
    tip = np.column_stack([40 * np.cos(2 * np.pi * k), 30 * np.sin(2 * np.pi * k),
                           -20 + 10 * np.sin(4 * np.pi * k)])
    b = 5 + 55 * np.sin(np.pi * k) ** 2
    c = 300 * k
    lines = ["G21 G90 G94 G17 G40 G49 G54", "M428", "F3000"]
    for (x, y, z), bb, cc in zip(tip, b, c):
        lines += [f"G1 X{x:.4f} Y{y:.4f} Z{z:.4f} B{bb:.4f} C{cc:.4f}", f"G4 P{DWELL}"]
    out.write_text("\n".join(lines + ["M429", "M2"]) + "\n")
    return out


def test_joint_commands_equal_linuxcnc_5axiskins(config, tmp_path):
    """The head-head (``xyzbc-head-head``) machine ``linuxcnc-bridgemill`` against LinuxCNC's
    ``5axiskins`` with its parameters: the joints LinuxCNC computes for a tool centre point
    program equal the library's at every programmed point and, through motion's cubic
    interpolator, in every servo period. Measured: 0.5 nm and 1e-14 deg at the 15 points,
    2.6 nm and 8.3e-7 deg (halsampler's 6 decimals) over 6,125 periods."""
    program = _head_head_program(tmp_path / "bridgemill.ngc")
    _compare_with_linuxcnc(config, "linuxcnc-bridgemill", program, points=15, periods=500)


def _tdr_program(out, points: int = 16) -> Path:
    """A tool centre point program (M428) for the A-B table dual rotary: the tip along a
    closed curve around the A table's face centre (rotation point + offsets) while A sweeps
    -90 .. 150 deg and B -40 .. 120 deg (beyond 90: the tool on the far side of the A axis,
    cos B < 0), a dwell at each point."""
    k = np.arange(points) / points
    tip = np.column_stack([-70 + 40 * np.cos(2 * np.pi * k), -50 + 30 * np.sin(2 * np.pi * k),
                           -90 + 10 * np.sin(4 * np.pi * k)])
    a = -90 + 240 * k
    b = -40 + 160 * np.sin(np.pi * k) ** 2
    lines = ["G21 G90 G94 G17 G40 G49 G54", "M428", "F3000"]
    for (x, y, z), aa, bb in zip(tip, a, b):
        lines += [f"G1 X{x:.4f} Y{y:.4f} Z{z:.4f} A{aa:.4f} B{bb:.4f}", f"G4 P{DWELL}"]
    out.write_text("\n".join(lines + ["M429", "M2"]) + "\n")
    return out


def test_joint_commands_equal_linuxcnc_xyzab_tdr_kins(config, tmp_path):
    """The A-B table dual rotary (``xyzab-tdr``) machine ``linuxcnc-xyzab-tdr`` against
    LinuxCNC's ``xyzab_tdr_kins`` with the sim's parameters: the joints LinuxCNC computes for a
    tool centre point program equal the library's at every programmed point and, through
    motion's cubic interpolator, in every servo period; and the library's inverse from tool tip
    and orientation gives them too, on either solution. Measured: 0.5 nm and 1.4e-14 deg at the
    15 points (the inverse from tip and orientation: 0.5 nm, 2.8e-14 deg), 1.4 nm and 8.3e-7
    deg (halsampler's 6 decimals) over 7,592 periods."""
    program = _tdr_program(tmp_path / "tdr.ngc")
    found, q = _compare_with_linuxcnc(config, "linuxcnc-xyzab-tdr", program, points=15,
                                      periods=500)
    # the library's inverse from tool tip and orientation, on the solution of the programmed
    # B (cos B < 0 beyond 90 deg), gives LinuxCNC's joints too
    kin = load_machine("linuxcnc-xyzab-tdr").kinematics
    P, O = kin.forward(q)
    inverse = kin.inverse(P, O, c_near=q[:, 4])
    assert (np.cos(q[:, 4]) < 0).any() and (np.cos(q[:, 4]) > 0).any()
    error = np.abs(np.array(found) - np.column_stack([inverse[:, :3],
                                                      np.degrees(inverse[:, 3:])]))
    assert error[:, :3].max() < LINEAR_TOL, error[:, :3].max(axis=0)
    assert error[:, 3:].max() < ANGLE_TOL, error[:, 3:].max(axis=0)


def _compare_with_linuxcnc(config, machine_name, program, *, points, periods):
    """Run ``program`` on the configuration of ``machine_name``; LinuxCNC's joints while it
    dwells at each programmed point against read_program's (the library's linear_axes), and in
    every servo period against the cubic interpolator over the library's inverse of the
    planner's position. Returns LinuxCNC's joints at the points and the library's axes
    there."""
    machine = load_machine(machine_name)
    rec = run_gcode(config(machine_name), program)
    assert rec.overruns == 0
    joints = rec.joints
    world = np.column_stack([rec.columns[f"w{i}"] for i in range(5)])
    parsed = read_program(program, machine, tcp=True)
    last_move = np.r_[np.flatnonzero(np.diff(parsed.line)), parsed.line.size - 1]
    q = parsed.q[last_move]
    tip, _ = machine.kinematics.forward(q)
    targets = np.column_stack([tip, np.degrees(q[:, 3:])])
    expected = np.column_stack([q[:, :3], np.degrees(q[:, 3:])])
    at, found = 0, []
    for k, target in enumerate(targets):
        n = _stationary_point(world, at, target)
        assert n is not None, (f"point {k} (line {parsed.line[last_move[k]]}) never reached: "
                               + _why_not_reached(world, at, target))
        found.append(joints[n + 4])
        at = n
    error = np.abs(np.array(found) - expected)
    assert len(found) >= points   # the points after the first: precontour's path starts there
    assert error[:, :3].max() < LINEAR_TOL, error[:, :3].max(axis=0)
    assert error[:, 3:].max() < ANGLE_TOL, error[:, 3:].max(axis=0)
    inverse = np.column_stack([machine.kinematics.linear_axes(world[:, :3],
                                                              np.radians(world[:, 3]),
                                                              np.radians(world[:, 4])),
                               world[:, 3:]])
    running = np.flatnonzero(rec.columns["line"] > 0)
    n = np.arange(max(running[0], 3), running[-1])
    smoothed = (inverse[n - 3] + 4 * inverse[n - 2] + inverse[n - 1]) / 6
    error = np.abs(joints[n] - smoothed)
    assert n.size > periods
    assert error[:, :3].max() < LINEAR_TOL, error[:, :3].max(axis=0)
    assert error[:, 3:].max() < ANGLE_TOL, error[:, 3:].max(axis=0)
    return found, q
