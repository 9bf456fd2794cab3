"""``run``'s outputs on LinuxCNC 2.9 itself: the generated configuration starts and runs
G-code, the stream reaches the joints sample for sample, and how the planner times the
G-code (docs/linuxcnc.md gives the numbers)."""

from __future__ import annotations

import numpy as np

from precontour.tables import read_trajectory
from precontour.linuxcnc.run import block_timing, run_gcode, run_stream

from lcnc_fixtures import config, lcnc, paper_run, threeplus2_run  # noqa: F401 (fixtures)

#: halsampler prints 6 decimals (mm, degrees): the rounding of a recorded value.
PRINTED = 5.0000001e-7


def test_configuration_starts_and_runs_a_program_to_its_points(config, tmp_path):
    program = tmp_path / "p.ngc"
    program.write_text("G21 G90 G94\nG0 X1 Y2 Z3 A4 C5\nG93\nG1 X11 Y-2 Z3.5 A9 C-5 F600\n"
                       "G1 X11 Y-2 Z3.5 A9 C-6 F1200\nG94\nM2\n")
    rec = run_gcode(config("zhang2013"), program)
    assert rec.overruns == 0 and np.all(np.diff(rec.sample) == 1)
    assert rec.ts == 0.001
    np.testing.assert_allclose(rec.joints[0], 0.0, atol=PRINTED)  # homed at 0
    np.testing.assert_allclose(rec.joints[-1], [11, -2, 3.5, 9, -6], atol=PRINTED)
    # trivial kinematics: joints are the planner's position, delayed by the cubic
    # interpolator: J(n) = (W(n-3) + 4 W(n-2) + W(n-1)) / 6
    world = np.column_stack([rec.columns[f"w{i}"] for i in range(5)])
    smoothed = (world[:-3] + 4 * world[1:-2] + world[2:-1]) / 6
    np.testing.assert_allclose(rec.joints[3:], smoothed, atol=2 * PRINTED)
    lines = set(rec.columns["line"].tolist())
    assert {4, 5} <= lines  # the planner ran both G1 blocks


def test_stream_reaches_the_joints_sample_for_sample(config, paper_run):
    """The stream path holds the timing the compensation was computed for: every servo
    period the next command, no underrun."""
    commands = read_trajectory(paper_run.commands)
    rec = run_stream(config("zhang2013"), paper_run.stream)
    expected = np.column_stack([commands.q[:, :3], np.degrees(commands.q[:, 3:])])
    assert rec.joints.shape == expected.shape
    assert rec.overruns == 0 and np.all(np.diff(rec.sample) == 1)
    assert rec.columns["underruns"][-1] == 0
    np.testing.assert_allclose(rec.joints, expected, rtol=0, atol=PRINTED)


def test_gcode_timing_on_the_planner(config, paper_run, threeplus2_run):
    """What docs/linuxcnc.md reports, measured: LinuxCNC 2.9's planner stretches blocks
    in which a rotary axis moves (no blend arcs or tangent blends with rotary motion: each
    such junction is a parabolic blend, each block at most about sqrt(a L) fast), so the
    G-code of simultaneous five-axis motion does not keep its timing and the stream is
    the output for LinuxCNC; where the rotary axes stand still (3+2 cutting) it does."""
    paper = block_timing(paper_run.program.read_text(),
                         run_gcode(config("zhang2013"), paper_run.program))
    programmed, executed = paper.duration
    assert paper.rotary.all()
    assert executed > 2.5 * programmed  # measured 10.24 s for 2.77 s
    assert paper.late_blocks() > 0.9 * paper.rotary.size

    result = threeplus2_run.result
    timing = block_timing(threeplus2_run.program.read_text(),
                          run_gcode(config("zhang2013"), threeplus2_run.program))
    source_line = result.limited.line[result.program.kept[1:]]
    assert source_line.size == timing.line.size
    # the contour at a steady feed (lines 10-16: lines and tangent arcs, A and C still),
    # leaving out the blocks within 50 ms of its start and end (the stops around it)
    contour = np.flatnonzero((source_line >= 10) & (source_line <= 16))
    steady = contour[(timing.programmed[contour] > timing.programmed[contour[0]] + 0.05)
                     & (timing.programmed[contour] < timing.programmed[contour[-1]] - 0.05)]
    assert not timing.rotary[steady].any() and steady.size > 200
    late = timing.late[steady]
    assert np.all(np.isfinite(late))
    assert np.ptp(late) < timing.ts  # every block on time, relative to the contour's start
