"""The limit check: finite differences against hand-worked values, and the time-stretch it
asks for."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from precontour.machine.machine_file import load_machine, parse_machine, builtin_machine_text
from precontour.errors import MachineFileError
from precontour.trajectory.limits import AxisLimits, check_limits

TS = 1e-3


def _limits(v=10.0, a=100.0, j=1000.0, low=-np.inf, high=np.inf):
    full = lambda x: np.full(5, float(x))  # noqa: E731
    return AxisLimits(position_min=full(low), position_max=full(high), velocity=full(v),
                      acceleration=full(a), jerk=full(j))


def test_from_machine_reads_the_drive_limits():
    limits = AxisLimits.from_machine(load_machine("zhang2013"))
    np.testing.assert_array_equal(limits.velocity, [250, 250, 250, 3, 5])
    np.testing.assert_array_equal(limits.jerk, [2e5, 2e5, 2e5, 3000, 4000])
    # no travel in the file: none, but the tilt axis's +-180 deg (as the G-code reader's)
    np.testing.assert_array_equal(limits.position_max, [np.inf] * 3 + [np.pi, np.inf])
    np.testing.assert_array_equal(limits.position_min, [-np.inf] * 3 + [-np.pi, -np.inf])
    text = builtin_machine_text().replace("v_max = 3.0\n", "v_max = 3.0\np_min = -1.0\n"
                                          "p_max = 1.5\n")
    limits = AxisLimits.from_machine(parse_machine(text))
    assert limits.position_min[3] == -1.0 and limits.position_max[3] == 1.5
    with pytest.raises(MachineFileError, match="p_max"):
        parse_machine(text.replace("p_max = 1.5", "p_max = -2.0"))


def test_within_limits():
    t = np.arange(1000) * TS
    q = np.zeros((1000, 5))
    q[:, 0] = 0.5 * np.sin(2 * t)       # v 1, a 2, j 4
    check = check_limits(q, TS, _limits())
    assert check.ok and check.format() == "within the machine's limits"
    assert check.peaks["velocity"][0] == pytest.approx(1.0, rel=1e-3)
    assert check.peaks["jerk"][0] == pytest.approx(4.0, rel=1e-2)
    assert check.stretch.max() <= 1.0


def test_a_jerk_spike_names_axis_time_and_stretch():
    # A step of acceleration on Y at sample 500: third difference = 1 a-step / ts.
    q = np.zeros((1000, 5))
    acc = np.where(np.arange(1000) >= 500, 50.0, 0.0)
    q[:, 1] = np.cumsum(np.cumsum(acc) * TS) * TS
    check = check_limits(q, TS, _limits(v=1e9, a=1e9, j=1000.0))
    (excess,) = check.excesses
    assert excess.axis == "Y" and excess.quantity == "jerk"
    # Hand-worked: the jerk difference is 50 / ts = 50,000, 50 x the limit.
    assert excess.value == pytest.approx(50 / TS, rel=1e-6)
    assert excess.time == pytest.approx(0.4995, abs=2e-3)
    assert check.stretch.max() == pytest.approx(50 ** (1 / 3), rel=1e-6)
    assert check.ratio.max() == pytest.approx(50, rel=1e-6)
    assert np.flatnonzero(check.stretch > 1).min() >= 495
    assert "Y jerk" in check.format() and "5000.0 %" in check.format()


def test_velocity_acceleration_and_position():
    q = np.zeros((100, 5))
    q[:, 2] = np.arange(100) * 20 * TS      # 20 mm/s: twice the limit
    q[60:, 4] = -2.0                          # C jumps: velocity, acceleration and jerk
    check = check_limits(q, TS, _limits(low=-1.0))
    kinds = {(e.axis, e.quantity) for e in check.excesses}
    assert ("Z", "velocity") in kinds and ("C", "position") in kinds
    assert ("C", "acceleration") in kinds and ("C", "jerk") in kinds
    assert not check.position_ok
    assert check.stretch[30] == pytest.approx(2.0)


def test_messages_name_the_machines_axis_letters():
    """On a B-C machine the tilt slot is B in limit messages and the summary table."""
    from precontour.machine.machine_file import load_machine
    from precontour.trajectory.builtin_paths import builtin_path
    from precontour.trajectory.generate import generate_trajectory, summarize

    machine = load_machine("linuxcnc-xyzbc-trt")
    limits = AxisLimits.from_machine(machine)
    assert limits.axis_names == ("X", "Y", "Z", "B", "C")
    traj = generate_trajectory(builtin_path("paper"), machine)
    tight = dataclasses.replace(limits, jerk=limits.jerk * np.array([1, 1, 1, 1e-3, 1]))
    check = check_limits(traj.q, traj.ts, tight)
    assert any(e.axis == "B" and e.quantity == "jerk" for e in check.excesses)
    assert "B jerk" in check.format() and "rad/s^3" in check.format()
    table = summarize(traj, machine).format()
    assert "\nB (rad)" in table and "\nA (rad)" not in table
