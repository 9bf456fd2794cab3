"""Axis controllers named in a machine file, their linear closed-loop error models, and design.

A :class:`Controller` is a named set of five per-axis controllers of one ``type``. Each
controller type registers a parser in :data:`CONTROLLER_TYPES`; linear types (``pid``,
``p-pi``, and ``tf``, a closed loop given as its transfer function) also give a
:class:`~precontour.machine.drives.LinearErrorModel` per axis for the closed-form
predictor, while the nonlinear sliding-mode controller (``smc``) is only simulated
(:mod:`precontour.simulation.control_laws`). :func:`design_p_pi` and :func:`design_smc` reproduce the
gains shipped with the built-in machine.

Machine-file keys and units (per axis, named as the machine's axes: X Y Z A C, or X Y Z B C on a
B-C machine; "mm" reads "rad" on the rotary axes):

====== ======= =================================================================
type   key     meaning, unit
====== ======= =================================================================
pid    kp      proportional gain, V/mm
pid    ki      integral gain, V/(mm s)
pid    kd      derivative gain, V/(mm/s)
pid    kvff    velocity feed-forward, fraction of the nominal damping torque B X'
               (0..1, default 0)
pid    kaff    acceleration feed-forward, fraction of the nominal inertia torque
               J X'' (0..1, default 0)
p-pi   kp      position-loop gain, 1/s (velocity reference per position error)
p-pi   kv      velocity-loop proportional gain, V/(mm/s)
p-pi   ki_v    velocity-loop integral gain, V/mm (V/(mm/s) per s)
p-pi   kvff    velocity feed-forward into the velocity reference, fraction of X'
               (0..1, default 0)
p-pi   kaff    acceleration feed-forward, fraction of the nominal inertia torque
               J X'' (0..1, default 0)
smc    lambda  sliding-surface slope, 1/s
smc    ks      feedback gain on the sliding variable, N m s/rad (motor side)
smc    gamma_d adaptation rate rho of the disturbance torque estimate, N m/rad
smc    gamma_J adaptation rate of the inertia estimate, kg m^2 s^2/rad^2 (default 0,
               as published)
smc    gamma_B adaptation rate of the damping estimate, kg m^2 s/rad^2 (default 0,
               as published)
tf     num     closed-loop x/X numerator in s, highest power first (list)
tf     den     closed-loop x/X denominator in s, highest power first (list); the
               model must be proper and stable (identified by ``precontour identify``)
tf     base    optional, at the controller's level: the name of the controller of the
               same machine file that the drives run (the one the loop was identified
               with; not itself a ``tf``), for what needs drives and friction: learning
               against the virtual machine (``precontour compensate --learn``); written by
               ``precontour identify`` when the log's currents gave every drive's J, B
               and friction
====== ======= =================================================================
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
from scipy import optimize

from ._config import ConfigTable
from .drives import AXES, Drive, LinearErrorModel, p_pi_error_model, pid_error_model
from ..errors import UnsupportedControllerError

#: Relative tolerance to which :func:`design_p_pi` and :func:`design_smc` hit their bandwidth.
DESIGN_RTOL = 1e-6


def _feedforward(table: ConfigTable) -> dict[str, float]:
    return dict(kvff=table.get_float("kvff", 0.0, minval=0.0, maxval=1.0),
                kaff=table.get_float("kaff", 0.0, minval=0.0, maxval=1.0))


@dataclass(frozen=True)
class PIDGains:
    """PID position controller of one axis with optional model-based feed-forward.

    u = kp e + ki int(e) + kd e' + (kvff B X' + kaff J X'') / K  (volts), K = ka kt rg, with
    the drive's nominal J and B: kvff = kaff = 1 cancel the model's damping and inertia
    torques. Gains per mm (linear axes) or per rad (rotary axes), as in the paper's Table 1.
    """

    kp: float
    ki: float
    kd: float
    kvff: float = 0.0
    kaff: float = 0.0

    def error_model(self, drive: Drive) -> LinearErrorModel:
        return pid_error_model(drive, self.kp, self.ki, self.kd, kvff=self.kvff,
                               kaff=self.kaff)

    @classmethod
    def from_table(cls, table: ConfigTable) -> "PIDGains":
        gains = cls(kp=table.get_float("kp", above=0.0),
                    ki=table.get_float("ki", minval=0.0),
                    kd=table.get_float("kd", minval=0.0),
                    **_feedforward(table))
        table.finish()
        return gains


@dataclass(frozen=True)
class PPIGains:
    """Cascaded P position loop around a PI velocity loop, one axis.

    v_ref = kp e + kvff X'  (mm/s),  e_v = v_ref - x'  (x' from the encoder),
    u = kv e_v + ki_v int(e_v) + kaff J X'' / K  (volts).

    Attributes
    ----------
    kp : float
        Position-loop gain, 1/s.
    kv : float
        Velocity-loop proportional gain, V/(mm/s) or V/(rad/s).
    ki_v : float
        Velocity-loop integral gain, V/mm or V/rad.
    kvff, kaff : float
        Velocity and acceleration feed-forward fractions, 0..1.
    """

    kp: float
    kv: float
    ki_v: float
    kvff: float = 0.0
    kaff: float = 0.0

    def error_model(self, drive: Drive) -> LinearErrorModel:
        return p_pi_error_model(drive, self.kp, self.kv, self.ki_v, kvff=self.kvff,
                                kaff=self.kaff)

    @classmethod
    def from_table(cls, table: ConfigTable) -> "PPIGains":
        gains = cls(kp=table.get_float("kp", above=0.0),
                    kv=table.get_float("kv", above=0.0),
                    ki_v=table.get_float("ki_v", minval=0.0),
                    **_feedforward(table))
        table.finish()
        return gains


@dataclass(frozen=True)
class SMCGains:
    """Sliding-mode controller of one axis as published (Altintas, Erkorkmaz & Zhu 2000).

    The law (motor side; derivation in :mod:`precontour.simulation.control_laws`) is
    u = [J^ (lambda e' + X'') + B^ x' + d^ + ks S] / (ka kt rg) with S = lambda e + e', the
    measured velocity x' and d^ = rho int S dt (rho = ``gamma_d``); J^, B^ are the nominal J, B
    unless the optional rates ``gamma_J``, ``gamma_B`` adapt them. With frozen estimates the
    closed loop's characteristic polynomial is (s + lambda)(J s^2 + ks s + rho). Nonlinear
    (the adaptation, and friction compensation through d^): it has no ``error_model``, so the
    closed-form predictor refuses it.

    Attributes
    ----------
    lam : float
        Sliding-surface slope lambda, 1/s (machine-file key ``lambda``).
    ks : float
        Feedback gain on S, N m s/rad at the motor.
    gamma_d : float
        Disturbance adaptation rate rho, N m/rad: d^' = rho S / rg.
    gamma_J, gamma_B : float
        Optional inertia and damping adaptation rates, kg m^2 s^2/rad^2 and kg m^2 s/rad^2
        (0: the published law).
    """

    lam: float
    ks: float
    gamma_d: float
    gamma_J: float = 0.0
    gamma_B: float = 0.0

    def characteristic_polynomial(self, drive: Drive) -> np.ndarray:
        """Frozen-estimate closed loop, highest power first: (s + lambda)(J s^2 + ks s + rho)
        = J s^3 + (J lambda + ks) s^2 + (ks lambda + rho) s + rho lambda."""
        J, lam, ks, rho = drive.J, self.lam, self.ks, self.gamma_d
        return np.array([J, J * lam + ks, ks * lam + rho, rho * lam])

    def feedback_error_model(self, drive: Drive) -> LinearErrorModel:
        """e(s)/X(s) of the feedback part alone (estimates frozen at J, B; the acceleration
        feed-forward J X'' removed): J s^3 / ((s + lambda)(J s^2 + ks s + rho)).

        The measured-velocity term B x' cancels the plant's damping, so B drops out. Its -3 dB
        bandwidth is what :func:`design_smc` sets. With the feed-forward the nominal linear
        loop tracks exactly (e = 0): this model describes how fast the loop rejects
        disturbances and model errors.
        """
        return LinearErrorModel(num=np.array([drive.J, 0.0, 0.0, 0.0]),
                                den=self.characteristic_polynomial(drive), axis=drive.axis)

    @classmethod
    def from_table(cls, table: ConfigTable) -> "SMCGains":
        gains = cls(lam=table.get_float("lambda", above=0.0),
                    ks=table.get_float("ks", above=0.0),
                    gamma_d=table.get_float("gamma_d", minval=0.0),
                    gamma_J=table.get_float("gamma_J", 0.0, minval=0.0),
                    gamma_B=table.get_float("gamma_B", 0.0, minval=0.0))
        table.finish()
        return gains


@dataclass(frozen=True)
class TransferFunction:
    """A closed loop given directly as its transfer function x(s)/X(s) = num(s)/den(s).

    Continuous time, coefficients highest power first; proper (deg num <= deg den) and stable.
    This is what identification from a servo log gives (:mod:`precontour.identification`): the
    loop as a whole, whatever the controller inside. The error model is e/X = 1 - x/X.
    """

    num: tuple
    den: tuple

    def error_model(self, drive: Drive) -> LinearErrorModel:
        num, den = np.asarray(self.num, float), np.asarray(self.den, float)
        return LinearErrorModel(num=np.polysub(den, num), den=den, axis=drive.axis)

    @classmethod
    def from_table(cls, table: ConfigTable) -> "TransferFunction":
        num = np.trim_zeros(np.array(table.get_float_list("num")), "f")
        den = np.trim_zeros(np.array(table.get_float_list("den", min_length=2)), "f")
        if den.size < 2:
            raise table.error("den", "must have degree >= 1 (a nonzero leading coefficient)")
        if num.size > den.size:
            raise table.error("num", f"degree {num.size - 1} exceeds the denominator's "
                                     f"{den.size - 1}: the model must be proper")
        poles = np.roots(den)
        if np.any(poles.real >= 0):
            worst = poles[np.argmax(poles.real)]
            raise table.error("den", f"the closed loop is not stable (pole at {worst:.6g} rad/s)")
        table.finish()
        return cls(num=tuple(num.tolist()), den=tuple(den.tolist()))


@dataclass(frozen=True)
class Controller:
    """A named controller set: one per-axis controller for each of X, Y, Z, A, C."""

    name: str
    type: str
    axes: tuple
    source: str = field(default="", compare=False)  # for messages; not part of the law
    #: A closed loop's (``tf``) controller with drives, from the machine file's ``base`` key.
    base: str | None = None

    @property
    def is_linear(self) -> bool:
        return all(hasattr(axis, "error_model") for axis in self.axes)

    def error_models(self, drives: tuple[Drive, ...]) -> tuple[LinearErrorModel, ...]:
        """Closed-loop error transfer functions of the five axes (stable, else an error)."""
        if not self.is_linear:
            linear = ", ".join(k for k, v in CONTROLLER_TYPES.items() if v.linear)
            where = f"{self.source}: " if self.source else ""
            raise UnsupportedControllerError(
                f"{where}controller {self.name!r} (type {self.type!r}) is nonlinear; the "
                f"closed-form predictor needs a linear controller (type {linear}); simulate this one with "
                "precontour.simulation.virtual_machine.simulate instead")
        models = tuple(ctrl.error_model(drive) for ctrl, drive in zip(self.axes, drives))
        for model in models:
            try:
                model.check_stable()
            except UnsupportedControllerError as exc:
                where = f"{self.source}: " if self.source else ""
                raise UnsupportedControllerError(
                    f"{where}[controllers.{self.name}] {exc}: check its gains") from None
        return models


class _PerAxisParser:
    """Parser of a ``[controllers.<name>]`` table with one gains table per axis."""

    def __init__(self, gains_cls):
        self.gains_cls = gains_cls
        self.linear = hasattr(gains_cls, "error_model")

    def __call__(self, name: str, table: ConfigTable,
                 axis_names: tuple[str, ...] = AXES) -> Controller:
        kind = table.get_str("type")
        axes = tuple(self.gains_cls.from_table(table.get_table(axis)) for axis in axis_names)
        table.finish()
        return Controller(name=name, type=kind, axes=axes, source=table.source)


class _ClosedLoopParser(_PerAxisParser):
    """Parser of a closed loop given per axis as a whole (``tf``), with the optional ``base``:
    the machine file's controller that the drives run, checked by
    :func:`check_closed_loop_bases` once all controllers are read."""

    closed_loop = True

    def __call__(self, name: str, table: ConfigTable,
                 axis_names: tuple[str, ...] = AXES) -> Controller:
        base = table.get_str("base") if table.has("base") else None
        controller = super().__call__(name, table, axis_names)
        return dataclasses.replace(controller, base=base)


CONTROLLER_TYPES: dict[str, Callable[..., Controller]] = {
    "pid": _PerAxisParser(PIDGains),
    "p-pi": _PerAxisParser(PPIGains),
    "smc": _PerAxisParser(SMCGains),
    "tf": _ClosedLoopParser(TransferFunction),
}


def is_closed_loop(controller: Controller) -> bool:
    """Whether ``controller`` gives the loops as a whole (``tf``): no drives or friction in it."""
    return getattr(CONTROLLER_TYPES.get(controller.type), "closed_loop", False)


def check_closed_loop_bases(controllers: dict, error) -> None:
    """Every ``base`` names another controller of the machine that has drives (not a closed
    loop); ``error(name, message)`` makes the exception for controller ``name``."""
    for name, controller in controllers.items():
        if controller.base is None:
            continue
        target = controllers.get(controller.base)
        if target is None:
            raise error(name, f"base: no controller {controller.base!r} in this machine file "
                              f"(it has {', '.join(controllers)})")
        if is_closed_loop(target):
            raise error(name, f"base: controller {controller.base!r} is itself of type "
                              f"{target.type!r}; name one the drives run (pid, p-pi, smc)")


# --------------------------------------------------------------------------------------------
# Bandwidth and design
# --------------------------------------------------------------------------------------------

def closed_loop_bandwidth(model: LinearErrorModel) -> float:
    """-3 dB bandwidth of x/X = 1 - e/X in Hz: the lowest frequency where |x/X| < 1/sqrt(2).

    Raises :class:`~precontour.errors.UnsupportedControllerError` if |x/X| never falls below
    -3 dB up to 1e6 rad/s.
    """
    num = np.polysub(model.den, model.num)

    def excess(w):
        # scipy.signal.freqs's own evaluation (importing scipy.signal costs 0.5 s at start-up)
        s = 1j * np.atleast_1d(w)
        return np.abs(np.polyval(num, s) / np.polyval(model.den, s)) - 2 ** -0.5

    grid = np.logspace(-1, 6, 1401)
    below = np.flatnonzero(excess(grid) < 0)
    if below.size == 0:
        raise UnsupportedControllerError(
            f"axis {model.axis or '?'}: |x/X| stays above -3 dB up to 1e6 rad/s")
    i = below[0]
    if i == 0:
        return float(grid[0] / (2 * np.pi))
    w3 = optimize.brentq(lambda w: excess(w)[0], grid[i - 1], grid[i], xtol=1e-12, rtol=1e-12)
    return float(w3 / (2 * np.pi))


def design_p_pi(drive: Drive, bandwidth_hz: float, *, velocity_ratio: float = 2.0,
                pi_zero_ratio: float = 0.25) -> PPIGains:
    """P-PI gains with a -3 dB bandwidth of x/X equal to ``bandwidth_hz`` (no feed-forward).

    Design rule:

    1. velocity loop at ``velocity_ratio`` times the target: w_v = velocity_ratio 2 pi f,
       kv = (J w_v - B) / K, so that the proportional velocity loop's pole
       (B + K kv) / J sits at w_v;
    2. PI zero at ``pi_zero_ratio`` w_v: ki_v = pi_zero_ratio w_v kv;
    3. kp (1/s) by root finding so that the closed loop's -3 dB bandwidth is the target.

    The default ratio 2 (rather than the textbook 4-5) is what sampling at 1 kHz allows: with
    the encoder velocity by backward difference and the zero-order hold, the sampled loop at
    the paper's 55.8 Hz has a smallest damping ratio of 0.28 with ratio 2, 0.03 with ratio 3,
    and is unstable with ratio 4 (velocity loop near 1400 rad/s).

    Parameters
    ----------
    drive : Drive
    bandwidth_hz : float
        Target -3 dB bandwidth of x/X, Hz.
    velocity_ratio, pi_zero_ratio : float
        See the rule above.
    """
    K = drive.gain
    w_v = velocity_ratio * 2 * np.pi * bandwidth_hz
    kv = (drive.J * w_v - drive.B) / K
    ki_v = pi_zero_ratio * w_v * kv

    def miss(log_kp):
        model = p_pi_error_model(drive, np.exp(log_kp), kv, ki_v)
        return closed_loop_bandwidth(model) / bandwidth_hz - 1.0

    w_b = 2 * np.pi * bandwidth_hz
    log_kp = optimize.brentq(miss, np.log(w_b / 20), np.log(w_b * 2), xtol=DESIGN_RTOL / 10)
    gains = PPIGains(kp=float(np.exp(log_kp)), kv=float(kv), ki_v=float(ki_v))
    gains.error_model(drive).check_stable()
    return gains


def smc_triple_pole_gains(drive: Drive, pole: float) -> tuple[float, float, float]:
    """(lambda, ks, rho) placing the frozen-estimate loop's poles at -pole (x3).

    (s + lambda)(J s^2 + ks s + rho) = J (s + p)^3 gives lambda = p, ks = 2 J p, rho = J p^2.
    """
    J = drive.J
    return float(pole), float(2 * J * pole), float(J * pole**2)


def design_smc(drive: Drive, bandwidth_hz: float, *, gamma_J: float = 0.0,
               gamma_B: float = 0.0) -> SMCGains:
    """Sliding-mode gains whose feedback loop has a -3 dB bandwidth of ``bandwidth_hz``.

    Design rule: put the three poles of the frozen-estimate loop (s + lambda)(J s^2 + ks s +
    rho) at one real pole -p (:func:`smc_triple_pole_gains`), and find p by root finding so
    that the -3 dB bandwidth of x/X = 1 - e/X of :meth:`SMCGains.feedback_error_model` is the
    target (about 3.9 p). Sampled at 1 kHz with the zero-order hold and backward-difference
    derivatives the loop keeps a smallest damping ratio of 0.96 for bandwidths up to 60 Hz
    (0.58 at 117 Hz, unstable near 300 Hz); the bandwidth shipped for ``smc`` is set by the
    chatter measurement in the machine file. The optional adaptation rates of J^ and B^ are
    passed through.
    """
    def gains_for(log_p):
        lam, ks, rho = smc_triple_pole_gains(drive, float(np.exp(log_p)))
        return SMCGains(lam=lam, ks=ks, gamma_d=rho, gamma_J=gamma_J, gamma_B=gamma_B)

    def miss(log_p):
        model = gains_for(log_p).feedback_error_model(drive)
        return closed_loop_bandwidth(model) / bandwidth_hz - 1.0

    w_b = 2 * np.pi * bandwidth_hz
    log_p = optimize.brentq(miss, np.log(w_b / 10), np.log(w_b * 10), xtol=DESIGN_RTOL / 10)
    return gains_for(log_p)
