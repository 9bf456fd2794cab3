"""Minimum-jerk C3 quintic spline fit of sampled axis commands (spec section 3, paper App. A).

:func:`fit_min_jerk` fits one axis: a piecewise quintic through a subset of the samples (the
knots), C3 at the joints, at rest (zero velocity, acceleration and jerk) at both ends, and of
minimum integrated squared jerk. Knots are added where the samples stray from the spline by
more than a tolerance (an encoder resolution), one per out-of-tolerance stretch per round. The
result is a :class:`scipy.interpolate.PPoly`.

Each solve is one banded KKT system (bandwidth 5) in the knot velocities and accelerations and
one multiplier per knot for jerk continuity, so a fit costs O(samples) per round.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import PPoly
from scipy.linalg import solve_banded

from ..machine.drives import AXES, ROTARY_AXES
from ..errors import InputError

#: Default fit tolerances: 1 um for linear axes (mm), 1 urad for rotary axes (rad).
DEFAULT_TOL_LINEAR = 1e-3
DEFAULT_TOL_ROTARY = 1e-6
#: Samples per segment of the first fit (spec section 3: n = floor(Ns / 50)).
INITIAL_SAMPLES_PER_SEGMENT = 50
#: A C3 quintic at rest at both ends needs three segments (4 knots) to interpolate freely.
MIN_SAMPLES = 4

# Quintic Hermite basis on tau in [0, 1] for c = [p0, h v0, h^2 a0, p1, h v1, h^2 a1]:
# monomial coefficients (rows: powers 0..5; columns: basis functions).
_HERMITE_MONOMIAL = np.array([
    [1.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [0.0, 1.0, 0.0, 0.0, 0.0, 0.0],
    [0.0, 0.0, 0.5, 0.0, 0.0, 0.0],
    [-10.0, -6.0, -1.5, 10.0, -4.0, 0.5],
    [15.0, 8.0, 1.5, -15.0, 7.0, -1.0],
    [-6.0, -3.0, -0.5, 6.0, -3.0, 0.5],
])
# Gram matrix of the basis' third derivatives: int_0^1 S'''(tau)^2 dtau = c^T G c. It is the
# spec's jerk integral (section 3) written in Hermite coordinates.
_JERK_GRAM = np.array([
    [720.0, 360.0, 60.0, -720.0, 360.0, -60.0],
    [360.0, 192.0, 36.0, -360.0, 168.0, -24.0],
    [60.0, 36.0, 9.0, -60.0, 24.0, -3.0],
    [-720.0, -360.0, -60.0, 720.0, -360.0, 60.0],
    [360.0, 168.0, 24.0, -360.0, 192.0, -36.0],
    [-60.0, -24.0, -3.0, 60.0, -36.0, 9.0],
])
# Third derivative of the basis at tau = 0 and tau = 1.
_JERK_START = np.array([-60.0, -36.0, -9.0, 60.0, -24.0, 3.0])
_JERK_END = np.array([-60.0, -24.0, -3.0, 60.0, -36.0, 9.0])
_P = np.array([0, 3])        # positions of the fixed knot values in c
_Y = np.array([1, 2, 4, 5])  # positions of the unknown velocities / accelerations in c
_BAND = 5                    # half bandwidth of the KKT matrix with 3 unknowns per knot


@dataclass(frozen=True)
class SplineFit:
    """Result of :func:`fit_min_jerk`.

    Attributes
    ----------
    spline : scipy.interpolate.PPoly
        The C3 quintic, ``spline(t, nu)``; breakpoints are the knot times.
    knot_index : ndarray of int
        Indices of the samples used as knots (first and last sample included).
    max_deviation : float
        max |spline(t_k) - x_k| over all samples.
    tolerance : float
        The tolerance the fit was asked to meet.
    rounds : int
        Number of solves (knot-insertion rounds + 1).
    """

    spline: PPoly
    knot_index: np.ndarray
    max_deviation: float
    tolerance: float
    rounds: int

    @property
    def n_knots(self) -> int:
        return int(self.knot_index.size)

    def __call__(self, t, nu: int = 0):
        return self.spline(t, nu)


def fit_min_jerk(t: np.ndarray, x: np.ndarray, tol: float, *, max_rounds: int = 500,
                 name: str = "x") -> SplineFit:
    """Fit a minimum-jerk C3 quintic spline to samples ``x(t)`` within ``tol``.

    Parameters
    ----------
    t : ndarray, shape (N,)
        Strictly increasing sample times, s.
    x : ndarray, shape (N,)
        Samples (mm or rad). The spline starts and ends at rest at ``x[0]`` and ``x[-1]``.
    tol : float
        Largest allowed |spline(t_k) - x_k|, same unit as ``x``.
    max_rounds : int
        Safety bound on knot-insertion rounds.
    name : str
        Axis name for messages.

    Returns
    -------
    SplineFit
    """
    t = np.asarray(t, dtype=float)
    x = np.asarray(x, dtype=float)
    if t.ndim != 1 or x.shape != t.shape:
        raise ValueError(f"{name}: t and x must be 1-D of equal length, got {t.shape}, {x.shape}")
    if t.size < MIN_SAMPLES:
        raise InputError(f"too few samples for a spline fit: {t.size}, need at least "
                         f"{MIN_SAMPLES}", field=name)
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(x))):
        raise InputError("samples must be finite", field=name)
    if not np.all(np.diff(t) > 0):
        raise InputError("time must be strictly increasing", field=name)
    if not tol > 0:
        raise ValueError(f"{name}: tolerance must be > 0, got {tol!r}")

    n_samples = t.size
    n_segments = max(3, (n_samples - 1) // INITIAL_SAMPLES_PER_SEGMENT)
    knots = np.unique(np.round(np.linspace(0, n_samples - 1, n_segments + 1)).astype(np.intp))
    for rounds in range(1, max_rounds + 1):
        coef = _solve_min_jerk(t[knots], x[knots])
        deviation = _evaluate_at_samples(coef, t, knots) - x
        outside = np.abs(deviation) > tol
        if not outside.any():
            break
        new = np.union1d(knots, _worst_of_each_stretch(np.abs(deviation), outside))
        if new.size == knots.size:
            # the worst samples are knots already: what is left is round-off of the values
            worst = int(np.argmax(np.abs(deviation)))
            raise InputError(
                f"the spline fit cannot get within the tolerance {tol:.3g}: "
                f"{float(np.abs(deviation[worst])):.3g} remains at sample {worst + 1}, a knot "
                f"already (round-off of values up to {float(np.abs(x).max()):.3g}); use a "
                "larger tolerance", field=name)
        knots = new
    else:
        raise InputError(f"the spline fit did not get within the tolerance {tol:.3g} in "
                         f"{max_rounds} rounds; use a larger tolerance", field=name)
    spline = _to_ppoly(coef, t[knots])
    return SplineFit(spline=spline, knot_index=knots,
                     max_deviation=float(np.abs(deviation).max()), tolerance=float(tol),
                     rounds=rounds)


@dataclass(frozen=True)
class AxisFits:
    """Spline fits of the five axes of a trajectory, in axis order X, Y, Z, A, C."""

    fits: tuple[SplineFit, ...]

    def __iter__(self):
        return iter(self.fits)

    def __getitem__(self, index):
        if isinstance(index, str):
            index = AXES.index(index)
        return self.fits[index]

    @property
    def n_knots(self) -> tuple[int, ...]:
        return tuple(fit.n_knots for fit in self.fits)

    def __call__(self, t, nu: int = 0) -> np.ndarray:
        """Evaluate all five splines: returns shape ``t.shape + (5,)``."""
        return np.stack([fit.spline(t, nu) for fit in self.fits], axis=-1)


def fit_axes(t: np.ndarray, q: np.ndarray, *, tol_linear: float = DEFAULT_TOL_LINEAR,
             tol_rotary: float = DEFAULT_TOL_ROTARY) -> AxisFits:
    """Fit each of the five axis commands ``q[:, i]`` with :func:`fit_min_jerk`."""
    q = np.asarray(q, dtype=float)
    fits = tuple(
        fit_min_jerk(t, q[:, i], tol_rotary if axis in ROTARY_AXES else tol_linear, name=axis)
        for i, axis in enumerate(AXES))
    return AxisFits(fits)


def _solve_min_jerk(t_knots: np.ndarray, x_knots: np.ndarray) -> np.ndarray:
    """Hermite coordinates ``c`` (shape (n, 6)) of the minimum-jerk C3 quintic through the
    knots, at rest at both ends (spec section 3).

    Unknowns per knot k: velocity, acceleration (scaled time) and the multiplier of the jerk
    continuity condition at k (the end conditions jerk = 0 at knots 0 and n).
    """
    n = t_knots.size - 1
    time_scale = (t_knots[-1] - t_knots[0]) / n  # keeps the scaled segment lengths near 1
    h = np.diff(t_knots) / time_scale
    size = 3 * (n + 1)
    ab = np.zeros((2 * _BAND + 1, size))
    rhs = np.zeros(size)

    # Cost sum_i c_i^T G c_i / h_i^5 with c_i = E_p p_i + diag(s_i) y_i, s_i = (h, h^2, h, h^2).
    s = np.stack([h, h * h, h, h * h], axis=1)                      # (n, 4)
    inv_h5 = h ** -5
    p = np.stack([x_knots[:-1], x_knots[1:]], axis=1)              # (n, 2)
    hess = _JERK_GRAM[np.ix_(_Y, _Y)][None] * s[:, :, None] * s[:, None, :] * inv_h5[:, None, None]
    grad = (p @ _JERK_GRAM[np.ix_(_P, _Y)]) * s * inv_h5[:, None]   # (n, 4)
    base = 3 * np.arange(n)
    var = np.stack([base, base + 1, base + 3, base + 4], axis=1)    # (n, 4) unknown indices
    rows = np.broadcast_to(var[:, :, None], hess.shape)
    cols = np.broadcast_to(var[:, None, :], hess.shape)
    np.add.at(ab, (_BAND + rows - cols, cols), hess)
    np.add.at(rhs, var, -grad)

    # Jerk continuity: segment i adds +jerk(end) to the row of knot i+1 and -jerk(start) to
    # the row of knot i; knots 0 and n get only one term, which makes them "jerk = 0".
    inv_h3 = h ** -3
    end_y = _JERK_END[_Y][None] * s * inv_h3[:, None]
    start_y = _JERK_START[_Y][None] * s * inv_h3[:, None]
    end_p = (p @ _JERK_END[_P]) * inv_h3
    start_p = (p @ _JERK_START[_P]) * inv_h3
    mult_next = (base + 5)[:, None]
    mult_this = (base + 2)[:, None]
    for mult, coef_y, sign in ((mult_next, end_y, 1.0), (mult_this, start_y, -1.0)):
        row = np.broadcast_to(mult, var.shape)
        np.add.at(ab, (_BAND + row - var, var), sign * coef_y)  # constraint rows
        np.add.at(ab, (_BAND + var - row, row), sign * coef_y)  # their transposes
    np.add.at(rhs, base + 5, -end_p)
    np.add.at(rhs, base + 2, start_p)

    # At rest at both ends: replace the rows of v_0, a_0, v_n, a_n by identity rows.
    for fixed in (0, 1, 3 * n, 3 * n + 1):
        for col in range(max(0, fixed - _BAND), min(size, fixed + _BAND + 1)):
            ab[_BAND + fixed - col, col] = 0.0
        ab[_BAND, fixed] = 1.0
        rhs[fixed] = 0.0

    solution = solve_banded((_BAND, _BAND), ab, rhs, overwrite_ab=True, overwrite_b=True,
                            check_finite=False)
    velocity = solution[0::3]
    acceleration = solution[1::3]
    coef = np.empty((n, 6))
    coef[:, 0] = x_knots[:-1]
    coef[:, 1] = h * velocity[:-1]
    coef[:, 2] = h * h * acceleration[:-1]
    coef[:, 3] = x_knots[1:]
    coef[:, 4] = h * velocity[1:]
    coef[:, 5] = h * h * acceleration[1:]
    return coef


def _evaluate_at_samples(coef: np.ndarray, t: np.ndarray, knots: np.ndarray) -> np.ndarray:
    """Spline value at every sample; the knots are samples, so each segment's samples are a
    contiguous run and ``np.repeat`` replaces a search."""
    counts = np.diff(knots)
    counts[-1] += 1                                                # the last sample
    start = np.repeat(t[knots[:-1]], counts)
    length = np.repeat(np.diff(t[knots]), counts)
    tau = (t - start) / length
    monomial = (coef @ _HERMITE_MONOMIAL.T).T                      # (6, n), powers ascending
    value = np.repeat(monomial[5], counts)
    for power in range(4, -1, -1):
        value *= tau
        value += np.repeat(monomial[power], counts)
    return value


def _worst_of_each_stretch(abs_deviation: np.ndarray, outside: np.ndarray) -> np.ndarray:
    """Index of the largest deviation in each run of consecutive out-of-tolerance samples."""
    index = np.flatnonzero(outside)
    run_start = np.ones(index.size, dtype=bool)
    run_start[1:] = np.diff(index) > 1
    run_id = np.cumsum(run_start) - 1
    values = abs_deviation[index]
    run_max = np.maximum.reduceat(values, np.flatnonzero(run_start))
    is_max = values == run_max[run_id]
    _, first = np.unique(run_id[is_max], return_index=True)
    return index[is_max][first]


def _to_ppoly(coef: np.ndarray, t_knots: np.ndarray) -> PPoly:
    """PPoly in real time from Hermite coordinates on the unit interval."""
    h = np.diff(t_knots)
    monomial = coef @ _HERMITE_MONOMIAL.T                          # tau powers 0..5
    power = np.arange(6)
    local = monomial / h[:, None] ** power                         # (t - t_i) powers 0..5
    return PPoly(local[:, ::-1].T.copy(), t_knots, extrapolate=True)
