"""Compiled piecewise polynomials: the polynomial pieces of a B-spline and their evaluation.

A quintic B-spline with knots at every sample is, between two distinct knots, one polynomial.
Its Taylor coefficients at the left end of each piece (highest power first) make evaluation a
Horner sum at a located piece. The path splines of trajectory generation and the reference
curves of the contour-error search both evaluate millions of points this way; scipy's
:class:`~scipy.interpolate.BSpline` would redo the Cox-de Boor recursion at every point.
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import BSpline, make_interp_spline

from .kernels import jit, run_chunks

#: Pieces or points per task of the compiled loops.
_CHUNK = 4096
#: Data points per banded system of :func:`interpolating_spline` (the systems are solved in
#: parallel, each in cache).
FIT_POINTS = 8192
#: Data points each system of :func:`interpolating_spline` reaches past its own on either
#: side. An interpolating spline's dependence on a data point decays geometrically with the
#: distance in knots (by about 0.43 per knot for the quintic), so after 128 knots it is far
#: below round-off; ``tests/test_piecewise.py`` compares the pieces with one scipy system on
#: irregularly spaced random data.
FIT_OVERLAP = 128


def bspline_pieces(curve: BSpline, control: np.ndarray | None = None):
    """The polynomial pieces of a B-spline with the knots and degree of ``curve`` and the
    control points ``control`` (default ``curve.c``, shape (n, dims)): the breaks (distinct
    knots) and the Taylor coefficients / m! at each piece's left break, highest power first,
    shape (pieces, k + 1, dims)."""
    knots, control, breaks, spans = bspline_layout(curve, control)
    return breaks, _taylor_coefficients(knots, control, curve.k, breaks, spans)


def joint_control(tip: BSpline, orientation: BSpline) -> np.ndarray:
    """The control points of a tool tip and an orientation curve side by side (tip in dims
    0-2, orientation in 3-5), for one conversion to pieces; they must share knots and degree."""
    if not (tip.k == orientation.k and np.array_equal(tip.t, orientation.t)):
        raise ValueError("the tip and orientation curves must share their knots and degree")
    return np.concatenate([tip.c, orientation.c], axis=1)


def bspline_layout(curve: BSpline, control: np.ndarray | None = None):
    """``(knots, control, breaks, spans)`` of a B-spline, as the compiled helpers take them:
    contiguous knots and control points (n, dims), the distinct knots, and the span of each
    piece (the last copy of its left break: knots[span] <= x < knots[span + 1])."""
    knots = np.ascontiguousarray(curve.t, dtype=float)
    control = curve.c if control is None else control
    control = np.ascontiguousarray(np.reshape(control, (control.shape[0], -1)), dtype=float)
    distinct = np.concatenate([[True], np.diff(knots) > 0])
    return knots, control, knots[distinct], np.flatnonzero(distinct)[1:] - 1


def interpolating_spline(x: np.ndarray, y: np.ndarray, k: int = 5) -> BSpline:
    """The interpolating spline of :func:`scipy.interpolate.make_interp_spline` ``(x, y, k)``
    with not-a-knot ends, for odd k and strictly increasing x: its collocation systems are
    solved in overlapping pieces of :data:`FIT_POINTS` points, in parallel, by banded
    Gaussian elimination without pivoting. That is stable because a B-spline collocation
    matrix whose sites satisfy the Schoenberg-Whitney conditions is totally positive (de
    Boor, A Practical Guide to Splines, ch. XIII: SPLINT and BANFAC do the same). Linear in
    the points, with no band matrix for all of them. Even k or too few points go to scipy.
    ``y`` has the points along axis 0."""
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    n = x.size
    if k % 2 == 0 or n < 2 * k + 2:
        return make_interp_spline(x, y, k=k)
    half = (k + 1) // 2
    knots = np.concatenate([np.full(k + 1, x[0]), x[half:-half], np.full(k + 1, x[-1])])
    values = np.ascontiguousarray(y.reshape(n, -1))
    coef = np.empty_like(values)
    run_chunks(_collocation_pieces, (n + FIT_POINTS - 1) // FIT_POINTS, np.ascontiguousarray(x),
               values, int(k), FIT_POINTS, FIT_OVERLAP, coef)
    return BSpline.construct_fast(knots, coef.reshape(y.shape), k)


@jit
def _collocation_pieces(first, stop, x, y, k, points, overlap, coef):
    """Coefficients of the not-a-knot interpolant, pieces [first, stop) of ``points`` data
    points: a piece's knots are the whole curve's from its (k+1)-th on, so its coefficient j
    is the curve's lo + j."""
    n = x.size
    for piece in range(first, stop):
        start = piece * points
        end = min(n, start + points)
        lo = max(0, start - overlap)
        hi = min(n, end + overlap)
        local = _not_a_knot_coefficients(x[lo:hi], y[lo:hi], k)
        for i in range(start, end):      # (loops: a slice assignment compiles a shape check)
            for d in range(y.shape[1]):
                coef[i, d] = local[i - lo, d]


@jit
def _not_a_knot_coefficients(x, y, k):
    m = x.size
    half = (k + 1) // 2
    knots = np.empty(m + k + 1)
    for i in range(k + 1):
        knots[i] = x[0]
        knots[m + i] = x[m - 1]
    for i in range(k + 1, m):
        knots[i] = x[i - k - 1 + half]
    band = np.zeros((m, 2 * k + 1))      # band[i, j - i + k] = A[i, j]
    basis = np.empty(k + 1)
    left = np.empty(k + 1)
    right = np.empty(k + 1)
    for i in range(m):
        # x_i's knot interval: knots[span] <= x_i < knots[span + 1] (the last one closed)
        span = min(max(k + 1 + i - half, k), m - 1)
        # the k + 1 B-splines nonzero there (Piegl & Tiller, The NURBS Book, A2.2)
        basis[0] = 1.0
        for j in range(1, k + 1):
            left[j] = x[i] - knots[span + 1 - j]
            right[j] = knots[span + j] - x[i]
            saved = 0.0
            for r in range(j):
                temp = basis[r] / (right[r + 1] + left[j - r])
                basis[r] = saved + right[r + 1] * temp
                saved = left[j - r] * temp
            basis[j] = saved
        for r in range(k + 1):
            band[i, span - k + r - i + k] = basis[r]
    c = y.copy()
    for p in range(m):                   # elimination without pivoting
        pivot = band[p, k]
        for i in range(p + 1, min(m, p + k + 1)):
            factor = band[i, p - i + k] / pivot
            if factor != 0.0:
                for j in range(p + 1, min(m, p + k + 1)):
                    band[i, j - i + k] -= factor * band[p, j - p + k]
                for d in range(c.shape[1]):
                    c[i, d] -= factor * c[p, d]
    for i in range(m - 1, -1, -1):       # back substitution
        for j in range(i + 1, min(m, i + k + 1)):
            u = band[i, j - i + k]
            if u != 0.0:
                for d in range(c.shape[1]):
                    c[i, d] -= u * c[j, d]
        for d in range(c.shape[1]):
            c[i, d] /= band[i, k]
    return c


def evaluate(breaks: np.ndarray, coef: np.ndarray, x, nu: int = 0, dims: slice = slice(None)):
    """The ``nu``-th derivative of the piecewise polynomial ``(breaks, coef)`` at ``x``, in the
    dimensions ``dims`` of ``coef``: shape ``np.shape(x) + (n_dims,)``. Outside the breaks the
    end pieces extend, as :class:`~scipy.interpolate.BSpline` extrapolates. Sorted ``x`` are
    located by walking from the previous point's piece, others by bisection."""
    x = np.asarray(x, dtype=float)
    first, stop, step = dims.indices(coef.shape[2])
    if step != 1 or stop <= first:
        raise ValueError(f"dims must be a non-empty contiguous slice, got {dims}")
    if not 0 <= nu:
        raise ValueError(f"the derivative order must be >= 0, got {nu}")
    points = np.ascontiguousarray(x.ravel())
    out = np.empty((points.size, stop - first))
    run_chunks(_evaluate_points, (points.size + _CHUNK - 1) // _CHUNK, breaks, coef, points,
               int(nu), first, out)
    return out.reshape(x.shape + (stop - first,))


def _taylor_coefficients(knots, control, degree, breaks, spans):
    """Taylor coefficients / m! of a B-spline at the left end of each piece, highest power
    first: the derivatives' control points by differencing (Piegl & Tiller, The NURBS Book,
    A3.3) on the bases of every degree from one Cox-de Boor triangle (A2.2)."""
    pieces = breaks.size - 1
    coef = np.empty((pieces, degree + 1, control.shape[1]))
    run_chunks(_taylor_chunks, (pieces + _CHUNK - 1) // _CHUNK, knots, control, int(degree),
               breaks, spans, coef)
    return coef


@jit
def _taylor_chunks(first, stop, knots, control, degree, breaks, spans, coef):
    """:func:`_taylor_coefficients` of the pieces of chunks [first, stop)."""
    dims = control.shape[1]
    pieces = breaks.size - 1
    for chunk in range(first, stop):
        basis = np.zeros((degree + 1, degree + 1))   # basis[q, r] = N_{span-q+r, q}(x)
        left = np.zeros(degree + 1)
        right = np.zeros(degree + 1)
        points = np.zeros((degree + 1, degree + 1, dims))
        for j in range(chunk * _CHUNK, min(pieces, (chunk + 1) * _CHUNK)):
            taylor_coefficients_at(knots, control, degree, breaks[j], spans[j], basis, left,
                                   right, points, coef, j)


@jit(inline="always")
def taylor_coefficients_at(knots, control, degree, x, span, basis, left, right, points, out,
                           piece):
    """Taylor coefficients / m! at x (see _taylor_coefficients), into out[piece, degree - m]
    (scalar loops throughout: no array views per piece)."""
    dims = control.shape[1]
    basis[0, 0] = 1.0
    for q in range(1, degree + 1):
        left[q] = x - knots[span + 1 - q]
        right[q] = knots[span + q] - x
        saved = 0.0
        for r in range(q):
            temp = basis[q - 1, r] / (right[r + 1] + left[q - r])
            basis[q, r] = saved + right[r + 1] * temp
            saved = left[q - r] * temp
        basis[q, q] = saved
    first = span - degree
    for i in range(degree + 1):
        for d in range(dims):
            points[0, i, d] = control[first + i, d]
    factorial = 1.0
    for m in range(degree + 1):
        if m > 0:
            factorial *= m
            for i in range(degree + 1 - m):
                scale = (degree - m + 1) / (knots[first + i + degree + 1]
                                            - knots[first + i + m])
                for d in range(dims):
                    points[m, i, d] = scale * (points[m - 1, i + 1, d] - points[m - 1, i, d])
        for d in range(dims):
            total = 0.0
            for i in range(degree + 1 - m):
                total += basis[degree - m, i] * points[m, i, d]
            out[piece, degree - m, d] = total / factorial


@jit(inline="always")
def locate(breaks, x, hint):
    """Index of the piece containing x (breaks[piece] <= x < breaks[piece + 1]; the end
    pieces beyond the ends): ``hint`` or its successor when x is there, else bisection."""
    last = breaks.size - 2
    piece = min(max(hint, 0), last)
    if breaks[piece] <= x or piece == 0:
        if piece == last or x < breaks[piece + 1]:
            return piece
        if piece + 1 == last or x < breaks[piece + 2]:
            return piece + 1
    lo, hi = 0, last
    while lo < hi:      # the last piece whose left break is <= x (0 if none)
        mid = (lo + hi + 1) >> 1
        if breaks[mid] <= x:
            lo = mid
        else:
            hi = mid - 1
    return lo


@jit(inline="always")
def derivative(coef, piece, s, nu, d):
    """The nu-th derivative of dimension d of ``piece`` at local coordinate s (Horner's
    scheme on the derivative's coefficients)."""
    degree = coef.shape[1] - 1
    if nu > degree:
        return 0.0
    total = 0.0
    for p in range(degree - nu + 1):       # power degree - p, differentiated nu times
        power = degree - p
        scale = 1.0
        for m in range(power - nu + 1, power + 1):
            scale *= m
        total = total * s + scale * coef[piece, p, d]
    return total


@jit
def _evaluate_points(first_chunk, stop_chunk, breaks, coef, x, nu, first, out):
    n = x.size
    count = out.shape[1]
    for chunk in range(first_chunk, stop_chunk):
        piece = 0
        for i in range(chunk * _CHUNK, min(n, (chunk + 1) * _CHUNK)):
            piece = locate(breaks, x[i], piece)
            s = x[i] - breaks[piece]
            for d in range(count):
                out[i, d] = derivative(coef, piece, s, nu, first + d)
