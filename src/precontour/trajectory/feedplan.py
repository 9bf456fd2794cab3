"""Feed planning: the time law s(t) along a :class:`~precontour.trajectory.pathspline.PathSpline`.

The profile starts and stops at rest, is jerk limited (continuous acceleration), keeps the tool
tip speed below the programmed and maximum feed, the tip acceleration below a limit, and every
axis (after inverse kinematics) below its velocity, acceleration and jerk limits. It is built
in four vectorized stages, the classic CNC way:

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
here is linear in the number of grid points and samples and has no Python loop over them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import minimum_filter1d

from ..machine.drives import AXES
from ..errors import PrecontourError, ToolPathError, plain

#: Default maximum tool tip feed, mm/s (the paper's test path).
DEFAULT_FEED = 100.0
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


def axis_limits(machine) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Velocity, acceleration and jerk limits of the five drives, shape (5,) each (mm or rad
    per s, s^2, s^3); ``inf`` where the machine file gives none."""
    get = lambda name: np.array([np.inf if getattr(d, name) is None else getattr(d, name)  # noqa: E731
                                 for d in machine.drives], dtype=float)
    return get("v_max"), get("a_max"), get("j_max")


def plan_feed(path, machine, *, feed: float = DEFAULT_FEED,
              acceleration: float = DEFAULT_ACCELERATION, jerk: float = DEFAULT_JERK,
              ts: float = 0.001, programmed_feed=None, grid_step: float | None = None,
              max_iterations: int = 12, max_samples: int = 50_000_000) -> FeedProfile:
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
    if grid_step is None:
        grid_step = min(feed * ts / 2.0, L / 2000.0)
    elif not (np.isfinite(grid_step) and grid_step > 0):
        raise ValueError(f"grid_step must be positive and finite, got {plain(grid_step)!r}")
    n_grid = int(np.ceil(L / grid_step)) + 1
    s_grid = np.linspace(0.0, L, n_grid)
    h = s_grid[1] - s_grid[0]

    feed_of_s = _feed_on_grid(path, s_grid, programmed_feed, feed)
    geometry = _grid_geometry(path, machine, s_grid, h)
    n_filter = max(1, int(np.ceil(2.0 * acceleration / jerk / ts)))
    reach = 0.5 * n_filter * ts  # a limit is felt over the distance its speed covers in T/2
    _check_continuity(geometry, s_grid)

    scale = np.ones(n_grid)
    for iteration in range(1, max_iterations + 1):
        v_lim, a_lim = _limit_curves(geometry, feed_of_s, lim, scale, reach, h)
        v = _acceleration_passes(v_lim, a_lim, h)
        s = _time_law(v, h, ts, n_filter, L, max_samples)
        P, O = path(s)
        q = machine.kinematics.inverse(P, O)
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


def _grid_geometry(path, machine, s_grid, h):
    """Derivatives with respect to s of the tip (analytic) and the axes (finite differences
    of the path-mode inverse kinematics) on the planning grid."""
    P, O = path(s_grid)
    dP = np.linalg.norm(path.tip(s_grid, 1), axis=1)
    ddP = np.linalg.norm(path.tip(s_grid, 2), axis=1)
    q = machine.kinematics.inverse(P, O)
    dq = np.gradient(q, h, axis=0)
    ddq = np.gradient(dq, h, axis=0)
    dddq = np.gradient(ddq, h, axis=0)
    return dP, ddP, np.abs(dq), np.abs(ddq), np.abs(dddq)


def _erode(values, speed, reach, h):
    """Running minimum of ``values`` in which grid point k reaches the points within
    ``speed[k] * reach`` of it (rounded up to a power-of-two speed band; one
    :func:`scipy.ndimage.minimum_filter1d` per band, so the cost is O(N log(range))."""
    out = np.array(values, dtype=float)
    level = float(np.max(speed))
    while level > 0:
        width = int(np.ceil(level * reach / h))
        if width < 1:
            break
        band = (speed <= level) & (speed > 0.5 * level)
        if band.any():
            out = np.minimum(out, minimum_filter1d(np.where(band, values, np.inf),
                                                   2 * width + 1, mode="nearest"))
        level *= 0.5
    return out


def _check_continuity(geometry, s_grid):
    """Refuse paths whose rotary commands jump between neighbouring grid points: through the
    A-C trunnion's other pole (tool pointing down, A jumps) or so close to A = 0 that C
    turns by more than a radian within one grid step; no feed would make them feasible."""
    h = s_grid[1] - s_grid[0]
    dq = geometry[2] * h
    jump = dq[:, 3:] > 1.0
    if jump.any():
        k, axis = np.unravel_index(np.flatnonzero(jump.ravel())[0], jump.shape)
        name = AXES[3 + axis]
        why = ("the orientation passes through a singular direction of the kinematics"
               if name == "A" else "the orientation passes too close to A = 0 (tool along "
               "the C axis) for C to follow; move the path off that direction or pass "
               "exactly through it")
        raise PrecontourError(f"axis {name} jumps by {dq[k, 3 + axis]:.6g} rad within "
                              f"{h:.3g} mm near s = {s_grid[k]:.6g} mm of the path: {why}")


def _limit_curves(geometry, feed_of_s, lim, scale, reach, h):
    dP, ddP, dq, ddq, dddq = geometry
    m, c = MARGIN, CURVATURE_SHARE
    with np.errstate(divide="ignore"):
        candidates = [
            np.full(dP.shape, lim.feed),
            feed_of_s / dP,
            np.sqrt(c * m * lim.acceleration / ddP),
            np.min(m * lim.v / dq, axis=1),
            np.min(np.sqrt(c * m * lim.a / ddq), axis=1),
            np.min(np.cbrt(c * m * lim.j / dddq), axis=1),
        ]
    v_lim = np.minimum.reduce(candidates) * scale
    v_lim = _erode(v_lim, v_lim, reach, h)
    with np.errstate(divide="ignore", invalid="ignore"):
        a_tip = m * lim.acceleration - ddP * v_lim**2
        a_axes = np.min((m * lim.a - ddq * v_lim[:, None] ** 2) / dq, axis=1)
    a_lim = np.minimum(a_tip, a_axes) * scale**2
    a_lim = _erode(a_lim, v_lim, reach, h)
    # The curvature share keeps a_lim >= (1 - c) m * limit > 0 wherever v_lim is unscaled.
    return v_lim, np.maximum(a_lim, 1e-9 * m * lim.acceleration)


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
    (|x| / limit)^(1/order) over all checked quantities x of derivative order 1-3."""
    n = s.size
    ratio = np.zeros(max(n - 2, 0))
    if n < 4:
        return ratio
    h_idx = np.clip(np.rint(s / s_grid[1]).astype(int), 0, s_grid.size - 1)
    feed_here = feed_of_s[h_idx]

    def fold(values, limit, order, offset):
        r = (np.abs(values) / limit) ** (1.0 / order)
        r = r.reshape(r.shape[0], -1).max(axis=1)
        # Assign a difference to the interior samples it touches.
        np.maximum.at(ratio, np.clip(np.arange(r.size) + offset, 0, ratio.size - 1), r)

    vP = np.linalg.norm(np.diff(P, axis=0), axis=1) / ts  # interval k..k+1
    for offset in (-1, 0):
        fold(vP / np.minimum(feed_here[:-1], feed_here[1:]), 1.0, 1, offset)
        fold(np.diff(s) / ts, lim.feed, 1, offset)
        fold(np.diff(q, axis=0) / ts / lim.v, 1.0, 1, offset)
    fold(np.linalg.norm(np.diff(P, 2, axis=0), axis=1) / ts**2, lim.acceleration, 2, 0)
    fold(np.diff(s, 3) / ts**3, lim.jerk, 3, 0)
    fold(np.diff(q, 2, axis=0) / ts**2 / lim.a, 1.0, 2, 0)
    fold(np.diff(q, 3, axis=0) / ts**3 / lim.j, 1.0, 3, 0)
    fold(np.diff(q, 3, axis=0) / ts**3 / lim.j, 1.0, 3, 1)
    return ratio
