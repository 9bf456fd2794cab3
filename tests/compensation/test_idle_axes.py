"""Axes the reference does not move keep their reference command (compensation/idle_axes.py)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from conftest import servo_of
from precontour.compensation.idle_axes import (hold_idle_axes, hold_resting_axes, idle_axes,
                                              resting_axes)
from precontour.compensation.precompensate import compensate
from precontour.compensation.programmed_end import final_rest_start
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
    than uncompensated. Held at its reference, X is exactly the reference command and, during
    the motion (up to the final rest), the tip maximum stays near the uncompensated one while
    the mean falls: measured 43.64 um loose, 0.263 held, 3.358 uncompensated (means 7.46,
    0.022, 0.946 um).

    The final rest is judged apart (issue 42 item 5): the held command's corrections creep
    through the rest (the friction feed-forward on) and stop at the programmed end point,
    where C, held off by static friction, slips as the feed-forward switches off. Before the
    end taper the command crept to the program's end and the slip came after it, with the
    controller holding the last command: 11.29 um 30 ms after the program (0.537 um within
    it). With the taper it comes 10 ms before the end: 7.13 um within the program, 9.45 um at
    most over 0.5 s of holding after it. Learning against the machine handles that slip."""
    assert np.ptp(circle.q[:, 0]) < 1e-9
    servo = servo_of(machine, "pid-high")
    reference = ReferencePath.from_trajectory(circle)
    run = dict(REALISTIC, encoder_resolution=TOL * [1, 1, 1, 10, 10])
    rest = final_rest_start(circle.q)
    n, held_after = circle.n_samples, 500
    index = np.r_[np.arange(n), np.full(held_after, n - 1)]
    t = circle.t[0] + np.arange(n + held_after) * circle.ts
    settling = ReferencePath.from_trajectory(replace(circle, t=t, q=circle.q[index],
                                                     P=circle.P[index], O=circle.O[index]))

    def tip(q):
        sim = simulate(circle.t, q, machine, "pid-high", **run)
        errors = contour_errors(reference, sim.q_act, machine.kinematics)
        return {"tip_max_um": 1e3 * errors.tip[:rest].max(),
                "tip_mean_um": 1e3 * errors.tip[:rest].mean()}

    def settled_max(q):
        """Max tip error (um) over the program and 0.5 s of the last command held."""
        sim = simulate(t, q[index], machine, "pid-high", **run)
        return 1e3 * contour_errors(settling, sim.q_act, machine.kinematics).tip.max()

    before = tip(circle.q)
    results = {hold: compensate(servo, circle, reference=reference,
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
    assert settled_max(held) < 10.0
