"""Virtual machine for controllers given as a closed-loop transfer function (type ``tf``).

Such a controller (e.g. identified from a servo log) describes each axis only as x/X, so the
virtual machine runs that linear closed loop on the command; drive friction, feed-forward and
plant scales are part of the identified loop and are not applied again. ``discrete`` mode
runs x/X at the sample period, discretized by Tustin (the inverse of how
:mod:`precontour.identification.tf_fit` obtained the continuous model from the sampled loop, so
an identified model reproduces its log); ``continuous`` mode integrates x/X exactly (first-order
hold, :func:`scipy.signal.cont2discrete`) on 8 ``substeps`` points per period of the quintic
interpolant of the command that the other continuous-time laws follow.
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import make_interp_spline

#: Controller types this module simulates.
CLOSED_LOOP_TYPES: tuple[str, ...] = ("tf",)


def simulate_closed_loop(t: np.ndarray, q: np.ndarray, controller, mode: str, ts: float,
                         substeps: int) -> np.ndarray:
    """Actual positions (N, 5) of the closed loops x/X of ``controller`` driven by ``q``.

    The drives start at rest at q[0]; x - q[0] = (x/X)(X - q[0]).
    """
    from scipy import signal     # here: scipy.signal takes 0.5 s to import

    q0 = q[0]
    if mode == "continuous":
        # lfilter is cheap: 8 first-order-hold points per sub-step bring the hold's error
        # (h^2/8 of the command's curvature) far below the loops' own errors.
        m = 8 * max(int(substeps), 1)
        fine_t = t[0] + ts / m * np.arange(m * (t.size - 1) + 1)
        fine_t[::m] = t
        drive = make_interp_spline(t, q, k=5)(fine_t) - q0
        step, pick = ts / m, slice(None, None, m)
    else:
        drive, step, pick = q - q0, ts, slice(None)
    out = np.empty_like(q)
    for i, axis in enumerate(controller.axes):
        method = "bilinear" if mode == "discrete" else "foh"
        # leading zeros of x/X's numerator (a machine file may write them: its degree is below
        # the denominator's) would make scipy warn of badly conditioned coefficients
        num = np.trim_zeros(np.asarray(axis.num, dtype=float), "f")
        num_d, den_d, _ = signal.cont2discrete((num, np.asarray(axis.den)), step,
                                               method=method)
        out[:, i] = signal.lfilter(np.ravel(num_d), den_d, drive[:, i])[pick]
    return out + q0
