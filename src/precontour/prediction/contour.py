"""Contour errors: distance of the actual tool tip and orientation from the reference curves.

Spec section 5 (paper Eqs. 18-21). The reference tool tip P(u) and orientation O(w) are C4
quintic interpolating splines of the reference samples, parameterized by time. For each actual
sample the closest reference point is searched inside a window around the time-corresponding
parameter, so a path that comes back near itself cannot capture the wrong branch: the nearest
reference sample in the window starts Newton's method on the spline. The per-sample search is
compiled (numba) and runs on all cores (threads over chunks of samples).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy.interpolate import BSpline, make_interp_spline

from ..errors import InputError
from ..kernels import jit, run_chunks
from ..machine.kinematics import angle_between
from ..piecewise import bspline_pieces, joint_control
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
#: Newton's method also stops after a step below this (s) when the step after it is
#: estimated below PARAMETER_TOLERANCE / 10.
LAST_STEP = 1e-6
#: Largest step (s) outside a bracket; keeps the iteration local where the path stops.
MAX_STEP = 0.005
_TIP, _ORIENTATION = 0, 1
#: Samples per task of the compiled search.
_CHUNK = 4096
# The compiled helpers called per sample are inlined: a call that passes arrays costs two
# atomic reference-count updates per array, which made the search about twice as slow. LLVM
# inlines them (forceinline), not numba (inline="always"), which types and compiles a copy of
# the helper at each call site: all of it inlined by numba, in a parallel loop, took 27 s to
# compile, now 3 s. _distance is numba-inlined: called with a constant, it would be compiled
# once more for that value. The capsule tree (_capsule_tree, _tree_nearest) added 0.8 s
# of compilation, measured on an empty cache (the same with _tree_nearest not inlined; 5 %
# faster inlined where it is needed).


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

    def summary(self) -> "ErrorSummary":
        """max and mean of each, in um and mrad, as named fields (``s.tip_max_um``); also a
        read-only mapping with the same keys (``s["tip_max_um"]``), as before."""
        return ErrorSummary(tip_max_um=1e3 * float(self.tip.max()),
                            tip_mean_um=1e3 * float(self.tip.mean()),
                            ori_max_mrad=1e3 * float(self.orientation.max()),
                            ori_mean_mrad=1e3 * float(self.orientation.mean()))


@dataclass(frozen=True, eq=False)
class ErrorSummary(Mapping):
    """The max and mean contour errors: tool tip in um, orientation in mrad. Named fields,
    and a read-only mapping of the same names (equal to a dict of them)."""

    tip_max_um: float
    tip_mean_um: float
    ori_max_mrad: float
    ori_mean_mrad: float

    def __getitem__(self, key: str) -> float:
        if key not in _SUMMARY_FIELDS:
            raise KeyError(key)
        return getattr(self, key)

    def __iter__(self):
        return iter(_SUMMARY_FIELDS)

    def __len__(self) -> int:
        return len(_SUMMARY_FIELDS)

    def __repr__(self) -> str:
        return "ErrorSummary(" + ", ".join(f"{k}={getattr(self, k)!r}"
                                           for k in _SUMMARY_FIELDS) + ")"


_SUMMARY_FIELDS = ("tip_max_um", "tip_mean_um", "ori_max_mrad", "ori_mean_mrad")


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
        # one interpolation of both: they share the collocation matrix and its factorization
        both = make_interp_spline(t, np.concatenate([P, O], axis=1), k=5)
        tip, orientation = (BSpline(both.t, np.ascontiguousarray(both.c[:, part]), both.k)
                            for part in (slice(0, 3), slice(3, 6)))
        return cls(t=t, tip=tip, orientation=orientation, P=P, O=O)

    def closest_tip(self, P_act: np.ndarray, u0: np.ndarray | None = None,
                    window: float = DEFAULT_WINDOW,
                    window_length: float = DEFAULT_WINDOW_LENGTH, *,
                    with_points: bool = False):
        """Parameter u* of the reference point closest to each ``P_act`` (spec Eq. 19):
        P'(u*) . (P(u*) - P_act) = 0, searched within the window around ``u0``. With
        ``with_points``: ``(u*, P(u*))``, the points found by the search."""
        u, _, points = self._search(u0, window, window_length, P_act, _TIP)
        return (u, points) if with_points else u

    def closest_orientation(self, O_act: np.ndarray, w0: np.ndarray | None = None,
                            window: float = DEFAULT_WINDOW,
                            window_length: float = DEFAULT_WINDOW_LENGTH, *,
                            with_points: bool = False):
        """Parameter w* of the reference orientation closest to each ``O_act`` (spec Eq. 21):
        O'(w*) . O_act = 0 on the unit sphere, searched within the window around ``w0``. With
        ``with_points``: ``(w*, O(w*))`` (the curve's value, not normalized)."""
        w, _, points = self._search(w0, window, window_length, O_act, _ORIENTATION)
        return (w, points) if with_points else w

    def errors(self, P_act: np.ndarray, O_act: np.ndarray, t: np.ndarray | None = None,
               window: float = DEFAULT_WINDOW, window_length: float = DEFAULT_WINDOW_LENGTH,
               *, with_points: bool = False):
        """Contour errors of actual tips ``P_act`` and orientations ``O_act`` sampled at
        ``t`` (default: the reference's own time stamps). With ``with_points``:
        ``(errors, P(u*), O(w*))``, the closest points the search found (O not normalized)."""
        t = self.t if t is None else np.asarray(t, dtype=float)
        u, tip, P_closest = self._search(t, window, window_length, P_act, _TIP)
        w, orientation, O_closest = self._search(t, window, window_length, O_act, _ORIENTATION)
        errors = ContourErrors(tip=tip, orientation=orientation, tip_parameter=u,
                               orientation_parameter=w)
        return (errors, P_closest, O_closest) if with_points else errors

    @cached_property
    def _pieces(self):
        """Breaks and Taylor coefficients of both curves, tip in dims 0-2 and orientation in
        3-5 (:meth:`from_samples` gives them the same knots)."""
        return bspline_pieces(self.tip, joint_control(self.tip, self.orientation))

    @cached_property
    def _tip_arrays(self):
        breaks, coef = self._pieces
        return _curve_arrays(breaks, coef, self.P)

    @cached_property
    def _orientation_arrays(self):
        breaks, coef = self._pieces
        return _curve_arrays(breaks, coef, self.O)

    @cached_property
    def _own_windows(self):
        return self._window(self.t, DEFAULT_WINDOW, DEFAULT_WINDOW_LENGTH)

    @cached_property
    def _tip_isolation(self):
        _, _, samples, tree = self._tip_arrays
        return _isolation(samples, tree, *self._own_windows[1:], ISOLATION_SPAN)

    @cached_property
    def _orientation_isolation(self):
        _, _, samples, tree = self._orientation_arrays
        return _isolation(samples, tree, *self._own_windows[1:], ISOLATION_SPAN)

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

    def _search(self, start, window, window_length, points, kind):
        """Closest parameter in each window, the distance there (mm or rad) and the closest
        curve point: the nearest reference sample in the window
        (exact: what the triangle inequality rules out is skipped), refined by
        Newton's method on the spline; the refined point is kept unless the sample itself is
        nearer. Compiled, one sample per iteration, spread over the available cores."""
        start = self.t if start is None else np.asarray(start, dtype=float)
        if (window, window_length) == (DEFAULT_WINDOW, DEFAULT_WINDOW_LENGTH) and (
                start is self.t or (start.shape == self.t.shape and np.array_equal(start, self.t))):
            base, lo, hi = self._own_windows    # the usual case: searched at its own samples
        else:
            base, lo, hi = self._window(start, window, window_length)
        breaks, coef, samples, tree = (self._tip_arrays if kind == _TIP
                                        else self._orientation_arrays)
        isolation = self._tip_isolation if kind == _TIP else self._orientation_isolation
        points = np.ascontiguousarray(points, dtype=float)
        return _closest_parameters(kind, self.t, samples, tree, isolation, breaks, coef,
                                   points, base, lo, hi)


def contour_errors(reference: ReferencePath, q_act: np.ndarray, kinematics,
                   t: np.ndarray | None = None, window: float = DEFAULT_WINDOW,
                   window_length: float = DEFAULT_WINDOW_LENGTH) -> ContourErrors:
    """Contour errors of actual axis positions ``q_act`` (N, 5) against ``reference``."""
    P_act, O_act = kinematics.forward(q_act)
    return reference.errors(P_act, O_act, t, window, window_length)


def _curve_arrays(breaks: np.ndarray, coef: np.ndarray, samples: np.ndarray):
    """What the compiled search needs of a reference curve: the pieces of both curves
    (:attr:`ReferencePath._pieces`; the search takes its curve's three of their six
    dimensions), the samples and their capsule tree (:func:`_capsule_tree`)."""
    samples = np.ascontiguousarray(samples)
    return breaks, coef, samples, _capsule_tree(samples)


@jit(forceinline=True)
def _evaluate(breaks, coef, offset, x, hint, out):
    """Value and first two derivatives of the piecewise polynomial at x into out[0..2, :]
    (Horner's scheme carried for the derivatives; dimensions offset .. offset + 2 of
    ``coef``), the piece found by walking from ``hint`` (parameters searched lie within a few
    pieces of a known sample)."""
    last = coef.shape[0] - 1
    piece = min(max(hint, 0), last)
    while piece > 0 and breaks[piece] > x:
        piece -= 1
    while piece < last and breaks[piece + 1] <= x:
        piece += 1
    s = x - breaks[piece]
    for d in range(3):
        value = coef[piece, 0, offset + d]
        first = 0.0
        second = 0.0
        for p in range(1, coef.shape[1]):
            second = second * s + first
            first = first * s + value
            value = value * s + coef[piece, p, offset + d]
        out[0, d] = value
        out[1, d] = first
        out[2, d] = 2.0 * second


@jit(forceinline=True)
def _gradient_curvature(kind, breaks, coef, x, hint, point, out):
    """d/du and d2/du2 of the search objective: |P(u) - p|^2 / 2 (tip, spec Eq. 19) or
    -O(w) . o (orientation on the unit sphere, spec Eq. 21)."""
    _evaluate(breaks, coef, 3 * kind, x, hint, out)
    g = 0.0
    c = 0.0
    if kind == 0:
        for d in range(3):
            r = out[0, d] - point[d]
            g += out[1, d] * r
            c += out[2, d] * r + out[1, d] * out[1, d]
    else:
        for d in range(3):
            g -= out[1, d] * point[d]
            c -= out[2, d] * point[d]
    return g, c


@jit(inline="always")
def _distance(kind, values, row, point):
    """Of ``values[row]`` from ``point``: tip, the Euclidean distance; orientation, the angle
    (atan2 of |a x b| and a . b, as ``angle_between``)."""
    if kind == 0:
        s = 0.0
        for d in range(3):
            s += (values[row, d] - point[d]) ** 2
        return np.sqrt(s)
    v0, v1, v2 = values[row, 0], values[row, 1], values[row, 2]
    cx = v1 * point[2] - v2 * point[1]
    cy = v2 * point[0] - v0 * point[2]
    cz = v0 * point[1] - v1 * point[0]
    dot = v0 * point[0] + v1 * point[1] + v2 * point[2]
    return np.arctan2(np.sqrt(cx * cx + cy * cy + cz * cz), dot)


@jit(forceinline=True)
def _chord(samples, k, point):
    # (the capsule tree's centre distance is this same expression: an exactly resting node is
    # decided by it bit for bit)
    s = 0.0
    for d in range(3):
        s += (samples[k, d] - point[d]) ** 2
    return np.sqrt(s)


#: Samples per leaf of the capsule tree (:func:`_capsule_tree`), and per block of the isolation
#: (:func:`_isolation`); a block's core is the block and one sample either side.
ISOLATION_BLOCK = 8
#: A block's isolation is taken over the search windows of its samples and of this many
#: samples either side, so that it serves any point whose window lies within those.
ISOLATION_SPAN = 4
#: Steps of the walk downhill from the time-corresponding sample before the isolation test.
#: Where the reference nearly rests and the actual lags along it, the walk would cross the
#: whole window one sample at a time (up to 2 MAX_WINDOW_FACTOR time windows: 2,000 samples
#: at 1 kHz); beyond this many steps the capsule tree finds the nearest sample instead.
DESCENT_STEPS = 32
#: Round-off allowance of the capsule tree, relative to the size of each distance computed
#: (:func:`_to_segment`): radii are enlarged by it when built and a capsule is ruled out only
#: by this much more than its distance bound (each is computed to a few units of 1e-16), so
#: nothing the brute-force comparison would pick is ever ruled out.
CAPSULE_SLACK = 1e-14
#: Entries of the tree search's stack: a depth-first search holds at most two per level.
_STACK = 128


def _capsule_tree(samples: np.ndarray):
    """Capsules around the samples, per level: a node is a run of consecutive samples (level
    0: ISOLATION_BLOCK of them; each level above: two nodes of the level below), bounded by
    the segment from its first to its last sample widened by its radius, the farthest of its
    samples from that segment. ``radii``: level l's nodes from ``offsets[l]``; built in one
    compiled pass, O(n). A radius is 0 exactly when every sample of its node is the same
    point, bit for bit."""
    n = samples.shape[0]
    counts = [-(-n // ISOLATION_BLOCK)]
    while counts[-1] > 1:
        counts.append(-(-counts[-1] // 2))
    offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.intp)
    radii = np.empty(offsets[-1])
    _build_capsules(samples, radii, offsets)
    return radii, offsets


@jit(forceinline=True)
def _to_segment(samples, a, b, x, y, z):
    """Distance of (x, y, z) from the segment from samples[a] to samples[b], and the size its
    round-off scales with (|point - samples[a]| + |samples[b] - samples[a]|). Differences
    from samples[a] and a cross product: no cancellation of the coordinates' magnitude."""
    wx = x - samples[a, 0]
    wy = y - samples[a, 1]
    wz = z - samples[a, 2]
    ux = samples[b, 0] - samples[a, 0]
    uy = samples[b, 1] - samples[a, 1]
    uz = samples[b, 2] - samples[a, 2]
    ww = np.sqrt(wx * wx + wy * wy + wz * wz)
    uu = ux * ux + uy * uy + uz * uz
    scale = ww + np.sqrt(uu)
    along = wx * ux + wy * uy + wz * uz
    if along <= 0.0 or uu == 0.0:
        return ww, scale
    if along >= uu:
        vx = x - samples[b, 0]
        vy = y - samples[b, 1]
        vz = z - samples[b, 2]
        return np.sqrt(vx * vx + vy * vy + vz * vz), scale
    cx = wy * uz - wz * uy
    cy = wz * ux - wx * uz
    cz = wx * uy - wy * ux
    return np.sqrt((cx * cx + cy * cy + cz * cz) / uu), scale


@jit
def _build_capsules(samples, radii, offsets):
    """:func:`_capsule_tree`'s radii: a leaf's from its samples, a node's above from its
    children's (the farther end of each child's segment from the node's segment plus the
    child's radius: an upper bound, as the distance from a segment is convex along the
    other), each enlarged by CAPSULE_SLACK of its round-off size."""
    n = samples.shape[0]
    for leaf in range(offsets[1]):
        first = leaf * ISOLATION_BLOCK
        last = min(first + ISOLATION_BLOCK, n) - 1
        radius = 0.0
        same = True
        for j in range(first, last + 1):
            for d in range(3):
                same = same and samples[j, d] == samples[first, d]
            d, scale = _to_segment(samples, first, last, samples[j, 0], samples[j, 1],
                                   samples[j, 2])
            radius = max(radius, d + CAPSULE_SLACK * scale)
        # (0 claims identical samples; any other node has a positive radius)
        radii[leaf] = 0.0 if same else max(radius, 1e-300)
    size = ISOLATION_BLOCK
    for level in range(1, offsets.size - 1):
        size *= 2
        below = offsets[level - 1]
        for node in range(offsets[level + 1] - offsets[level]):
            first = node * size
            last = min(first + size, n) - 1
            mid = first + size // 2               # the right child's first sample
            left = below + 2 * node
            radius = radii[left]
            if mid <= last:
                right = left + 1
                identical = radii[left] == 0.0 and radii[right] == 0.0
                for d in range(3):
                    identical = identical and samples[mid, d] == samples[first, d]
                if not identical:
                    # the children's inner ends (their outer ends are the node's)
                    radius = 0.0
                    for j, child in ((mid - 1, left), (mid, right)):
                        d, scale = _to_segment(samples, first, last, samples[j, 0],
                                               samples[j, 1], samples[j, 2])
                        radius = max(radius, d + CAPSULE_SLACK * scale + radii[child])
                    radius = max(radius, 1e-300)
            radii[offsets[level] + node] = radius


@jit(forceinline=True)
def _tree_nearest(radii, offsets, samples, point, lo, hi, start, best_k, best, stack,
                  bounds):
    """Nearest sample of [lo, hi] to ``point`` and its distance, given a candidate
    (``best_k`` at ``best``; -1 at inf for none): a depth-first search of the capsule tree
    (:func:`_capsule_tree`) from the smallest node holding the window, the child whose capsule
    is nearer first. A node is ruled out when its capsule is at least ``best`` away (triangle
    inequality, with CAPSULE_SLACK for round-off); a node of radius 0 (a stretch exactly at
    rest) is decided by one distance without visiting its samples. Of equal distances, the
    sample :func:`_preferred` from ``start`` (the candidate's index, where there is one).
    ``stack``, ``bounds``: scratch of _STACK entries.

    Cost: where the reference nearly rests its samples lie on a short, nearly straight
    capsule, and every node but those on the way to the nearest sample is ruled out:
    O(log window) nodes. The triangle-inequality skips along the samples that this replaces
    advanced one sample at a time there (the actual lagging along the reference's line),
    O(window) per point."""
    n = samples.shape[0]
    a = lo // ISOLATION_BLOCK
    b = hi // ISOLATION_BLOCK
    level = 0
    while (a >> level) != (b >> level):
        level += 1
    # an entry is node * 64 + level (levels < 64 for any array that fits in memory), with a
    # lower bound of the distances of its samples (-inf: not computed)
    stack[0] = ((a >> level) << 6) | level
    bounds[0] = -np.inf
    top = 1
    while top > 0:
        top -= 1
        if bounds[top] >= best:
            continue
        level = stack[top] & 63
        node = stack[top] >> 6
        size = ISOLATION_BLOCK << level
        first = node * size
        last = min(first + size, n) - 1
        if level == 0:
            for j in range(max(first, lo), min(last, hi) + 1):
                d = _chord(samples, j, point)
                if d < best or (d == best and _preferred(j, best_k, start)):
                    best = d
                    best_k = j
            continue
        # the children within the window, their bounds, the nearer pushed last (searched
        # first): where the distance falls monotonically across the window (the actual
        # lagging along a reference at rest) the first leaf reached holds the nearest sample
        # and every other node is ruled out
        split = first + size // 2                   # the right child's first sample
        count = 0
        for side in range(2):
            if (split > lo) if side == 0 else (split <= min(last, hi)):
                child = 2 * node + side
                c_first = first if side == 0 else split
                c_last = min(split - 1, last) if side == 0 else last
                radius = radii[offsets[level - 1] + child]
                if radius == 0.0:
                    # every sample of the child is the same: the one of the window
                    # preferred at equal distances, decided by its own distance
                    k = min(max(start, c_first, lo), c_last, hi)
                    d = _chord(samples, k, point)
                    if d < best or (d == best and _preferred(k, best_k, start)):
                        best = d
                        best_k = k
                    continue
                d, scale = _to_segment(samples, c_first, c_last, point[0], point[1],
                                       point[2])
                bound = d - radius - CAPSULE_SLACK * scale
                if bound >= best:
                    continue
                stack[top] = (child << 6) | (level - 1)
                bounds[top] = bound
                top += 1
                count += 1
        if count == 2 and bounds[top - 1] > bounds[top - 2]:
            stack[top - 1], stack[top - 2] = stack[top - 2], stack[top - 1]
            bounds[top - 1], bounds[top - 2] = bounds[top - 2], bounds[top - 1]
    return best_k, best


@jit(forceinline=True)
def _preferred(j, k, start):
    """Whether sample j is preferred to sample k at an equal distance, as the scan from
    ``start`` that the tree search replaced chose (it kept the first of equals it met, going
    up from start, then down): start itself, then the samples above it nearest first, then
    those below it nearest first (k = -1: no sample yet). Results stay those of the scan
    where the reference rests exactly, as at a stop, where equal distances are common."""
    if k < 0 or j == start:
        return True
    if k == start:
        return False
    if (j > start) != (k > start):
        return j > start
    return abs(j - start) < abs(k - start)


@jit(forceinline=True)
def _nearest_sample(samples, tree, isolation, point, base, lo, hi):
    """Index of the sample in [lo, hi] nearest to ``point`` (Euclidean; on the unit sphere
    that is also the smallest angle); ``tree``: the samples' :func:`_capsule_tree`. Exact:
    from ``base`` down to the nearest of its neighbours (at most DESCENT_STEPS steps), then
    the nearest of the core of that sample's block (:func:`_isolation`) is it if the core's
    centre is at least ``best + |point - centre|`` from every other sample of the window
    (triangle inequality), as nearly always. Else the capsule tree's search
    (:func:`_tree_nearest`), whose cost does not grow with the samples of the window."""
    isolated, lower, upper = isolation
    best_k = base
    best = _chord(samples, base, point)
    steps = 0
    while best_k > lo and steps < DESCENT_STEPS:
        d = _chord(samples, best_k - 1, point)
        if not d < best:
            break
        best_k -= 1
        best = d
        steps += 1
    if best_k == base:
        while best_k < hi and steps < DESCENT_STEPS:
            d = _chord(samples, best_k + 1, point)
            if not d < best:
                break
            best_k += 1
            best = d
            steps += 1
    block = best_k // ISOLATION_BLOCK
    first, last, centre = _block_core(block, samples.shape[0])
    if lower[block] <= lo and hi <= upper[block]:
        for j in range(max(first, lo), min(last, hi) + 1):
            d = _chord(samples, j, point)
            if d < best:
                best = d
                best_k = j
        if isolated[block] >= best + _chord(samples, centre, point):
            return best_k
    radii, offsets = tree
    # (allocated only here: most points never need them)
    stack = np.empty(_STACK, dtype=np.int64)
    bounds = np.empty(_STACK)
    return _tree_nearest(radii, offsets, samples, point, lo, hi, best_k, best_k, best, stack,
                         bounds)[0]


@jit(forceinline=True)
def _block_core(block, n):
    """First and last sample of a block's core, and its centre sample."""
    start = block * ISOLATION_BLOCK
    return (max(start - 1, 0), min(start + ISOLATION_BLOCK, n - 1),
            min(start + ISOLATION_BLOCK // 2, n - 1))


def _isolation(samples, tree, lo, hi, span):
    """For each block of ISOLATION_BLOCK samples: the smallest distance from its centre
    sample to the samples outside its core within [lower, upper] (the union of the windows
    [lo, hi] of its samples and of ``span`` samples either side), and that range. Computed
    once per reference curve; :func:`_nearest_sample` then needs no search for a point whose
    nearest core sample is nearer than that distance less the point's distance from the
    centre, as nearly always."""
    n = samples.shape[0]
    blocks = (n + ISOLATION_BLOCK - 1) // ISOLATION_BLOCK
    isolated = np.empty(blocks)
    lower = np.empty(blocks, dtype=np.intp)
    upper = np.empty(blocks, dtype=np.intp)
    run_chunks(_isolation_chunks, (blocks + _CHUNK - 1) // _CHUNK, samples, *tree,
               np.ascontiguousarray(lo, dtype=np.intp), np.ascontiguousarray(hi, dtype=np.intp),
               int(span), isolated, lower, upper)
    return isolated, lower, upper


@jit
def _isolation_chunks(first, stop, samples, radii, offsets, lo, hi, span, isolated, lower,
                      upper):
    """:func:`_isolation` of the blocks of chunks [first, stop)."""
    n = samples.shape[0]
    blocks = isolated.size
    point = np.empty(3)
    stack = np.empty(_STACK, dtype=np.int64)
    bounds = np.empty(_STACK)
    for chunk in range(first, stop):
        for block in range(chunk * _CHUNK, min(blocks, (chunk + 1) * _CHUNK)):
            start = block * ISOLATION_BLOCK
            j0 = max(start - span, 0)
            a = lo[j0]      # (not constants: literal arguments compile a callee once more)
            b = hi[j0]
            for j in range(j0, min(start + ISOLATION_BLOCK + span, n)):
                a = min(a, lo[j])
                b = max(b, hi[j])
            lower[block] = a
            upper[block] = b
            core_first, core_last, centre = _block_core(block, n)
            for d in range(3):
                point[d] = samples[centre, d]
            # the samples of [a, b] either side of the core (one call site: each inlined
            # copy of the tree search costs compile time)
            best = np.inf
            none = centre - centre - 1      # -1, not a literal (which compiles a callee again)
            for side in range(2):
                side_lo = a if side == 0 else core_last + 1
                side_hi = core_first - 1 if side == 0 else b
                if side_lo <= side_hi:
                    best = _tree_nearest(radii, offsets, samples, point, side_lo, side_hi,
                                         centre, none, best, stack, bounds)[1]
            isolated[block] = best


def _closest_parameters(kind, t, samples, tree, isolation, breaks, coef, points, base, lo,
                        hi):
    """Closest parameter of every point (see ReferencePath._search), in chunks of samples
    spread over the cores."""
    n = points.shape[0]
    parameter = np.empty(n)
    distance = np.empty(n)
    closest = np.empty((n, 3))
    run_chunks(_closest_chunks, (n + _CHUNK - 1) // _CHUNK, kind, t, samples, *tree,
               *isolation, breaks, coef, points, base, lo, hi, parameter, distance, closest)
    return parameter, distance, closest


@jit
def _closest_chunks(first, stop, kind, t, samples, radii, offsets, isolated, lower, upper,
                    breaks, coef, points, base, lo, hi, parameter, distance, closest):
    """:func:`_closest_parameters` of the points of chunks [first, stop)."""
    n = points.shape[0]
    tree = (radii, offsets)
    isolation = (isolated, lower, upper)
    for chunk in range(first, stop):
        out = np.empty((3, 3))
        spare = np.empty((3, 3))
        point = np.empty(3)
        for i in range(chunk * _CHUNK, min(n, (chunk + 1) * _CHUNK)):
            for d in range(3):
                point[d] = points[i, d]
            parameter[i], distance[i] = _closest_parameter(
                kind, t, samples, tree, isolation, breaks, coef, point, base[i], lo[i],
                hi[i], out, spare)
            for d in range(3):
                closest[i, d] = out[0, d]


@jit(forceinline=True)
def _closest_parameter(kind, t, samples, tree, isolation, breaks, coef, point, base, lo,
                       hi, out, spare):
    """Closest parameter of one point within the sample window [lo, hi], and its distance;
    the closest curve point is left in out[0] (``spare``: scratch of out's shape)."""
    k = _nearest_sample(samples, tree, isolation, point, base, lo, hi)
    # The minimum lies within one sample of the best sample: bracket it there and refine
    # by Newton's method safeguarded with bisection on the sign of the gradient.
    hint = k - (t.size - breaks.size) // 2   # the piece of sample k, or near it
    a = t[max(k - 1, lo)]
    b = t[min(k + 1, hi)]
    # (one call site per helper: each inlined copy costs compile time)
    interior = True
    for side in range(2):
        g_side = _gradient_curvature(kind, breaks, coef, b if side else a, hint, point,
                                     spare)[0]
        interior = interior and (g_side > 0.0 if side else g_side < 0.0)
    u = t[k]
    # Elsewhere (a minimum at the window's edge, or a flat stretch where the reference
    # stands still) take bounded Newton / gradient steps inside the window.
    u_lo, u_hi = t[lo], t[hi]
    u_previous, c_previous = u, 0.0          # the previous iterate (none at the first)
    u_evaluated = u
    c = 0.0
    for iteration in range(NEWTON_ITERATIONS):
        if iteration > 0:
            u_previous, c_previous = u_evaluated, c
        g, c = _gradient_curvature(kind, breaks, coef, u, hint, point, out)
        u_evaluated = u
        # Newton's error after a step s is about |g''| s^2 / (2 c); g'' from the change of c
        # since the previous iterate
        next_step = np.inf
        if c > 0.0 and u != u_previous and abs(g) <= LAST_STEP * c:
            next_step = 0.5 * abs((c - c_previous) / (u - u_previous)) * (g / c) ** 2 / c
        if c > 0.0 and (abs(g) <= PARAMETER_TOLERANCE * c
                        or next_step <= 0.1 * PARAMETER_TOLERANCE):
            # converged: the last Newton step is below the tolerance, or the step after it
            # would be (taking it as a bracket test would fail in round-off where it does not
            # move u, and bisect away)
            u = min(max(u - g / c, u_lo), u_hi)
            break
        if g > 0.0:
            b = u
        else:
            a = u
        if interior:
            newton = u - g / c if c > 0.0 else u
            u_new = newton if (c > 0.0 and a < newton < b) else 0.5 * (a + b)
        else:
            step = -g / c if c > 0.0 else -np.sign(g) * MAX_STEP
            u_new = min(max(u + min(max(step, -MAX_STEP), MAX_STEP), u_lo), u_hi)
        converged = abs(u_new - u) <= PARAMETER_TOLERANCE
        u = u_new
        if converged:
            break
    _evaluate(breaks, coef, 3 * kind, u, hint, out)
    # the curve interpolates the samples: its distance at t[k] is the sample's
    refined = _distance(kind, out, 0, point)
    at_sample = _distance(kind, samples, k, point)
    if refined <= at_sample:
        return u, refined
    for d in range(3):
        out[0, d] = samples[k, d]
    return t[k], at_sample
