"""The identification motion: within the drive limits, one axis at a time, then all together."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from precontour.errors import InputError
from precontour.identification import excitation_trajectory, write_excitation
from precontour.machine.drives import AXES
from precontour.tables import read_trajectory


@pytest.fixture(scope="module")
def excitation(machine):
    return excitation_trajectory(machine)


def test_within_the_drive_limits_and_back_at_the_start(machine, excitation):
    q, ts = excitation.q, machine.servo_period
    v = np.diff(q, axis=0) / ts
    a = np.diff(v, axis=0) / ts
    j = np.diff(a, axis=0) / ts
    for i, drive in enumerate(machine.drives):
        assert np.abs(v[:, i]).max() <= drive.v_max
        assert np.abs(a[:, i]).max() <= drive.a_max
        assert np.abs(j[:, i]).max() <= drive.j_max
    np.testing.assert_allclose(q[0], 0.0, atol=1e-12)
    np.testing.assert_allclose(q[-1], 0.0, atol=1e-9)
    np.testing.assert_allclose(np.diff(excitation.t), ts, rtol=1e-9)


def test_one_axis_at_a_time_then_all_together(excitation):
    moving = np.abs(np.diff(excitation.q, axis=0)) > 0
    count = moving.sum(axis=1)
    assert count.max() == len(AXES)
    together = np.flatnonzero(count == len(AXES)).min()
    single = np.flatnonzero(count[:together] == 1)
    order = [AXES[int(np.flatnonzero(moving[k])[0])] for k in single]
    runs = [order[0]] + [b for a, b in zip(order, order[1:]) if a != b]
    assert runs == list(AXES)
    # Before the all-axes part, never two axes at once.
    assert count[:together].max() == 1


def test_multisine_rides_on_a_drift_speed(machine, excitation):
    """Within each drift pass the speed never reaches zero (friction stays on one side)."""
    v = np.diff(excitation.q[:, 0]) / machine.servo_period
    fast = np.abs(v) > 0.3 * np.abs(v).max()
    assert fast.sum() > 2000


def test_csv_round_trip(tmp_path, machine):
    traj = excitation_trajectory(machine, axes=("C",))
    path = tmp_path / "exc.csv"
    write_excitation(path, traj, machine)
    back = read_trajectory(path)
    np.testing.assert_array_equal(back.q, traj.q)


def test_halstreamer_program_is_the_excitation_in_degrees(tmp_path, machine):
    traj = excitation_trajectory(machine, axes=("C",))
    path = tmp_path / "exc.txt"
    write_excitation(path, traj, machine)
    rows = [line.split() for line in path.read_text().splitlines()
            if line.strip() and not line.startswith("#")]
    values = np.array(rows, dtype=float)
    assert values.shape == traj.q.shape
    np.testing.assert_allclose(values[:, :3], traj.q[:, :3], rtol=0, atol=1e-9)
    np.testing.assert_allclose(np.radians(values[:, 3:]), traj.q[:, 3:], rtol=0, atol=1e-9)


def test_gcode_program_reaches_the_excitation_positions(tmp_path, machine):
    from precontour.toolpath import read_program

    traj = excitation_trajectory(machine, axes=("C",))
    path = tmp_path / "exc.ngc"
    write_excitation(path, traj, machine)
    program = read_program(path, machine)
    # every block ends on a command sample (within the G-code's decimals), the last at the end
    np.testing.assert_allclose(program.q[-1], traj.q[-1], rtol=0, atol=1e-5)
    c = traj.q[:, 4]
    assert c.min() - 1e-5 <= program.q[:, 4].min() and program.q[:, 4].max() <= c.max() + 1e-5


def test_bad_options(machine):
    with pytest.raises(InputError, match="safety"):
        excitation_trajectory(machine, safety=1.5)
    with pytest.raises(InputError, match=r"unsupported output type '\.xyz'"):
        write_excitation("exc.xyz", excitation_trajectory(machine, axes=("C",)), machine)
