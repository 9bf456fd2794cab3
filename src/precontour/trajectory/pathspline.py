"""Geometric C3 splines of a programmed tool path: tool tip P(s) and orientation O(s).

Both curves share one parameter s (mm), the combined path length

    ds^2 = |dP|^2 + (L_eq * dtheta)^2,        L_eq = :data:`L_EQ` = 1 mm/rad,

where dtheta is the angle the tool orientation turns. Where the tip moves, s is its arc length
to within a fraction (L_eq * dtheta/|dP|)^2 / 2 (about 0.05 % for a typical 0.03 rad/mm
five-axis path); where the tip stands still while the tool turns (a pure rotation move), s keeps
growing by L_eq per rad, so such moves never make the parameterization degenerate. The tip and
the (unnormalized) orientation are interpolated by quintic not-a-knot B-splines
(:func:`scipy.interpolate.make_interp_spline`, C4 at the knots) through every programmed point;
the orientation is normalized on evaluation, which keeps it unit length and C3. The parameter
comes from one pass of chord lengths followed by one re-parameterization with the combined
length of the chord-length spline (5-point Gauss-Legendre per segment).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import BSpline, make_interp_spline

from ..errors import InputError, ToolPathError, plain
from ..machine.kinematics import angle_between, normalize_orientations

#: Equivalent length of one radian of tool rotation in the combined path parameter, mm/rad.
L_EQ = 1.0

#: Consecutive points closer than this in combined length (mm) are duplicates: the later one
#: is dropped, with its programmed feed.
DUPLICATE_TOLERANCE = 1e-6

#: Largest turn of the tool orientation between two consecutive programmed points, rad. The
#: orientation spline is normalized on evaluation; beyond a right angle its chord could pass
#: near the origin and the normalized curve would whip round.
MAX_ORIENTATION_STEP = np.pi / 2

_GAUSS_X, _GAUSS_W = np.polynomial.legendre.leggauss(5)


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

    def tip(self, s, nu: int = 0) -> np.ndarray:
        """Tool tip P(s) (nu = 0) or its nu-th derivative with respect to s; shape
        ``np.shape(s) + (3,)``, mm/mm^nu."""
        return self.tip_spline(s, nu)

    def orientation(self, s, nu: int = 0) -> np.ndarray:
        """Unit orientation O(s) or its nu-th derivative (nu <= 3); shape
        ``np.shape(s) + (3,)``, 1/mm^nu."""
        if nu not in (0, 1, 2, 3):
            raise ValueError(f"orientation derivatives are available up to order 3, got {nu}")
        derivs = [self.orientation_spline(s, k) for k in range(nu + 1)]
        return _normalized_derivatives(derivs)[nu]

    def __call__(self, s, nu: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """``(P, O)`` or their nu-th derivatives at ``s``, as in :meth:`tip` and
        :meth:`orientation`."""
        return self.tip(s, nu), self.orientation(s, nu)


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


def fit_path(P, O, *, l_eq: float = L_EQ, source: str = "") -> PathSpline:
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
    P = np.asarray(P, dtype=float)
    O = np.asarray(O, dtype=float)
    if P.ndim != 2 or P.shape[1] != 3 or O.shape != P.shape:
        raise ToolPathError(f"P and O must both have shape (M, 3), got {P.shape} and {O.shape}",
                            source=src)
    if not l_eq > 0 or not np.isfinite(l_eq):
        raise ValueError(f"l_eq must be a positive finite length in mm/rad, got {plain(l_eq)!r}")
    for name, arr in (("P", P), ("O", O)):
        bad = ~np.isfinite(arr).all(axis=1)
        if bad.any():
            row = int(np.flatnonzero(bad)[0])
            raise ToolPathError(f"{name} is not finite ({arr[row].tolist()})", source=src,
                                row=row + 1, field=name)
    if P.shape[0] < 2:
        raise ToolPathError(f"a tool path needs at least 2 points, got {P.shape[0]}", source=src)
    try:
        O = normalize_orientations(O, source=src)
    except InputError as exc:
        raise ToolPathError(str(exc)) from None

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
    P, O = P[index], O[index]
    d_ang = angle_between(O[:-1], O[1:])
    big = d_ang > MAX_ORIENTATION_STEP
    if big.any():
        i = int(np.flatnonzero(big)[0])
        raise ToolPathError(f"tool orientation turns by {d_ang[i]:.6g} rad from the previous "
                            f"point (at most {MAX_ORIENTATION_STEP:.6g}); insert points",
                            source=src, row=int(index[i + 1]) + 1, field="O")
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


def _interpolate(s: np.ndarray, P: np.ndarray, O: np.ndarray) -> tuple[BSpline, BSpline]:
    k = min(5, s.size - 1)
    return make_interp_spline(s, P, k=k), make_interp_spline(s, O, k=k)


def _segment_lengths(tip: BSpline, orient: BSpline, s: np.ndarray, l_eq: float) -> np.ndarray:
    h = np.diff(s)
    u = s[:-1, None] + 0.5 * h[:, None] * (_GAUSS_X + 1.0)
    dP = tip(u, 1)
    dO = _normalized_derivatives([orient(u), orient(u, 1)])[1]
    speed = np.sqrt(np.sum(dP**2, axis=-1) + l_eq**2 * np.sum(dO**2, axis=-1))
    return 0.5 * h * (speed @ _GAUSS_W)
