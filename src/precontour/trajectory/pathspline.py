"""Geometric C3 splines of a programmed tool path: tool tip P(s) and orientation O(s).

Both curves share one parameter s (mm), the combined path length

    ds^2 = |dP|^2 + (L_eq * dtheta)^2,        L_eq = :data:`L_EQ` = 1 mm/rad,

where dtheta is the angle the tool orientation turns. Where the tip moves, s is its arc length
to within a fraction (L_eq * dtheta/|dP|)^2 / 2 (about 0.05 % for a typical 0.03 rad/mm
five-axis path); where the tip stands still while the tool turns (a pure rotation move), s keeps
growing by L_eq per rad, so such moves never make the parameterization degenerate. The tip and
the (unnormalized) orientation are interpolated by quintic not-a-knot B-splines
(:func:`precontour.piecewise.interpolating_spline`, scipy's
:func:`~scipy.interpolate.make_interp_spline` solved in pieces; C4 at the knots) through every
programmed point; the orientation is normalized on evaluation, which keeps it unit length and
C3. The parameter comes from one pass of chord lengths followed by one re-parameterization with
the combined length of the chord-length spline (5-point Gauss-Legendre per segment). The splines
are evaluated from their polynomial pieces (:mod:`precontour.piecewise`), compiled.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy.interpolate import BSpline

from ..errors import InputError, ToolPathError, plain
from ..kernels import jit, run_chunks
from ..machine.kinematics import angle_between, normalize_orientations
from ..piecewise import (bspline_layout, bspline_pieces, derivative, evaluate,
                         interpolating_spline, joint_control, locate, taylor_coefficients_at)

#: Equivalent length of one radian of tool rotation in the combined path parameter, mm/rad.
L_EQ = 1.0

#: Consecutive points closer than this in combined length (mm) are duplicates: the later one
#: is dropped, with its programmed feed.
DUPLICATE_TOLERANCE = 1e-6

#: Largest turn of the tool orientation between two consecutive programmed points, rad. The
#: orientation spline is normalized on evaluation; beyond a right angle its chord could pass
#: near the origin and the normalized curve would whip round.
MAX_ORIENTATION_STEP = np.pi / 2

#: Turn (degrees) between consecutive moves of a tool path, tip and orientation together (the
#: combined length's chords), at and above which a programmed point is a corner
#: (:func:`corner_points`): the tool stops there, and the path on each side is its own spline.
#: Why: an interpolating spline through a corner overshoots it; through a polyline of a few
#: points it leaves the polyline by far more (APT GOTO points are straight moves: a 40 x 4 mm
#: rectangle of four GOTOs became a curve 23.5 mm off its sides, a zigzag of 1 mm points 13 um
#: before each turn). Smooth CL data turn far less between points: the built-in and test paths
#: at most 24.6 degrees (`paper`, at one point of dense points; 7.9 on `flank`'s 40 points),
#: while the blade finishing pass of the APT test data plunges and retracts at 79.5 and 100.5.
CORNER_ANGLE = 45.0

_GAUSS_X, _GAUSS_W = np.polynomial.legendre.leggauss(5)
#: Segments per task of the compiled segment lengths.
_CHUNK = 4096


@dataclass(frozen=True)
class PathSpline:
    """Tool tip and orientation as C3 functions of the combined path length s (mm).

    Attributes
    ----------
    tip_spline : BSpline
        P(s), mm, shape ``(3,)`` per parameter value.
    orientation_spline : BSpline
        Unnormalized orientation v(s); O(s) = v(s)/|v(s)|.
    s_points : ndarray, shape (M,)
        Parameter of each (kept) programmed point; ``s_points[0] = 0``.
    point_index : ndarray, shape (M,)
        Row (0-based) of the input tool path each kept point came from.
    l_eq : float
        Equivalent length of one radian of rotation, mm/rad.
    """

    tip_spline: BSpline
    orientation_spline: BSpline
    s_points: np.ndarray
    point_index: np.ndarray
    l_eq: float = L_EQ

    @property
    def length(self) -> float:
        """Total combined length L (mm); s runs over [0, L]."""
        return float(self.s_points[-1])

    @cached_property
    def _pieces(self):
        """Breaks and Taylor coefficients of both splines: tip in dims 0-2, orientation in
        3-5 (:func:`fit_path` gives them the same knots)."""
        return bspline_pieces(self.tip_spline,
                              joint_control(self.tip_spline, self.orientation_spline))

    def tip(self, s, nu: int = 0) -> np.ndarray:
        """Tool tip P(s) (nu = 0) or its nu-th derivative with respect to s; shape
        ``np.shape(s) + (3,)``, mm/mm^nu."""
        return evaluate(*self._pieces, s, nu, slice(0, 3))

    def orientation(self, s, nu: int = 0) -> np.ndarray:
        """Unit orientation O(s) or its nu-th derivative (nu <= 3); shape
        ``np.shape(s) + (3,)``, 1/mm^nu."""
        if nu not in (0, 1, 2, 3):
            raise ValueError(f"orientation derivatives are available up to order 3, got {nu}")
        derivs = [evaluate(*self._pieces, s, k, slice(3, 6)) for k in range(nu + 1)]
        return _normalized_derivatives(derivs)[nu]

    def __call__(self, s, nu: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """``(P, O)`` or their nu-th derivatives at ``s``, as in :meth:`tip` and
        :meth:`orientation`."""
        if nu == 0:
            return self.sample(s, with_tip_derivatives=False)[:2]
        return self.tip(s, nu), self.orientation(s, nu)

    def sample(self, s, with_tip_derivatives: bool = True):
        """``(P, O, |P'|, |P''|)`` at ``s`` in one compiled pass (the feed planner's grid):
        shapes ``np.shape(s) + (3,)`` twice, then ``np.shape(s)``; the last two are empty
        without ``with_tip_derivatives``."""
        x = np.asarray(s, dtype=float)
        points = np.ascontiguousarray(x.ravel())
        n = points.size
        P, O = np.empty((n, 3)), np.empty((n, 3))
        m = n if with_tip_derivatives else 0
        speed, bend = np.empty(m), np.empty(m)
        run_chunks(_sample, (n + _CHUNK - 1) // _CHUNK, *self._pieces, points,
                   bool(with_tip_derivatives), P, O, speed, bend)
        if not with_tip_derivatives:
            return P.reshape(x.shape + (3,)), O.reshape(x.shape + (3,)), speed, bend
        return (P.reshape(x.shape + (3,)), O.reshape(x.shape + (3,)), speed.reshape(x.shape),
                bend.reshape(x.shape))


def _normalized_derivatives(v: list[np.ndarray]) -> list[np.ndarray]:
    """Derivatives of n = v/|v| up to len(v)-1 <= 3 from those of v.

    With v = r n, |n| = 1: r' = n.v', r'' = n.v'' + r|n'|^2, r''' = n.v''' + 3 r n'.n'' (from
    differentiating n.n = 1), and each n^(k) follows from Leibniz's rule for r n.
    """
    dot = lambda a, b: np.sum(a * b, axis=-1, keepdims=True)  # noqa: E731
    r = np.linalg.norm(v[0], axis=-1, keepdims=True)
    n = [v[0] / r]
    if len(v) > 1:
        r1 = dot(n[0], v[1])
        n.append((v[1] - r1 * n[0]) / r)
    if len(v) > 2:
        r2 = dot(n[0], v[2]) + r * dot(n[1], n[1])
        n.append((v[2] - r2 * n[0] - 2 * r1 * n[1]) / r)
    if len(v) > 3:
        r3 = dot(n[0], v[3]) + 3 * r * dot(n[1], n[2])
        n.append((v[3] - r3 * n[0] - 3 * r2 * n[1] - 3 * r1 * n[2]) / r)
    return n


def checked_points(P, O, *, source: str = "", first_row: int = 0
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Programmed tool tips ``P`` and orientations ``O`` as float arrays, the orientations
    normalized (:func:`~precontour.machine.kinematics.normalize_orientations`, with its one
    notice), after checking shapes (M, 3), M >= 2 and finite values; a
    :class:`~precontour.errors.ToolPathError` names the first bad row (``first_row`` + 1 on,
    as :func:`fit_path`)."""
    src = source or None
    P = np.asarray(P, dtype=float)
    O = np.asarray(O, dtype=float)
    if P.ndim != 2 or P.shape[1] != 3 or O.shape != P.shape:
        raise ToolPathError(f"P and O must both have shape (M, 3), got {P.shape} and {O.shape}",
                            source=src)
    for name, arr in (("P", P), ("O", O)):
        bad = ~np.isfinite(arr).all(axis=1)
        if bad.any():
            row = int(np.flatnonzero(bad)[0])
            raise ToolPathError(f"{name} is not finite ({arr[row].tolist()})", source=src,
                                row=first_row + row + 1, field=name)
    if P.shape[0] < 2:
        raise ToolPathError(f"a tool path needs at least 2 points, got {P.shape[0]}", source=src)
    try:
        O = normalize_orientations(O, source=src)
    except InputError as exc:
        raise ToolPathError(str(exc)) from None
    return P, O


def fit_path(P, O, *, l_eq: float = L_EQ, source: str = "", first_row: int = 0) -> PathSpline:
    """Fit C3 quintic splines through programmed tool tips and orientations.

    Parameters
    ----------
    P : array_like, shape (M, 3)
        Tool tip points, mm, workpiece frame.
    O : array_like, shape (M, 3)
        Unit tool orientations (normalized within
        :data:`precontour.machine.kinematics.UNIT_TOLERANCE`, rejected beyond).
    l_eq : float
        Equivalent length of one radian of tool rotation, mm/rad (see module docstring).
    source : str
        Name of the tool path, for messages.
    first_row : int
        Row (0-based) of the tool path's first point in its file, for messages (a stretch of
        a longer path; ``point_index`` stays relative to ``P``).

    Returns
    -------
    PathSpline
        Splines passing exactly (to round-off) through every kept point. Consecutive
        duplicates (closer than :data:`DUPLICATE_TOLERANCE` in combined length) are dropped.
        With fewer than 6 distinct points the spline degree drops to M - 1 (one polynomial).

    Raises
    ------
    ToolPathError
        Bad shapes, non-finite values, non-unit orientations, fewer than two distinct
        points (a single point or a zero-length path), or an orientation turning by more
        than :data:`MAX_ORIENTATION_STEP` between consecutive points.
    """
    src = source or None
    if not l_eq > 0 or not np.isfinite(l_eq):
        raise ValueError(f"l_eq must be a positive finite length in mm/rad, got {plain(l_eq)!r}")
    P, O = checked_points(P, O, source=source, first_row=first_row)

    d_tip = np.linalg.norm(np.diff(P, axis=0), axis=1)
    d_ang = angle_between(O[:-1], O[1:])
    chord = np.hypot(d_tip, l_eq * d_ang)
    keep = np.concatenate([[True], chord >= DUPLICATE_TOLERANCE])
    # A run of duplicates collapses onto its first point; chords to the next kept point are
    # recomputed below from the kept points themselves.
    index = np.flatnonzero(keep)
    if index.size < 2:
        raise ToolPathError(f"zero-length path: all {P.shape[0]} points have the same tool "
                            "tip and orientation", source=src)
    dropped = index.size < P.shape[0]
    if dropped:
        P, O = P[index], O[index]
        d_ang = angle_between(O[:-1], O[1:])
    big = d_ang > MAX_ORIENTATION_STEP
    if big.any():
        i = int(np.flatnonzero(big)[0])
        raise ToolPathError(f"tool orientation turns by {d_ang[i]:.6g} rad from the previous "
                            f"point (at most {MAX_ORIENTATION_STEP:.6g}); insert points",
                            source=src, row=first_row + int(index[i + 1]) + 1, field="O")
    if dropped:
        chord = np.hypot(np.linalg.norm(np.diff(P, axis=0), axis=1), l_eq * d_ang)

    s = np.concatenate([[0.0], np.cumsum(chord)])
    tip, orient = _interpolate(s, P, O)
    # One re-parameterization pass: measure each segment's combined length on the chord-length
    # spline and refit, so that s is (nearly) the combined arc length.
    seg = _segment_lengths(tip, orient, s, l_eq)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    tip, orient = _interpolate(s, P, O)
    return PathSpline(tip_spline=tip, orientation_spline=orient, s_points=s,
                      point_index=index, l_eq=float(l_eq))




def fit_toolpath(toolpath, *, l_eq: float = L_EQ) -> PathSpline:
    """:func:`fit_path` of a :class:`precontour.toolpath.ToolPath`."""
    return fit_path(toolpath.P, toolpath.O, l_eq=l_eq, source=toolpath.source)


def corner_points(P: np.ndarray, O: np.ndarray, *, l_eq: float = L_EQ,
                  angle: float = CORNER_ANGLE) -> np.ndarray:
    """Rows (0-based, interior points only) where the tool path turns by ``angle`` degrees or
    more (:data:`CORNER_ANGLE`) between the move that ends there and the move that starts
    there. A move is the chord of tip and orientation in the combined length's units
    (``P`` difference, ``l_eq`` times the unit orientations' difference); duplicate points
    (a chord below :data:`DUPLICATE_TOLERANCE`) are skipped, a corner among them is at the
    first of them. ``P``, ``O``: shape (M, 3); ``O`` need not be unit length yet."""
    P = np.asarray(P, dtype=float)
    O = np.asarray(O, dtype=float)
    if P.shape[0] < 3:
        return np.zeros(0, dtype=int)
    with np.errstate(invalid="ignore", divide="ignore"):
        unit = O / np.linalg.norm(O, axis=1, keepdims=True)
    chord = np.concatenate([np.diff(P, axis=0), l_eq * np.diff(unit, axis=0)], axis=1)
    length = np.linalg.norm(chord, axis=1)
    moves = np.flatnonzero(length >= DUPLICATE_TOLERANCE)   # move k: point k -> point k + 1
    if moves.size < 2:
        return np.zeros(0, dtype=int)
    direction = chord[moves] / length[moves, None]
    cosine = np.einsum("ij,ij->i", direction[1:], direction[:-1])
    turn = np.degrees(np.arccos(np.clip(cosine, -1.0, 1.0)))
    # the corner is the point the first of the two moves ends at
    return moves[:-1][turn >= angle] + 1


def _interpolate(s: np.ndarray, P: np.ndarray, O: np.ndarray) -> tuple[BSpline, BSpline]:
    # one interpolation of both: they share the collocation matrix and its factorization
    both = interpolating_spline(s, np.concatenate([P, O], axis=1), k=min(5, s.size - 1))
    # construct_fast: the knots are the interpolant's (BSpline() would check and sort them)
    return tuple(BSpline.construct_fast(both.t, np.ascontiguousarray(both.c[:, part]), both.k)
                 for part in (slice(0, 3), slice(3, 6)))


def _segment_lengths(tip: BSpline, orient: BSpline, s: np.ndarray, l_eq: float) -> np.ndarray:
    """Combined length of each segment [s_i, s_i+1] of the splines: 5-point Gauss-Legendre
    of sqrt(|P'|^2 + l_eq^2 |O'|^2), O = v/|v|."""
    knots, control, breaks, spans = bspline_layout(tip, joint_control(tip, orient))
    s = np.ascontiguousarray(s, dtype=float)
    out = np.empty(s.size - 1)
    run_chunks(_gauss_lengths, (out.size + _CHUNK - 1) // _CHUNK, knots, control, int(tip.k),
               breaks, spans, s, float(l_eq), _GAUSS_X, _GAUSS_W, out)
    return out


@jit
def _gauss_lengths(first, stop, knots, control, degree, breaks, spans, s, l_eq, nodes, weights,
                   out):
    # Each segment lies in one piece (the breaks are data sites); the piece's Taylor
    # coefficients are made when the segments reach it, not stored for the whole spline.
    n = s.size - 1
    dims = control.shape[1]
    for chunk in range(first, stop):
        coef = np.empty((1, degree + 1, dims))
        basis = np.zeros((degree + 1, degree + 1))
        left = np.zeros(degree + 1)
        right = np.zeros(degree + 1)
        points = np.zeros((degree + 1, degree + 1, dims))
        current = -1
        for i in range(chunk * _CHUNK, min(n, (chunk + 1) * _CHUNK)):
            h = s[i + 1] - s[i]
            piece = locate(breaks, s[i] + 0.5 * h, max(current, 0))
            if piece != current:
                taylor_coefficients_at(knots, control, degree, breaks[piece], spans[piece],
                                       basis, left, right, points, coef, 0)
                current = piece
            total = 0.0
            for g in range(nodes.size):
                x = s[i] + 0.5 * h * (nodes[g] + 1.0) - breaks[piece]
                tip2 = 0.0
                vv = 0.0
                vdv = 0.0
                dvdv = 0.0
                for d in range(3):
                    dp = derivative(coef, 0, x, 1, d)
                    v = derivative(coef, 0, x, 0, 3 + d)
                    dv = derivative(coef, 0, x, 1, 3 + d)
                    tip2 += dp * dp
                    vv += v * v
                    vdv += v * dv
                    dvdv += dv * dv
                # O' = (v' - (n.v') n)/|v|, n = v/|v|: |O'|^2 = (|v'|^2 - (n.v')^2)/|v|^2
                turn2 = max(dvdv - vdv * vdv / vv, 0.0) / vv
                total += weights[g] * np.sqrt(tip2 + l_eq * l_eq * turn2)
            out[i] = 0.5 * h * total


@jit
def _sample(first, stop, breaks, coef, x, with_tip_derivatives, P, O, speed, bend):
    n = x.size
    for chunk in range(first, stop):
        piece = 0
        for i in range(chunk * _CHUNK, min(n, (chunk + 1) * _CHUNK)):
            piece = locate(breaks, x[i], piece)
            u = x[i] - breaks[piece]
            for d in range(3):
                P[i, d] = derivative(coef, piece, u, 0, d)
                O[i, d] = derivative(coef, piece, u, 0, 3 + d)
            r = np.sqrt(O[i, 0] * O[i, 0] + O[i, 1] * O[i, 1] + O[i, 2] * O[i, 2])
            for d in range(3):
                O[i, d] /= r
            if with_tip_derivatives:
                first = 0.0
                second = 0.0
                for d in range(3):
                    first += derivative(coef, piece, u, 1, d) ** 2
                    second += derivative(coef, piece, u, 2, d) ** 2
                speed[i] = np.sqrt(first)
                bend[i] = np.sqrt(second)
