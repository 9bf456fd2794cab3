"""Feed drives: the physical plant of each axis and its closed-loop error model.

A :class:`Drive` holds one axis's amplifier, motor, transmission and friction (spec section 2).
A :class:`LinearErrorModel` is the transfer function from the commanded position X(s) to the
tracking error e(s) = X(s) - x(s) of a drive closed by a linear controller; the closed-form
predictor (:mod:`precontour.prediction.tracking`) consumes it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import UnsupportedControllerError

AXES: tuple[str, ...] = ("X", "Y", "Z", "A", "C")
LINEAR_AXES: tuple[str, ...] = ("X", "Y", "Z")
ROTARY_AXES: tuple[str, ...] = ("A", "C")


@dataclass(frozen=True)
class TrackingSummary:
    """The largest tracking error of each axis, in um (slots 0-2, linear) and urad (slots
    3-4, rotary): what ``predict`` and ``simulate`` results' ``summary()`` give.

    Attributes
    ----------
    axis_names : tuple of str
        The machine's letters of the five slots.
    max_abs : tuple of float
        max |e| of each axis, um or urad.
    """

    axis_names: tuple[str, ...]
    max_abs: tuple[float, ...]

    @classmethod
    def of(cls, e: np.ndarray, axis_names=AXES) -> "TrackingSummary":
        """The summary of tracking errors ``e`` (N, 5), mm and rad."""
        peak = np.abs(np.asarray(e, dtype=float)).max(axis=0) * 1e3
        peak[3:] *= 1e3
        return cls(axis_names=tuple(axis_names), max_abs=tuple(float(v) for v in peak))

    def units(self) -> tuple[str, ...]:
        return ("um",) * 3 + ("urad",) * (len(self.max_abs) - 3)

    def __getitem__(self, axis: str) -> float:
        """max |e| of the axis named ``axis`` (its unit: :meth:`units`)."""
        return self.max_abs[self.axis_names.index(axis)]

    def format(self) -> str:
        return ", ".join(f"{name} {value:.4g} {unit}" for name, value, unit
                         in zip(self.axis_names, self.max_abs, self.units()))


@dataclass(frozen=True)
class Friction:
    """Stribeck-type friction torque at the motor, spec section 2 (paper Eq. 28, Table 2).

    ``*_pos`` parameters apply for w > 0 and ``*_neg`` for w < 0 (the negative-side speeds
    ``W1_neg``, ``W2_neg`` are negative, as in the paper, so the exponentials decay).
    Torques in N m, speeds in rad/s at the motor.
    """

    Ts_pos: float
    W1_pos: float
    Tc_pos: float
    W2_pos: float
    Ts_neg: float
    W1_neg: float
    Tc_neg: float
    W2_neg: float

    def torque(self, w: np.ndarray) -> np.ndarray:
        """Friction torque Tf(w) in N m for motor speed(s) ``w`` in rad/s; Tf(0) = 0."""
        w = np.asarray(w, dtype=float)
        # Each side's formula is evaluated on its own side only; the other side would overflow.
        w_pos = np.maximum(w, 0.0)
        w_neg = np.minimum(w, 0.0)
        pos = self.Ts_pos * np.exp(-w_pos / self.W1_pos) + self.Tc_pos * (1.0 - np.exp(-w_pos / self.W2_pos))
        neg = self.Ts_neg * np.exp(-w_neg / self.W1_neg) + self.Tc_neg * (1.0 - np.exp(-w_neg / self.W2_neg))
        return np.where(w > 0, pos, np.where(w < 0, neg, 0.0))


@dataclass(frozen=True)
class Drive:
    """One feed drive (spec section 2).

    Attributes
    ----------
    axis : str
        Axis name, one of ``X Y Z A C`` (``B`` in slot 3 on a B-C machine).
    ka : float
        Current amplifier gain, A/V.
    kt : float
        Motor torque constant, N m/A.
    rg : float
        Transmission: mm/rad (ball screw) or rad/rad (rotary gear).
    J : float
        Inertia at the motor, kg m^2.
    B : float
        Viscous damping at the motor, kg m^2/s.
    friction : Friction or None
        Nonlinear friction, used only by the time-domain simulator.
    v_max, a_max, j_max : float or None
        Axis velocity, acceleration and jerk limits (mm or rad, per s, s^2, s^3) for
        trajectory generation.
    p_min, p_max : float or None
        Axis travel (position limits, mm or rad); on the tilt axis (slot 3) also the range
        inverse kinematics chooses the tilt sign within.
    """

    axis: str
    ka: float
    kt: float
    rg: float
    J: float
    B: float
    friction: Friction | None = None
    v_max: float | None = None
    a_max: float | None = None
    j_max: float | None = None
    p_min: float | None = None
    p_max: float | None = None

    @property
    def gain(self) -> float:
        """K = ka kt rg, the drive's gain from controller volts to position-scaled torque."""
        return self.ka * self.kt * self.rg

    @property
    def is_rotary(self) -> bool:
        return self.axis not in LINEAR_AXES


@dataclass(frozen=True)
class LinearErrorModel:
    """Transfer function e(s)/X(s) = num(s)/den(s) of one closed-loop axis.

    Coefficients are highest power first (``numpy.polyval`` order); ``deg num <= deg den``.
    The closed loop must be stable (all poles in the open left half plane).
    """

    num: np.ndarray
    den: np.ndarray
    axis: str = ""

    def __post_init__(self):
        num = np.atleast_1d(np.asarray(self.num, dtype=float))
        den = np.atleast_1d(np.asarray(self.den, dtype=float))
        num = np.trim_zeros(num, "f")
        den = np.trim_zeros(den, "f")
        if den.size < 2:
            raise ValueError("error model denominator must have degree >= 1")
        if num.size == 0:
            num = np.zeros(1)
        if num.size > den.size:
            raise ValueError("error model must be proper: deg num <= deg den")
        object.__setattr__(self, "num", num)
        object.__setattr__(self, "den", den)

    @property
    def order(self) -> int:
        return self.den.size - 1

    @property
    def poles(self) -> np.ndarray:
        return np.roots(self.den)

    @property
    def dc_gain(self) -> float:
        return float(self.num[-1] / self.den[-1]) if self.den[-1] != 0 else np.inf

    def check_stable(self) -> None:
        poles = self.poles
        if np.any(poles.real >= 0):
            worst = poles[np.argmax(poles.real)]
            raise UnsupportedControllerError(
                f"axis {self.axis or '?'}: closed loop is not stable (pole at {worst:.6g} rad/s)")


def pid_error_model(drive: Drive, kp: float, ki: float, kd: float, *, kvff: float = 0.0,
                    kaff: float = 0.0) -> LinearErrorModel:
    """Error transfer function of a PID position loop around ``drive`` (spec section 2).

    With the optional feed-forward u_ff = kvff (B/K) X' + kaff (J/K) X'' (fractions of the
    nominal model's damping and inertia torques, see :class:`~precontour.machine.controllers.PIDGains`):

        e(s)/X(s) = (J (1 - kaff) s^3 + B (1 - kvff) s^2)
                    / (J s^3 + (B + K kd) s^2 + K kp s + K ki),   K = ka kt rg.
    """
    K = drive.gain
    J, B = drive.J, drive.B
    return LinearErrorModel(num=np.array([J * (1.0 - kaff), B * (1.0 - kvff), 0.0, 0.0]),
                            den=np.array([J, B + K * kd, K * kp, K * ki]), axis=drive.axis)


def p_pi_error_model(drive: Drive, kp: float, kv: float, ki_v: float, *, kvff: float = 0.0,
                     kaff: float = 0.0) -> LinearErrorModel:
    """Error transfer function of a cascaded P position / PI velocity loop around ``drive``.

    Velocity reference v_ref = kp e + kvff X', velocity error e_v = v_ref - x' (x' the measured
    velocity), u = kv e_v + ki_v int(e_v) + kaff (J/K) X''. With J x'' + B x' = K u:

        e(s)/X(s) = s (J (1 - kaff) s^2 + (B + K kv (1 - kvff)) s + K ki_v (1 - kvff))
                    / (J s^3 + (B + K kv) s^2 + K (kv kp + ki_v) s + K ki_v kp).
    """
    K = drive.gain
    J, B = drive.J, drive.B
    r = 1.0 - kvff
    return LinearErrorModel(num=np.array([J * (1.0 - kaff), B + K * kv * r, K * ki_v * r, 0.0]),
                            den=np.array([J, B + K * kv, K * (kv * kp + ki_v), K * ki_v * kp]),
                            axis=drive.axis)
