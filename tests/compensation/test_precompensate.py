import numpy as np
import pytest

from conftest import servo_of
from precontour.trajectory.builtin_paths import builtin_path
from precontour.compensation.precompensate import compensate
from precontour.compensation.programmed_end import (end_at_programmed_end,
                                                    required_final_rest, with_final_rest)
from precontour.prediction.contour import ReferencePath, contour_errors
from precontour.simulation.virtual_machine import simulate_trajectory
from precontour.prediction.tracking import predict_tracking
from precontour.trajectory.generate import generate_trajectory


@pytest.fixture(scope="module")
def paper(machine):
    return generate_trajectory(builtin_path("paper"), machine)


def _reduction(before, after):
    b, a = before.summary(), after.summary()
    return {key: 1.0 - a[key] / b[key] for key in b}


def test_virtual_machine_without_friction_agrees_with_prediction(machine, paper):
    for name in ("pid-high", "pid-low"):
        models = machine.error_models(name)
        # fit 10x finer than the 1 um default: the fit residual passes almost unattenuated
        # through e(s)/X(s) at high frequency and would otherwise be ~1.5 % of max|e|
        predicted = predict_tracking(paper.t, paper.q, models, tol_linear=1e-4,
                                     tol_rotary=1e-7)(paper.t)
        sim = simulate_trajectory(paper, machine, name, mode="continuous", friction=False,
                                  ff_friction=False)
        scale = np.abs(predicted).max(axis=0)
        assert np.all(np.abs(sim.e - predicted).max(axis=0) <= 0.01 * scale), name


@pytest.mark.parametrize("controller", ["pid-high", "pid-low"])
def test_compensation_in_the_linear_virtual_machine(machine, paper, controller):
    """Measured, not predicted: the exact linear machine runs both commands, on the plan with
    the final rest its compensation needs to end at the programmed end point
    (:func:`~precontour.compensation.programmed_end.required_final_rest`, as ``run`` and
    ``compensate`` plan it: 0.82 s for pid-low, the default 0.2 s dwell for pid-high). On the
    0.2 s dwell alone, pid-low's corrections taper while its axes still lag, and the max
    orientation error removed by one pass, 99.32 % before the end taper, falls to 94.1 % (the
    lag left in the rest); with the rest, one pass removes 95.35 / 98.75 % of the max / mean
    tip error and 99.32 / 99.54 % of the orientation's (before: 95.35 / 98.76, 99.32 /
    99.57)."""
    servo = servo_of(machine, controller)
    models = servo.models
    paper = with_final_rest(paper, required_final_rest(models))
    reference = ReferencePath.from_trajectory(paper)
    measured = {}
    for passes in (1, 4):
        result = compensate(servo, paper, iterations=passes)
        assert 1 <= result.iterations <= passes
        for label, traj in (("original", paper), ("compensated", result.trajectory)):
            sim = simulate_trajectory(traj, machine, controller, mode="continuous",
                                      friction=False, ff_friction=False)
            measured[passes, label] = contour_errors(reference, sim.q_act, machine.kinematics)
    one = _reduction(measured[1, "original"], measured[1, "compensated"])
    more = _reduction(measured[4, "original"], measured[4, "compensated"])
    assert one["tip_mean_um"] >= 0.95 and one["ori_mean_mrad"] >= 0.95
    assert one["ori_max_mrad"] >= 0.95
    assert one["tip_max_um"] >= 0.90            # measured 91.5 % (high) and 95.0 % (low)
    assert min(more.values()) >= 0.99


def test_tracking_method_adds_the_predicted_errors(machine, paper):
    servo = servo_of(machine, "pid-low")
    models = servo.models
    result = compensate(servo, paper, method="tracking")
    e = predict_tracking(paper.t, paper.q, models, tol_linear=1e-4, tol_rotary=1e-7)(paper.t)
    # the corrections taper to zero over the final rest: the commands end at the programmed
    # end point (issue 42 item 5)
    np.testing.assert_allclose(result.trajectory.q,
                               end_at_programmed_end(paper.q, paper.q + e, paper.ts), atol=1e-12)
    np.testing.assert_array_equal(result.trajectory.q[-1], paper.q[-1])
    assert result.after.tip.mean() < 0.1 * result.before.tip.mean()


def test_compensated_commands_stay_smooth(machine, paper):
    """Paper Fig. 16: velocity and acceleration of the commands nearly unchanged, and the
    correction a smooth function of time (no sample-to-sample steps)."""
    servo = servo_of(machine, "pid-high")
    result = compensate(servo, paper, iterations=2)
    q_ref, q_comp = paper.q, result.trajectory.q
    assert np.all(np.isfinite(q_comp))
    for order, bound in ((1, 0.01), (2, 0.05)):
        ref = np.abs(np.diff(q_ref, order, axis=0)).max(axis=0)
        comp = np.abs(np.diff(q_comp, order, axis=0)).max(axis=0)
        np.testing.assert_array_less(np.abs(comp / ref - 1.0), bound)
    correction = q_comp - q_ref
    assert np.abs(correction[:, :3]).max() < 0.2 and np.abs(correction[:, 3:]).max() < 2e-3
    step = np.abs(np.diff(correction, axis=0)).max(axis=0)
    # measured: 1.6-3.3 % on X Y Z A, 6 % on C (the C correction turns fastest where the
    # orientation reference comes to rest at the end of the path)
    assert np.all(step <= 0.1 * np.abs(correction).max(axis=0) + 1e-12)


def test_bad_arguments(machine, paper):
    servo = servo_of(machine, "pid-low")
    with pytest.raises(ValueError, match="unknown compensation method 'magic'"):
        compensate(servo, paper, method="magic")
    with pytest.raises(ValueError, match="iterations must be >= 1"):
        compensate(servo, paper, iterations=0)
