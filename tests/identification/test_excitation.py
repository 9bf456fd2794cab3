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


@pytest.mark.parametrize("name, letter", [("zhang2013", "A"), ("linuxcnc-xyzbc-trt", "B")])
def test_a_drive_without_limits_is_named_by_the_machines_letter(name, letter):
    import dataclasses

    from precontour import load_machine

    machine = load_machine(name)
    drives = list(machine.drives)
    drives[3] = dataclasses.replace(drives[3], v_max=None)
    machine = dataclasses.replace(machine, drives=tuple(drives))
    with pytest.raises(InputError, match=rf"field 'drives\.{letter}\.v_max': drive {letter} "
                                         "has no v_max"):
        excitation_trajectory(machine, axes=("A",))


@pytest.mark.parametrize("name", ["zhang2013", "linuxcnc-xyzac-trt", "linuxcnc-xyzbc-trt"])
def test_the_promised_fraction_of_the_limits_on_every_builtin_machine(name):
    """Plain finite differences of the motion against 0.5 of v_max, a_max and j_max, and
    positions within each axis's travel. On the LinuxCNC machines (v_max 20 mm/s) the drift
    passes of 2.5 s could not cover +-25 mm and the landing correction took X to 173 % of
    v_max; they are lengthened now."""
    from precontour import load_machine
    machine = load_machine(name)
    traj = excitation_trajectory(machine, axes=("X", "A", "C"))
    q, ts = traj.q, machine.servo_period
    for order, key in ((1, "v_max"), (2, "a_max"), (3, "j_max")):
        peak = np.abs(np.diff(q, order, axis=0)).max(axis=0) / ts**order
        limit = np.array([getattr(d, key) for d in machine.drives])
        assert np.all(peak <= 0.5 * limit * (1 + 1e-9)), (key, peak / limit)
    for i, drive in enumerate(machine.drives):
        low = -np.pi if i == 3 else -np.inf
        high = np.pi if i == 3 else np.inf
        low = max(low, drive.p_min if drive.p_min is not None else -np.inf)
        high = min(high, drive.p_max if drive.p_max is not None else np.inf)
        assert low <= q[:, i].min() and q[:, i].max() <= high
    # each axis moved over the default travel, the drift passes at speed
    assert np.ptp(q[:, 0]) == pytest.approx(50.0) and np.ptp(q[:, 4]) == pytest.approx(1.0)


def test_travel_asked_for_must_fit_and_the_default_is_shortened(machine):
    from precontour.machine.machine_file import builtin_machine_text, parse_machine
    with pytest.raises(InputError, match=r"field '--travel-rotary': A: a half travel of 4 rad "
                                         r"does not fit in the A axis's travel \[-3.14159, "
                                         r"3.14159\] rad; give at most 3.14159"):
        excitation_trajectory(machine, axes=("A",), travel={"A": 4.0})
    with pytest.raises(InputError, match=r"X: a half travel of 1e\+09 mm does not fit in the X "
                                         r"axis's travel \[-1e\+06, 1e\+06\] mm \(the machine "
                                         r"file gives none"):
        excitation_trajectory(machine, axes=("X",), travel={"X": 1e9})
    with pytest.raises(InputError, match=r"field 'max_samples': the excitation would have at "
                                         r"least 4.\d+e\+07 samples"):
        excitation_trajectory(machine, axes=("X",), travel={"X": 1e5})
    short = parse_machine(builtin_machine_text().replace(
        "[drives.Z]\n", "[drives.Z]\np_min = 290\np_max = 310\n"), source="short.toml")
    traj = excitation_trajectory(short, axes=("Z",), start=np.array([0, 0, 300.0, 0, 0]))
    assert traj.q[:, 2].min() == pytest.approx(291.0) and traj.q[:, 2].max() == pytest.approx(309.0)
    # a travel that fits only off the start: the centre moves into the travel
    traj = excitation_trajectory(short, axes=("Z",), travel={"Z": 5.0})
    assert traj.q[:, 2].min() == pytest.approx(290.0) and traj.q[:, 2].max() == pytest.approx(300.0)
