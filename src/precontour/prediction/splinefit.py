"""Minimum-jerk C3 quintic spline fit of sampled axis commands (spec section 3, paper App. A).

:func:`fit_min_jerk` fits one axis: a piecewise quintic through a subset of the samples (the
knots), C3 at the joints, at rest (zero velocity, acceleration and jerk) at both ends, and of
minimum integrated squared jerk. Knots are added where the samples stray from the spline by
more than a tolerance (an encoder resolution), one per out-of-tolerance stretch per round. The
result is a :class:`scipy.interpolate.PPoly`.

Each solve is one banded KKT system (bandwidth 5) in the knot velocities and accelerations and
one multiplier per knot for jerk continuity, so a fit costs O(samples) per round. A round that
adds few knots solves again only a stretch of knots around each (the influence of a knot dies
out geometrically along the spline), with the unchanged spline's velocity, acceleration and
jerk as the stretch's end conditions.
"""

from __future__ import annotations

import threading
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import PPoly
from scipy.linalg.lapack import dgbsv

from ..defaults import FIT_TOL_LINEAR as DEFAULT_TOL_LINEAR
from ..defaults import FIT_TOL_ROTARY as DEFAULT_TOL_ROTARY
from ..machine.drives import AXES, ROTARY_AXES
from ..errors import InputError
from ..kernels import jit
from ..parallel import jobs

# DEFAULT_TOL_LINEAR, DEFAULT_TOL_ROTARY, the default fit tolerances (1 um on the linear
# axes, 1 urad on the rotary ones), are defined in precontour.defaults.
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
_Y = np.array([1, 2, 4, 5])  # positions of the unknown velocities / accelerations in c
_BAND = 5                    # half bandwidth of the KKT matrix with 3 unknowns per knot
_DIAGONAL = 2 * _BAND        # row of the diagonal in gbsv's band storage


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


#: Smallest tolerance accepted, in units in the last place of the largest |value|.
ROUND_OFF_ULPS = 256


def fit_min_jerk(t: np.ndarray, x: np.ndarray, tol: float, *, max_rounds: int = 500,
                 name: str = "x", initial_knots: np.ndarray | None = None) -> SplineFit:
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
    initial_knots : ndarray of int, optional
        Sample indices to start from instead of the uniform first fit, e.g. the knots of a
        fit of a similar command (a corrected command needs at least the knots of the
        original one: starting there saves the rounds that would find them again). The
        first and last sample are always knots.

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
    # Below a few hundred ulps of the values the fit can only interpolate every sample: the
    # tolerance is round-off, not an encoder resolution.
    floor = ROUND_OFF_ULPS * np.spacing(max(float(np.abs(x).max()), 1.0))
    if tol < floor:
        raise InputError(f"the spline fit cannot get within the tolerance {tol:.3g}: it is "
                         f"below the round-off of values up to {float(np.abs(x).max()):.3g} "
                         f"({floor:.3g}); use a larger tolerance", field=name)

    n_samples = t.size
    if n_samples > 3 * INITIAL_SAMPLES_PER_SEGMENT:
        # every INITIAL_SAMPLES_PER_SEGMENT-th sample from the first: a piece of a long
        # program cut at a multiple of it starts from the same knots as the whole program
        knots = np.append(np.arange(0, n_samples - 1, INITIAL_SAMPLES_PER_SEGMENT),
                          n_samples - 1).astype(np.intp)
    else:
        n_segments = max(3, (n_samples - 1) // INITIAL_SAMPLES_PER_SEGMENT)
        knots = np.unique(np.round(np.linspace(0, n_samples - 1, n_segments + 1)).astype(np.intp))
    if initial_knots is not None:
        given = np.asarray(initial_knots, dtype=np.intp)
        given = given[(given > 0) & (given < n_samples - 1)]
        if given.size >= 2:
            knots = _sorted_union(np.array([0, n_samples - 1], dtype=np.intp), np.sort(given))
    coef = None
    for rounds in range(1, max_rounds + 1):
        if coef is None:
            coef = _solve_min_jerk(t[knots], x[knots])
            deviation = _evaluate_at_samples(coef, t, knots) - x
        outside = np.abs(deviation) > tol
        if not outside.any():
            break
        new = _sorted_union(knots, _worst_of_each_stretch(np.abs(deviation), outside))
        if new.size == knots.size:
            # the worst samples are knots already: what is left is round-off of the values
            worst = int(np.argmax(np.abs(deviation)))
            raise InputError(
                f"the spline fit cannot get within the tolerance {tol:.3g}: "
                f"{float(np.abs(deviation[worst])):.3g} remains at sample {worst + 1}, a knot "
                f"already (round-off of values up to {float(np.abs(x).max()):.3g}); use a "
                "larger tolerance", field=name)
        coef = _solve_with_new_knots(t, x, knots, coef, new, deviation)
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

    @property
    def knot_indices(self) -> tuple[np.ndarray, ...]:
        return tuple(fit.knot_index for fit in self.fits)

    def __call__(self, t, nu: int = 0) -> np.ndarray:
        """Evaluate all five splines: returns shape ``t.shape + (5,)``."""
        return np.stack([fit.spline(t, nu) for fit in self.fits], axis=-1)


def fit_axes(t: np.ndarray, q: np.ndarray, *, tol_linear: float = DEFAULT_TOL_LINEAR,
             tol_rotary: float = DEFAULT_TOL_ROTARY,
             initial_knots: tuple | None = None) -> AxisFits:
    """Fit each of the five axis commands ``q[:, i]`` with :func:`fit_min_jerk`
    (``initial_knots``: one knot-index array per axis, e.g. ``AxisFits.knot_indices`` of a
    fit of a similar command)."""
    q = np.asarray(q, dtype=float)

    def fit(i):
        return fit_min_jerk(t, q[:, i], tol_rotary if AXES[i] in ROTARY_AXES else tol_linear,
                            name=AXES[i],
                            initial_knots=None if initial_knots is None else initial_knots[i])
    return AxisFits(tuple(map_axes(fit)))


def map_axes(work) -> list:
    """[work(0), ..., work(4)], the axes spread over the cores: the fits' banded solves
    (LAPACK) and compiled loops release the interpreter lock, and the axes are independent."""
    workers = min(len(AXES), jobs())
    if workers == 1:
        return [work(i) for i in range(len(AXES))]
    # rotary axes first: at their finer tolerance they need the most knots (the longest
    # jobs first keeps the cores evenly busy)
    order = [i for i, axis in enumerate(AXES) if axis in ROTARY_AXES][::-1]
    order += [i for i, axis in enumerate(AXES) if axis not in ROTARY_AXES]
    with ThreadPoolExecutor(max_workers=workers) as pool:
        done = dict(zip(order, pool.map(work, order)))
    return [done[i] for i in range(len(AXES))]


def _solve_min_jerk(t_knots: np.ndarray, x_knots: np.ndarray) -> np.ndarray:
    """Hermite coordinates ``c`` (shape (n, 6)) of the minimum-jerk C3 quintic through the
    knots, at rest at both ends (spec section 3)."""
    t_knots = np.ascontiguousarray(t_knots, dtype=float)
    return _solve_chains(t_knots, np.ascontiguousarray(x_knots, dtype=float),
                         np.array([0, t_knots.size], dtype=np.intp), np.zeros((1, 6)),
                         (t_knots[-1] - t_knots[0]) / (t_knots.size - 1))


def _solve_chains(t_knots, x_knots, first, ends, time_scale):
    """Hermite coordinates of the minimum-jerk C3 quintics of independent chains of knots,
    stacked: chain w is knots first[w] .. first[w + 1] - 1 and starts and ends with the
    velocity, acceleration and jerk ends[w] = (v0, a0, j0, v1, a1, j1) (zeros: at rest, the
    spec's end conditions; else those of the unchanged spline around a stretch solved again).
    One banded solve for all; returns the chains' segments in order.

    Unknowns per knot k: velocity, acceleration (time divided by ``time_scale``, which keeps
    the scaled segment lengths near 1) and the multiplier of the jerk continuity condition
    at k (at a chain's end knots: its given end jerk).
    """
    h = np.diff(t_knots) / time_scale
    scaled = ends * time_scale ** np.array([1.0, 2.0, 3.0, 1.0, 2.0, 3.0])
    ab, rhs = _kkt_system(h, x_knots, first, scaled, _band_buffer(3 * x_knots.size))
    _, _, solution, info = dgbsv(_BAND, _BAND, ab, rhs, overwrite_ab=True, overwrite_b=True)
    if info != 0:  # pragma: no cover - distinct knot times make the system regular
        raise np.linalg.LinAlgError(f"minimum-jerk system is singular (LAPACK info {info})")
    segment = np.ones(h.size, dtype=bool)
    segment[first[1:-1] - 1] = False                 # the joins between chains
    start = np.flatnonzero(segment)
    h = h[start]
    velocity = solution[0::3]
    acceleration = solution[1::3]
    coef = np.empty((start.size, 6))
    coef[:, 0] = x_knots[start]
    coef[:, 1] = h * velocity[start]
    coef[:, 2] = h * h * acceleration[start]
    coef[:, 3] = x_knots[start + 1]
    coef[:, 4] = h * velocity[start + 1]
    coef[:, 5] = h * h * acceleration[start + 1]
    return coef


#: A new knot changes the minimum-jerk solution by a factor of about 0.43 less per knot
#: further away (measured): beyond LOCAL_REACH knots by less than 1e-11 of the change. A
#: round that adds few knots therefore solves again only LOCAL_REACH knots either side of
#: each, with the velocity, acceleration and jerk of the unchanged spline around as end
#: conditions (what the whole solve gives there, to that factor); the spline stays C3.
LOCAL_REACH = 32
#: ... when those stretches hold at most this fraction of the knots (else the whole solve).
LOCAL_FRACTION = 0.8


def _solve_with_new_knots(t, x, knots, coef, new, deviation):
    """Hermite coordinates of the fit through the knots ``new``, a superset of ``knots``
    whose fit ``coef`` is; ``deviation`` (spline - x) updated in place. Solved again only
    around the added knots where they are few."""
    position = np.searchsorted(knots, new)
    is_old = (position < knots.size) & (knots[np.minimum(position, knots.size - 1)] == new)
    added = np.flatnonzero(~is_old)
    lo = np.maximum(added - LOCAL_REACH, 0)
    hi = np.minimum(added + LOCAL_REACH, new.size - 1)
    # merge overlapping or touching stretches, so that the segments just outside each are
    # old ones (and its end knots old knots)
    starts = np.ones(added.size, dtype=bool)
    starts[1:] = lo[1:] > np.maximum.accumulate(hi)[:-1] + 1
    first = np.flatnonzero(starts)
    lo, hi = lo[first], np.maximum.reduceat(hi, first)
    if np.sum(hi - lo + 1) > LOCAL_FRACTION * new.size:
        coef = _solve_min_jerk(t[new], x[new])
        deviation[:] = _evaluate_at_samples(coef, t, new) - x
        return coef
    # end conditions: at a stretch's first knot those of the old segment ending there, at
    # its last knot those of the old segment starting there
    ends = np.zeros((lo.size, 6))
    inner = lo > 0
    j = np.searchsorted(knots, new[lo[inner]]) - 1
    length = t[knots[j + 1]] - t[knots[j]]
    ends[inner, 0] = coef[j, 4] / length
    ends[inner, 1] = coef[j, 5] / length ** 2
    ends[inner, 2] = coef[j] @ _JERK_END / length ** 3
    inner = hi < new.size - 1
    j = np.searchsorted(knots, new[hi[inner]])
    length = t[knots[j + 1]] - t[knots[j]]
    ends[inner, 3] = coef[j, 1] / length
    ends[inner, 4] = coef[j, 2] / length ** 2
    ends[inner, 5] = coef[j] @ _JERK_START / length ** 3
    stacked = new[np.concatenate([np.arange(a, b + 1) for a, b in zip(lo, hi)])]
    solved = _solve_chains(t[stacked], x[stacked], np.append(0, np.cumsum(hi - lo + 1)), ends,
                           (t[new[-1]] - t[new[0]]) / (new.size - 1))
    # every other segment is an old one
    result = coef[np.searchsorted(knots, new[:-1], side="right") - 1]
    result[np.concatenate([np.arange(a, b) for a, b in zip(lo, hi)])] = solved
    _update_deviation(result, t, x, new, lo, hi, deviation)
    return result


@jit
def _update_deviation(coef, t, x, knots, lo, hi, deviation):
    """deviation = spline - x on the samples of the knot stretches [lo[w], hi[w]]."""
    for w in range(lo.size):
        start = knots[lo[w]]
        stop = knots[hi[w]] + 1
        value = _evaluate_segments(coef, t, knots, lo[w], hi[w], start, stop)
        for k in range(start, stop):
            deviation[k] = value[k - start] - x[k]


_buffers = threading.local()


def _band_buffer(columns: int) -> np.ndarray:
    """This thread's band storage of ``columns`` columns, transposed: a fit solves dozens of
    systems of up to 3 x 10^5 unknowns, and fresh memory for each costs more than the
    solve's own zeroing."""
    buffer = getattr(_buffers, "band", None)
    if buffer is None or buffer.shape[0] < columns:
        buffer = np.empty((max(columns, 3 * 4096), 3 * _BAND + 1))
        _buffers.band = buffer
    return buffer[:columns]


@jit
def _kkt_system(h, x_knots, first, ends, band_t):
    """Banded KKT matrix and right-hand side of :func:`_solve_chains`, in the band storage
    LAPACK's gbsv factors in place (half bandwidth _BAND, _BAND more rows for the fill-in of
    pivoting).

    Cost sum_i c_i^T G c_i / h_i^5 with c_i = E_p p_i + diag(s_i) y_i, s_i = (h, h^2, h, h^2):
    each segment adds its 4 x 4 Hessian block on the velocities and accelerations of its two
    knots. Jerk continuity: segment i adds +jerk(end) to the multiplier row of knot i + 1 and
    -jerk(start) to that of knot i; a chain's end knots get only one term, which makes them
    "jerk = the given end jerk". The given end velocities and accelerations become identity
    rows.
    """
    size = 3 * x_knots.size
    # built column by column (band_t[col, row], shape (size, 3 _BAND + 1)) and handed over
    # transposed: Fortran order, which gbsv would otherwise copy the matrix into
    band_t[:] = 0.0
    ab = band_t.T
    rhs = np.zeros(size)
    var = np.empty(4, dtype=np.intp)
    scale = np.empty(4)
    for chain in range(first.size - 1):
        for i in range(first[chain], first[chain + 1] - 1):
            hi = h[i]
            inv_h3 = 1.0 / (hi * hi * hi)
            inv_h5 = inv_h3 / (hi * hi)
            p0 = x_knots[i]
            p1 = x_knots[i + 1]
            base = 3 * i
            var[0], var[1], var[2], var[3] = base, base + 1, base + 3, base + 4
            scale[0], scale[1], scale[2], scale[3] = hi, hi * hi, hi, hi * hi
            for a in range(4):
                ya = _Y[a]
                for b in range(4):
                    ab[_DIAGONAL + var[a] - var[b], var[b]] += (
                        _JERK_GRAM[ya, _Y[b]] * scale[a] * scale[b] * inv_h5)
                rhs[var[a]] -= ((p0 * _JERK_GRAM[0, ya] + p1 * _JERK_GRAM[3, ya])
                                * scale[a] * inv_h5)
                end = _JERK_END[ya] * scale[a] * inv_h3
                start = -_JERK_START[ya] * scale[a] * inv_h3
                ab[_DIAGONAL + base + 5 - var[a], var[a]] += end      # constraint rows
                ab[_DIAGONAL + var[a] - base - 5, base + 5] += end    # their transposes
                ab[_DIAGONAL + base + 2 - var[a], var[a]] += start
                ab[_DIAGONAL + var[a] - base - 2, base + 2] += start
            rhs[base + 5] -= (p0 * _JERK_END[0] + p1 * _JERK_END[3]) * inv_h3
            rhs[base + 2] += (p0 * _JERK_START[0] + p1 * _JERK_START[3]) * inv_h3
        head = 3 * first[chain]
        tail = 3 * (first[chain + 1] - 1)
        rhs[head + 2] -= ends[chain, 2]          # -jerk(start) = -j0
        rhs[tail + 2] += ends[chain, 5]          # jerk(end) = j1
        for fixed, value in ((head, ends[chain, 0]), (head + 1, ends[chain, 1]),
                             (tail, ends[chain, 3]), (tail + 1, ends[chain, 4])):
            for col in range(max(0, fixed - _BAND), min(size, fixed + _BAND + 1)):
                ab[_DIAGONAL + fixed - col, col] = 0.0
            ab[_DIAGONAL, fixed] = 1.0
            rhs[fixed] = value
    return ab, rhs


def _evaluate_at_samples(coef, t, knots):
    """Spline value at every sample; the knots are samples, so each segment's samples are a
    contiguous run. (Called from Python: from compiled code, the constant arguments would
    compile the kernel a second time, for their literal values.)"""
    return _evaluate_segments(coef, t, knots, 0, knots.size - 1, 0, t.size)


@jit
def _evaluate_segments(coef, t, knots, lo, hi, start, stop):
    """Spline value at the samples start .. stop - 1 of segments lo .. hi - 1 (the last
    segment's end sample included)."""
    value = np.empty(stop - start)
    monomial = np.empty(6)
    for i in range(lo, hi):
        for power in range(6):
            m = 0.0
            for j in range(6):
                m += _HERMITE_MONOMIAL[power, j] * coef[i, j]
            monomial[power] = m
        first = t[knots[i]]
        length = t[knots[i + 1]] - first
        end = knots[i + 1] + 1 if i == hi - 1 else knots[i + 1]
        for k in range(knots[i], end):
            tau = (t[k] - first) / length
            v = monomial[5]
            for power in range(4, -1, -1):
                v = v * tau + monomial[power]
            value[k - start] = v
    return value


def _sorted_union(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Union of two sorted index arrays, sorted (np.union1d hashes: 10x slower here)."""
    merged = np.concatenate([a, b])
    merged.sort(kind="stable")
    keep = np.empty(merged.size, dtype=bool)
    keep[0] = True
    np.not_equal(merged[1:], merged[:-1], out=keep[1:])
    return merged[keep]


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
    return PPoly(_local_power_coefficients(coef, t_knots), t_knots, extrapolate=True)


@jit
def _local_power_coefficients(coef, t_knots):
    """PPoly coefficients (highest power of t - t_i first, shape (6, n)) of the segments in
    Hermite coordinates ``coef``: the tau powers, tau = (t - t_i) / h_i, divided by h_i^power."""
    n = coef.shape[0]
    out = np.empty((6, n))
    for i in range(n):
        inverse = 1.0 / (t_knots[i + 1] - t_knots[i])
        scale = 1.0
        for power in range(6):
            m = 0.0
            for j in range(6):
                m += _HERMITE_MONOMIAL[power, j] * coef[i, j]
            out[5 - power, i] = m * scale
            scale *= inverse
    return out
