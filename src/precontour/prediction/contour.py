"""Contour errors: distance of the actual tool tip and orientation from the reference curves.

Spec section 5 (paper Eqs. 18-21). The reference tool tip P(u) and orientation O(w) are C4
quintic interpolating splines of the reference samples, parameterized by time. For each actual
sample the closest reference point is searched inside a window around the time-corresponding
parameter, so a path that comes back near itself cannot capture the wrong branch: the nearest
reference sample in the window (from a k-d tree) starts Newton's method on the spline.
Everything is vectorized over samples.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy.interpolate import BSpline, make_interp_spline
from scipy.spatial import cKDTree

from ..errors import InputError
from ..machine.kinematics import angle_between
from ..trajectory.sampled import Trajectory

#: The closest point is searched within DEFAULT_WINDOW seconds of the time-corresponding
#: point, widened to DEFAULT_WINDOW_LENGTH of path progress (tip arc length plus
#: ORIENTATION_LENGTH mm per rad of orientation change) where the path moves slowly: near a stop
#: the actual machine can lag far behind in time while being close in space.
DEFAULT_WINDOW = 0.05
DEFAULT_WINDOW_LENGTH = 2.0
MAX_WINDOW_FACTOR = 20
ORIENTATION_LENGTH = 100.0
NEWTON_ITERATIONS = 60
#: Newton's method stops for a sample when its parameter step is below this (s): 1 ns is
#: 0.1 nm of path at 100 mm/s.
PARAMETER_TOLERANCE = 1e-9
#: Largest step (s) outside a bracket; keeps the iteration local where the path stops.
MAX_STEP = 0.005
#: Newton's method starts from the nearest reference sample in the window, found among this
#: many nearest reference samples (k-d tree), or by scanning the window where none is in it.
NEIGHBOURS = 16


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
                    window: float = DEFAULT_WINDOW,
                    window_length: float = DEFAULT_WINDOW_LENGTH) -> np.ndarray:
        """Parameter u* of the reference point closest to each ``P_act`` (spec Eq. 19):
        P'(u*) . (P(u*) - P_act) = 0, searched within the window around ``u0``."""
        curve, d1, d2 = self.tip, self.tip.derivative(), self.tip.derivative(2)

        def gradient_and_curvature(u, i):
            r = curve(u) - P_act[i]
            v = d1(u)
            return (np.einsum("ij,ij->i", v, r),
                    np.einsum("ij,ij->i", d2(u), r) + np.einsum("ij,ij->i", v, v))

        def distance(u):
            return np.linalg.norm(curve(u) - P_act, axis=1)
        return self._search(u0, window, window_length, gradient_and_curvature, distance,
                            lambda k, i: np.linalg.norm(self.P[k] - P_act[i], axis=1),
                            self._tip_tree, P_act)

    def closest_orientation(self, O_act: np.ndarray, w0: np.ndarray | None = None,
                            window: float = DEFAULT_WINDOW,
                            window_length: float = DEFAULT_WINDOW_LENGTH) -> np.ndarray:
        """Parameter w* of the reference orientation closest to each ``O_act`` (spec Eq. 21):
        O'(w*) . O_act = 0 on the unit sphere, searched within the window around ``w0``."""
        curve, d1, d2 = (self.orientation, self.orientation.derivative(),
                         self.orientation.derivative(2))

        def gradient_and_curvature(w, i):
            # minimize -O(w) . O_act; |O(w)| = 1 up to the interpolation's round-off
            return (-np.einsum("ij,ij->i", d1(w), O_act[i]),
                    -np.einsum("ij,ij->i", d2(w), O_act[i]))
        return self._search(w0, window, window_length, gradient_and_curvature,
                            lambda w: angle_between(curve(w), O_act),
                            lambda k, i: angle_between(self.O[k], O_act[i]),
                            self._orientation_tree, O_act)

    def errors(self, P_act: np.ndarray, O_act: np.ndarray, t: np.ndarray | None = None,
               window: float = DEFAULT_WINDOW,
               window_length: float = DEFAULT_WINDOW_LENGTH) -> ContourErrors:
        """Contour errors of actual tips ``P_act`` and orientations ``O_act`` sampled at
        ``t`` (default: the reference's own time stamps)."""
        t = self.t if t is None else np.asarray(t, dtype=float)
        u = self.closest_tip(P_act, t, window, window_length)
        w = self.closest_orientation(O_act, t, window, window_length)
        tip = np.linalg.norm(self.tip(u) - P_act, axis=1)
        orientation = angle_between(self.orientation(w), O_act)
        return ContourErrors(tip=tip, orientation=orientation, tip_parameter=u,
                             orientation_parameter=w)

    @cached_property
    def _tip_tree(self) -> cKDTree:
        return cKDTree(self.P)

    @cached_property
    def _orientation_tree(self) -> cKDTree:
        # chord length on the unit sphere is monotone in the angle
        return cKDTree(self.O)

    @cached_property
    def progress(self) -> np.ndarray:
        """Path progress at each reference sample: tip arc length plus ORIENTATION_LENGTH mm
        per rad of orientation change (monotone), mm."""
        step = (np.linalg.norm(np.diff(self.P, axis=0), axis=1)
                + ORIENTATION_LENGTH * angle_between(self.O[:-1], self.O[1:]))
        return np.concatenate([[0.0], np.cumsum(step)])

    def _window(self, start, window, window_length):
        """Sample-index bounds [lo, hi] of the search window of each start parameter."""
        n = self.t.size
        step = (self.t[-1] - self.t[0]) / (n - 1)
        base = np.clip(np.rint((start - self.t[0]) / step).astype(np.intp), 0, n - 1)
        reach = int(np.floor(window / step))
        progress = self.progress
        lo = np.minimum(np.maximum(base - reach, 0),
                        np.searchsorted(progress, progress[base] - window_length, side="left"))
        hi = np.maximum(np.minimum(base + reach, n - 1),
                        np.searchsorted(progress, progress[base] + window_length, side="right") - 1)
        # On a long slow stretch the path-progress window would cover thousands of samples;
        # MAX_WINDOW_FACTOR time windows either side is more than any lag and keeps the
        # search linear in the number of samples.
        longest = MAX_WINDOW_FACTOR * max(reach, 1)
        return base, np.maximum(lo, base - longest), np.minimum(hi, base + longest)

    def _search(self, start, window, window_length, gradient_and_curvature, distance,
                sample_distance, tree, points):
        """Closest parameter in each window: find the nearest reference sample in the window
        (``tree``, a k-d tree of the reference samples, queried with the actual ``points``;
        ``sample_distance(k, i)``: distance of actual point i to reference sample k), refine
        by Newton's method, and keep the refined point unless the sample itself is nearer."""
        start = self.t if start is None else np.asarray(start, dtype=float)
        base, lo, hi = self._window(start, window, window_length)
        everyone = np.arange(base.size)
        # The NEIGHBOURS nearest samples overall, nearest first: if any lies in the window,
        # the first such is the nearest sample in the window (a nearer one would be listed).
        _, near = tree.query(points, k=min(NEIGHBOURS, self.t.size))
        in_window = (near >= lo[:, None]) & (near <= hi[:, None])
        found = in_window.any(axis=1)
        best_k = np.where(found, near[everyone, np.argmax(in_window, axis=1)], base)
        # Where the path comes back near itself more than NEIGHBOURS times, scan the window.
        missing = np.flatnonzero(~found)
        if missing.size:
            best = sample_distance(base[missing], missing)
            for offset in range(int((lo - base)[missing].min()),
                                int((hi - base)[missing].max()) + 1):
                k = base[missing] + offset
                inside = (k >= lo[missing]) & (k <= hi[missing])
                i = missing[inside]
                d = sample_distance(k[inside], i)
                better = d < best[inside]
                best[np.flatnonzero(inside)[better]] = d[better]
                best_k[i[better]] = k[inside][better]
        # The minimum lies within one sample of the best sample: bracket it there and refine
        # by Newton's method safeguarded with bisection on the sign of the gradient.
        a = self.t[np.maximum(best_k - 1, lo)]
        b = self.t[np.minimum(best_k + 1, hi)]
        g_a, _ = gradient_and_curvature(a, everyone)
        g_b, _ = gradient_and_curvature(b, everyone)
        interior = (g_a < 0) & (g_b > 0)
        # Elsewhere (a minimum at the window's edge, or a flat stretch where the reference
        # stands still) take bounded Newton / gradient steps inside the window.
        u_lo, u_hi = self.t[lo], self.t[hi]
        u = self.t[best_k].copy()
        # Samples leave the iteration once their step falls below PARAMETER_TOLERANCE.
        active = everyone
        for _ in range(NEWTON_ITERATIONS):
            ua, aa, bb = u[active], a[active], b[active]
            g, c = gradient_and_curvature(ua, active)
            bb = np.where(g > 0, ua, bb)
            aa = np.where(g > 0, aa, ua)
            a[active], b[active] = aa, bb
            newton = ua - g / np.where(c > 0, c, np.inf)
            inside = (c > 0) & (newton > aa) & (newton < bb)
            bracketed = np.where(inside, newton, 0.5 * (aa + bb))
            free_step = np.where(c > 0, -g / np.where(c > 0, c, 1.0), -np.sign(g) * MAX_STEP)
            free = np.clip(ua + np.clip(free_step, -MAX_STEP, MAX_STEP), u_lo[active],
                           u_hi[active])
            u_new = np.where(interior[active], bracketed, free)
            u[active] = u_new
            active = active[np.abs(u_new - ua) > PARAMETER_TOLERANCE]
            if active.size == 0:
                break
        candidates = [u, self.t[best_k]]
        values = np.stack([distance(c) for c in candidates])
        return np.choose(np.argmin(values, axis=0), candidates)


def contour_errors(reference: ReferencePath, q_act: np.ndarray, kinematics,
                   t: np.ndarray | None = None, window: float = DEFAULT_WINDOW,
                   window_length: float = DEFAULT_WINDOW_LENGTH) -> ContourErrors:
    """Contour errors of actual axis positions ``q_act`` (N, 5) against ``reference``."""
    P_act, O_act = kinematics.forward(q_act)
    return reference.errors(P_act, O_act, t, window, window_length)
