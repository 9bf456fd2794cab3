import numpy as np
import pytest
from scipy import signal
from scipy.integrate import solve_ivp
from scipy.interpolate import PPoly

from precontour.machine.drives import LinearErrorModel
from precontour.errors import UnsupportedControllerError
from precontour.prediction.splinefit import fit_min_jerk
from precontour.prediction.tracking import PartialFractions, predict_tracking, tracking_error

from conftest import AnalyticAxis, analytic_axis

DURATION = 2.5
T = np.round(np.arange(0, DURATION + 5e-4, 1e-3), 12)


def _pid_closed_loop_ivp(spline, drive, gains, t_eval):
    """Independent reference: integrate plant + continuous PID, e = S - x."""
    K = drive.gain
    ds = spline.derivative()

    def rhs(t, y):
        x, v, integral = y
        err = spline(t) - x
        u = gains.kp * err + gains.ki * integral + gains.kd * (ds(t) - v)
        return [v, (K * u - drive.B * v) / drive.J, err]

    sol = solve_ivp(rhs, (t_eval[0], t_eval[-1]), [float(spline(t_eval[0])), 0.0, 0.0],
                    method="DOP853", rtol=1e-12, atol=1e-13, t_eval=t_eval, max_step=2e-3)
    return spline(t_eval) - sol.y[0]


@pytest.mark.parametrize("controller", ["pid-high", "pid-low"])
@pytest.mark.parametrize("axis, travel", [(0, 60.0), (4, 2.0)])
def test_closed_form_matches_solve_ivp(machine, controller, axis, travel):
    x = analytic_axis(T, DURATION, 25.0, travel, 0.05 * travel, 2.3)[0]
    fit = fit_min_jerk(T, x, 1e-3 if axis < 3 else 1e-6)
    ctrl = machine.controller(controller)
    model = ctrl.error_models(machine.drives)[axis]
    e = tracking_error(fit.spline, model)(T)
    reference = _pid_closed_loop_ivp(fit.spline, machine.drives[axis], ctrl.axes[axis], T)
    assert np.abs(e - reference).max() <= 1e-9 * np.abs(reference).max()


@pytest.mark.parametrize("controller", ["pid-high", "pid-low"])
def test_prediction_from_samples_matches_exact_analytic_error(machine, controller):
    """Predict from 1 ms samples; compare with the exact error of the analytic command,
    integrating J e''' + (B + K kd) e'' + K kp e' + K ki e = J X''' + B X'' (spec section 4)."""
    specs = [(-40, 80, 6, 2.0), (10, 30, 4, 3.0), (300, -20, 3, 1.5), (0.2, 1.2, 0.05, 2.0),
             (-1.0, 2.0, 0.1, 2.5)]
    motions = [AnalyticAxis(DURATION, *s) for s in specs]
    q = np.stack([m(T) for m in motions], axis=1)
    ctrl = machine.controller(controller)
    models = ctrl.error_models(machine.drives)
    prediction = predict_tracking(T, q, models)
    e_pred = prediction(T)
    for i, (drive, gains) in enumerate(zip(machine.drives, ctrl.axes)):
        K, J, B = drive.gain, drive.J, drive.B
        motion = motions[i]

        def rhs(t, y, motion=motion):
            e, e1, e2 = y
            forcing = J * motion(t, 3) + B * motion(t, 2)
            e3 = (forcing - (B + K * gains.kd) * e2 - K * gains.kp * e1 - K * gains.ki * e) / J
            return [e1, e2, e3]

        exact = solve_ivp(rhs, (0, DURATION), [0, 0, 0], method="DOP853", rtol=1e-10,
                          atol=1e-14, t_eval=T, max_step=5e-3).y[0]
        floor = 0.5e-3 if i < 3 else 1e-5
        assert np.abs(e_pred[:, i] - exact).max() <= 0.01 * np.abs(exact).max() + floor, i


def _random_stable_model(rng, poles, n_zeros):
    den = np.real(np.poly(poles))
    num = rng.normal(size=n_zeros + 1)
    return LinearErrorModel(num=num, den=den)


@pytest.mark.parametrize("poles", [
    [-3.0, -40.0, -120.0],
    [-5.0, -5.0, -60.0],                               # repeated
    [-2.0 + 15j, -2.0 - 15j, -30.0],                   # complex pair
    [-8.0, -8.0, -8.0, -20 + 5j, -20 - 5j, -100.0],    # order 6, triple + complex
    [-4 + 3j, -4 - 3j, -4 + 3j, -4 - 3j],              # repeated complex pair
    [-1.5, -7.0, -25.0, -60.0, -90.0, -150.0],
])
@pytest.mark.parametrize("proper", [False, True])
def test_general_models_match_state_space_integration(poles, proper):
    rng = np.random.default_rng(len(poles) + 10 * proper)
    order = len(poles)
    model = _random_stable_model(rng, poles, order if proper else order - 1)
    t = T[:1501]
    x = analytic_axis(t, t[-1], 1.0, 3.0, 0.4, 1.7)[0]
    fit = fit_min_jerk(t, x, 1e-4)
    e = tracking_error(fit.spline, model)(t)

    A, Bm, C, D = signal.tf2ss(model.num, model.den)
    rest = float(fit.spline(t[0]))

    def rhs(tt, z):
        return A @ z + Bm[:, 0] * (fit.spline(tt) - rest)

    z = solve_ivp(rhs, (t[0], t[-1]), np.zeros(order), method="DOP853", rtol=1e-12, atol=1e-14,
                  t_eval=t, max_step=2e-3).y
    reference = C[0] @ z + D[0, 0] * (fit.spline(t) - rest) + model.dc_gain * rest
    assert np.abs(e - reference).max() <= 1e-9 * np.abs(reference).max()


def test_partial_fractions_reconstruct_the_transfer_function():
    model = LinearErrorModel(num=[1.0, 2.0, 0.0, 3.0], den=np.real(np.poly([-2, -2, -3 + 1j, -3 - 1j])))
    pf = PartialFractions.from_model(model)
    s = np.array([0.3 + 2j, 1.0, -0.5 + 4j])
    value = pf.direct + sum(
        w * r / (s - p) ** (j + 1) + (w == 2) * np.conj(r) / (s - np.conj(p)) ** (j + 1) / 2 * 0
        for p, m, rs, w in zip(pf.poles, pf.multiplicity, pf.residues, pf.weight)
        for j, r in enumerate(rs) if w == 1)
    # complex pair contributions, both members
    for p, m, rs, w in zip(pf.poles, pf.multiplicity, pf.residues, pf.weight):
        if w == 2:
            for j, r in enumerate(rs):
                value = value + r / (s - p) ** (j + 1) + np.conj(r) / (s - np.conj(p)) ** (j + 1)
    np.testing.assert_allclose(value, np.polyval(model.num, s) / np.polyval(model.den, s), rtol=1e-10)


def test_long_segments_do_not_overflow(machine):
    # a quintic move, then a 500 s hold as ONE segment, then another move: exp(l t) on a global
    # time axis would overflow (l up to -190 rad/s); local time keeps everything finite
    t = np.concatenate([np.linspace(0, 1, 1001), np.linspace(501, 502, 1001)])
    x = np.concatenate([analytic_axis(t[:1001], 1.0, 0, 50, 0, 1)[0],
                        analytic_axis(t[1001:] - 501, 1.0, 50, -50, 0, 1)[0]])
    spline = PPoly(np.zeros((6, 1)), [0, 1])  # placeholder replaced below
    fit1 = fit_min_jerk(t[:1001], x[:1001], 1e-4)
    fit2 = fit_min_jerk(t[1001:], x[1001:], 1e-4)
    c = np.concatenate([fit1.spline.c, np.array([[0, 0, 0, 0, 0, 50.0]]).T, fit2.spline.c], axis=1)
    spline = PPoly(c, np.concatenate([fit1.spline.x, fit2.spline.x]))
    model = machine.error_models("pid-low")[0]
    err = tracking_error(spline, model)
    e = err(t)
    assert np.all(np.isfinite(e))
    assert abs(err(500.9)) < 1e-12          # settled during the hold
    # the second move's error equals the first's, mirrored (linearity, settled state)
    np.testing.assert_allclose(e[1001:], -e[:1001], atol=1e-12 * np.abs(e).max() + 1e-15)


def test_error_before_start_and_after_end(machine):
    x = analytic_axis(T, DURATION, 5.0, 20.0, 1.0, 2.0)[0]
    fit = fit_min_jerk(T, x, 1e-3)
    err = tracking_error(fit.spline, machine.error_models("pid-low")[0])
    assert err(-1.0) == 0.0
    late = err(np.array([DURATION + 0.5, DURATION + 5.0]))
    assert abs(late[1]) < 1e-6 * np.abs(err(T)).max()    # slowest pole -6.1 rad/s
    assert late.shape == (2,)


def test_unstable_model_is_refused():
    fit = fit_min_jerk(T[:100], np.linspace(0, 1, 100) ** 2, 1e-3)
    with pytest.raises(UnsupportedControllerError, match="not stable"):
        tracking_error(fit.spline, LinearErrorModel(num=[1.0, 0.0], den=[1.0, -2.0], axis="X"))
