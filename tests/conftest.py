"""Shared fixtures and helpers: the built-in machine, a smooth analytic five-axis trajectory,
and the sampled (ZOH) closed loops that the controller and virtual-machine tests check against."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.signal as sig

from precontour import load_machine

#: Draws over which a result decided by friction at a stop is judged (the path as given, then
#: with 1e-9 mm of normal noise on the tip points, seeds 1, 2, ...): where static friction
#: holds an axis is decided by nanometres, so such a test asserts on the worst draw, with the
#: margin measured over many more draws (each test's docstring says how many and what).
FRICTION_DRAWS = 5


def assert_pose_round_trip(kin, P, O):
    """``kin.inverse`` of a tool tip ``P`` and orientation ``O`` (normalised here), then
    ``kin.forward``: the pose again, to 1e-9 mm and twice the pole tolerance. Returns the
    axes (for each type's own checks of the solution chosen)."""
    from precontour.machine.kinematics.ac_trunnion import POLE_TOLERANCE

    P = np.array(P)
    O = np.array(O) / np.linalg.norm(O)
    q = kin.inverse(P, O)
    P2, O2 = kin.forward(q)
    np.testing.assert_allclose(P2, P, atol=1e-9, rtol=0)
    np.testing.assert_allclose(O2, O, atol=2 * POLE_TOLERANCE + 1e-15, rtol=0)
    return q


@pytest.fixture(scope="session")
def machine():
    return load_machine("zhang2013")


def nanometre_draws(toolpath, draws: int = FRICTION_DRAWS):
    """``toolpath`` as given, then ``draws - 1`` copies with 1e-9 mm of normal noise on its tip
    points (seeds 1, 2, ...): the draws of :data:`FRICTION_DRAWS`."""
    import dataclasses

    yield toolpath
    for seed in range(1, draws):
        noise = np.random.default_rng(seed).normal(0.0, 1e-9, np.shape(toolpath.P))
        yield dataclasses.replace(toolpath, P=toolpath.P + noise)


def smoothstep7(s):
    """C3 rest-to-rest ramp 0 -> 1 on s in [0, 1] (zero velocity, acceleration, jerk at ends)."""
    s = np.clip(s, 0.0, 1.0)
    return 35 * s**4 - 84 * s**5 + 70 * s**6 - 20 * s**7


class AnalyticAxis:
    """A smooth rest-to-rest axis motion start + travel*ramp(s) + wiggle*bump(s)*sin(2 pi f t),
    s = t / duration, with exact derivatives (numpy.polynomial and the Leibniz rule)."""

    def __init__(self, duration, start, travel, wiggle, freq):
        from numpy.polynomial import Polynomial as Poly

        ramp = Poly([0, 0, 0, 0, 35, -84, 70, -20])
        bump = Poly([0, 0, 0, 0, 1]) * Poly([1, -1]) ** 4 * 256   # zero v, a, j at both ends
        self.duration, self.start, self.travel, self.wiggle, self.freq = (
            duration, start, travel, wiggle, freq)
        self.ramp = [ramp.deriv(k) if k else ramp for k in range(4)]
        self.bump = [bump.deriv(k) if k else bump for k in range(4)]

    def __call__(self, t, k=0):
        """k-th time derivative at t (k = 0..3)."""
        from math import comb

        t = np.asarray(t, dtype=float)
        s = t / self.duration
        omega = 2 * np.pi * self.freq
        total = 0.0
        for i in range(k + 1):
            b = self.bump[i](s) / self.duration**i
            total = total + comb(k, i) * b * omega ** (k - i) * np.sin(omega * t + (k - i) * np.pi / 2)
        return self.start * (k == 0) + self.travel * self.ramp[k](s) / self.duration**k + self.wiggle * total


def analytic_axis(t, duration, start, travel, wiggle, freq):
    """(x, v, a, j) of :class:`AnalyticAxis` at t."""
    axis = AnalyticAxis(duration, start, travel, wiggle, freq)
    return tuple(axis(t, k) for k in range(4))


def zoh_plant(drive: Drive, ts: float):
    A = np.array([[0.0, drive.rg], [0.0, -drive.B / drive.J]])
    Bm = np.array([[0.0], [drive.ka * drive.kt / drive.J]])
    Ad, Bd, Cd, Dd, _ = sig.cont2discrete((A, Bm, np.array([[1.0, 0.0]]), np.zeros((1, 1))),
                                          ts, method="zoh")
    Np, Dp = sig.ss2tf(Ad, Bd, Cd, Dd)
    return np.trim_zeros(Np[0], "f"), Dp


def discrete_p_pi_error(drive: Drive, g: PPIGains, ts: float):
    """e(z)/X(z) of the sampled P-PI (no feed-forward): encoder velocity D = (z-1)/(Ts z),
    rectangle-rule PI C = kv + ki_v Ts z/(z-1); e/X = (1 + P C D) / (1 + P C (kp + D))."""
    Np, Dp = zoh_plant(drive, ts)
    Nc = g.kv * np.array([1.0, -1.0]) + g.ki_v * ts * np.array([1.0, 0.0])
    Dc = np.array([1.0, -1.0])
    Nd, Dd = np.array([1.0, -1.0]), np.array([ts, 0.0])
    base = np.polymul(np.polymul(Dp, Dc), Dd)
    num = np.polyadd(base, np.polymul(np.polymul(Np, Nc), Nd))
    den = np.polyadd(base, np.polymul(np.polymul(Np, Nc), np.polyadd(g.kp * Dd, Nd)))
    return num, den


def discrete_smc_characteristic(drive: Drive, g, ts: float):
    """Characteristic polynomial in z of the sampled sliding-mode loop, frozen estimates.

    The law K u = J lam e' + B x' + rho Ts z/(z-1) S + ks S (feed-forward left out: it does not
    move the poles), S = lam e + e', with e' = (z-1)/(Ts z) e and x' = (z-1)/(Ts z) x, closed
    around the ZOH plant x = P u with e = -x: multiplied out by K Ts z (z-1).
    """
    Np, Dp = zoh_plant(drive, ts)
    zm1 = np.array([1.0, -1.0])
    # Ts z (z-1) [J lam e' + (ks + rho Ts z/(z-1)) S] / e and Ts z (z-1) B x' / x:
    law_e = np.polyadd(drive.J * g.lam * np.polymul(zm1, zm1),
                       np.polymul(np.polyadd(g.ks * zm1, [g.gamma_d * ts, 0.0]),
                                  [g.lam * ts + 1.0, -1.0]))
    law_x = drive.B * np.polymul(zm1, zm1)
    # K Ts z (z-1) u = (law_x - law_e) x, K = ka kt rg; x = (Np/Dp) u (P takes volts).
    return np.polyadd(np.polymul(Dp, drive.gain * ts * np.array([1.0, -1.0, 0.0])),
                      np.polymul(Np, np.polysub(law_e, law_x)))


def discrete_closed_loop_error(drive, gains, ts):
    """e(z)/X(z) of the ZOH plant (cont2discrete) closed by the rectangle/backward-difference
    PID C(z) = kp + ki Ts z/(z-1) + kd (z-1)/(Ts z), as polynomials in z."""
    A = np.array([[0.0, drive.rg], [0.0, -drive.B / drive.J]])
    Bm = np.array([[0.0], [drive.ka * drive.kt / drive.J]])
    Ad, Bd, Cd, Dd, _ = sig.cont2discrete((A, Bm, np.array([[1.0, 0.0]]), np.zeros((1, 1))),
                                          ts, method="zoh")
    Np, Dp = sig.ss2tf(Ad, Bd, Cd, Dd)
    Nc = (gains.kp * np.array([1.0, -1.0, 0.0]) + gains.ki * ts * np.array([1.0, 0.0, 0.0])
          + gains.kd / ts * np.array([1.0, -2.0, 1.0]))
    Dc = np.array([1.0, -1.0, 0.0])
    num = np.polymul(Dp, Dc)
    den = np.polyadd(num, np.polymul(np.trim_zeros(Np[0], "f"), Nc))
    return num, den


def servo_of(machine, controller: str, limits=None):
    """``load_servo(machine, controller)``, with the axis ``limits`` a test sets instead of
    the machine's where given."""
    import dataclasses

    from precontour import load_servo

    servo = load_servo(machine, controller)
    return servo if limits is None else dataclasses.replace(servo, axis_limits=limits)
