"""The servo-rate overlay's files (precontour.cnc.run): the program gets one line that starts
it, and the overlay rows are the compensated minus the traced commands from the first move."""

from __future__ import annotations

import numpy as np

from precontour.cnc import ControllerTrace
from precontour.cnc.run import (OVERLAY_LEAD, OVERLAY_RAMP, OVERLAY_START, OVERLAY_TAIL,
                                overlay_offsets, overlay_program)


def test_the_first_move_starts_the_overlay_and_the_line_numbers_stay():
    text = "%\r\nG21 G90\r\n  G0 X1 Y2\r\nG1 X3 F100\r\nM2\r\n%\r\n"
    out = overlay_program(text, 3)
    assert out.splitlines() == ["%", "G21 G90", f"  {OVERLAY_START} G0 X1 Y2", "G1 X3 F100",
                                "M2", "%"]
    assert out.replace(OVERLAY_START + " ", "") == text
    numbered = overlay_program("N10 G21\nN20 G1 X3 F100\n", 2)
    assert numbered.splitlines()[1] == f"N20 {OVERLAY_START} G1 X3 F100"


def test_overlay_rows_start_at_the_first_move_in_joint_units():
    n = 400
    t = np.arange(n) * 1e-3
    command = np.column_stack([t, 2 * t, 0 * t, 0.1 * t, 0.2 * t])
    line = np.where(np.arange(n) < 120, 3, 4 + (np.arange(n) - 120) // 50)
    trace = ControllerTrace(t=t, command=command, line=line)
    correction = np.zeros_like(command)
    correction[:, 0] = 1e-3 * np.arange(n)
    correction[:, 3] = np.radians(1e-3) * np.arange(n)
    rows = overlay_offsets(trace, command + correction, np.arange(4, 10))
    tail = int(round(OVERLAY_TAIL / 1e-3))
    ramp = int(round(OVERLAY_RAMP / 1e-3))
    first = 120 + OVERLAY_LEAD                            # the first move's start
    assert rows.shape == (n - first + tail, 5)
    assert rows[0, 0] == 0.0                              # faded in from there
    assert np.all(np.diff(rows[:ramp, 0]) >= 0)
    assert np.allclose(rows[ramp:n - first, 3], 1e-3 * np.arange(first + ramp, n))  # degrees
    assert np.allclose(rows[ramp:n - first, 0], 1e-3 * np.arange(first + ramp, n))  # mm
    assert rows[n - first, 0] == rows[n - first - 1, 0] and rows[-1].tolist() == [0.0] * 5
