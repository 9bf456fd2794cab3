"""The virtual machine's time loops, compiled (numba, cached on disk): one axis per call, the
five axes being independent (:mod:`.virtual_machine` runs them, up to two at a time).

- discrete mode (:func:`_discrete_axis`): the control law at the servo period, a zero-order
  hold on u, the plant integrated with exponential (ETD2) sub-steps on one smooth friction
  branch, each zero crossing of the speed located within its sub-step
  (:func:`_discrete_period_events`) where the axis sticks or breaks away;
- continuous mode (:func:`_continuous_axis`): the continuous control law driven by a quintic
  interpolant of the commands (Taylor coefficients per knot interval), classical RK4;
- the Stribeck friction of spec section 2 by branch (:func:`_branch`, :func:`_friction`) and
  the feed-forward torque from the commanded speed (:func:`_feedforward_torque`).
"""

from __future__ import annotations

import math

import numpy as np

from ..kernels import jit
from .control_laws import (N_DISCRETE_STATES, continuous_derivative, continuous_output,
                           discrete_step, law_reset)

#: Commanded motor speeds below this (rad/s) count as zero in the friction feed-forward, so
#: that round-off in a resting command (or in its interpolant's derivative, ~1e-11) does not
#: switch the full static friction torque on and off.
FF_SPEED_DEADBAND = 1e-8

_jit = jit


@_jit
def _exp_step(J, B, rg, h):
    """Constants (E, P1, P2, Q0, Q1, Q2) of one exponential (ETD2) step of length h.

    With N(w) = (tau - Tf(w)) / J, the motor speed obeys w' = -(B/J) w + N(w). The linear
    part is integrated exactly; N is taken as linear in time between its values at the step
    start and at an exponential-Euler predictor (Cox & Matthews' ETD2), so the step is exact
    without friction and second order with smooth friction. The position x' = rg w is
    integrated exactly for the same model of N. phi_k(z) = sum_j z^j / (j + k)!, z = -B h / J,
    by its series near 0 (ten terms leave |z|^10 / 10! < 3e-17 for |z| < 0.1).
    """
    z = -B / J * h
    if abs(z) < 0.1:
        p1 = p2 = p3 = 0.0
        zj = 1.0
        f1, f2, f3 = 1.0, 2.0, 6.0  # (j + 1)!, (j + 2)!, (j + 3)! at j = 0
        for j in range(10):
            p1 += zj / f1
            p2 += zj / f2
            p3 += zj / f3
            zj *= z
            f1 *= j + 2
            f2 *= j + 3
            f3 *= j + 4
    else:
        em1 = math.expm1(z)
        p1 = em1 / z
        p2 = (em1 - z) / (z * z)
        p3 = (em1 - z - z * z / 2) / (z * z * z)
    return math.exp(z), h * p1, h * p2, rg * h * p1, rg * h * h * p2, rg * h * h * p3


@_jit
def _branch(fr, positive, w):
    """Friction torque of the w > 0 (``positive``) or w < 0 branch, continued through 0."""
    o = 0 if positive else 4
    return fr[o] * math.exp(w * fr[o + 1]) + fr[o + 2] * (1.0 - math.exp(w * fr[o + 3]))


@_jit
def _friction(fr, w):
    """Tf(w) with Tf(0) = 0 (the nominal model for the feed-forward)."""
    if w > 0.0 or w < 0.0:
        # (the branch as a variable: each literal True / False compiled _branch once more)
        return _branch(fr, w > 0.0, w)
    return 0.0


@_jit
def _feedforward_torque(fr, w_cmd):
    """Tff = Tf(w_cmd), commanded speeds below FF_SPEED_DEADBAND counting as zero."""
    if abs(w_cmd) < FF_SPEED_DEADBAND:
        return 0.0
    return _friction(fr, w_cmd)


@_jit
def _discrete_axis(q, ts, kind, p, J, B, rg, kakt, fr, fr_ff, friction, ff, res, origin,
                   noise, substeps, q_act, w_out, u_out):
    """One axis: discrete control law + zero-order hold + exponential plant integration.

    Over one servo period the applied torque tau = kt ka u_k + Tff_k is constant, so the axis
    follows the autonomous scalar ODE J w' = tau - B w - Tf(w): its speed is monotone, crosses
    zero at most once, and at w = 0 it sticks (Filippov) while Tf(0-) <= tau <= Tf(0+). The
    period is integrated with ETD2 sub-steps on the current friction branch; a period in which
    the speed leaves its branch is redone by :func:`_discrete_period_events`, which locates
    the crossing within its sub-step and either sticks the axis or continues on the other
    branch. ``fr`` is the plant's friction, ``fr_ff`` the model the feed-forward uses; the
    encoder reads x + ``noise[k]`` (none when ``noise`` is empty) on the grid ``res`` (0: none)
    whose origin is ``origin``.
    """
    n = q.shape[0]
    state = np.zeros(N_DISCRETE_STATES)
    law_reset(kind, p, state)
    inv_j = 1.0 / J
    if friction:
        E, P1, P2, Q0, Q1, Q2 = _exp_step(J, B, rg, ts / substeps)
    else:
        E, P1, P2, Q0, Q1, Q2 = _exp_step(J, B, rg, ts)
    ts_pos, ts_neg = fr[0], fr[4]
    x = q[0]
    w = 0.0
    for k in range(n):
        q_act[k] = x
        w_out[k] = w
        y = x if noise.shape[0] == 0 else x + noise[k]
        if res != 0.0:
            y = np.rint((y - origin) / res) * res + origin
        u = discrete_step(kind, p, state, k, q[k] - y, y, q, ts)
        u_out[k] = u
        if k == n - 1:
            break
        tau = kakt * u
        if ff:
            # Mean commanded speed over the hold interval [t_k, t_k+1).
            tau = tau + _feedforward_torque(fr_ff, (q[k + 1] - q[k]) / ts / rg)
        if not friction:
            n0 = tau * inv_j
            x = x + Q0 * w + Q1 * n0
            w = E * w + P1 * n0
            continue
        if w == 0.0:
            # At rest, tau decides: stick for the whole period, or break away its way.
            stuck = tau <= ts_pos and tau >= ts_neg
            positive = tau > 0.0
        else:
            stuck = False
            positive = w > 0.0
        if stuck:
            continue  # the branch's static torque exactly balances: w stays 0, x stays
        x0, w0 = x, w
        for _ in range(substeps):
            n0 = (tau - _branch(fr, positive, w)) * inv_j
            a = E * w + P1 * n0
            dn = (tau - _branch(fr, positive, a)) * inv_j - n0
            x = x + Q0 * w + Q1 * n0 + Q2 * dn
            w = a + P2 * dn
        if (w <= 0.0) if positive else (w >= 0.0):
            x, w = _discrete_period_events(x0, w0, tau, positive, J, B, rg, fr, substeps,
                                           ts / substeps)


@_jit
def _discrete_period_events(x, w, tau, positive, J, B, rg, fr, substeps, h):
    """One servo period with zero-crossing location (rare, so written for clarity)."""
    E, P1, P2, Q0, Q1, Q2 = _exp_step(J, B, rg, h)
    inv_j = 1.0 / J
    can_stick = tau <= fr[0] and tau >= fr[4]
    stuck = False
    for _ in range(substeps):
        if stuck:
            break  # w = 0 and x stay for the rest of the period
        n0 = (tau - _branch(fr, positive, w)) * inv_j
        a = E * w + P1 * n0
        dn = (tau - _branch(fr, positive, a)) * inv_j - n0
        x1 = x + Q0 * w + Q1 * n0 + Q2 * dn
        w1 = a + P2 * dn
        if (w1 <= 0.0) if positive else (w1 >= 0.0):
            # Speed reaches zero at theta h (linear in time within the sub-step); the
            # position gets the trapezoid of that part, an O(h^3) local error per event.
            theta = w / (w - w1)
            x_zero = x + rg * (0.5 * theta * h) * w
            if can_stick:
                x1, w1, stuck = x_zero, 0.0, True
            else:
                # Monotone speed: the rest of the sub-step runs from w = 0 on the other branch.
                positive = not positive
                _, R1, R2, _, S1, S2 = _exp_step(J, B, rg, (1.0 - theta) * h)
                n0 = (tau - fr[0 if positive else 4]) * inv_j
                a = R1 * n0
                dn = (tau - _branch(fr, positive, a)) * inv_j - n0
                x1 = x_zero + S1 * n0 + S2 * dn
                w1 = a + R2 * dn
        x, w = x1, w1
    return x, w


@_jit
def _taylor_coefficients(knots, coefs, x, l, work, taylor):
    """taylor[j] = X^(j)(x) / j!, j = 0 .. 5, of the quintic B-spline interpolant at x.

    ``coefs[j]`` holds the B-spline coefficients of the j-th derivative spline, whose knots are
    ``knots[j:-j]`` (degree 5 - j): with that offset, de Boor's algorithm for each derivative
    runs on the original knot interval l (t[l] <= x < t[l+1]; searched from l, returned).
    """
    last = knots.shape[0] - 7
    while l < last and x >= knots[l + 1]:
        l += 1
    factorial = 1.0
    for j in range(6):
        degree = 5 - j
        for i in range(degree + 1):
            work[i] = coefs[j, i + l - 5]
        for r in range(1, degree + 1):
            for i in range(degree, r - 1, -1):
                left = knots[i + l - degree]
                alpha = (x - left) / (knots[i + 1 + l - r] - left)
                work[i] = (1.0 - alpha) * work[i - 1] + alpha * work[i]
        if j > 1:
            factorial *= j
        taylor[j] = work[degree] / factorial
    return l


@_jit
def _command_at(taylor, d):
    """X, X', X'' at d past the Taylor point (see :func:`_taylor_coefficients`)."""
    c0, c1, c2, c3, c4, c5 = taylor[0], taylor[1], taylor[2], taylor[3], taylor[4], taylor[5]
    value = ((((c5 * d + c4) * d + c3) * d + c2) * d + c1) * d + c0
    slope = (((5 * c5 * d + 4 * c4) * d + 3 * c3) * d + 2 * c2) * d + c1
    curve = ((20 * c5 * d + 12 * c4) * d + 6 * c3) * d + 2 * c2
    return value, slope, curve


@_jit
def _continuous_rhs(kind, p, J, B, rg, kakt, fr, friction, positive, stuck, x, w, s0, s1, s2,
                    X, Xd, Xdd, tff):
    """Derivatives (x', w', s0', s1', s2'), the output u and the applied torque tau."""
    v = rg * w
    e = X - x
    edot = Xd - v
    u = continuous_output(kind, p, s0, s1, s2, e, edot, v, Xdd)
    tau = kakt * u + tff
    torque = tau - B * w
    if friction:
        torque = torque - _branch(fr, positive, w)
    wdot = 0.0 if stuck else torque / J
    d0, d1, d2 = continuous_derivative(kind, p, s0, s1, s2, e, edot, v, Xdd)
    return v, wdot, d0, d1, d2, u, tau


@_jit
def _continuous_axis(t, q0, knots, coefs, kind, p, J, B, rg, kakt, fr, fr_ff, friction, ff,
                     substeps, q_act, w_out, u_out):
    """One axis: continuous control law, command from a quintic interpolant, RK4 sub-steps.

    Stage times are t_k + j h / 2 (j = 0 .. 2 m, h = Ts / m); the command and its first two
    derivatives there come from the interpolant's Taylor polynomial at t_k (exact: the
    interpolant is one quintic on [t_k, t_k+1)). Friction follows one smooth branch within a
    sub-step. When the speed reaches zero, the crossing is located linearly within the
    sub-step; the axis then sticks (w = 0) while the applied torque stays within
    [Tf(0-), Tf(0+)], checked at every sub-step start, or continues on the other branch. The
    axis starts at rest (stuck, when it has friction).
    """
    n = t.shape[0]
    m = substeps
    h = (t[n - 1] - t[0]) / (n - 1) / m
    h2, h6 = h / 2, h / 6
    x, w = q0, 0.0
    s0 = s1 = s2 = 0.0
    stuck = friction
    # (typed booleans and integers, not literals: a literal argument compiles the callee once
    # more, for its value)
    positive = np.bool_(True)
    ts_pos, ts_neg = fr[0], fr[4]
    work = np.empty(6)
    taylor = np.empty(6)
    l = np.intp(5)
    for k in range(n):
        q_act[k] = x
        w_out[k] = w
        l = _taylor_coefficients(knots, coefs, t[k], l, work, taylor)
        X1, Xd1, Xdd1 = taylor[0], taylor[1], 2.0 * taylor[2]
        tff1 = _feedforward_torque(fr_ff, Xd1 / rg) if ff else 0.0
        for j in range(m if k < n - 1 else 1):
            dx1, dw1, ds1a, ds1b, ds1c, u1, tau1 = _continuous_rhs(
                kind, p, J, B, rg, kakt, fr, friction, positive, stuck, x, w, s0, s1, s2,
                X1, Xd1, Xdd1, tff1)
            if stuck and (tau1 > ts_pos or tau1 < ts_neg):
                stuck = np.bool_(False)
                positive = tau1 > 0.0
                dx1, dw1, ds1a, ds1b, ds1c, u1, tau1 = _continuous_rhs(
                    kind, p, J, B, rg, kakt, fr, friction, positive, stuck, x, w, s0, s1, s2,
                    X1, Xd1, Xdd1, tff1)
            if j == 0:
                u_out[k] = u1
            if k == n - 1:
                break
            i = 2 * m * k + 2 * j
            X2, Xd2, Xdd2 = _command_at(taylor, t[0] + h2 * (i + 1) - t[k])
            X3, Xd3, Xdd3 = _command_at(taylor, (t[k + 1] if j == m - 1
                                                 else t[0] + h2 * (i + 2)) - t[k])
            tff2 = _feedforward_torque(fr_ff, Xd2 / rg) if ff else 0.0
            tff3 = _feedforward_torque(fr_ff, Xd3 / rg) if ff else 0.0
            dx2, dw2, ds2a, ds2b, ds2c, _, _ = _continuous_rhs(
                kind, p, J, B, rg, kakt, fr, friction, positive, stuck, x + h2 * dx1,
                w + h2 * dw1, s0 + h2 * ds1a, s1 + h2 * ds1b, s2 + h2 * ds1c, X2, Xd2, Xdd2,
                tff2)
            dx3, dw3, ds3a, ds3b, ds3c, _, _ = _continuous_rhs(
                kind, p, J, B, rg, kakt, fr, friction, positive, stuck, x + h2 * dx2,
                w + h2 * dw2, s0 + h2 * ds2a, s1 + h2 * ds2b, s2 + h2 * ds2c, X2, Xd2, Xdd2,
                tff2)
            dx4, dw4, ds4a, ds4b, ds4c, _, tau4 = _continuous_rhs(
                kind, p, J, B, rg, kakt, fr, friction, positive, stuck, x + h * dx3,
                w + h * dw3, s0 + h * ds3a, s1 + h * ds3b, s2 + h * ds3c, X3, Xd3, Xdd3, tff3)
            x1 = x + h6 * (dx1 + 2 * (dx2 + dx3) + dx4)
            w1 = w + h6 * (dw1 + 2 * (dw2 + dw3) + dw4)
            s0 = s0 + h6 * (ds1a + 2 * (ds2a + ds3a) + ds4a)
            s1 = s1 + h6 * (ds1b + 2 * (ds2b + ds3b) + ds4b)
            s2 = s2 + h6 * (ds1c + 2 * (ds2c + ds3c) + ds4c)
            if friction and not stuck and ((w1 <= 0.0) if positive else (w1 >= 0.0)):
                # The crossing at theta h by linear interpolation of w; tau4 is the applied
                # torque at the sub-step end (an O(h) error in the torque over the O(h) rest).
                theta = w / (w - w1)
                x_zero = x + rg * (0.5 * theta * h) * w
                if tau4 <= ts_pos and tau4 >= ts_neg:
                    stuck = True
                    x1, w1 = x_zero, 0.0
                else:
                    # Euler from rest over the rest of the sub-step, on the new branch.
                    positive = not positive
                    rest = (1.0 - theta) * h
                    w1 = (tau4 - fr[0 if positive else 4]) / J * rest
                    x1 = x_zero + rg * 0.5 * rest * w1
            x, w = x1, w1
            X1, Xd1, Xdd1, tff1 = X3, Xd3, Xdd3, tff3
