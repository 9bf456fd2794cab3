"""Tests of the controller types: error models against block diagrams integrated by solve_ivp,
shipped gains (bandwidths, continuous and sampled stability), design functions, machine-file
errors, and the predictor's refusal of the nonlinear sliding-mode controller.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from conftest import discrete_closed_loop_error, discrete_p_pi_error, zoh_plant
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


def test_shipped_smc_bandwidth_exceeds_pid_high():

    smc = MACHINE.controller("smc")
    pid = MACHINE.controller("pid-high").error_models(MACHINE.drives)
    for gains, drive, pid_model in zip(smc.axes, MACHINE.drives, pid):
        fb = gains.feedback_error_model(drive)
        fb.check_stable()
        f_smc = closed_loop_bandwidth(fb)
        assert f_smc == pytest.approx(80.0, rel=1e-3)
        assert f_smc > 1.4 * closed_loop_bandwidth(pid_model)
        # The sampled frozen-estimate law is exactly the sampled PID with the equivalent gains.
        K = drive.gain
        equiv = PIDGains(kp=(gains.ks * gains.lam + gains.gamma_d) / K,
                         ki=gains.gamma_d * gains.lam / K, kd=(drive.J * gains.lam + gains.ks) / K)
        _, den = discrete_closed_loop_error(drive, equiv, TS)
        assert np.abs(np.roots(den)).max() < 0.95
        # gamma_J = J * 1 s^2, gamma_B = J * 10 s (documented in the machine file)
        assert gains.gamma_J == pytest.approx(drive.J, rel=1e-4)
        assert gains.gamma_B == pytest.approx(10 * drive.J, rel=1e-4)


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
        g = design_smc(drive, 80.0, gamma_J=drive.J, gamma_B=10 * drive.J)
        for key in ("lam", "ks", "gamma_d"):
            assert getattr(g, key) == pytest.approx(getattr(shipped, key), rel=5e-5)


@pytest.mark.parametrize("B", [0.0, 0.004])
def test_smc_triple_pole(B):
    drive = dataclasses.replace(MACHINE.drives[0], B=B)
    lam, ks, gamma_d = smc_triple_pole_gains(drive, 300.0)
    poles = SMCGains(lam=lam, ks=ks, gamma_d=gamma_d).feedback_error_model(drive).poles
    # A triple root is found to ~cube root of the round-off.
    np.testing.assert_allclose(poles, -300.0, atol=1e-2)
    if B == 0:
        assert lam == 300.0
    else:
        assert drive.J * (300.0 - lam) ** 3 == pytest.approx(B * lam**2, rel=1e-10)


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
SMC_X = "X = { lambda = 98.273, ks = 2.0228, gamma_d = 157.23, gamma_J = 0.007, gamma_B = 0.07 }"
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
    (SMC_X, "X = { ks = 2.0228, gamma_d = 157.23 }",
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
