"""Contour errors: distance of the actual tool tip and orientation from the reference curves.

Spec section 5 (paper Eqs. 18-21). The reference tool tip P(u) and orientation O(w) are C4
quintic interpolating splines of the reference samples, parameterized by time. For each actual
sample the closest reference point is found by Newton's method on the spline, started at the
time-corresponding parameter and kept inside a window around it, so a path that comes back near
itself cannot capture the wrong branch. Everything is vectorized over samples.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import BSpline, make_interp_spline

from .errors import InputError
from .trajectory import Trajectory

#: Half width (s) of the parameter window searched around the time-corresponding point.
DEFAULT_WINDOW = 0.05
#: Largest Newton step (s); keeps the iteration local where the path slows to a stop.
MAX_STEP = 0.005
NEWTON_ITERATIONS = 30
#: Sample offsets tried before Newton's method, to start it in the right basin even where the
#: reference stands still (Newton's method alone cannot leave a flat stretch).
SEED_OFFSETS = np.array([0, -1, 1, -2, 2, -3, 3, -5, 5, -8, 8, -12, 12, -18, 18, -25, 25,
                         -35, 35, -50, 50])


@dataclass(frozen=True)
class ContourErrors:
    """Tool-tip and orientation contour errors of a motion against its reference.

    Attributes
    ----------
    tip : ndarray, shape (N,)
        eps_p = |P(u*) - P_act|, mm.
    orientation : ndarray, shape (N,)
        eps_o = arccos(O_act . O(w*)), rad.
    tip_parameter, orientation_parameter : ndarray, shape (N,)
        u* and w* (s on the reference's time axis).
    """

    tip: np.ndarray
    orientation: np.ndarray
    tip_parameter: np.ndarray
    orientation_parameter: np.ndarray

    def summary(self) -> dict[str, float]:
        """max and mean of each, in um and mrad."""
        return {"tip_max_um": 1e3 * float(self.tip.max()),
                "tip_mean_um": 1e3 * float(self.tip.mean()),
                "ori_max_mrad": 1e3 * float(self.orientation.max()),
                "ori_mean_mrad": 1e3 * float(self.orientation.mean())}


@dataclass(frozen=True)
class ReferencePath:
    """The reference tool tip P(u) and orientation O(w) as C4 quintic splines of time.

    Build it with :meth:`from_trajectory`. ``tip(u, nu)`` and ``orientation(w, nu)`` are
    :class:`scipy.interpolate.BSpline` (values of shape ``u.shape + (3,)``).
    """

    t: np.ndarray
    tip: BSpline
    orientation: BSpline
    P: np.ndarray
    O: np.ndarray

    @classmethod
    def from_trajectory(cls, traj: Trajectory) -> "ReferencePath":
        if not traj.has_reference:
            raise InputError("contour errors need the reference tool path: columns "
                             "Px,Py,Pz,Oi,Oj,Ok", field="Px")
        return cls.from_samples(traj.t, traj.P, traj.O)

    @classmethod
    def from_samples(cls, t: np.ndarray, P: np.ndarray, O: np.ndarray) -> "ReferencePath":
        t = np.asarray(t, dtype=float)
        if t.size < 6:
            raise InputError(f"too few samples for the reference curves: {t.size}, need 6",
                             field="t")
        P = np.asarray(P, dtype=float)
        O = np.asarray(O, dtype=float)
        tip = make_interp_spline(t, P, k=5)
        orientation = make_interp_spline(t, O, k=5)
        return cls(t=t, tip=tip, orientation=orientation, P=P, O=O)

    def closest_tip(self, P_act: np.ndarray, u0: np.ndarray | None = None,
                    window: float = DEFAULT_WINDOW) -> np.ndarray:
        """Parameter u* of the reference point closest to each ``P_act`` (spec Eq. 19):
        P'(u*) . (P(u*) - P_act) = 0, searched within ``u0 +- window``."""
        curve, d1, d2 = self.tip, self.tip.derivative(), self.tip.derivative(2)

        def gradient_and_curvature(u):
            r = curve(u) - P_act
            v = d1(u)
            return np.einsum("ij,ij->i", v, r), np.einsum("ij,ij->i", d2(u), r) + np.einsum("ij,ij->i", v, v)
        seed = self._seed(u0, window, lambda k: np.linalg.norm(self.P[k] - P_act, axis=1))
        u = self._newton(gradient_and_curvature, seed, u0, window)
        # Newton finds a stationary point; also try the window ends and keep the nearest.
        return self._best_of(u, u0, window, lambda uu: np.linalg.norm(curve(uu) - P_act, axis=1))

    def closest_orientation(self, O_act: np.ndarray, w0: np.ndarray | None = None,
                            window: float = DEFAULT_WINDOW) -> np.ndarray:
        """Parameter w* of the reference orientation closest to each ``O_act`` (spec Eq. 21):
        O'(w*) . O_act = 0 on the unit sphere, searched within ``w0 +- window``."""
        curve, d1, d2 = (self.orientation, self.orientation.derivative(),
                         self.orientation.derivative(2))

        def gradient_and_curvature(w):
            # minimize -O(w) . O_act; |O(w)| = 1 up to the interpolation's round-off
            return (-np.einsum("ij,ij->i", d1(w), O_act), -np.einsum("ij,ij->i", d2(w), O_act))
        seed = self._seed(w0, window, lambda k: _angle(self.O[k], O_act))
        w = self._newton(gradient_and_curvature, seed, w0, window)
        return self._best_of(w, w0, window, lambda ww: _angle(curve(ww), O_act))

    def errors(self, P_act: np.ndarray, O_act: np.ndarray, t: np.ndarray | None = None,
               window: float = DEFAULT_WINDOW) -> ContourErrors:
        """Contour errors of actual tips ``P_act`` and orientations ``O_act`` sampled at
        ``t`` (default: the reference's own time stamps)."""
        t = self.t if t is None else np.asarray(t, dtype=float)
        u = self.closest_tip(P_act, t, window)
        w = self.closest_orientation(O_act, t, window)
        tip = np.linalg.norm(self.tip(u) - P_act, axis=1)
        orientation = _angle(self.orientation(w), O_act)
        return ContourErrors(tip=tip, orientation=orientation, tip_parameter=u,
                             orientation_parameter=w)

    def _seed(self, start, window, distance):
        """Best reference sample near each start parameter (within the window)."""
        start = self.t if start is None else np.asarray(start, dtype=float)
        step = (self.t[-1] - self.t[0]) / (self.t.size - 1)
        base = np.rint((start - self.t[0]) / step).astype(np.intp)
        reach = int(np.floor(window / step))
        offsets = SEED_OFFSETS[np.abs(SEED_OFFSETS) <= reach]
        best_k = np.clip(base, 0, self.t.size - 1)
        best = distance(best_k)
        for offset in offsets[1:]:
            k = np.clip(base + offset, 0, self.t.size - 1)
            d = distance(k)
            better = d < best
            best = np.where(better, d, best)
            best_k = np.where(better, k, best_k)
        return self.t[best_k]

    def _newton(self, gradient_and_curvature, seed, start, window):
        start = self.t if start is None else np.asarray(start, dtype=float)
        lo = np.maximum(start - window, self.t[0])
        hi = np.minimum(start + window, self.t[-1])
        u = np.clip(seed, lo, hi)
        for _ in range(NEWTON_ITERATIONS):
            g, c = gradient_and_curvature(u)
            # Where the distance is not convex (c <= 0) take a bounded gradient step instead.
            step = np.where(c > 0, -g / np.where(c > 0, c, 1.0), -np.sign(g) * MAX_STEP)
            step = np.clip(step, -MAX_STEP, MAX_STEP)
            u_new = np.clip(u + step, lo, hi)
            if np.all(np.abs(u_new - u) <= 1e-13 * (1.0 + np.abs(u))):
                u = u_new
                break
            u = u_new
        return u

    def _best_of(self, u, start, window, distance):
        start = self.t if start is None else np.asarray(start, dtype=float)
        candidates = [u, np.maximum(start - window, self.t[0]), np.minimum(start + window, self.t[-1])]
        values = np.stack([distance(c) for c in candidates])
        best = np.argmin(values, axis=0)
        return np.choose(best, candidates)


def _angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle between rows of a and b (not necessarily unit), accurate for small angles."""
    cross = np.linalg.norm(np.cross(a, b), axis=1)
    dot = np.einsum("ij,ij->i", a, b)
    return np.arctan2(cross, dot)


def contour_errors(reference: ReferencePath, q_act: np.ndarray, kinematics,
                   t: np.ndarray | None = None, window: float = DEFAULT_WINDOW) -> ContourErrors:
    """Contour errors of actual axis positions ``q_act`` (N, 5) against ``reference``."""
    P_act, O_act = kinematics.forward(q_act)
    return reference.errors(P_act, O_act, t, window)
