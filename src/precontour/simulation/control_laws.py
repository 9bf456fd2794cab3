"""Control laws of the virtual machine, vectorized over the five axes, by controller type.

Each controller type of :mod:`precontour.machine.controllers` registers a discrete-time law (run once
per servo period, output held by a zero-order hold) in :data:`DISCRETE_LAWS` and, when it has
one, a continuous-time law in :data:`CONTINUOUS_LAWS`; :func:`precontour.simulation.virtual_machine.simulate`
picks them by ``controller.type``. Laws use the drives' nominal J, B (the controller's model of
the machine), whatever plant the simulation integrates.

Plant, in position units (spec section 2): J x'' + B x' = K u - rg Tf, K = ka kt rg.

Adaptive sliding-mode law (Altintas, Erkorkmaz & Zhu, CIRP Annals 49(1) 2000, written at the
motor with e = X - x, position quantities divided by rg):

    (1) S = lambda e + e'                                 sliding variable
    (2) phi = lambda e' + X''                             reference acceleration of the surface
    (3) tau = J^ phi + B^ X' + d^ + ks S,  u = tau / (ka kt)
    (4) J^' = gamma_J phi S,  B^' = gamma_B X' S,  d^' = gamma_d S

With V = J S^2 / 2 + (J - J^)^2 / (2 gamma_J) + (B - B^)^2 / (2 gamma_B)
+ (d - d^)^2 / (2 gamma_d), the plant J x'' + B x' + d = tau gives
J S' = (J - J^) phi + (B - B^) X' + (d - d^) - ks S - B e', so the rates (4) cancel the parameter
terms: V' = -(ks + B) S^2 + B lambda e S. ks S replaces the discontinuous switching term of
textbook sliding mode (no chattering); J^ and B^ are projected onto
:data:`SMC_ESTIMATE_RANGE` times their nominal values. With frozen nominal estimates the error
obeys J e''' + (J lambda + B + ks) e'' + (ks lambda + gamma_d) e' + gamma_d lambda e = 0: the
linear loop tracks exactly, and the gains set how fast it rejects disturbances.

Discrete laws differentiate by backward differences of the encoder reading (velocity feedback
and e'), integrate by the rectangle rule including the current sample, and take feed-forward
from differences of the command samples q_k: velocity into a velocity loop by the same backward
difference as the feedback (so that e_v = 0 on perfect tracking), velocity and acceleration
torques by the mean over the hold interval [t_k, t_k+1): X'_k = (q_k+1 - q_k) / Ts and
X''_k = (q_k+2 - q_k+1 - q_k + q_k-1) / (2 Ts^2); the command rests before q_0 and after q_N-1.
"""

from __future__ import annotations

from typing import Callable, Protocol

import numpy as np

from ..machine.controllers import Controller
from ..machine.drives import AXES, Drive

#: Projection range of the sliding-mode estimates J^ and B^, as factors on the nominal J, B.
SMC_ESTIMATE_RANGE: tuple[float, float] = (0.25, 4.0)

_N_AXES = len(AXES)


class DiscreteLaw(Protocol):
    """A control law run once per servo period, vectorized over the five axes."""

    def reset(self, q_cmd: np.ndarray) -> None:
        """Zero the internal state; ``q_cmd`` (N, 5) is the whole command, for feed-forward."""

    def step(self, e: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Controller output u_k (V, shape (5,)) from e_k = q_cmd[k] - y_k and the reading y_k."""


class ContinuousLaw(Protocol):
    """A continuous-time control law with internal state ``s`` of shape (n_states, 5).

    The state starts at zero. ``e`` = X - x, ``edot`` = X' - x', ``v`` = x' (actual axis
    velocity) and ``a_cmd`` = X'' (command acceleration), each of shape (5,).
    """

    n_states: int

    def output(self, s: np.ndarray, e: np.ndarray, edot: np.ndarray, v: np.ndarray,
               a_cmd: np.ndarray) -> np.ndarray:
        """u (V), shape (5,)."""

    def derivative(self, s: np.ndarray, e: np.ndarray, edot: np.ndarray, v: np.ndarray,
                   a_cmd: np.ndarray) -> np.ndarray:
        """ds/dt, shape (n_states, 5)."""


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


def command_differences(q_cmd: np.ndarray, ts: float):
    """Backward-difference velocity, hold-interval mean velocity and acceleration, (N, 5) each.

    See the module docstring; the command rests before its first and after its last sample.
    """
    padded = np.concatenate([q_cmd[:1], q_cmd, q_cmd[-1:], q_cmd[-1:]])
    d = np.diff(padded, axis=0) / ts             # d[j] = (p[j+1] - p[j]) / ts, p[j] = q[j-1]
    v_back = d[:-2]
    v_hold = d[1:-1]
    a_hold = (d[2:] - d[:-2]) / (2 * ts)
    return v_back, v_hold, a_hold


# --------------------------------------------------------------------------------------------
# PID
# --------------------------------------------------------------------------------------------

class DiscretePID:
    """Discrete PID: u_k = kp e_k + ki I_k + kd (e_k - e_{k-1}) / Ts + feed-forward,
    I_k = I_{k-1} + Ts e_k; feed-forward (kvff B X'_k + kaff J X''_k) / K on the hold interval.

    The state (I, e_{k-1}) starts at zero, matching a drive at rest at its first command.
    """

    def __init__(self, controller: Controller, ts: float, drives: tuple[Drive, ...]):
        self.kp, self.ki, self.kd, kvff, kaff = _gains(controller, "kp", "ki", "kd", "kvff",
                                                       "kaff")
        self.ts = ts
        nom = _Nominal(drives)
        self._kd_ts = self.kd / ts
        self._cv = kvff * nom.B / nom.K
        self._ca = kaff * nom.J / nom.K
        self._ff = None
        self.reset(None)

    def reset(self, q_cmd: np.ndarray | None) -> None:
        self._integral = np.zeros(_N_AXES)
        self._e_prev = np.zeros(_N_AXES)
        self._k = 0
        self._ff = None
        if q_cmd is not None and (self._cv.any() or self._ca.any()):
            _, v_hold, a_hold = command_differences(q_cmd, self.ts)
            self._ff = self._cv * v_hold + self._ca * a_hold

    def step(self, e: np.ndarray, y: np.ndarray) -> np.ndarray:
        self._integral += self.ts * e
        u = self.kp * e + self.ki * self._integral + self._kd_ts * (e - self._e_prev)
        self._e_prev = e
        if self._ff is not None:
            u = u + self._ff[self._k]
        self._k += 1
        return u


class ContinuousPID:
    """Continuous PID u = kp e + ki z + kd e' + (kvff B X' + kaff J X'') / K, z' = e."""

    n_states = 1

    def __init__(self, controller: Controller, drives: tuple[Drive, ...]):
        self.kp, self.ki, self.kd, kvff, kaff = _gains(controller, "kp", "ki", "kd", "kvff",
                                                       "kaff")
        nom = _Nominal(drives)
        self._cv = kvff * nom.B / nom.K
        self._ca = kaff * nom.J / nom.K

    def output(self, s, e, edot, v, a_cmd):
        return (self.kp * e + self.ki * s[0] + self.kd * edot + self._cv * (edot + v)
                + self._ca * a_cmd)

    def derivative(self, s, e, edot, v, a_cmd):
        return e[np.newaxis]


# --------------------------------------------------------------------------------------------
# P-PI
# --------------------------------------------------------------------------------------------

class DiscretePPI:
    """Discrete cascaded P-PI with the encoder velocity v_k = (y_k - y_{k-1}) / Ts:

    e_v,k = kp e_k + kvff (q_k - q_{k-1}) / Ts - v_k,  I_k = I_{k-1} + Ts e_v,k,
    u_k = kv e_v,k + ki_v I_k + kaff J X''_k / K.
    """

    def __init__(self, controller: Controller, ts: float, drives: tuple[Drive, ...]):
        self.kp, self.kv, self.ki_v, self.kvff, kaff = _gains(controller, "kp", "kv", "ki_v",
                                                              "kvff", "kaff")
        self.ts = ts
        nom = _Nominal(drives)
        self._ca = kaff * nom.J / nom.K
        self.reset(None)

    def reset(self, q_cmd: np.ndarray | None) -> None:
        self._integral = np.zeros(_N_AXES)
        self._y_prev = None
        self._k = 0
        self._vff = self._aff = None
        if q_cmd is not None:
            v_back, _, a_hold = command_differences(q_cmd, self.ts)
            if self.kvff.any():
                self._vff = self.kvff * v_back
            if self._ca.any():
                self._aff = self._ca * a_hold

    def step(self, e: np.ndarray, y: np.ndarray) -> np.ndarray:
        # The drive starts at rest: the first reading has no predecessor.
        v = np.zeros(_N_AXES) if self._y_prev is None else (y - self._y_prev) / self.ts
        self._y_prev = y
        e_v = self.kp * e - v
        if self._vff is not None:
            e_v = e_v + self._vff[self._k]
        self._integral += self.ts * e_v
        u = self.kv * e_v + self.ki_v * self._integral
        if self._aff is not None:
            u = u + self._aff[self._k]
        self._k += 1
        return u


class ContinuousPPI:
    """Continuous P-PI: e_v = kp e + kvff X' - x', u = kv e_v + ki_v z + kaff J X'' / K, z' = e_v."""

    n_states = 1

    def __init__(self, controller: Controller, drives: tuple[Drive, ...]):
        self.kp, self.kv, self.ki_v, self.kvff, kaff = _gains(controller, "kp", "kv", "ki_v",
                                                              "kvff", "kaff")
        nom = _Nominal(drives)
        self._ca = kaff * nom.J / nom.K

    def _e_v(self, e, edot, v):
        return self.kp * e + self.kvff * (edot + v) - v

    def output(self, s, e, edot, v, a_cmd):
        return self.kv * self._e_v(e, edot, v) + self.ki_v * s[0] + self._ca * a_cmd

    def derivative(self, s, e, edot, v, a_cmd):
        return self._e_v(e, edot, v)[np.newaxis]


# --------------------------------------------------------------------------------------------
# Adaptive sliding mode
# --------------------------------------------------------------------------------------------

class _SMCBase:
    def __init__(self, controller: Controller, drives: tuple[Drive, ...]):
        self.lam, self.ks, self.gamma_d, self.gamma_J, self.gamma_B = _gains(
            controller, "lam", "ks", "gamma_d", "gamma_J", "gamma_B")
        nom = self.nominal = _Nominal(drives)
        lo, hi = SMC_ESTIMATE_RANGE
        self.J_bounds = (lo * nom.J, hi * nom.J)
        self.B_bounds = (lo * nom.B, hi * nom.B)

    def _torque(self, J_hat, B_hat, d_hat, e, edot, v_cmd, a_cmd):
        """Eq. (1)-(3) at the motor; returns (u, S_m, phi_m, v_m)."""
        rg = self.nominal.rg
        S_m = (self.lam * e + edot) / rg
        phi_m = (self.lam * edot + a_cmd) / rg
        v_m = v_cmd / rg
        tau = J_hat * phi_m + B_hat * v_m + d_hat + self.ks * S_m
        return tau / self.nominal.kakt, S_m, phi_m, v_m


class DiscreteSMC(_SMCBase):
    """Discrete adaptive sliding mode, Eq. (1)-(4) of the module docstring.

    e'_k = (e_k - e_{k-1}) / Ts; X'_k and X''_k are hold-interval means of the command
    differences; the estimates are updated by the rectangle rule with the current S before u_k
    is computed (as the PID integral), then projected.
    """

    def __init__(self, controller: Controller, ts: float, drives: tuple[Drive, ...]):
        super().__init__(controller, drives)
        self.ts = ts
        self.reset(None)

    def reset(self, q_cmd: np.ndarray | None) -> None:
        nom = self.nominal
        self.J_hat, self.B_hat = nom.J.copy(), nom.B.copy()
        self.d_hat = np.zeros(_N_AXES)
        self._e_prev = np.zeros(_N_AXES)
        self._k = 0
        self._v = self._a = None
        if q_cmd is not None:
            _, self._v, self._a = command_differences(q_cmd, self.ts)

    def step(self, e: np.ndarray, y: np.ndarray) -> np.ndarray:
        ts, k = self.ts, self._k
        edot = (e - self._e_prev) / ts
        self._e_prev = e
        rg = self.nominal.rg
        S_m = (self.lam * e + edot) / rg
        phi_m = (self.lam * edot + self._a[k]) / rg
        v_m = self._v[k] / rg
        self.d_hat = self.d_hat + ts * self.gamma_d * S_m
        self.J_hat = np.clip(self.J_hat + ts * self.gamma_J * phi_m * S_m, *self.J_bounds)
        self.B_hat = np.clip(self.B_hat + ts * self.gamma_B * v_m * S_m, *self.B_bounds)
        self._k = k + 1
        tau = self.J_hat * phi_m + self.B_hat * v_m + self.d_hat + self.ks * S_m
        return tau / self.nominal.kakt


class ContinuousSMC(_SMCBase):
    """Continuous adaptive sliding mode, Eq. (1)-(4); state (J^ - J, B^ - B, d^)."""

    n_states = 3

    def _estimates(self, s):
        nom = self.nominal
        return (np.clip(nom.J + s[0], *self.J_bounds), np.clip(nom.B + s[1], *self.B_bounds),
                s[2])

    def output(self, s, e, edot, v, a_cmd):
        J_hat, B_hat, d_hat = self._estimates(s)
        return self._torque(J_hat, B_hat, d_hat, e, edot, edot + v, a_cmd)[0]

    def derivative(self, s, e, edot, v, a_cmd):
        _, S_m, phi_m, v_m = self._torque(0.0, 0.0, 0.0, e, edot, edot + v, a_cmd)
        rate_J = self.gamma_J * phi_m * S_m
        rate_B = self.gamma_B * v_m * S_m
        # Projection: an estimate at a bound stops moving outwards.
        nom = self.nominal
        J, B = nom.J + s[0], nom.B + s[1]
        rate_J = np.where(((J <= self.J_bounds[0]) & (rate_J < 0))
                          | ((J >= self.J_bounds[1]) & (rate_J > 0)), 0.0, rate_J)
        rate_B = np.where(((B <= self.B_bounds[0]) & (rate_B < 0))
                          | ((B >= self.B_bounds[1]) & (rate_B > 0)), 0.0, rate_B)
        return np.stack([rate_J, rate_B, self.gamma_d * S_m])


#: Discrete control-law factories by controller type: ``factory(controller, ts, drives)``.
DISCRETE_LAWS: dict[str, Callable[[Controller, float, tuple[Drive, ...]], DiscreteLaw]] = {
    "pid": DiscretePID,
    "p-pi": DiscretePPI,
    "smc": DiscreteSMC,
}

#: Continuous control-law factories by controller type: ``factory(controller, drives)``.
CONTINUOUS_LAWS: dict[str, Callable[[Controller, tuple[Drive, ...]], ContinuousLaw]] = {
    "pid": ContinuousPID,
    "p-pi": ContinuousPPI,
    "smc": ContinuousSMC,
}
