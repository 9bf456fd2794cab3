"""Axes the reference does not move keep their reference command (compensation/idle_axes.py)."""

from __future__ import annotations

import numpy as np
import pytest

from precontour.compensation.idle_axes import (STILL_TAPER, hold_idle_axes, hold_resting_axes,
                                              idle_axes, idle_stretches, resting_axes)
from precontour.compensation.precompensate import compensate
from precontour.prediction.contour import ReferencePath, contour_errors
from precontour.simulation.virtual_machine import REALISTIC, simulate
from precontour.trajectory.builtin_paths import builtin_path
from precontour.trajectory.generate import generate_trajectory

TOL = np.array([1e-4] * 3 + [1e-7] * 2)


def test_hand_made_commands():
    t = np.linspace(0.0, 1.0, 11)
    reference = np.zeros((11, 5))
    reference[:, 0] = 5.0                  # X rests
    reference[:, 1] = t                    # Y moves
    reference[:, 3] = 0.2                  # A rests
    reference[:, 4] = -1.0 + 1e-12 * t     # C rests up to round-off
    q = reference.copy()
    q[:, 0] += 3e-5 * np.sin(t)            # X: 30 nm, below 0.1 um -> held
    q[:, 1] += 1e-6                        # Y moves: kept
    q[:, 2] += 2e-4 * t                    # Z rests, corrected by 0.2 um: kept
    q[:, 3] += 5e-8                        # A: below 1e-7 rad -> held
    q[:, 4] += 3e-7                        # C: above 1e-7 rad -> kept
    assert idle_axes(reference, q, TOL).tolist() == [True, False, False, True, False]
    held = hold_idle_axes(reference, q, TOL)
    np.testing.assert_array_equal(held[:, [0, 3]], reference[:, [0, 3]])
    np.testing.assert_array_equal(held[:, [1, 2, 4]], q[:, [1, 2, 4]])
    assert held is not q and q[-1, 0] != reference[-1, 0]   # the input is not changed
    assert hold_idle_axes(reference, held, TOL) is held   # nothing to change: same array
    assert hold_idle_axes(reference, q, 1e-9) is q        # no axis within a tighter tolerance
    # every resting axis, whatever its correction: X, Z, A and C (Y moves)
    assert resting_axes(reference, TOL).tolist() == [True, False, True, True, True]
    all_held = hold_resting_axes(reference, q, TOL)
    np.testing.assert_array_equal(all_held[:, [0, 2, 3, 4]], reference[:, [0, 2, 3, 4]])
    np.testing.assert_array_equal(all_held[:, 1], q[:, 1])
    assert hold_resting_axes(reference, all_held, TOL) is all_held
    # corrections within the tolerance alone (round-off) are hold_idle_axes' to hold
    within = reference + np.array([1e-12, 0.0, 0.0, 1e-15, 0.0])
    assert hold_resting_axes(reference, within, TOL) is within
    # C's round-off of 1e-12 is beyond a tolerance of 1e-13
    assert resting_axes(reference, 1e-13).tolist() == [True, False, True, True, False]


def test_an_axis_resting_for_a_stretch_is_held_there_where_its_correction_is_round_off():
    """Y rests, moves, rests again and moves back (1 ms samples). Its correction is 30 nm on
    the first rest (within the 0.1 um tolerance: held, the reference exactly), 1 um on the
    moves (kept beyond the taper), and on the second rest it grows from 0 to 0.2 um (a lead
    before the move back: a model result, so that stretch is not held at all). The taper is
    C2 and within STILL_TAPER of the stretch; without the sample period only whole axes are
    held, as before; a held command is held again as it is."""
    ts = 1e-3
    n = 400
    k = np.arange(n)
    reference = np.zeros((n, 5))
    reference[:, 0] = 1e-3 * k                             # X moves throughout
    y = np.zeros(n)
    y[100:200] = 1e-3 * (k[100:200] - 100)                 # Y: rests, moves, rests, moves
    y[200:300] = y[199]
    y[300:] = y[199] - 1e-3 * (k[300:] - 299)
    reference[:, 1] = y
    q = reference.copy()
    q[:, 0] += 1e-6
    q[:100, 1] += 3e-5
    q[100:200, 1] += 1e-6
    q[200:300, 1] += np.linspace(0.0, 2e-4, 100)
    q[300:, 1] += 1e-6
    tol = TOL
    stretches = idle_stretches(reference, q, tol, ts)
    assert not stretches[:, 0].any()
    assert stretches[:100, 1].all() and not stretches[100:, 1].any()
    held = hold_idle_axes(reference, q, tol, ts)
    taper = int(round(STILL_TAPER / ts))
    np.testing.assert_array_equal(held[:100 - taper, 1], reference[:100 - taper, 1])
    np.testing.assert_array_equal(held[100:, 1], q[100:, 1])     # the moves left as they are
    np.testing.assert_array_equal(held[:, [0, 2, 3, 4]], q[:, [0, 2, 3, 4]])
    # at the stretch's end the correction rises from 0 to its 30 nm monotonically inside the
    # stretch (a cubic B-spline kernel: C2), with no step of its whole size
    rise = held[100 - taper:100, 1] - reference[100 - taper:100, 1]
    assert np.all(np.diff(rise) >= 0) and rise[0] == 0 and rise[-1] <= 3e-5
    assert np.abs(np.diff(np.concatenate([rise, [3e-5]]))).max() < 1.5e-5
    assert hold_idle_axes(reference, reference, tol, ts) is reference   # nothing to hold
    assert hold_idle_axes(reference, q, tol) is q          # whole axes only


@pytest.fixture(scope="module")
def circle(machine):
    return generate_trajectory(builtin_path("circle"), machine)


def test_quantised_encoder_circle_not_made_worse(machine, circle):
    """pid-high on the realistic machine with a 0.1 um / 1 urad encoder. The circle never
    moves X; the linear pass asks X for nanometres, which switch the friction feed-forward on
    at a resting axis the encoder cannot see move: the tip ends up several times further off
    than uncompensated. Held at its reference, X is exactly the reference command and the
    tip maximum stays near the uncompensated one while the mean falls."""
    assert np.ptp(circle.q[:, 0]) < 1e-9
    models = machine.controller("pid-high").error_models(machine.drives)
    reference = ReferencePath.from_trajectory(circle)
    run = dict(REALISTIC, encoder_resolution=TOL * [1, 1, 1, 10, 10])

    def tip(q):
        sim = simulate(circle.t, q, machine, "pid-high", **run)
        return contour_errors(reference, sim.q_act, machine.kinematics).summary()

    before = tip(circle.q)
    results = {hold: compensate(circle, machine.kinematics, models, reference=reference,
                                min_passes=1, hold_idle=hold) for hold in (False, True)}
    loose = results[False].trajectory.q
    assert 0 < np.abs(loose[:, 0] - circle.q[:, 0]).max() < 1e-4
    held = results[True].trajectory.q
    np.testing.assert_array_equal(held[:, 0], circle.q[:, 0])
    np.testing.assert_array_equal(held[:, 1:], loose[:, 1:])
    worse, fixed = tip(loose), tip(held)
    assert worse["tip_max_um"] > 2 * before["tip_max_um"]
    assert fixed["tip_max_um"] < 1.2 * before["tip_max_um"]
    assert fixed["tip_mean_um"] < 0.2 * before["tip_mean_um"]
