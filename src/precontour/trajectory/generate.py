"""Trajectory generation: a programmed :class:`~precontour.toolpath.ToolPath` in, a
time-stamped five-axis :class:`~precontour.trajectory.sampled.Trajectory` out.

Glue of two stages: :func:`precontour.trajectory.pathspline.fit_path` (C3 geometric splines)
and :func:`precontour.trajectory.feedplan.plan_feed` (jerk-limited time law within feed and axis
limits), once per stretch between the tool path's corners
(:func:`~.pathspline.corner_points`: the tool stops at each, as at an exact stop); plus
:func:`summarize`, the numbers the command line prints about a trajectory.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..defaults import DEFAULT_DWELL, default_max_samples
from ..errors import InputError, ToolPathError, plain
from ..machine.drives import AXES
from ..machine.limits import axis_limits
from .feedplan import DEFAULT_ACCELERATION, DEFAULT_FEED, DEFAULT_JERK, plan_feed
from .pathspline import L_EQ, checked_points, corner_points, fit_path
from .sampled import Trajectory


# DEFAULT_DWELL and default_max_samples (the default sample limit, sized to this machine's
# memory: BYTES_PER_SAMPLE, MEMORY_SHARE) are defined in precontour.defaults, for the help.


def estimate_samples(length: float, feed: float, ts: float, dwell: float) -> float:
    """Fewest samples a trajectory can have: the combined path length ``length`` (mm) at no
    more than ``feed`` (mm/s), sampled every ``ts`` s, plus the final ``dwell`` (s)."""
    return length / (feed * ts) + dwell / ts + 1.0


def check_sample_estimate(estimate: float, limit: int | None, detail: str, *,
                          source: str | None = None, bound: str = "at least",
                          what: str = "trajectory", option: str | None = "--max-samples"
                          ) -> None:
    """Refuse, before any sample is made, a ``what`` whose estimated sample count exceeds
    ``limit`` (default :func:`default_max_samples`): the one check and message of every
    command that makes long trajectories (``trajectory``, ``run``, ``excite``). ``detail``
    says where the estimate comes from, ``bound`` how it bounds the count."""
    limit = default_max_samples() if limit is None else int(limit)
    if not estimate <= limit:
        how = f"max_samples, option {option}" if option else "max_samples"
        raise InputError(
            f"the {what} would have {bound} {estimate:.3g} samples ({detail}), more than the "
            f"limit of {limit} ({how}; default sized to this machine's memory)",
            source=source or None, field="max_samples")


def unfed_notice(toolpath, feed: float = DEFAULT_FEED) -> str | None:
    """The one notice for CL data that programs no feed (no ``FEDRAT``, no ``F`` column or an
    empty one): the feed it is planned at, ``feed`` mm/s; None when any point has a feed (or
    the path is built in, without a feed column)."""
    feeds = toolpath.feed
    if feeds is None or np.isfinite(np.asarray(feeds, dtype=float)[1:]).any():
        return None
    return (f"{toolpath.source}: no feed is programmed (no FEDRAT, no F column); planned at "
            f"{feed:g} mm/s ({feed * 60:g} mm/min)")


def generate_trajectory(toolpath, machine, *, feed: float = DEFAULT_FEED, ts: float = 0.001,
                        acceleration: float = DEFAULT_ACCELERATION, jerk: float = DEFAULT_JERK,
                        l_eq: float = L_EQ, dwell: float = DEFAULT_DWELL,
                        max_samples: int | None = None,
                        lines: np.ndarray | None = None) -> Trajectory:
    """Time-stamped axis commands that follow ``toolpath`` on ``machine`` within its limits.

    Parameters
    ----------
    toolpath : ToolPath
        Programmed tool tips (mm), unit orientations and optional feeds (mm/s, NaN where
        none); see :func:`precontour.trajectory.pathspline.fit_path` for how points are interpolated
        and which degenerate inputs raise :class:`~precontour.errors.ToolPathError`.
    machine : Machine
        Kinematics and drive limits.
    feed : float
        Maximum tool tip feed, mm/s; programmed feeds above it are capped.
    ts : float
        Sampling period, s.
    acceleration, jerk : float
        Tool tip acceleration (mm/s^2) and tangential jerk (mm/s^3) limits.
    l_eq : float
        Equivalent length of one radian of tool rotation in the path parameter, mm/rad.
    dwell : float
        Seconds the final position is held at the end. The drives lag their commands, so
        when the command stops the machine has not arrived yet; the dwell keeps that
        settling motion inside the trajectory, where errors are measured and where
        pre-compensation can act on it. 0 ends the trajectory when the command stops.
    max_samples : int, optional
        Largest number of samples (default :func:`default_max_samples`, sized to this
        machine's memory). Checked on an estimate (:func:`estimate_samples`) before any
        sample is made, and again on the planned motion.
    lines : array_like of int, shape (M,), optional
        Source line of each tool-path point (:attr:`precontour.toolpath.ReadReport.lines`).
        Given, the trajectory's ``line`` is at each sample the line of the point the tool is
        moving to (of the first point at the start, of the last during the final dwell), so
        that what happens at a sample can be traced to a line of the file.

    Returns
    -------
    Trajectory
        ``t`` uniform from 0 with step ``ts``; ``q`` (N, 5) from path-mode inverse kinematics
        (C unwrapped, continuous through A = 0); reference ``P``, ``O`` at each sample;
        ``line`` when ``lines`` is given. Starts and stops at rest, and stops at every corner
        of the tool path (:func:`~.pathspline.corner_points`), between which each stretch is
        its own spline and feed plan, continuing the axes' branch where the previous stopped.
    """
    for name, value in (("feed", feed), ("ts", ts)):
        if not (np.isfinite(value) and value > 0):
            raise InputError(f"{name} must be positive and finite, got {plain(value)!r}", field=name)
    if not (dwell >= 0 and np.isfinite(dwell)):
        raise InputError(f"dwell must be a finite number >= 0, got {plain(dwell)!r}", field="dwell")
    limit = default_max_samples() if max_samples is None else int(max_samples)
    if lines is not None:
        lines = np.asarray(lines)
        if lines.shape != (toolpath.n_points,):
            raise ValueError(f"lines must have one entry per tool-path point "
                             f"({toolpath.n_points}), got shape {lines.shape}")
    P_all, O_all = toolpath.P, toolpath.O
    corners = corner_points(P_all, O_all, l_eq=l_eq)
    if corners.size:
        # checked and normalized once here (a stretch's own normalization is then round-off,
        # silent); a path without corners is fitted as it is, to the last digit
        P_all, O_all = checked_points(P_all, O_all, source=toolpath.source)
    bounds = np.concatenate([[0], corners, [toolpath.n_points - 1]])
    paths = [fit_path(P_all[first:last + 1], O_all[first:last + 1], l_eq=l_eq,
                      source=toolpath.source, first_row=first)
             for first, last in zip(bounds[:-1], bounds[1:])]
    length = sum(path.length for path in paths)
    check_sample_estimate(estimate_samples(length, feed, ts, dwell), limit,
                          f"{length:.6g} mm of path at most {feed:g} mm/s, sampled every "
                          f"{ts:g} s, and a {dwell:g} s dwell", source=toolpath.source)
    n_hold = int(round(dwell / ts))
    pieces = []     # per stretch: q, P, O and line, the first sample dropped after the first
    budget = max(1, limit - n_hold)
    stopped = None  # the axes where the previous stretch stopped
    for path, first, last in zip(paths, bounds[:-1], bounds[1:]):
        feeds = None if toolpath.feed is None else toolpath.feed[first:last + 1]
        # a stretch continues on the branch the previous one stopped on (slot 4: C, or B)
        profile = plan_feed(path, machine, feed=feed, acceleration=acceleration, jerk=jerk,
                            ts=ts, programmed_feed=feeds, max_samples=max(1, budget),
                            c_near=None if stopped is None else float(stopped[4]))
        skip = 0 if stopped is None else 1   # a stretch starts where the previous stopped
        if stopped is not None:
            _check_join(stopped, profile.q[0], machine, toolpath.source, first)
        stopped = profile.q[-1]
        part = [profile.q[skip:], profile.P[skip:], profile.O[skip:], None]
        if lines is not None:
            # the kept point each sample moves to: the first s_points[k] >= s (round-off at
            # the end clipped to the last point)
            k = np.minimum(np.searchsorted(path.s_points, profile.s[skip:], side="left"),
                           path.s_points.size - 1)
            part[3] = lines[first + path.point_index[k]]
        pieces.append(part)
        budget -= profile.s.size - skip
    q, P, O = (np.concatenate([part[i] for part in pieces]) for i in range(3))
    line = None if lines is None else np.concatenate([part[3] for part in pieces])
    t = np.arange(q.shape[0]) * ts
    if n_hold:
        t = np.concatenate([t, t[-1] + ts * np.arange(1, n_hold + 1)])
        q, P, O = (np.concatenate([a, np.repeat(a[-1:], n_hold, axis=0)]) for a in (q, P, O))
        if line is not None:
            line = np.concatenate([line, np.repeat(line[-1:], n_hold)])
    return Trajectory(t=t, q=q, P=P, O=O, line=line)


#: Largest change of an axis (mm or rad) from where one stretch of a tool path stops to where
#: the next starts, at their corner: the same point on the same branch of the kinematics,
#: to round-off.
JOIN_TOLERANCE = 1e-9


def _check_join(stopped: np.ndarray, start: np.ndarray, machine, source: str,
                row: int) -> None:
    """Refuse a corner where the next stretch's axes do not start where the previous stretch's
    stopped: its tool orientation is a singular direction of the kinematics (the tool along
    the C axis of an A-C trunnion, where C is free), from which the next move needs C turned
    first."""
    jump = np.abs(np.asarray(start) - np.asarray(stopped))
    if np.all(jump <= JOIN_TOLERANCE):
        return
    axis = int(np.argmax(jump))
    name = getattr(machine, "axis_names", AXES)[axis]
    raise ToolPathError(f"axis {name} would jump by {jump[axis]:.6g} "
                        f"{'mm' if axis < 3 else 'rad'} at the corner: the tool orientation "
                        "there is a singular direction of the kinematics, from which the next "
                        "move needs another position of that axis; add points that turn the "
                        "tool off it before the corner", source=source or None, row=row + 1,
                        field="O")


@dataclass(frozen=True)
class TrajectorySummary:
    """Duration, samples, peak feed and each axis's peak derivatives against its limits.

    Peaks are finite differences at the sampling period: velocity (first), acceleration
    (second) and jerk (third differences). Units: mm or rad per s, s^2, s^3.
    """

    duration: float
    n_samples: int
    ts: float
    peak_feed: float
    peak_velocity: np.ndarray
    peak_acceleration: np.ndarray
    peak_jerk: np.ndarray
    v_max: np.ndarray
    a_max: np.ndarray
    j_max: np.ndarray
    axis_names: tuple[str, ...] = AXES

    @property
    def within_limits(self) -> bool:
        """True when no axis peak exceeds its limit (relative round-off 1e-9)."""
        tol = 1.0 + 1e-9
        return bool(np.all(self.peak_velocity <= self.v_max * tol)
                    and np.all(self.peak_acceleration <= self.a_max * tol)
                    and np.all(self.peak_jerk <= self.j_max * tol))

    def format(self) -> str:
        """Multi-line text: a header, then one line per axis with each peak, its limit and
        the percentage of the limit used (units mm or rad, per s, s^2, s^3)."""
        lines = [f"duration {self.duration:.4f} s, {self.n_samples} samples at "
                 f"{self.ts * 1e3:g} ms, peak feed {self.peak_feed:.2f} mm/s",
                 f"{'axis':<9}" + "".join(f"{head:>28}" for head in
                                          ("velocity peak/limit", "acceleration peak/limit",
                                           "jerk peak/limit"))]
        for i, axis in enumerate(self.axis_names):
            unit = "mm" if i < 3 else "rad"
            cells = []
            for peak, limit in ((self.peak_velocity, self.v_max),
                                (self.peak_acceleration, self.a_max),
                                (self.peak_jerk, self.j_max)):
                pct = f"{100 * peak[i] / limit[i]:5.1f}%" if np.isfinite(limit[i]) else "    -"
                cells.append(f"{peak[i]:9.4g} / {limit[i]:<8.4g}{pct:>7}")
            lines.append(f"{axis + ' (' + unit + ')':<9}" + "".join(f"{c:>28}" for c in cells))
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.format()


def summarize(trajectory: Trajectory, machine) -> TrajectorySummary:
    """Summary of ``trajectory`` against ``machine``'s drive limits (see
    :class:`TrajectorySummary`); the peak feed needs the reference tip ``P`` (0 without)."""
    ts = trajectory.ts
    q = trajectory.q
    peaks = []
    for order in (1, 2, 3):
        if q.shape[0] > order:
            peaks.append(np.abs(np.diff(q, order, axis=0)).max(axis=0) / ts**order)
        else:
            peaks.append(np.zeros(len(AXES)))
    peak_feed = 0.0
    if trajectory.P is not None and trajectory.n_samples > 1:
        peak_feed = float(np.linalg.norm(np.diff(trajectory.P, axis=0), axis=1).max() / ts)
    v, a, j = axis_limits(machine)
    return TrajectorySummary(duration=trajectory.duration, n_samples=trajectory.n_samples,
                             ts=ts, peak_feed=peak_feed, peak_velocity=peaks[0],
                             peak_acceleration=peaks[1], peak_jerk=peaks[2],
                             v_max=v, a_max=a, j_max=j,
                             axis_names=tuple(getattr(machine, "axis_names", AXES)))
