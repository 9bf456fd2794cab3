"""Physical drive parameters from motor currents: inertia, damping, friction per direction.

The least-squares method of Erkorkmaz & Altintas (IJMTM 41 (2001) 1487, the paper's ref. [19]):
the motor's equation of motion J w' + B w + Tf(w) = kt I is integrated over short windows
[t_a, t_b] so that no acceleration (a second difference of the encoder) is needed,

    J (w_b - w_a) + B (theta_b - theta_a) + int Tf(w) dt = kt int I dt,

with theta = x / rg, w from central differences of theta, and the current held over each
sample period (as the amplifier holds the controller's output). Friction has separate terms for
each direction of motion; with the base machine's Stribeck speeds W1, W2 it is linear in
Ts, Tc (spec section 2, paper Eq. 28):

    Tf(w) = Ts exp(-w/W1) + Tc (1 - exp(-w/W2)),  per side,

and without base friction it is Coulomb (Ts = Tc). Only windows in which the speed keeps one
sign and stays above :data:`MIN_SPEED` are used: at rest the friction torque is whatever holds
the axis, not a function of w.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..machine.drives import Drive, Friction

#: Samples per integration window.
WINDOW = 20
#: Motor speed (rad/s) every sample of a window must exceed.
MIN_SPEED = 0.5
#: Fewest windows per direction for that direction's friction terms.
MIN_WINDOWS = 10


@dataclass(frozen=True)
class PhysicalParameters:
    """Identified J (kg m^2), B (kg m^2/s) and friction of one drive, and the fit's quality.

    ``torque_fit_pct``: RMS of the windows' torque-impulse residual in % of their RMS.
    """

    axis: str
    J: float
    B: float
    friction: Friction | None
    windows: int
    torque_fit_pct: float


def identify_physical(drive: Drive, x: np.ndarray, current: np.ndarray, ts: float
                      ) -> PhysicalParameters | None:
    """J, B and friction of ``drive`` from its actual positions and motor currents, or None
    when the log has too few usable windows (e.g. the axis barely moves)."""
    theta = np.asarray(x, float) / drive.rg
    w = np.gradient(theta, ts)
    n_win = (theta.size - 2) // WINDOW
    if n_win < 3:
        return None
    starts = 1 + WINDOW * np.arange(n_win)
    idx = starts[:, None] + np.arange(WINDOW + 1)[None, :]  # window sample indices, inclusive
    ww = w[idx]
    positive = np.all(ww > MIN_SPEED, axis=1)
    negative = np.all(ww < -MIN_SPEED, axis=1)
    usable = positive | negative
    if usable.sum() < 3:
        return None
    idx, ww, positive, negative = idx[usable], ww[usable], positive[usable], negative[usable]
    a, b = idx[:, 0], idx[:, -1]
    csum = np.concatenate([[0.0], np.cumsum(current)])
    impulse = drive.kt * ts * (csum[b] - csum[a])
    base = drive.friction
    cols = [w[b] - w[a], theta[b] - theta[a]]
    names = ["J", "B"]
    sides = {}
    for side, mask in (("pos", positive), ("neg", negative)):
        if mask.sum() < MIN_WINDOWS:
            continue
        if base is not None:
            w1, w2 = getattr(base, f"W1_{side}"), getattr(base, f"W2_{side}")
            phi_s = np.exp(-ww / w1)
            phi_c = 1.0 - np.exp(-ww / w2)
        else:
            w1 = w2 = 1.0 if side == "pos" else -1.0
            phi_s = np.zeros_like(ww)
            phi_c = np.ones_like(ww)
        trap = lambda f: ts * (f.sum(axis=1) - 0.5 * (f[:, 0] + f[:, -1]))  # noqa: E731
        cols += [np.where(mask, trap(phi_s), 0.0), np.where(mask, trap(phi_c), 0.0)]
        names += [f"Ts_{side}", f"Tc_{side}"]
        sides[side] = (w1, w2)
    phi = np.stack(cols, axis=1)
    # Drop all-zero columns (Coulomb-only sides have no Ts column).
    keep = np.any(phi != 0, axis=0)
    if not keep[:2].all():  # no change of speed or no motion: J or B is not in the data
        return None
    norms = np.linalg.norm(phi[:, keep], axis=0)
    sol = np.zeros(phi.shape[1])
    sol[keep] = np.linalg.lstsq(phi[:, keep] / norms, impulse, rcond=None)[0] / norms
    values = dict(zip(names, sol))
    residual = phi @ sol - impulse
    scale = np.mean(impulse**2)
    fit = float(100 * np.sqrt(np.mean(residual**2) / scale)) if scale > 0 else float("inf")
    friction = None
    if sides:
        params = {}
        for side in ("pos", "neg"):
            if side in sides:
                tc = values[f"Tc_{side}"]
                ts_ = values[f"Ts_{side}"] if base is not None else tc
                w1, w2 = sides[side]
            elif base is not None:
                ts_, tc = getattr(base, f"Ts_{side}"), getattr(base, f"Tc_{side}")
                w1, w2 = getattr(base, f"W1_{side}"), getattr(base, f"W2_{side}")
            else:
                ts_ = tc = 0.0
                w1 = w2 = 1.0 if side == "pos" else -1.0
            # The sign convention of the machine file: >= 0 on the positive side, <= 0 below.
            clip = (lambda v: max(v, 0.0)) if side == "pos" else (lambda v: min(v, 0.0))
            params.update({f"Ts_{side}": float(clip(ts_)), f"Tc_{side}": float(clip(tc)),
                           f"W1_{side}": float(w1), f"W2_{side}": float(w2)})
        friction = Friction(**params)
    return PhysicalParameters(axis=drive.axis, J=float(values["J"]), B=float(max(values["B"], 0.0)),
                              friction=friction, windows=int(usable.sum()), torque_fit_pct=fit)
