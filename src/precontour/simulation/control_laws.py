"""Control laws of the virtual machine, one axis at a time, compiled, by controller type.

Each controller type of :mod:`precontour.machine.controllers` registers in :data:`LAWS` a
function that packs its gains into :class:`LawParameters` (a law code and one row of numbers
per axis). The compiled per-sample functions :func:`law_reset`, :func:`discrete_step` (run once
per servo period, output held by a zero-order hold), :func:`continuous_output` and
:func:`continuous_derivative` dispatch on that code; the integrators of
:mod:`precontour.simulation.virtual_machine` call them inside their compiled loops. Laws use the
drives' nominal J, B (the controller's model of the machine), whatever plant is integrated.
numba caches a compiled function by its own file only: the integrators' cached code embeds these
laws, so after editing this module delete ``__pycache__/*.nbi`` and ``*.nbc`` in this folder.

Plant, in position units (spec section 2): J x'' + B x' = K u - rg Tf, K = ka kt rg.

Sliding-mode law as published (Altintas, Erkorkmaz & Zhu, CIRP Annals 49(1) 2000, the paper's
reference [5]), written at the motor: with e = X - x, every position quantity is divided by rg,
and the plant is J w' + B w + d = tau (d: friction and any other disturbance torque).

    (1) S = lambda e + e'                         sliding surface
    (2) tau = J^ (lambda e' + X'') + B^ x' + d^ + Ks S,   u = tau / (ka kt)
    (3) d^ = rho int S dt                         adaptive disturbance estimate (rho = gamma_d)

Derivation. J S' = J (lambda e' + X'') - J x''. With J x'' = tau - B x' - d and (2),
J S' = (J - J^)(lambda e' + X'') + (B - B^) x' + (d - d^) - Ks S. With exact estimates
J^ = J, B^ = B and a constant d, V = J S^2 / 2 + (d - d^)^2 / (2 rho) has
V' = S (d - d^) - Ks S^2 - (d - d^) S = -Ks S^2 <= 0: S -> 0 and then e -> 0 with time constant
1 / lambda. Ks S is a continuous feedback term: no switching, so no chattering from the law
itself. The damping term uses the measured velocity x': with the commanded velocity (B^ X'),
J S' gains the term -B e' and V' = -(Ks + B) S^2 + B lambda e S is not negative definite.
The Slotine-Li form B^ (X' + lambda e) = B^ x' + B^ S is the same law with Ks + B^ for Ks.
Linear closed loop (frozen estimates, no disturbance): J S' + Ks S + rho int S = 0 with
S = (s + lambda) e gives

    (s + lambda)(J s^2 + Ks s + rho) e = 0,

i.e. J s^3 + (J lambda + Ks) s^2 + (Ks lambda + rho) s + rho lambda. On a plant J', B' with
nominal estimates J, B the error obeys
(J' s^3 + (B' - B + J lambda + Ks) s^2 + (Ks lambda + rho) s + rho lambda) e
= ((J' - J) s^3 + (B' - B) s^2) X.
Optional extension (not in the published law, off unless the machine file sets them): J^ and
B^ adapt at J^' = gamma_J (lambda e' + X'') S and B^' = gamma_B x' S (the regressors of J and
B in J S' above, so V' = -Ks S^2 with the two parameter terms added to V), projected onto
:data:`SMC_ESTIMATE_RANGE` times their nominal values.

Discrete laws differentiate by backward differences of the encoder reading (velocity feedback,
and e'), integrate by the rectangle rule including the current sample, and take feed-forward
from differences of the command samples q_k: velocity into a velocity loop by the same backward
difference as the feedback (so that e_v = 0 on perfect tracking), velocity and acceleration
torques by the mean over the hold interval [t_k, t_k+1): X'_k = (q_k+1 - q_k) / Ts and
X''_k = (q_k+2 - q_k+1 - q_k + q_k-1) / (2 Ts^2); the command rests before q_0 and after q_N-1.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..kernels import jit
from ..machine.controllers import Controller
from ..machine.drives import Drive

__all__ = ["LAWS", "LawParameters", "SMC_ESTIMATE_RANGE", "N_DISCRETE_STATES",
           "N_CONTINUOUS_STATES", "law_reset", "discrete_step", "continuous_output",
           "continuous_derivative"]

#: Projection range of the sliding-mode estimates J^ and B^, as factors on the nominal J, B.
SMC_ESTIMATE_RANGE: tuple[float, float] = (0.25, 4.0)

# Law codes, dispatched on inside the compiled loops.
_PID, _P_PI, _SMC = 0, 1, 2
_N_PARAMS = 13
#: Length of a law's state vector in discrete and in continuous time.
N_DISCRETE_STATES = 5
N_CONTINUOUS_STATES = 3

_jit = jit


@dataclass(frozen=True)
class LawParameters:
    """A control law ready for the compiled integrators.

    Attributes
    ----------
    kind : int
        Law code.
    params : ndarray, shape (5, 13)
        One row of gains (and nominal plant numbers) per axis X, Y, Z, A, C.
    """

    kind: int
    params: np.ndarray


class _Nominal:
    """The controller's model of the five drives: J, B, rg, ka kt, K, shape (5,) each."""

    def __init__(self, drives: tuple[Drive, ...]):
        self.J = np.array([d.J for d in drives], dtype=float)
        self.B = np.array([d.B for d in drives], dtype=float)
        self.rg = np.array([d.rg for d in drives], dtype=float)
        self.kakt = np.array([d.ka * d.kt for d in drives], dtype=float)
        self.K = self.kakt * self.rg


def _gains(controller: Controller, *names: str) -> list[np.ndarray]:
    return [np.array([getattr(g, name) for g in controller.axes], dtype=float)
            for name in names]


def _pack(kind: int, *columns: np.ndarray) -> LawParameters:
    params = np.zeros((len(columns[0]), _N_PARAMS))
    for j, column in enumerate(columns):
        params[:, j] = column
    return LawParameters(kind=kind, params=params)


def pid_parameters(controller: Controller, drives: tuple[Drive, ...]) -> LawParameters:
    """PID: u = kp e + ki int e + kd e' + (kvff B X' + kaff J X'') / K.

    Discrete: I_k = I_k-1 + Ts e_k, derivative (e_k - e_k-1) / Ts, feed-forward on the hold
    interval; the state (I, e_k-1) starts at zero, a drive at rest at its first command.
    """
    kp, ki, kd, kvff, kaff = _gains(controller, "kp", "ki", "kd", "kvff", "kaff")
    nom = _Nominal(drives)
    return _pack(_PID, kp, ki, kd, kvff * nom.B / nom.K, kaff * nom.J / nom.K)


def p_pi_parameters(controller: Controller, drives: tuple[Drive, ...]) -> LawParameters:
    """Cascaded P-PI: e_v = kp e + kvff X' - x', u = kv e_v + ki_v int e_v + kaff J X'' / K.

    Discrete: x'_k = (y_k - y_k-1) / Ts from the encoder (0 at the first sample, the drive
    starts at rest), X'_k by the same backward difference of the command.
    """
    kp, kv, ki_v, kvff, kaff = _gains(controller, "kp", "kv", "ki_v", "kvff", "kaff")
    nom = _Nominal(drives)
    return _pack(_P_PI, kp, kv, ki_v, kvff, kaff * nom.J / nom.K)


def smc_parameters(controller: Controller, drives: tuple[Drive, ...]) -> LawParameters:
    """Sliding mode, Eq. (1)-(3) of the module docstring (with the optional J^, B^ rates).

    Discrete: e'_k = (e_k - e_k-1) / Ts and x'_k = (y_k - y_k-1) / Ts (0 at the first
    sample), X''_k the hold-interval mean of the command differences; d^ (and J^, B^) are
    updated by the rectangle rule with the current S before u_k is computed (as the PID
    integral).
    """
    lam, ks, rho, gamma_J, gamma_B = _gains(controller, "lam", "ks", "gamma_d", "gamma_J",
                                            "gamma_B")
    nom = _Nominal(drives)
    lo, hi = SMC_ESTIMATE_RANGE
    return _pack(_SMC, lam, ks, rho, gamma_J, gamma_B, nom.J, nom.B, nom.rg, nom.kakt,
                 lo * nom.J, hi * nom.J, lo * nom.B, hi * nom.B)


#: Law packers by controller type: ``LAWS[type](controller, drives) -> LawParameters``.
LAWS: dict[str, Callable[[Controller, tuple[Drive, ...]], LawParameters]] = {
    "pid": pid_parameters,
    "p-pi": p_pi_parameters,
    "smc": smc_parameters,
}


# --------------------------------------------------------------------------------------------
# Compiled per-sample functions (one axis)
# --------------------------------------------------------------------------------------------

@_jit
def _command(q, j):
    """q_j, with the command at rest before its first and after its last sample."""
    if j < 0:
        return q[0]
    if j >= q.shape[0]:
        return q[q.shape[0] - 1]
    return q[j]


@_jit
def _v_back(q, k, ts):
    return (_command(q, k) - _command(q, k - 1)) / ts


@_jit
def _v_hold(q, k, ts):
    return (_command(q, k + 1) - _command(q, k)) / ts


@_jit
def _a_hold(q, k, ts):
    return (_v_hold(q, k + 1, ts) - _v_back(q, k, ts)) / (2 * ts)


@_jit
def _clip(value, lo, hi):
    return min(max(value, lo), hi)


@_jit
def law_reset(kind, p, state):
    """Zero a law's state (a drive at rest at its first command); J^, B^ start nominal."""
    state[:] = 0.0
    if kind == _SMC:
        state[1] = p[5]
        state[2] = p[6]


@_jit
def discrete_step(kind, p, state, k, e, y, q, ts):
    """Controller output u_k (V) of one axis from e_k = q_k - y_k and the reading y_k.

    ``q`` is the axis's whole command (for the feed-forward differences), ``state`` the law's
    state (length :data:`N_DISCRETE_STATES`), updated in place.
    """
    if kind == _PID:
        kp, ki, kd, cv, ca = p[0], p[1], p[2], p[3], p[4]
        state[0] += ts * e
        u = kp * e + ki * state[0] + (kd / ts) * (e - state[1])
        state[1] = e
        if cv != 0.0 or ca != 0.0:
            u = u + (cv * _v_hold(q, k, ts) + ca * _a_hold(q, k, ts))
        return u
    if kind == _P_PI:
        kp, kv, ki_v, kvff, ca = p[0], p[1], p[2], p[3], p[4]
        v = 0.0 if k == 0 else (y - state[1]) / ts
        state[1] = y
        e_v = kp * e - v
        if kvff != 0.0:
            e_v = e_v + kvff * _v_back(q, k, ts)
        state[0] += ts * e_v
        u = kv * e_v + ki_v * state[0]
        if ca != 0.0:
            u = u + ca * _a_hold(q, k, ts)
        return u
    # sliding mode; state: d^, J^, B^, e_k-1, y_k-1
    lam, ks, rho, gamma_J, gamma_B = p[0], p[1], p[2], p[3], p[4]
    rg, kakt = p[7], p[8]
    edot = (e - state[3]) / ts
    v = 0.0 if k == 0 else (y - state[4]) / ts
    state[3] = e
    state[4] = y
    s_m = (lam * e + edot) / rg
    phi_m = (lam * edot + _a_hold(q, k, ts)) / rg
    v_m = v / rg
    state[0] += ts * rho * s_m
    if gamma_J != 0.0:
        state[1] = _clip(state[1] + ts * gamma_J * phi_m * s_m, p[9], p[10])
    if gamma_B != 0.0:
        state[2] = _clip(state[2] + ts * gamma_B * v_m * s_m, p[11], p[12])
    return (state[1] * phi_m + state[2] * v_m + state[0] + ks * s_m) / kakt


@_jit
def continuous_output(kind, p, s0, s1, s2, e, edot, v, a_cmd):
    """u (V) of the continuous law; e = X - x, edot = X' - x', v = x', a_cmd = X''.

    The state (s0, s1, s2) starts at zero: PID int e; P-PI int e_v; sliding mode
    (J^ - J, B^ - B, d^).
    """
    if kind == _PID:
        return (p[0] * e + p[1] * s0 + p[2] * edot + p[3] * (edot + v) + p[4] * a_cmd)
    if kind == _P_PI:
        e_v = p[0] * e + p[3] * (edot + v) - v
        return p[1] * e_v + p[2] * s0 + p[4] * a_cmd
    lam, ks, rg = p[0], p[1], p[7]
    J_hat = _clip(p[5] + s0, p[9], p[10])
    B_hat = _clip(p[6] + s1, p[11], p[12])
    tau = J_hat * (lam * edot + a_cmd) / rg + B_hat * v / rg + s2 + ks * (lam * e + edot) / rg
    return tau / p[8]


@_jit
def continuous_derivative(kind, p, s0, s1, s2, e, edot, v, a_cmd):
    """d(s0, s1, s2)/dt of the continuous law (see :func:`continuous_output`)."""
    if kind == _PID:
        return e, 0.0, 0.0
    if kind == _P_PI:
        return p[0] * e + p[3] * (edot + v) - v, 0.0, 0.0
    lam, rho, gamma_J, gamma_B, rg = p[0], p[2], p[3], p[4], p[7]
    s_m = (lam * e + edot) / rg
    rate_J = gamma_J * (lam * edot + a_cmd) / rg * s_m
    rate_B = gamma_B * v / rg * s_m
    # Projection: an estimate at a bound stops moving outwards.
    J_hat, B_hat = p[5] + s0, p[6] + s1
    if (J_hat <= p[9] and rate_J < 0.0) or (J_hat >= p[10] and rate_J > 0.0):
        rate_J = 0.0
    if (B_hat <= p[11] and rate_B < 0.0) or (B_hat >= p[12] and rate_B > 0.0):
        rate_B = 0.0
    return rate_J, rate_B, rho * s_m
