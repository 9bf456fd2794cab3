"""Local re-timing: slow a sampled trajectory down smoothly where it asks too much of the
machine, and leave it sample-for-sample unchanged elsewhere.

Paper Sec. 4: where a compensated command would break an axis limit, the feed is re-planned
locally and the path compensated again. Here the reference trajectory q(s), P(s), O(s) of
the old time s is played back on a new clock tau with ds/dtau = r(tau) <= 1. By the chain rule

    dq/dtau     = q_s r
    d2q/dtau2   = q_ss r^2 + q_s r'
    d3q/dtau3   = q_sss r^3 + 3 q_ss r r' + q_s r''

(' = d/dtau), so a stretch rho = 1/r divides velocity, acceleration and jerk by rho, rho^2,
rho^3 while r' and r'' stay small: the stretch rises and falls over a ramp of
:data:`RAMP_TIME` with a C2 bell, so it adds terms of order q_s h / RAMP_TIME and
q_s h / RAMP_TIME^2 for a stretch 1 + h. A caller checks again and repeats if needed.

How: the stretch each sample needs is spread over :data:`SPREAD_TIME` plus the ramp either
side (a running maximum), smoothed with the bell (a kernel of unit sum, so the smoothed
stretch is at least the needed one wherever it was needed), and raised in each slowed
stretch of the path so that it adds a whole number of sampling periods. The old sample
times then land on new times tau_k = ts (k + sum of the added stretch before k); outside the
slowed windows these are whole samples and the old samples are copied exactly. Inside, a
cubic spline through (tau_k, k) gives the old (fractional) sample index of each new sample,
and cubic splines of the samples give q, P, O there (C2: continuous acceleration).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import CubicSpline
from scipy import ndimage
from scipy.ndimage import maximum_filter1d

from .sampled import Trajectory

#: Time (s) over which the stretch rises from 1 and falls back (half-width of the bell), by
#: default. A slowed window costs about (2 ramp + 2 spread) h for a stretch 1 + h, most of it
#: in the ramps; compensation within the limits takes shorter ones
#: (:data:`precontour.compensation.within_limits.LIMITS_RAMP`).
RAMP_TIME = 0.2
#: Time (s) either side of a sample that needs slowing over which its stretch is held, so the
#: motion is already slow when it reaches the sample (the drives and the compensation act
#: over tens of milliseconds around it), by default.
SPREAD_TIME = 0.05
#: Stretch below which a sample counts as not slowed (round-off of the smoothing).
_NEGLIGIBLE = 1e-12


@dataclass(frozen=True)
class Slowdown:
    """One slowed window, in the time of the trajectory before re-timing.

    Attributes
    ----------
    start, end : float
        Window, s (old clock).
    speed : float
        Lowest speed in it, as a fraction of the original (1 / largest stretch).
    added : float
        Time the window gained, s.
    lines : tuple of int, optional
        First and last source line of the samples in it, when known.
    """

    start: float
    end: float
    speed: float
    added: float
    lines: tuple[int, int] | None = None

    def format(self) -> str:
        where = f"t = {self.start:.3f}-{self.end:.3f} s"
        if self.lines is not None:
            where += f" (source lines {self.lines[0]}-{self.lines[1]})"
        return f"{where}: speed down to {100 * self.speed:.1f} %, +{self.added:.3f} s"


@dataclass(frozen=True)
class Retiming:
    """A re-timed trajectory and how it maps to the old one.

    Attributes
    ----------
    trajectory : Trajectory
        The slowed trajectory, same sampling period, from the same start time.
    old_index : ndarray, shape (M,)
        Old (fractional) sample index of each new sample: the time map s(tau) / ts.
    slowdowns : tuple of Slowdown
        The slowed windows.
    """

    trajectory: Trajectory
    old_index: np.ndarray
    slowdowns: tuple[Slowdown, ...]

    @property
    def line(self) -> np.ndarray | None:
        """Source line of each new sample (the old sample's at or before it), when known: the
        re-timed trajectory's own."""
        return self.trajectory.line


def retime(traj: Trajectory, stretch: np.ndarray, *, line: np.ndarray | None = None,
           ramp: float = RAMP_TIME, spread: float = SPREAD_TIME) -> Retiming:
    """Slow ``traj`` down locally by at least the factor ``stretch`` (N,) at each sample
    (1 or below: unchanged). See the module docstring. The re-timed trajectory keeps the
    source lines (``line``, else ``traj.line``): each new sample the old sample's at or
    before it."""
    stretch = np.asarray(stretch, dtype=float)
    n = traj.n_samples
    if stretch.shape != (n,) or not np.all(np.isfinite(stretch)):
        raise ValueError(f"stretch must be finite with shape ({n},), got {stretch.shape}")
    ts = traj.ts
    added = added_stretch(stretch, ts, ramp=ramp, spread=spread)       # per interval, (N-1,)
    # Old sample k lands on new (fractional) sample index k + (stretch added before it);
    # every window adds whole samples, so outside windows the landings are whole numbers.
    landing = np.arange(n) + np.concatenate([[0.0], np.cumsum(added)])
    m = int(round(landing[-1])) + 1
    new_index = np.arange(m, dtype=float)
    k_of = np.clip(np.searchsorted(landing, new_index + 1e-6, side="right") - 1, 0, n - 1)
    old_index = k_of.astype(float)
    values = np.concatenate([traj.q] + ([traj.P, traj.O] if traj.has_reference else []),
                            axis=1)
    out = values[k_of]
    for first, last in _windows(added):        # one pass per slowed window (few)
        lo, hi = max(first - _PAD, 0), min(last + _PAD, n - 1)
        keys = np.arange(lo, hi + 1)
        inside = slice(int(np.floor(landing[first] + 1e-6)) + 1,
                       int(np.ceil(landing[last] - 1e-6)))
        u = CubicSpline(landing[keys], keys.astype(float))(new_index[inside])
        old_index[inside] = u
        out[inside] = CubicSpline(keys.astype(float), values[keys])(u)
    t = traj.t[0] + new_index * ts
    q = out[:, :5]
    P = O = None
    if traj.has_reference:
        P = out[:, 5:8]
        O = out[:, 8:11] / np.linalg.norm(out[:, 8:11], axis=1, keepdims=True)
    new_line = None
    line = traj.line if line is None else np.asarray(line)
    if line is not None:
        new_line = line[np.clip(np.floor(old_index + 1e-9).astype(int), 0, n - 1)]
    return Retiming(trajectory=Trajectory(t=t, q=q, P=P, O=O, line=new_line),
                    old_index=old_index,
                    slowdowns=slowdowns_of(old_index, ts, t0=traj.t[0], line=line))


#: Exact samples either side of a window that its splines pass through, so they join the
#: copied samples smoothly.
_PAD = 8


def _windows(added: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) old sample of each run of stretched intervals."""
    on = np.concatenate([[0], (added > 0).astype(np.int8), [0]])
    edges = np.flatnonzero(np.diff(on))
    return list(zip(edges[::2].tolist(), edges[1::2].tolist()))


def _spread_samples(ts: float, ramp: float, spread: float) -> tuple[int, int]:
    """The bell's half-width and the reach either side over which :func:`added_stretch` holds
    a sample's need, in samples."""
    half = max(1, int(round(ramp / ts)))
    return half, half + max(0, int(round(spread / ts)))


def stretch_reach(ts: float, *, ramp: float = RAMP_TIME, spread: float = SPREAD_TIME) -> int:
    """Samples either side of a sample within which :func:`added_stretch` may stretch the
    motion for that sample's need (held over its reach, then smoothed by the bell), plus one."""
    half, reach = _spread_samples(ts, ramp, spread)
    return reach + half + 1


def added_stretch(stretch: np.ndarray, ts: float, *, ramp: float = RAMP_TIME,
                  spread: float = SPREAD_TIME) -> np.ndarray:
    """Stretch added to each sampling interval (N-1,): rho - 1 >= the need at each sample's
    intervals, spread, smoothed with a C2 bell, and summing to a whole number over each
    slowed window."""
    need = np.maximum(np.asarray(stretch, dtype=float) - 1.0, 0.0)
    level = np.maximum(need[1:], need[:-1])
    if not level.any():
        return np.zeros_like(level)
    half, reach = _spread_samples(ts, ramp, spread)
    held = maximum_filter1d(level, 2 * reach + 1, mode="constant", cval=0.0)
    x = np.linspace(-1.0, 1.0, 2 * half + 3)[1:-1]
    bell = (1.0 - x * x) ** 3          # value, slope and curvature vanish at both ends: C2
    bell /= bell.sum()
    from scipy.signal import oaconvolve     # here: scipy.signal takes 0.5 s to import

    smooth = oaconvolve(held, bell, mode="same")
    smooth[smooth < _NEGLIGIBLE] = 0.0
    # Whole samples per window: raise each window's stretch by the factor that rounds it up.
    on = smooth > 0
    starts = on & ~np.concatenate([[False], on[:-1]])
    label = np.cumsum(starts) * on
    sums = np.bincount(label, weights=smooth)
    scale = np.ones_like(sums)
    scale[1:] = np.ceil(sums[1:] - 1e-9) / sums[1:]
    return smooth * scale[label]


def held_through_stops(stretch: np.ndarray, q: np.ndarray, *, levels=None) -> np.ndarray:
    """``stretch`` (N,) raised, over each approach to a rest and each start from one, to the
    largest stretch in it or in that rest.

    An approach is the run of samples over which the commands' speed (the largest step of any
    axis; ``levels``, shape (5,), scales each axis's, e.g. by its velocity limit) falls until
    the commands rest exactly; a start, the run over which it rises from a rest. A stretch
    within a rest (the corrections settling after a stop, or leading a start) counts for the
    approach before it and the start after it.

    Why: where friction decides where the axes come to rest, the speed is not to change while
    they decelerate to it: a stretch that rises there adds its own deceleration (q_s r',
    see the module docstring). On ``circle`` with ``pid-high`` and a 0.1 s ramp, the corrections
    settling 30 ms after the final stop asked for slowing; without the hold the speed fell
    from 0.99 to 0.78 of the planned one during the deceleration, and the final stop's error
    on the realistic machine rose
    (:data:`precontour.compensation.within_limits.LIMITS_RAMP`)."""
    stretch = np.asarray(stretch, dtype=float)
    q = np.asarray(q, dtype=float)
    n = stretch.size
    if n < 3 or not np.any(stretch > 1.0):
        return stretch
    step = np.abs(np.diff(q, axis=0))
    if levels is not None:
        step = step / np.asarray(levels, dtype=float)
    speed = np.concatenate([[0.0], step.max(axis=1)])      # per sample: the step into it
    rest = speed == 0.0
    rest_label, rests = ndimage.label(rest)
    rest_peak = np.ones(rests + 1)
    if rests:
        rest_peak[1:] = ndimage.maximum(stretch, rest_label, np.arange(1, rests + 1))
    out = stretch.copy()
    falling = np.zeros(n, dtype=bool)
    falling[1:] = speed[1:] < speed[:-1]
    rising = np.zeros(n, dtype=bool)
    rising[:-1] = speed[:-1] < speed[1:]
    for mask, approach in ((falling, True), (rising, False)):
        label, count = ndimage.label(mask & ~rest)
        if not count:
            continue
        peak = ndimage.maximum(stretch, label, np.arange(1, count + 1))
        # one pass per approach or start (a program's stops: O(samples) in all)
        for k, (run,) in enumerate(ndimage.find_objects(label)):
            first, last = run.start, run.stop - 1
            beside = last + 1 if approach else first - 1
            if not 0 <= beside < n or not rest[beside]:
                continue
            need = max(peak[k], rest_peak[rest_label[beside]])
            if need > 1.0:
                lo, hi = max(first - 1, 0), min(last + 2, n)
                out[lo:hi] = np.maximum(out[lo:hi], need)
    return out


def slowdowns_of(old_index: np.ndarray, ts: float, *, t0: float = 0.0,
                 line: np.ndarray | None = None) -> tuple[Slowdown, ...]:
    """The slowed windows of a time map (old fractional index of each new sample)."""
    rate = np.diff(old_index)                 # old samples per new sample: speed fraction
    slow = rate < 1.0 - 1e-9
    if not slow.any():
        return ()
    edges = np.flatnonzero(np.diff(np.concatenate([[0], slow.astype(np.int8), [0]])))
    result = []
    for first, stop in zip(edges[::2], edges[1::2]):   # one entry per window, few
        a, b = old_index[first], old_index[stop]
        lines = None
        if line is not None:
            lines = (int(line[int(np.floor(a))]), int(line[min(int(np.ceil(b)), line.size - 1)]))
        result.append(Slowdown(start=t0 + a * ts, end=t0 + b * ts,
                               speed=float(rate[first:stop].min()),
                               added=float((stop - first) - (b - a)) * ts, lines=lines))
    return tuple(result)
