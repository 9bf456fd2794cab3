"""Closed-form tracking error of a linear drive following a piecewise-polynomial command.

Spec section 4 (paper Eqs. 12-17), generalized to any proper, stable error transfer function
e(s)/X(s) = num(s)/den(s). With the partial fractions

    G(s) = d + sum_k sum_{j=1..m_k} r_kj / (s - l_k)^j,

each pole l_k of multiplicity m_k drives a Jordan chain z_1' = l z_1 + u, z_j' = l z_j + z_{j-1}
and e = d u + sum r_kj z_kj. On a segment where the command u is a polynomial in the local time
tau, each chain is an exact polynomial (particular) part plus exp(J tau) times the remaining
initial state: for PID (three distinct real poles) this is the paper's cubic + three
exponentials. Continuity of the chain states across joints is the paper's continuity of
e, e', e''. The states are carried in local time, so exp(l tau) never overflows however long a
segment is, and the joint-to-joint recursion is one compiled pass over the segments (linear in
their number).
"""

from __future__ import annotations

from dataclasses import dataclass
from math import factorial

import numpy as np
from scipy.interpolate import PPoly

from ..kernels import jit
from ..machine.drives import AXES, ROTARY_AXES, LinearErrorModel
from .splinefit import (DEFAULT_TOL_LINEAR, DEFAULT_TOL_ROTARY, AxisFits, fit_min_jerk,
                        map_axes)

#: Poles closer than this (relative to their magnitude) are treated as one repeated pole.
POLE_CLUSTER_RTOL = 1e-4


@dataclass(frozen=True)
class PartialFractions:
    """G(s) = direct + sum_k sum_j residues[k][j-1] / (s - poles[k])^j.

    Only one pole of each complex-conjugate pair is kept (``Im >= 0``); ``weight`` is 2 for
    those with ``Im > 0`` so that the real response is ``weight * Re(...)``.
    """

    direct: float
    poles: np.ndarray              # (n_poles,) complex
    multiplicity: np.ndarray       # (n_poles,) int
    residues: tuple                # tuple of (m_k,) complex arrays
    weight: np.ndarray             # (n_poles,) float

    @classmethod
    def from_model(cls, model: LinearErrorModel) -> "PartialFractions":
        num, den = model.num, model.den
        direct = float(num[0] / den[0]) if num.size == den.size else 0.0
        roots = np.roots(den)
        centres, counts = _cluster_roots(roots)
        residues = []
        for k, (centre, count) in enumerate(zip(centres, counts)):
            others = np.concatenate([np.full(c, z) for i, (z, c) in enumerate(zip(centres, counts))
                                     if i != k]) if len(centres) > 1 else np.zeros(0)
            rest = den[0] * np.poly(others) if others.size else np.array([den[0]], dtype=complex)
            # Taylor coefficients of (s - l)^m G(s) = num(s) / rest(s) at s = l.
            taylor = _series_divide(_taylor(num, centre, count), _taylor(rest, centre, count), count)
            # r_{k,m-q} = taylor[q]
            residues.append(taylor[::-1].copy())
        keep = np.array([c.imag >= 0 for c in centres])
        weight = np.where(np.abs(centres.imag) > 0, 2.0, 1.0)
        return cls(direct=direct, poles=centres[keep], multiplicity=counts[keep],
                   residues=tuple(r for r, k in zip(residues, keep) if k), weight=weight[keep])


@dataclass(frozen=True)
class TrackingError:
    """Closed-form tracking error e(t) = command - actual of one axis (spec section 4).

    Callable on any time grid: ``e(t)``. Before the first breakpoint the axis is at rest; after
    the last one the command holds its final value and e(t) decays to zero.
    """

    breaks: np.ndarray             # (n_seg + 1,) segment starts; the last segment is the hold
    forced: np.ndarray             # (n_seg + 1, deg + 1) real polynomial part, ascending powers
    poles: np.ndarray              # (n_states,) complex pole of each chain state
    chain_power: np.ndarray        # (n_states,) power of tau in front of exp(l tau)
    free: np.ndarray               # (n_seg + 1, n_states) complex: weight * residue * state
    offset: float                  # steady error of the resting axis (0 for a servo loop)

    def __post_init__(self):
        object.__setattr__(self, "_arrays", (
            np.ascontiguousarray(self.breaks, dtype=float),
            np.ascontiguousarray(self.forced, dtype=float),
            np.ascontiguousarray(self.poles, dtype=complex),
            np.ascontiguousarray(self.chain_power, dtype=np.int64),
            np.ascontiguousarray(self.free, dtype=complex)))

    def __call__(self, t) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        value = _error_at(*self._arrays, np.ascontiguousarray(t.ravel()))
        value += self.offset
        return value.reshape(t.shape)


@jit
def _error_at(breaks, forced, poles, powers, free, t):
    """e(t) without the offset at each time: the segment's polynomial part plus its free
    response, zero before the first break. The segment is found from the previous sample's
    (the usual sorted grid) or by bisection."""
    last = breaks.size - 1
    value = np.empty(t.size)
    real = np.empty(poles.size, dtype=np.bool_)
    for s in range(poles.size):
        real[s] = poles[s].imag == 0.0
    segment = 0
    for k in range(t.size):
        x = t[k]
        if not (breaks[segment] <= x and (segment == last or x < breaks[segment + 1])):
            # the last break <= x (0 if none) by bisection: np.searchsorted's side="right",
            # without compiling numpy's generic search (complex comparisons included)
            lo, hi = 0, last
            while lo < hi:
                mid = (lo + hi + 1) >> 1
                if breaks[mid] <= x:
                    lo = mid
                else:
                    hi = mid - 1
            segment = lo
        tau = x - breaks[segment]
        if tau < 0.0:
            value[k] = 0.0
            continue
        total = forced[segment, forced.shape[1] - 1]
        for p in range(forced.shape[1] - 2, -1, -1):
            total = total * tau + forced[segment, p]
        for s in range(poles.size):
            if real[s]:
                term = free[segment, s].real * np.exp(poles[s].real * tau)
            else:
                term = (free[segment, s] * np.exp(poles[s] * tau)).real
            if powers[s]:
                term *= tau ** powers[s]
            total += term
        value[k] = total
    return value


def tracking_error(spline: PPoly, model: LinearErrorModel) -> TrackingError:
    """Closed-form tracking error of a drive with error model ``model`` commanded ``spline``.

    Parameters
    ----------
    spline : scipy.interpolate.PPoly
        Piecewise polynomial command (e.g. :attr:`SplineFit.spline`), 1-D, any degree.
        The axis rests at ``spline(spline.x[0])`` before the first breakpoint.
    model : LinearErrorModel
        Stable error transfer function e(s)/X(s).
    """
    model.check_stable()
    pf = PartialFractions.from_model(model)
    breaks = np.asarray(spline.x, dtype=float)
    # Command in ascending powers of local time, minus its rest value: zero initial state then
    # means "at rest at the first command" (linearity; see `offset`).
    u = spline.c[::-1].T.astype(float).copy()                      # (n_seg, deg + 1)
    rest = u[0, 0]
    u[:, 0] -= rest
    final = float(spline(breaks[-1])) - rest
    hold = np.zeros((1, u.shape[1]))
    hold[0, 0] = final
    u = np.vstack([u, hold])
    h = np.diff(breaks)
    n_seg = u.shape[0]                                              # includes the hold

    forced = pf.direct * u
    state_poles, state_power, free_cols = [], [], []
    for pole, mult, residues, weight in zip(pf.poles, pf.multiplicity, pf.residues, pf.weight):
        chain_forced, chain_free = _chain_response(u, h, complex(pole),
                                                   np.asarray(residues, dtype=complex),
                                                   float(weight))
        forced = forced + chain_forced
        for p in range(mult):
            state_poles.append(pole)
            state_power.append(p)
            free_cols.append(chain_free[:, p])
    free = np.stack(free_cols, axis=1) if free_cols else np.zeros((n_seg, 0), complex)
    return TrackingError(breaks=breaks, forced=forced, poles=np.array(state_poles, complex),
                         chain_power=np.array(state_power, int), free=free,
                         offset=model.dc_gain * rest)


@jit
def _chain_response(u, h, pole, residues, weight):
    """One pole's Jordan chain driven by the segment polynomials ``u`` (n_seg, deg + 1,
    ascending powers; the last segment is the hold, ``h`` the lengths of the others).

    Returns its real polynomial part of e, weight Re(sum_j r_j z_p,j) per segment, and the
    free-response amplitudes weight beta_p (n_seg, m): e gets weight Re(beta_p tau^p e^(l tau)).
    Per segment: the particular polynomial of each chain state (z' = l z + source), then the
    homogeneous amplitudes w_i = z_i(0) - z_p,i(0), carried across the joint by the exact
    chain exponential, w(next) = exp(J h) w + z_p(h) - z_p,next(0), from rest (z(0) = 0).
    One pass over the segments: linear in their number.
    """
    n_seg, n_coef = u.shape
    m = residues.size
    forced = np.zeros((n_seg, n_coef))
    free = np.empty((n_seg, m), dtype=np.complex128)
    chain = np.empty((m, n_coef), dtype=np.complex128)
    state = np.zeros(m, dtype=np.complex128)
    carried = np.zeros(m, dtype=np.complex128)
    inverse_factorial = np.ones(m)
    for p in range(1, m):
        inverse_factorial[p] = inverse_factorial[p - 1] / p
    for i in range(n_seg):
        for j in range(m):
            following = 0j
            for p in range(n_coef - 1, -1, -1):
                source = u[i, p] if j == 0 else chain[j - 1, p]
                # (p+1) c_{p+1} = pole c_p + s_p
                following = ((p + 1) * following - source) / pole
                chain[j, p] = following
        for p in range(n_coef):
            total = 0j
            for j in range(m):
                total += residues[j] * chain[j, p]
            forced[i, p] = weight * total.real
        if i == 0:
            for j in range(m):
                state[j] = -chain[j, 0]          # at rest: z(0) = 0
        else:
            hi = h[i - 1]
            decay = np.exp(pole * hi)
            for j in range(m - 1, -1, -1):       # exp(J h) is lower triangular
                total = 0j
                power = 1.0
                for l in range(j, -1, -1):
                    total += decay * power * inverse_factorial[j - l] * state[l]
                    power *= hi
                state[j] = total + carried[j] - chain[j, 0]
        for p in range(m):
            total = 0j
            for l in range(m - p):
                total += residues[l + p] * state[l]
            free[i, p] = weight * total * inverse_factorial[p]
        if i < n_seg - 1:
            hi = h[i]
            for j in range(m):                   # z_p(h) at the segment's end
                value = chain[j, n_coef - 1]
                for p in range(n_coef - 2, -1, -1):
                    value = value * hi + chain[j, p]
                carried[j] = value
    return forced, free


def _cluster_roots(roots: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Group numerically repeated roots; return their centres and multiplicities."""
    roots = np.asarray(roots, dtype=complex)
    order = np.argsort(roots.real + 1e-3 * roots.imag)
    remaining = list(roots[order])
    centres, counts = [], []
    while remaining:
        z = remaining.pop(0)
        scale = max(abs(z), 1.0)
        group = [z] + [w for w in remaining if abs(w - z) <= POLE_CLUSTER_RTOL * scale]
        for w in group[1:]:
            remaining.remove(w)
        centre = np.mean(group)
        if abs(centre.imag) <= 1e-12 * scale:
            centre = complex(centre.real, 0.0)
        centres.append(centre)
        counts.append(len(group))
    return np.array(centres, dtype=complex), np.array(counts, dtype=int)


def _taylor(poly: np.ndarray, at: complex, count: int) -> np.ndarray:
    """First ``count`` Taylor coefficients of a polynomial (highest power first) at ``at``."""
    coef = np.asarray(poly, dtype=complex)
    out = np.zeros(count, dtype=complex)
    for q in range(count):
        out[q] = np.polyval(coef, at) / factorial(q) if coef.size else 0.0
        coef = np.polyder(coef) if coef.size > 1 else np.zeros(1, complex)
    return out


def _series_divide(a: np.ndarray, b: np.ndarray, count: int) -> np.ndarray:
    """First ``count`` coefficients of the power series a / b."""
    out = np.zeros(count, dtype=complex)
    for q in range(count):
        out[q] = (a[q] - np.dot(out[:q], b[q:0:-1])) / b[0]
    return out


@dataclass(frozen=True)
class AxisPrediction:
    """Predicted tracking errors of the five axes of a trajectory.

    ``prediction(t)`` returns e(t) of shape ``t.shape + (5,)`` (command minus actual; mm, rad).
    """

    fits: AxisFits
    errors: tuple[TrackingError, ...]

    def __call__(self, t) -> np.ndarray:
        return np.stack(map_axes(lambda i: self.errors[i](t)), axis=-1)


def predict_tracking(t: np.ndarray, q: np.ndarray, models: tuple[LinearErrorModel, ...], *,
                     tol_linear: float | None = None, tol_rotary: float | None = None,
                     initial_knots: tuple | None = None,
                     previous: tuple[np.ndarray, AxisPrediction] | None = None) -> AxisPrediction:
    """Fit each axis command (spec section 3) and predict its tracking error (section 4).

    Parameters
    ----------
    t : ndarray, shape (N,)
        Sample times, s.
    q : ndarray, shape (N, 5)
        Axis commands X, Y, Z (mm), A, C (rad).
    models : tuple of 5 LinearErrorModel
        Closed-loop error models, e.g. ``machine.error_models(name)``.
    tol_linear, tol_rotary : float, optional
        Fit tolerances (defaults 1 um, 1 urad).
    initial_knots : tuple of 5 int arrays, optional
        Knots to start each axis's fit from (``AxisPrediction.fits.knot_indices`` of a
        prediction of a similar command, see :func:`fit_min_jerk`).
    previous : (q, AxisPrediction), optional
        Commands and the prediction of an earlier call with the same ``t``, models and
        tolerances: an axis whose command is identical to its command there is taken from it
        (a compensation pass changes the rotary axes once and then only the linear ones).
    """
    t = np.asarray(t, dtype=float)
    q = np.asarray(q, dtype=float)
    tol_linear = DEFAULT_TOL_LINEAR if tol_linear is None else tol_linear
    tol_rotary = DEFAULT_TOL_ROTARY if tol_rotary is None else tol_rotary

    def axis(i):
        if previous is not None and np.array_equal(previous[0][:, i], q[:, i]):
            return previous[1].fits[i], previous[1].errors[i]
        fit = fit_min_jerk(t, q[:, i], tol_rotary if AXES[i] in ROTARY_AXES else tol_linear,
                           name=AXES[i],
                           initial_knots=None if initial_knots is None else initial_knots[i])
        return fit, tracking_error(fit.spline, models[i])
    fits, errors = zip(*map_axes(axis))
    return AxisPrediction(fits=AxisFits(tuple(fits)), errors=tuple(errors))
