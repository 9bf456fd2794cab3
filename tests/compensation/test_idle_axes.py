"""Axes the reference does not move keep their reference command (compensation/idle_axes.py)."""

from __future__ import annotations

import numpy as np
import pytest

from precontour.compensation.idle_axes import (hold_idle_axes, hold_resting_axes, idle_axes,
                                              resting_axes)
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
