"""Compensation within the machine's limits: slowed where needed, checked with plain finite
differences; impossible limits are errors."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from precontour.compensation.within_limits import compensate_within_limits
from precontour.errors import MachineLimitError
from precontour.trajectory.builtin_paths import builtin_path
from precontour.trajectory.generate import generate_trajectory
from precontour.trajectory.limits import AxisLimits


@pytest.fixture(scope="module")
def circle(machine):
    return generate_trajectory(builtin_path("circle"), machine)


def _peaks(q, ts):
    return [np.abs(np.diff(q, k, axis=0)).max(axis=0) / ts**k for k in (1, 2, 3)]


def test_slows_down_where_compensation_breaks_a_limit(machine, circle):
    models = machine.controller("pid-high").error_models(machine.drives)
    limits = AxisLimits.from_machine(machine)
    line = np.arange(circle.n_samples) // 10 + 1
    result = compensate_within_limits(circle, machine.kinematics, models, limits, line=line)
    # The first compensation breaks a jerk limit (A and C near the end of the circle).
    assert not result.first_check.ok and result.rounds >= 2
    q = result.result.trajectory.q
    for peak, limit in zip(_peaks(q, circle.ts), (limits.velocity, limits.acceleration,
                                                  limits.jerk)):
        assert np.all(peak <= limit * (1 + 1e-9))
    assert result.slowdowns and result.added_time > 0
    assert result.reference.n_samples == circle.n_samples + round(result.added_time / circle.ts)
    for slow in result.slowdowns:
        assert 0 < slow.speed < 1 and slow.lines[0] <= slow.lines[1]
    # The time map runs through the planned samples, slower where it slowed.
    assert result.planned_index[0] == 0 and result.planned_index[-1] == circle.n_samples - 1
    assert np.all(np.diff(result.planned_index) > 0)
    assert np.all(np.diff(result.line) >= 0)
    # Still compensates: the predicted errors shrink.
    assert result.result.after.tip.max() < 0.2 * result.result.before.tip.max()


def test_within_limits_is_left_alone(machine, circle):
    models = machine.controller("pid-low").error_models(machine.drives)
    result = compensate_within_limits(circle, machine.kinematics, models,
                                      AxisLimits.from_machine(machine))
    assert result.rounds == 1 and result.slowdowns == ()
    assert result.reference is circle


def test_impossible_limits_are_errors(machine, circle):
    models = machine.controller("pid-high").error_models(machine.drives)
    limits = AxisLimits.from_machine(machine)
    travel = dataclasses.replace(limits, position_max=np.full(5, 10.0))
    with pytest.raises(MachineLimitError, match="travel"):
        compensate_within_limits(circle, machine.kinematics, models, travel)
    with pytest.raises(MachineLimitError, match=r"after 1 compensation round\(s\)"):
        compensate_within_limits(circle, machine.kinematics, models, limits, max_rounds=1)


def test_splicing_matches_compensating_everything_again(machine, circle):
    models = machine.controller("pid-high").error_models(machine.drives)
    limits = AxisLimits.from_machine(machine)
    spliced = compensate_within_limits(circle, machine.kinematics, models, limits, splice=True)
    full = compensate_within_limits(circle, machine.kinematics, models, limits, splice=False)
    assert spliced.rounds == full.rounds >= 2
    assert spliced.reference.n_samples == full.reference.n_samples
    dq = np.abs(spliced.result.trajectory.q - full.result.trajectory.q).max(axis=0)
    # Measured 3e-5 mm and 6e-8 rad: the two spline fits' difference, far below the errors.
    assert np.all(dq <= [1e-4] * 3 + [1e-6] * 2), dq
    a, b = spliced.result.after.summary(), full.result.after.summary()
    assert a["tip_max_um"] == pytest.approx(b["tip_max_um"], rel=0.05)
    assert a["ori_max_mrad"] == pytest.approx(b["ori_max_mrad"], rel=0.05)
    assert spliced.result.before.tip.max() == pytest.approx(full.result.before.tip.max())
