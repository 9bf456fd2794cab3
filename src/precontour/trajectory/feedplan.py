"""Feed planning: the time law s(t) along a :class:`~precontour.trajectory.pathspline.PathSpline`.

The profile starts and stops at rest, is jerk limited (continuous acceleration), keeps the tool
tip speed below the programmed and maximum feed, the tip acceleration below a limit, and every
axis (after inverse kinematics) below its velocity, acceleration and jerk limits. It is built
in four stages, the classic CNC way, each one pass over the grid or the samples (numpy, or
compiled loops where a stage would otherwise make a dozen array passes):

1. A velocity limit curve v_lim(s) on a uniform s grid, from the feed, the tip curvature and
   each axis's derivatives dq/ds, d2q/ds2, d3q/ds3 (finite differences of the inverse
   kinematics on the grid):  v <= F/|P'|,  |P''| v^2 <= a_tip/2,  |q_i'| v <= v_i,
   |q_i''| v^2 <= a_i/2,  |q_i'''| v^3 <= j_i/2.  The tangential acceleration left over,
   a_lim(s) = min(a_tip - |P''| v_lim^2, (a_i - |q_i''| v_lim^2)/|q_i'|), bounds s''.
2. Forward and backward acceleration passes as running minima (exact for a(s) varying
   along the path, with sigma(s) = integral of a_lim ds):
   v^2(s) = min_k [v_lim^2(s_k) + 2 |sigma(s) - sigma(s_k)|], start and end at rest.
3. Jerk limiting by a moving-average (FIR) filter of the velocity in time, of length
   T = 2 a_tip / j_tip, which bounds the tangential jerk by 2 a/T <= j_tip by construction.
   Because the filter averages velocities over T, the limit curves of stage 1 are first
   eroded: each grid point's limit also applies within the distance its own speed covers in
   T/2 (a running minimum in s whose reach grows with the local speed limit).
4. Sampling at the servo period and a check of every limit on every sample with finite
   differences; where an axis limit is still exceeded (the filter and the finite grids are
   only nearly exact for nonlinear kinematics) v_lim is lowered locally and the plan is
   redone. The built-in paths need one pass; paths grazing A = 0 usually two.

Why not a library: TOPP-RA (time-optimal path parameterization) handles velocity and
acceleration constraints but not jerk, and its output would still need smoothing; Ruckig
plans jerk-limited point-to-point motions and cannot follow a prescribed path. The method
here is linear in the number of grid points and samples and has no interpreted loop over them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..defaults import DEFAULT_FEED
from ..machine.drives import AXES
from ..machine.limits import axis_limits
from ..errors import PrecontourError, ToolPathError, plain
from ..kernels import jit, run_chunks

# DEFAULT_FEED, the default maximum tool tip feed in mm/s, is defined in precontour.defaults.
#: Default tool tip acceleration limit, mm/s^2 (0.2 g, a usual contouring setting).
DEFAULT_ACCELERATION = 2000.0
#: Default tangential jerk limit, mm/s^3 (50 m/s^3, a usual contouring setting; filter 80 ms).
DEFAULT_JERK = 50000.0
#: Share of a limit granted to the centripetal (path-curvature) terms in stage 1.
CURVATURE_SHARE = 0.5
#: The plan aims this fraction below each acceleration, jerk and axis limit (the feed is aimed
#: at exactly); the check on the samples uses the full limits.
MARGIN = 0.98
#: Relative round-off tolerated when checking the sampled trajectory against a limit.
CHECK_RTOL = 1e-9
#: Fewest grid points or samples per thread of the compiled limit curves and checks.
_GRAIN = 4096


@dataclass(frozen=True)
class FeedProfile:
    """A planned time law along a path and the samples it produces.

    Attributes
    ----------
    t : ndarray, shape (N,)
        Time, s, uniform from 0 with step ``ts``.
    s : ndarray, shape (N,)
        Path parameter (combined length, mm) at each sample; 0 at the start, L at the end.
    P, O : ndarray, shape (N, 3)
        Tool tip (mm) and unit orientation at each sample.
    q : ndarray, shape (N, 5)
        Axis commands X, Y, Z (mm), A, C (rad) from path-mode inverse kinematics.
    ts : float
        Sampling period, s.
    iterations : int
        Planning passes needed until every limit held on every sample.
    """

    t: np.ndarray
    s: np.ndarray
    P: np.ndarray
    O: np.ndarray
    q: np.ndarray
    ts: float
    iterations: int


@dataclass(frozen=True)
class _Limits:
    feed: float
    acceleration: float
    jerk: float
    v: np.ndarray  # (5,) axis limits, inf where none
    a: np.ndarray
    j: np.ndarray


def plan_feed(path, machine, *, feed: float = DEFAULT_FEED,
              acceleration: float = DEFAULT_ACCELERATION, jerk: float = DEFAULT_JERK,
              ts: float = 0.001, programmed_feed=None, grid_step: float | None = None,
              max_iterations: int = 12, max_samples: int = 50_000_000,
              c_near: float | None = None) -> FeedProfile:
    """Plan a jerk-limited feed profile along ``path`` within feed and axis limits.

    Parameters
    ----------
    path : PathSpline
        Geometric path (tool tip and orientation as functions of s).
    machine : Machine
        Kinematics (path-mode ``inverse``) and drive limits (``v_max``, ``a_max``,
        ``j_max``; missing ones are not enforced).
    feed : float
        Maximum tool tip feed, mm/s; also caps ds/dt (so pure rotations run at most
        ``feed / path.l_eq`` rad/s when the drives give no tighter limit).
    acceleration : float
        Tool tip acceleration limit (tangential plus centripetal), mm/s^2.
    jerk : float
        Tangential jerk limit d3s/dt3, mm/s^3.
    ts : float
        Sampling period, s.
    programmed_feed : array_like, shape (M,), optional
        Feed (mm/s) of the move ending at each programmed point, aligned with the tool path
        the spline was fitted to (``path.point_index`` picks the kept points); NaN where none.
        Feeds above ``feed`` are capped at ``feed``.
    grid_step : float, optional
        Step of the planning grid in s, mm; default ``min(feed * ts / 2, L / 2000)``.
    max_iterations : int
        Planning passes before giving up.
    max_samples : int
        Largest number of samples the plan may have (memory guard).
    c_near : float, optional
        The inverse kinematics' branch the path starts on: the one whose C (B on a two-tilt
        machine) is nearest this (a path that continues another where it stopped); default
        the kinematics' own choice for a path.

    Returns
    -------
    FeedProfile
        Samples that satisfy, with finite differences at the sampling period and a relative
        tolerance of :data:`CHECK_RTOL`: |dP/dt| <= programmed feed, ds/dt <= feed,
        |d2P/dt2| <= acceleration, |d3s/dt3| <= jerk and every axis's velocity,
        acceleration and jerk limit.

    Raises
    ------
    ValueError
        Non-positive limits or sampling period; a non-positive programmed feed
        (:class:`~precontour.errors.ToolPathError` naming the point's row).
    PrecontourError
        No feasible plan found within ``max_iterations`` passes, a plan longer than
        ``max_samples``, or a rotary axis that jumps (the path crosses a singular direction
        such as the tool pointing straight down on an A-C trunnion).
    """
    for name, value in (("feed", feed), ("acceleration", acceleration), ("jerk", jerk),
                        ("ts", ts)):
        if not (np.isfinite(value) and value > 0):
            raise ValueError(f"{name} must be positive and finite, got {plain(value)!r}")
    v_ax, a_ax, j_ax = axis_limits(machine)
    lim = _Limits(feed, acceleration, jerk, v_ax, a_ax, j_ax)
    L = path.length
    n_grid = grid_points(L, feed, ts, grid_step)
    s_grid = np.linspace(0.0, L, n_grid)
    h = s_grid[1] - s_grid[0]

    feed_of_s = _feed_on_grid(path, s_grid, programmed_feed, feed)
    geometry = _grid_geometry(path, machine, s_grid, c_near)
    n_filter = max(1, int(np.ceil(2.0 * acceleration / jerk / ts)))
    reach = 0.5 * n_filter * ts  # a limit is felt over the distance its speed covers in T/2
    _check_continuity(geometry, s_grid, tuple(getattr(machine, "axis_names", AXES)))
    speed_cap = _speed_limit(*geometry, h, feed_of_s, lim.feed, lim.acceleration, lim.v, lim.a,
                             lim.j, MARGIN, CURVATURE_SHARE)

    scale = np.ones(n_grid)
    for iteration in range(1, max_iterations + 1):
        v_lim, a_lim = _limit_curves(geometry, speed_cap, lim, scale, reach, h)
        v = _acceleration_passes(v_lim, a_lim, h)
        s = _time_law(v, h, ts, n_filter, L, max_samples)
        P, O = path(s)
        q = machine.kinematics.inverse(P, O, c_near)
        ratio = _violation(s, P, q, ts, feed_of_s, s_grid, lim)
        worst = float(ratio.max(initial=0.0))
        if worst <= 1.0 + CHECK_RTOL:
            return FeedProfile(t=np.arange(s.size) * ts, s=s, P=P, O=O, q=q, ts=ts,
                               iterations=iteration)
        # Slow down around each offending sample by the local time-scaling factor needed,
        # spread over the filter's reach so that the averaged profile feels it too.
        bad = ratio > 1.0
        factor = np.ones(n_grid)
        idx = np.clip(np.rint(s[1:-1][bad] / h).astype(int), 0, n_grid - 1)
        np.minimum.at(factor, idx, MARGIN / ratio[bad])
        factor = _erode(factor, v_lim, reach, h)
        scale *= factor
    raise PrecontourError(f"feed planning did not meet the limits after {max_iterations} "
                          f"passes (worst ratio {worst:.6g}); lower the feed or the limits")


def grid_points(length: float, feed: float, ts: float, grid_step: float | None = None) -> int:
    """Points of the planning grid over a path ``length`` mm long: steps of ``grid_step``
    mm, by default min(feed * ts / 2, length / 2000) (half a sample at full feed, and at
    least 2000 steps)."""
    if grid_step is None:
        # counted without dividing the length by a step made from it: L / (L / 2000) can
        # round to 2000 + 2e-13, which would add a step on some short paths and not others
        return max(int(np.ceil(length / (feed * ts / 2.0))), 2000) + 1
    if not (np.isfinite(grid_step) and grid_step > 0):
        raise ValueError(f"grid_step must be positive and finite, got {plain(grid_step)!r}")
    return int(np.ceil(length / grid_step)) + 1


def _feed_on_grid(path, s_grid, programmed_feed, feed):
    """Tip feed limit F(s) on the grid: the programmed feed of the move containing s."""
    F = np.full(s_grid.size, float(feed))
    if programmed_feed is None:
        return F
    pf = np.asarray(programmed_feed, dtype=float)
    if pf.ndim != 1 or pf.size <= path.point_index[-1]:
        raise ToolPathError(f"programmed feed must have one entry per point, got shape "
                            f"{pf.shape} for at least {path.point_index[-1] + 1} points",
                            field="feed")
    pf = pf[path.point_index]
    bad = ~(np.isnan(pf) | (pf > 0))
    if bad[1:].any():
        i = int(np.flatnonzero(bad[1:])[0]) + 1
        raise ToolPathError(f"programmed feed must be positive, got {pf[i]:g} mm/s",
                            row=int(path.point_index[i]) + 1, field="feed")
    pf = np.where(np.isnan(pf), feed, np.minimum(pf, feed))
    # Move i ends at point i, so s in (s_{i-1}, s_i] belongs to pf[i].
    seg = np.clip(np.searchsorted(path.s_points, s_grid, side="left"), 1, pf.size - 1)
    return pf[seg]


def _grid_geometry(path, machine, s_grid, c_near=None):
    """The tool tip's |P'| and |P''| (analytic) and the axes q (path-mode inverse
    kinematics) on the planning grid. The axes' derivatives with respect to s are their
    finite differences, :func:`numpy.gradient` applied up to three times, which the compiled
    limit curves take where they need them (:func:`_slope_first` and the next two)."""
    P, O, dP, ddP = path.sample(s_grid)
    q = np.ascontiguousarray(machine.kinematics.inverse(P, O, c_near))
    return dP, ddP, q


@jit(forceinline=True)
def _gradient_rows(i, last):
    """The rows :func:`numpy.gradient` differences at row i (central inside, one-sided at
    the ends) and how many grid steps apart they are."""
    if i == 0:
        return 1, 0, 1.0
    if i == last:
        return last, last - 1, 1.0
    return i + 1, i - 1, 2.0


@jit(forceinline=True)
def _slope_first(q, i, k, h):
    """:func:`numpy.gradient` of column k of q at row i, with numpy's operations."""
    upper, lower, steps = _gradient_rows(i, q.shape[0] - 1)
    return (q[upper, k] - q[lower, k]) / (steps * h)


@jit(forceinline=True)
def _slope_second(q, i, k, h):
    """:func:`numpy.gradient` of :func:`_slope_first` at row i."""
    upper, lower, steps = _gradient_rows(i, q.shape[0] - 1)
    return (_slope_first(q, upper, k, h) - _slope_first(q, lower, k, h)) / (steps * h)


@jit(forceinline=True)
def _slope_third(q, i, k, h):
    """:func:`numpy.gradient` of :func:`_slope_second` at row i."""
    upper, lower, steps = _gradient_rows(i, q.shape[0] - 1)
    return (_slope_second(q, upper, k, h) - _slope_second(q, lower, k, h)) / (steps * h)


def _erode(values, speed, reach, h):
    """Running minimum of ``values`` in which grid point k reaches the points within
    ``speed[k] * reach`` of it (rounded up to a power-of-two speed band): per band, a
    running minimum of fixed width (van Herk / Gil-Werman), so the cost is O(N log(range))."""
    values = np.ascontiguousarray(values, dtype=float)
    moving = speed[speed > 0]
    if moving.size == 0:
        return values.copy()
    return _erode_bands(values, np.ascontiguousarray(speed, dtype=float), float(reach),
                        float(h), float(np.max(moving)), float(np.min(moving)))


@jit
def _erode_bands(values, speed, reach, h, fastest, slowest):
    n = values.size
    out = values.copy()
    masked = np.empty(n)     # the band's values, inf elsewhere
    prefix = np.empty(n)     # minimum of masked from the start of its block
    suffix = np.empty(n)     # minimum of masked to the end of its block (or of the grid)
    level = fastest
    # Bands below the slowest speed are empty; the halving stops there (the width never drops
    # below one point, so it would otherwise run on to the smallest float).
    while level >= slowest:
        width = int(np.ceil(level * reach / h))
        block = 2 * width + 1
        members = 0
        place = 0
        for i in range(n):
            inside = speed[i] <= level and speed[i] > 0.5 * level
            masked[i] = values[i] if inside else np.inf
            members += inside
            prefix[i] = masked[i] if place == 0 else min(prefix[i - 1], masked[i])
            place = place + 1 if place + 1 < block else 0
        if members:
            for start in range(((n - 1) // block) * block, -1, -block):
                end = min(start + block, n) - 1
                suffix[end] = masked[end]
                for i in range(end - 1, start - 1, -1):
                    suffix[i] = min(suffix[i + 1], masked[i])
            for j in range(n):
                a = j - width
                b = j + width
                if a < 0:       # the window [0, b] lies in the first block
                    window = prefix[min(b, n - 1)]
                elif b < n:     # a full window spans at most two blocks
                    window = min(suffix[a], prefix[b])
                elif a // block == (n - 1) // block:
                    window = suffix[a]
                else:
                    window = min(suffix[a], prefix[n - 1])
                out[j] = min(out[j], window)
        level *= 0.5
    return out


def _check_continuity(geometry, s_grid, axis_names=AXES):
    """Refuse paths whose rotary commands jump between neighbouring grid points: through the
    trunnion's other pole (tool pointing down, the tilt axis jumps) or so close to tilt 0
    that the rotary axis turns by more than a radian within one grid step; no feed would
    make them feasible. ``axis_names``: the machine's letters (tilt in slot 3, rotary in 4)."""
    h = s_grid[1] - s_grid[0]
    k, axis, step = _first_jump(geometry[2], h, 3, 1.0)
    if k >= 0:
        name, tilt, rotary = axis_names[axis], axis_names[3], axis_names[4]
        why = ("the orientation passes through a singular direction of the kinematics"
               if axis == 3 else f"the orientation passes too close to {tilt} = 0 (tool "
               f"along the {rotary} axis) for {rotary} to follow; move the path off that "
               "direction or pass exactly through it")
        raise PrecontourError(f"axis {name} jumps by {step:.6g} rad within "
                              f"{h:.3g} mm near s = {s_grid[k]:.6g} mm of the path: {why}")


@jit
def _first_jump(q, h, first_axis, limit):
    """The first grid row and axis (from ``first_axis`` on) whose change over one grid step,
    |dq/ds| h, exceeds ``limit``, and that change; (-1, -1, 0) if none."""
    for i in range(q.shape[0]):
        for k in range(first_axis, q.shape[1]):
            step = abs(_slope_first(q, i, k, h)) * h
            if step > limit:
                return i, k, step
    return -1, -1, 0.0


def _limit_curves(geometry, speed_cap, lim, scale, reach, h):
    dP, ddP, q = geometry
    v_lim = speed_cap * scale
    v_lim = _erode(v_lim, v_lim, reach, h)
    a_lim = _acceleration_limit(ddP, q, h, v_lim, lim.acceleration, lim.a, MARGIN) * scale**2
    a_lim = _erode(a_lim, v_lim, reach, h)
    # The curvature share keeps a_lim >= (1 - c) m * limit > 0 wherever v_lim is unscaled.
    return v_lim, np.maximum(a_lim, 1e-9 * MARGIN * lim.acceleration)


def _speed_limit(dP, ddP, q, h, feed_of_s, feed, acceleration, v, a, j, m, c):
    """Stage 1: v_lim(s) before scaling, the least of the feed, tip curvature and axis
    velocity, acceleration and jerk limits (a zero derivative sets no limit). The roots are
    monotone, so each order's least bound is rooted once."""
    out = np.empty(dP.size)
    run_chunks(_speed_limit_at, dP.size, dP, ddP, q, float(h), feed_of_s, float(feed),
               float(acceleration), v, a, j, float(m), float(c), out, grain=_GRAIN)
    return out


@jit(error_model="numpy")
def _speed_limit_at(begin, end, dP, ddP, q, h, feed_of_s, feed, acceleration, v, a, j, m, c,
                    out):
    """:func:`_speed_limit` at grid points [begin, end)."""
    for i in range(begin, end):
        first = min(feed, feed_of_s[i] / dP[i])
        second = c * m * acceleration / ddP[i]
        third = np.inf
        for k in range(v.size):
            first = min(first, m * v[k] / abs(_slope_first(q, i, k, h)))
            second = min(second, c * m * a[k] / abs(_slope_second(q, i, k, h)))
            third = min(third, c * m * j[k] / abs(_slope_third(q, i, k, h)))
        out[i] = min(first, np.sqrt(second), np.cbrt(third))


def _acceleration_limit(ddP, q, h, v_lim, acceleration, a, m):
    """Stage 1: a_lim(s) before scaling, the tangential acceleration the tip and every axis
    leave over at v_lim (an axis that does not move sets no limit)."""
    out = np.empty(ddP.size)
    run_chunks(_acceleration_limit_at, ddP.size, ddP, q, float(h), v_lim, float(acceleration),
               a, float(m), out, grain=_GRAIN)
    return out


@jit(error_model="numpy")
def _acceleration_limit_at(begin, end, ddP, q, h, v_lim, acceleration, a, m, out):
    """:func:`_acceleration_limit` at grid points [begin, end)."""
    for i in range(begin, end):
        v2 = v_lim[i] * v_lim[i]
        best = m * acceleration - ddP[i] * v2
        for k in range(a.size):
            slope = abs(_slope_first(q, i, k, h))
            left = (m * a[k] - abs(_slope_second(q, i, k, h)) * v2) / slope
            if not np.isnan(left):
                best = min(best, left)
        out[i] = best


def _acceleration_passes(v_lim, a_lim, h):
    """Largest v(s) <= v_lim with |v dv/ds| <= a_lim, at rest at both ends (running minima)."""
    sigma = np.concatenate([[0.0], np.cumsum(0.5 * (a_lim[1:] + a_lim[:-1]) * h)])
    v2 = v_lim**2
    v2[0] = v2[-1] = 0.0
    fwd = np.minimum.accumulate(v2 - 2 * sigma) + 2 * sigma
    bwd = np.minimum.accumulate((v2 + 2 * sigma)[::-1])[::-1] - 2 * sigma
    return np.sqrt(np.maximum(np.minimum(fwd, bwd), 0.0))


def _time_law(v, h, ts, n_filter, L, max_samples):
    """Sample s(t) of the acceleration-limited profile v(s) at ts, then filter its velocity
    with a moving average of ``n_filter`` samples (jerk limit); returns s at each sample."""
    # Constant acceleration between grid nodes: v^2 is linear in s, so dt = 2h/(v0 + v1).
    dt = 2.0 * h / (v[1:] + v[:-1])
    t_node = np.concatenate([[0.0], np.cumsum(dt)])
    accel = (v[1:] ** 2 - v[:-1] ** 2) / (2.0 * h)
    if not t_node[-1] / ts <= max_samples:
        raise PrecontourError(f"the planned motion would take {t_node[-1]:.6g} s, more than "
                              f"{max_samples} samples; the path is too slow somewhere "
                              "(a limit too low, or a near-singular orientation)")
    n_cells = int(np.ceil(t_node[-1] / ts))
    t = np.arange(n_cells + 1) * ts
    k = np.clip(np.searchsorted(t_node, t, side="right") - 1, 0, v.size - 2)
    tau = np.clip(t - t_node[k], 0.0, dt[k])
    s_raw = np.minimum(k * h + v[k] * tau + 0.5 * accel[k] * tau**2, L)
    s_raw[-1] = L
    v_cell = np.diff(s_raw) / ts
    v_filt = np.convolve(v_cell, np.full(n_filter, 1.0 / n_filter))
    s = np.concatenate([[0.0], np.cumsum(v_filt) * ts])
    s *= L / s[-1]
    return s


def _violation(s, P, q, ts, feed_of_s, s_grid, lim):
    """Per interior sample k (1..N-2), the largest time-scaling factor a limit asks for:
    (|x| / limit)^(1/order) over all checked quantities x of derivative order 1-3. A first
    difference counts for both its samples, a second for its middle one, a third for its
    two middle ones (the tangential jerk d3s/dt3 for its first middle one)."""
    if s.size < 4:
        return np.zeros(max(s.size - 2, 0))
    h_idx = np.clip(np.rint(s / s_grid[1]).astype(int), 0, s_grid.size - 1)
    # s as a column, so that the difference helpers serve s, P and q alike
    ratio = np.empty(s.size - 2)
    run_chunks(_violation_ratios, ratio.size, np.ascontiguousarray(s).reshape(-1, 1),
               np.ascontiguousarray(P), np.ascontiguousarray(q), float(ts), feed_of_s[h_idx],
               float(lim.feed), float(lim.acceleration), float(lim.jerk), lim.v, lim.a, lim.j,
               ratio, grain=_GRAIN)
    return ratio


@jit(inline="always")
def _second_difference(x, k, i):
    """(x[k+2] - x[k+1]) - (x[k+1] - x[k]) in column i, as :func:`numpy.diff` rounds it."""
    return (x[k + 2, i] - x[k + 1, i]) - (x[k + 1, i] - x[k, i])


@jit(inline="always")
def _third_difference(x, k, i):
    """The third difference of column i at k..k+3, as :func:`numpy.diff` rounds it."""
    return _second_difference(x, k + 1, i) - _second_difference(x, k, i)


@jit(forceinline=True)
def _first_ratio(s, P, q, k, ts, feed_here, feed, v):
    """Largest ratio of the first differences over interval k..k+1."""
    d0 = P[k + 1, 0] - P[k, 0]
    d1 = P[k + 1, 1] - P[k, 1]
    d2 = P[k + 1, 2] - P[k, 2]
    r = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2) / ts / min(feed_here[k], feed_here[k + 1])
    r = max(r, abs(s[k + 1, 0] - s[k, 0]) / ts / feed)
    for i in range(q.shape[1]):
        r = max(r, abs((q[k + 1, i] - q[k, i]) / ts / v[i]))
    return r


@jit(forceinline=True)
def _axis_jerk_ratio(q, k, ts3, j):
    """Largest |third difference / ts^3 / limit| of the axes over samples k..k+3 (before
    the cube root)."""
    r = 0.0
    for i in range(q.shape[1]):
        r = max(r, abs(_third_difference(q, k, i) / ts3 / j[i]))
    return r


@jit(error_model="numpy")
def _violation_ratios(begin, end, s, P, q, ts, feed_here, feed, acceleration, jerk, v, a, j,
                      ratio):
    """The ratios of interior samples begin + 1 .. end (see :func:`_violation`)."""
    # The roots are monotone, so each order's largest ratio is rooted once.
    n = s.shape[0]
    ts2 = ts**2     # powers as Python rounds them (not ts * ts * ts)
    ts3 = ts**3
    for r in range(begin, end):     # interior sample r + 1
        first = max(_first_ratio(s, P, q, r, ts, feed_here, feed, v),
                    _first_ratio(s, P, q, r + 1, ts, feed_here, feed, v))
        d0 = _second_difference(P, r, 0)
        d1 = _second_difference(P, r, 1)
        d2 = _second_difference(P, r, 2)
        second = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2) / ts2 / acceleration
        for i in range(q.shape[1]):
            second = max(second, abs(_second_difference(q, r, i) / ts2 / a[i]))
        third = 0.0
        if r <= n - 4:
            third = max(abs(_third_difference(s, r, 0)) / ts3 / jerk,
                        _axis_jerk_ratio(q, r, ts3, j))
        if r >= 1:
            third = max(third, _axis_jerk_ratio(q, r - 1, ts3, j))
        ratio[r] = max(first, np.sqrt(second), third ** (1.0 / 3.0))
