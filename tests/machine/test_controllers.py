"""Tests of the controller types: error models against block diagrams integrated by solve_ivp,
shipped gains (bandwidths, continuous and sampled stability), design functions, machine-file
errors, and the predictor's refusal of the nonlinear sliding-mode controller.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from conftest import (discrete_closed_loop_error, discrete_p_pi_error,
                      discrete_smc_characteristic, zoh_plant)
import scipy.signal as sig
from scipy.integrate import solve_ivp
from scipy.interpolate import PPoly

from precontour.machine.controllers import (PIDGains, PPIGains, SMCGains, closed_loop_bandwidth,
                                    design_p_pi, design_smc, smc_triple_pole_gains)
from precontour.machine.drives import Drive
from precontour.errors import MachineFileError, UnsupportedControllerError
from precontour.machine.machine_file import builtin_machine_text, load_machine
from precontour.prediction.tracking import tracking_error

MACHINE = load_machine("zhang2013")
TS = MACHINE.servo_period

# smoothstep7 as ascending coefficients: zero velocity, acceleration and jerk at 0 and 1.
_STEP7 = np.array([0, 0, 0, 0, 35, -84, 70, -20], dtype=float)


def out_and_back(T1=0.15, T2=0.25, up=5.0, down=-8.0) -> PPoly:
    """Two rest-to-rest degree-7 segments (C3 at the joint) as a PPoly command."""
    c = np.zeros((8, 2))
    for j, (T, travel) in enumerate(((T1, up), (T2, down))):
        asc = travel * _STEP7 / T ** np.arange(8)
        c[:, j] = asc[::-1]
    c[-1, 1] += up
    return PPoly(c, [0.0, T1, T1 + T2])


def simulate_block_diagram(drive: Drive, gains, command: PPoly, t_eval: np.ndarray):
    """Tracking error of the controller's block diagram, written in state space
    (x, x', controller integral) and integrated by solve_ivp; returns e(t_eval)."""
    J, B, K = drive.J, drive.B, drive.gain
    d1, d2 = command.derivative(1), command.derivative(2)
    end = command.x[-1]

    def cmd(t):
        if t >= end:
            return float(command(end)), 0.0, 0.0
        return float(command(t)), float(d1(t)), float(d2(t))

    def rhs(t, y):
        x, v, z = y
        X, Xd, Xdd = cmd(t)
        e = X - x
        if isinstance(gains, PIDGains):
            u = (gains.kp * e + gains.ki * z + gains.kd * (Xd - v)
                 + gains.kvff * B / K * Xd + gains.kaff * J / K * Xdd)
            dz = e
        else:
            e_v = gains.kp * e + gains.kvff * Xd - v
            u = gains.kv * e_v + gains.ki_v * z + gains.kaff * J / K * Xdd
            dz = e_v
        return [v, (K * u - B * v) / J, dz]

    sol = solve_ivp(rhs, (0.0, t_eval[-1]), [float(command(0.0)), 0.0, 0.0], method="DOP853",
                    t_eval=t_eval, rtol=1e-13, atol=1e-15, max_step=2e-3,
                    first_step=1e-6)
    return command(np.minimum(t_eval, end)) - sol.y[0]


def random_drive(rng) -> Drive:
    J = 10 ** rng.uniform(-4.5, -2)
    # B/J as on the paper's drives (3-14 1/s): a stiff plant would only slow the oracle down.
    return Drive(axis="X", ka=rng.uniform(1, 7), kt=rng.uniform(0.3, 0.5),
                 rg=rng.uniform(0.005, 2.0), J=J, B=J * rng.uniform(2.0, 20.0))


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("kind", ["pid", "p-pi"])
def test_error_model_matches_block_diagram(kind, seed):
    """e(s)/X(s) of pid (with feed-forward) and p-pi (with feed-forward) reproduce the block
    diagram's response: closed-form tracking error of the model vs solve_ivp."""
    rng = np.random.default_rng(100 * seed + len(kind))
    drive = random_drive(rng)
    kvff, kaff = rng.uniform(0, 1, size=2)
    if seed == 0:
        kvff = kaff = 0.0
    if kind == "pid":
        i = int(rng.integers(5))
        base = MACHINE.controller("pid-high").axes[i]
        # Scale the paper's gains to this drive's J/K so that the loop keeps its poles.
        ref = MACHINE.drives[i]
        s = (drive.J / drive.gain) / (ref.J / ref.gain)
        gains = PIDGains(kp=base.kp * s, ki=base.ki * s, kd=base.kd * s, kvff=kvff, kaff=kaff)
    else:
        g = design_p_pi(drive, rng.uniform(20, 60), velocity_ratio=rng.uniform(1.5, 3.5),
                        pi_zero_ratio=rng.uniform(0.1, 0.5))
        gains = dataclasses.replace(g, kvff=kvff, kaff=kaff)
    model = gains.error_model(drive)
    model.check_stable()
    command = out_and_back()
    t = np.linspace(0.0, 0.6, 301)
    ref = simulate_block_diagram(drive, gains, command, t)
    got = tracking_error(command, model)(t)
    scale = np.abs(ref).max()
    assert scale > 0
    assert np.abs(got - ref).max() < 1e-9 * scale, np.abs(got - ref).max() / scale


def test_full_feedforward_leaves_only_the_uncancelled_terms():
    """With kvff = kaff = 1 the PID numerator vanishes (the model is cancelled) and the P-PI
    numerator keeps only B s^2 (its velocity loop's damping is not fed forward)."""
    drive = MACHINE.drives[1]
    pid = PIDGains(kp=30, ki=650, kd=0.4, kvff=1.0, kaff=1.0).error_model(drive)
    assert np.all(pid.num == 0.0)
    ppi = PPIGains(kp=200, kv=1.5, ki_v=400, kvff=1.0, kaff=1.0).error_model(drive)
    np.testing.assert_allclose(ppi.num, [drive.B, 0.0, 0.0])


# ------------------------------------------------------------------------------------------
# Shipped gains and design
# ------------------------------------------------------------------------------------------

@pytest.mark.parametrize("name, target", [("p-pi-high", 55.8), ("p-pi-low", 38.6)])
def test_shipped_p_pi_bandwidth_and_stability(name, target):
    ctrl = MACHINE.controller(name)
    models = ctrl.error_models(MACHINE.drives)  # raises if a continuous loop is unstable
    for model, drive, gains in zip(models, MACHINE.drives, ctrl.axes):
        # Gains are rounded to 5 digits: measured within 0.003 % of the target.
        assert closed_loop_bandwidth(model) == pytest.approx(target, rel=1e-3)
        assert gains.kvff == 0.0 and gains.kaff == 0.0
        _, den = discrete_p_pi_error(drive, gains, TS)
        # Sampled at 1 kHz the loop stays stable and damped: measured spectral radius
        # <= 0.92, smallest damping ratio of the sampled poles 0.28 (high) and 0.68 (low).
        z = np.roots(den)
        assert np.abs(z).max() < 0.93, (name, drive.axis)
        s = np.log(z.astype(complex)) / TS
        assert np.min(-s.real / np.abs(s)) > 0.25, (name, drive.axis)


def test_smc_characteristic_polynomial_is_the_published_factored_form():
    """Worked by hand: J = 0.01, lambda = 100, ks = 2, rho = 100 gives
    (s + 100)(0.01 s^2 + 2 s + 100) = 0.01 s^3 + 3 s^2 + 300 s + 10000 = 0.01 (s + 100)^3."""
    drive = dataclasses.replace(MACHINE.drives[0], J=0.01, B=0.5)  # B drops out
    g = SMCGains(lam=100.0, ks=2.0, gamma_d=100.0)
    np.testing.assert_allclose(g.characteristic_polynomial(drive), [0.01, 3.0, 300.0, 10000.0],
                               rtol=1e-15)
    model = g.feedback_error_model(drive)
    np.testing.assert_allclose(model.den, [0.01, 3.0, 300.0, 10000.0], rtol=1e-15)
    np.testing.assert_allclose(model.num, [0.01, 0.0, 0.0, 0.0])
    np.testing.assert_allclose(model.poles, -100.0, atol=0.05)  # triple root
    # A second hand-worked case with distinct roots: J = 1, lambda = 5, ks = 3, rho = 2:
    # (s + 5)(s^2 + 3 s + 2) = (s + 5)(s + 1)(s + 2) = s^3 + 8 s^2 + 17 s + 10.
    unit = dataclasses.replace(drive, J=1.0)
    g2 = SMCGains(lam=5.0, ks=3.0, gamma_d=2.0)
    np.testing.assert_array_equal(g2.characteristic_polynomial(unit), [1.0, 8.0, 17.0, 10.0])
    np.testing.assert_allclose(np.sort(g2.feedback_error_model(unit).poles.real),
                               [-5.0, -2.0, -1.0], rtol=1e-12)
    # Shipped gains: the factored form, multiplied out by numpy.
    for gains, d in zip(MACHINE.controller("smc").axes, MACHINE.drives):
        np.testing.assert_allclose(gains.characteristic_polynomial(d),
                                   np.polymul([1.0, gains.lam], [d.J, gains.ks, gains.gamma_d]),
                                   rtol=1e-14)


def test_shipped_smc_design():
    smc = MACHINE.controller("smc")
    for gains, drive in zip(smc.axes, MACHINE.drives):
        fb = gains.feedback_error_model(drive)
        fb.check_stable()
        assert closed_loop_bandwidth(fb) == pytest.approx(35.0, rel=1e-3)
        # Triple real pole at -lambda (gains rounded to 5 digits).
        np.testing.assert_allclose(fb.poles.real, -gains.lam, rtol=1e-2)
        # The published law: no inertia or damping adaptation.
        assert gains.gamma_J == 0.0 and gains.gamma_B == 0.0
        # Sampled at 1 kHz (ZOH, backward differences) the loop stays stable and damped:
        # measured spectral radius 0.955, smallest damping ratio 0.97.
        z = np.roots(discrete_smc_characteristic(drive, gains, TS))
        assert np.abs(z).max() < 0.96, drive.axis
        s = np.log(z.astype(complex)) / TS
        assert np.min(-s.real / np.abs(s)) > 0.9, drive.axis


def test_sampled_smc_loop_loses_damping_as_bandwidth_grows():
    """The 1 kHz loop limits the design: measured smallest damping ratio of the sampled poles
    0.96 at 60 Hz, 0.58 at 117 Hz; near 300 Hz it is unstable."""
    drive = MACHINE.drives[0]

    def worst(bandwidth):
        z = np.roots(discrete_smc_characteristic(drive, design_smc(drive, bandwidth), TS))
        s = np.log(z.astype(complex)) / TS
        return np.abs(z).max(), np.min(-s.real / np.abs(s))

    assert worst(60.0)[1] > 0.9
    assert 0.3 < worst(117.0)[1] < 0.7
    assert worst(300.0)[0] > 1.0


def test_design_functions_reproduce_shipped_gains():
    for name, f in (("p-pi-high", 55.8), ("p-pi-low", 38.6)):
        for drive, shipped in zip(MACHINE.drives, MACHINE.controller(name).axes):
            g = design_p_pi(drive, f)
            for key in ("kp", "kv", "ki_v"):
                assert getattr(g, key) == pytest.approx(getattr(shipped, key), rel=5e-5)
            # the design rule itself
            w_v = 2.0 * 2 * np.pi * f
            assert (drive.B + drive.gain * g.kv) / drive.J == pytest.approx(w_v, rel=1e-12)
            assert g.ki_v / g.kv == pytest.approx(w_v / 4, rel=1e-12)
    for drive, shipped in zip(MACHINE.drives, MACHINE.controller("smc").axes):
        g = design_smc(drive, 35.0)
        for key in ("lam", "ks", "gamma_d", "gamma_J", "gamma_B"):
            assert getattr(g, key) == pytest.approx(getattr(shipped, key), rel=5e-5)
    g = design_smc(MACHINE.drives[3], 35.0, gamma_J=1e-4, gamma_B=1e-3)
    assert (g.gamma_J, g.gamma_B) == (1e-4, 1e-3)


@pytest.mark.parametrize("B", [0.0, 0.004])
def test_smc_triple_pole(B):
    drive = dataclasses.replace(MACHINE.drives[0], B=B)
    lam, ks, rho = smc_triple_pole_gains(drive, 300.0)
    # (s + 300)(J s^2 + 600 J s + 90000 J) = J (s + 300)^3, whatever B (the law cancels it).
    assert (lam, ks, rho) == pytest.approx((300.0, 600.0 * drive.J, 90000.0 * drive.J),
                                           rel=1e-15)
    poles = SMCGains(lam=lam, ks=ks, gamma_d=rho).feedback_error_model(drive).poles
    # A triple root is found to ~cube root of the round-off.
    np.testing.assert_allclose(poles, -300.0, atol=1e-2)


def test_bandwidth_of_a_first_order_loop():
    from precontour.machine.drives import LinearErrorModel

    # x/X = a / (s + a): -3 dB at a rad/s exactly
    model = LinearErrorModel(num=[1.0, 0.0], den=[1.0, 2 * np.pi * 40.0])
    assert closed_loop_bandwidth(model) == pytest.approx(40.0, rel=1e-9)
    never = LinearErrorModel(num=[0.0, 0.0], den=[1.0, 1.0])  # x = X at every frequency
    with pytest.raises(UnsupportedControllerError, match="stays above -3 dB"):
        closed_loop_bandwidth(never)


# ------------------------------------------------------------------------------------------
# Nonlinear controller and machine-file errors
# ------------------------------------------------------------------------------------------

def test_predictor_refuses_smc():
    from precontour.prediction.tracking import predict_tracking

    smc = MACHINE.controller("smc")
    assert not smc.is_linear
    assert not hasattr(smc.axes[0], "error_model")
    msg = (r"controller 'smc' \(type 'smc'\) is nonlinear; the closed-form predictor needs a "
           r"linear controller \(type pid, p-pi, tf\)")
    with pytest.raises(UnsupportedControllerError, match=msg):
        smc.error_models(MACHINE.drives)
    t = np.arange(50) * TS
    with pytest.raises(UnsupportedControllerError, match="is nonlinear"):
        predict_tracking(t, np.zeros((50, 5)), smc.error_models(MACHINE.drives))


def _edit(text, old, new):
    assert old in text, old
    return text.replace(old, new, 1)


PPI_X = "X = { kp = 203.86, kv = 0.97926, ki_v = 171.66 }"
SMC_X = "X = { lambda = 56.403, ks = 0.78964, gamma_d = 22.269 }"
PID_X = "X = { kp = 30.000, ki = 650.00, kd = 0.4000 }"


@pytest.mark.parametrize("old, new, pattern", [
    (PPI_X, "X = { kp = 203.86, ki_v = 171.66 }", r"\[controllers.p-pi-high.X\] kv: missing key"),
    (PPI_X, "X = { kp = 203.86, kv = 0.97926, ki_v = 171.66, kd = 0.1 }",
     r"\[controllers.p-pi-high.X\] kd: unknown key"),
    (PPI_X, "X = { kp = -203.86, kv = 0.97926, ki_v = 171.66 }",
     r"\[controllers.p-pi-high.X\] kp: must be > 0, got -203.86"),
    (PPI_X, "X = { kp = 203.86, kv = 0.97926, ki_v = -1.0 }",
     r"\[controllers.p-pi-high.X\] ki_v: must be >= 0, got -1"),
    (PPI_X, "X = { kp = 203.86, kv = 0.97926, ki_v = 171.66, kvff = 1.5 }",
     r"\[controllers.p-pi-high.X\] kvff: must be <= 1, got 1.5"),
    (PPI_X, "X = { kp = 203.86, kv = 0.97926, ki_v = 171.66, kaff = -0.5 }",
     r"\[controllers.p-pi-high.X\] kaff: must be >= 0, got -0.5"),
    (PPI_X, "X = { kp = 203.86, kv = \"fast\", ki_v = 171.66 }",
     r"\[controllers.p-pi-high.X\] kv: must be a number"),
    (PID_X, "X = { kp = 30.000, ki = 650.00, kd = 0.4000, kaff = 2.0 }",
     r"\[controllers.pid-high.X\] kaff: must be <= 1, got 2"),
    (PID_X, "X = { kp = 30.000, ki = 650.00, kd = 0.4000, kff = 0.5 }",
     r"\[controllers.pid-high.X\] kff: unknown key"),
    (SMC_X, "X = { ks = 0.78964, gamma_d = 22.269 }",
     r"\[controllers.smc.X\] lambda: missing key"),
    (SMC_X, "X = { lambda = 98.273, ks = 0.0, gamma_d = 157.23 }",
     r"\[controllers.smc.X\] ks: must be > 0, got 0"),
    (SMC_X, "X = { lambda = 98.273, ks = 2.0228, gamma_d = -157.23 }",
     r"\[controllers.smc.X\] gamma_d: must be >= 0, got -157.23"),
    (SMC_X, "X = { lambda = 98.273, ks = 2.0228, gamma_d = 157.23, gamma_J = -1e-3 }",
     r"\[controllers.smc.X\] gamma_J: must be >= 0"),
    (SMC_X, "X = { lambda = 98.273, ks = 2.0228, gamma_d = 157.23, lam = 3.0 }",
     r"\[controllers.smc.X\] lam: unknown key"),
    ("type = \"smc\"", "type = \"sliding\"",
     r"\[controllers.smc\] type: unknown value 'sliding'; choose one of pid, p-pi, smc"),
])
def test_machine_file_errors_for_new_types(tmp_path, old, new, pattern):
    path = tmp_path / "bad.toml"
    path.write_text(_edit(builtin_machine_text(), old, new))
    with pytest.raises(MachineFileError, match=pattern) as info:
        load_machine(path)
    assert str(path) in str(info.value)


def test_optional_keys_default_to_zero(tmp_path):
    text = _edit(builtin_machine_text(), SMC_X, "X = { lambda = 98.273, ks = 2.0228, gamma_d = 1 }")
    text = _edit(text, PPI_X, "X = { kp = 203.86, kv = 0.97926, ki_v = 171.66, kvff = 0.5 }")
    path = tmp_path / "m.toml"
    path.write_text(text)
    m = load_machine(path)
    assert m.controller("smc").axes[0] == SMCGains(lam=98.273, ks=2.0228, gamma_d=1.0)
    assert m.controller("p-pi-high").axes[0] == PPIGains(kp=203.86, kv=0.97926, ki_v=171.66,
                                                         kvff=0.5)
    assert m.controller("pid-high").axes[0].kvff == 0.0
