"""Timing an NC program as a CNC executes it: :func:`program_trajectory`.

The program (:class:`~precontour.toolpath.program.Program`) is a chain of linear moves in
machine axes (arcs already cut into chords); each has a programmed time (G93: 60/F; G94:
length / F) or, for a rapid, none. The time law is built the way FIR-interpolating CNCs do it
(Tajima & Sencer; LinuxCNC's and most look-aheads produce the same kind of motion):

1. **Segments.** The program splits at rapids and stops into segments that start and end at
   rest. Consecutive rapids form one segment; so do consecutive feed moves.
2. **Nominal motion.** Within a segment each move takes its programmed time, or longer where
   an axis would exceed its velocity limit (rapids: as fast as the slowest axis allows, i.e.
   the machine's rapid rate within its axis limits). The nominal axis commands move at constant
   speed along each block -- linearly in the axes, or, for a TCP move, linearly in the tool tip
   and the rotary axes with the linear axes from the kinematics -- and are sampled at the servo
   period.
3. **Jerk limiting.** Two moving averages in time, of lengths T1 and T2, filter each axis: the
   velocity steps between blocks become ramps, so |a| <= dv/T1 and |j| <= dv/(T1 T2) for a
   velocity step dv. T1 and T2 are the shortest the segment's largest step allows on every
   axis: T1 = max(dv_i/a_i, sqrt(dv_i/j_i)), T2 = max(dv_i/j_i)/T1. Averaging never raises a
   velocity, so velocity limits hold. In TCP moves the filters average the tool tip and the
   rotary axes, and the linear axes are their kinematics (``linear_axes``), as a TCP
   controller computes its joints: the tip follows the averaged tip path, and stands still
   while only the rotary axes turn (averaging the linear axes themselves would cut the chord
   of their circle and move the tip).
4. **Check and slow down.** Every sample is checked against each axis's velocity, acceleration
   and jerk limit (finite differences at the servo period, rest before and after the
   segment), and every corner against its tolerance (below). Where a limit is exceeded
   (velocity steps adding up within T1, or a TCP move whose linear axes speed up mid-block),
   the filtered samples are re-timed there (:func:`~.retime.retime`: slowed smoothly by the
   stretch the limit asks for, ratio^(1/order), on a new clock, the path unchanged) and
   checked again; a limit still broken after :data:`MAX_PASSES` re-timings is named by axis,
   quantity, limit and program line. (Slowing the blocks instead, with the filters as they
   were, cascaded: each slowed window's edges were velocity steps the filters had not been
   sized for. A 242-block output of ``run``, 6.03 s of 60/F, planned 91.9 s; now 6.08 s.)
   A segment split at stops keeps the filters of the segment it was split from.

**Corners between linear blocks** are blended by the filters, as a CNC blends within a
tolerance: a velocity step dv at a corner displaces the path by at most dv * r across each
leg, and passes the corner point at about r times the part of dv across the corner's bisector
(r = integral of tau h(tau) over tau > 0 of the filters' combined kernel h, between
(T1 + T2)/12 and (T1 + T2)/8). Where that would exceed the corner tolerance (the program's
G64 P; 0 under G61/G61.1; else ``tolerance``, default :data:`DEFAULT_TOLERANCE`), the two
blocks are slowed near the corner (long blocks are cut one filter window from each end, so
that only their ends slow down); where it would take a slow-down below :data:`SHARP_CORNER`
of the speed, the axes stop at the corner instead, which costs less time (about one filter
window) and passes through it exactly. That estimate holds for one corner at a time; where
corners follow each other within a filter window (short blocks, dense rapids), their
displacements add up. So the filtered path itself is measured: the distance from each corner
point to the polyline of the samples whose filter window reaches it. A corner farther than
:data:`CORNER_CHECK` of its tolerance slows the blocks within a filter window of it again (to
:data:`MARGIN` of the tolerance); one still outside after :data:`CORNER_PASSES` passes
becomes a stop.

**The tool orientation at a corner** is bounded as well (``orientation_tolerance``, default
the rotary decimation tolerance, 1e-5 rad): the corner is passed as a pose, the tip (or the
linear axes) within the corner tolerance and the orientation within its own at the same
moment. Without it a move that only turns the rotary axes began turning them a filter window
before the tip had reached its start (LinuxCNC's boat, A-C: 27 mrad off where the tip was
within 10 um of the point at line 376, 33.5 mrad where it was within 0.7 um). The estimate above is made on
the six-dimensional path of tip over its tolerance and orientation over its own (the
orientation's velocity on each leg: the rotary velocity through the orientation's Jacobian at
the corner), so that a tip move followed by a rotation is a right-angle corner there, which
becomes a stop; the measure is the least, along the polyline of the samples' poses, of the
larger of the two distances over their tolerances. On LinuxCNC's boats and impeller this
costs 14-25 % of their planned time at 1e-5 rad, 0.5-2.3 % at 1e-3 rad. **Block times are
kept** otherwise: every block runs
in its programmed time, and a segment lasts the sum of its block times plus T1 + T2 (the
filters' start-up and run-out), because a moving average delays the motion by half its
length and does not stretch it.

Why not the CL-path planner (:mod:`.pathspline` + :mod:`.feedplan`): it runs an interpolating
quintic spline through every point and plans its own feed along it. A program's blocks are
straight lines with given times; through a corner such a spline overshoots (it has no
tolerance), and its feed plan would not keep the block times. The limits and the sample
check tolerance are shared with it.

The reference tool path P, O is the direct kinematics of the filtered axis commands: the
interpolated program path as the machine is told to move, rapids included.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..defaults import DEFAULT_CORNER_ORIENTATION_TOLERANCE as DEFAULT_ORIENTATION_TOLERANCE
from ..defaults import DEFAULT_CORNER_TOLERANCE as DEFAULT_TOLERANCE
from ..errors import MachineLimitError, PrecontourError
from ._program_geometry import (_across, _box, _pose_distance, _reach, _segment_distance,
                                _violations)
from ..machine.limits import axis_limits
from .feedplan import CHECK_RTOL
from .generate import DEFAULT_DWELL, default_max_samples
from .retime import retime
from .sampled import Trajectory

#: The plan aims this fraction below each axis limit; the check uses the full limits.
MARGIN = 0.98
# DEFAULT_TOLERANCE, the default corner tolerance in mm (the blend of a corner passes within
# this of it), is defined in precontour.defaults.
#: A corner whose blend would need the speed cut below this fraction is a stop instead.
SHARP_CORNER = 0.5
#: Corner blends below this (mm) are round-off, not corners.
BLEND_ROUND_OFF = 1e-9
#: Pose blends (in units of the tolerances: the path's and the orientation's) below this are
#: round-off, not corners.
POSE_ROUND_OFF = 1e-6
#: Planning passes per segment before giving up.
MAX_PASSES = 30
#: Ramp and hold (s) of the local slow-downs that keep the axis limits (:func:`~.retime.retime`;
#: the values compensation within the limits uses): a window slowed by 1 + h costs about
#: (2 ramp + 2 spread) h.
LIMITS_RAMP = 0.05
LIMITS_SPREAD = 0.01
#: A corner whose blend passes farther than this fraction of its tolerance from it is slowed
#: again (to :data:`MARGIN` of it): a margin over the guarantee, for round-off and for
#: measures of the distance on other samples of the same path.
CORNER_CHECK = 0.99
#: Passes that slow a corner whose blend is still outside its tolerance, before it becomes a
#: stop instead.
CORNER_PASSES = 8
#: The former fixed sample limit of a program's trajectory (5 * 10^7 samples are about 14 hours
#: at 1 kHz and 9 GB of arrays). The default is now the memory-sized limit of CL data
#: (``default_max_samples``), so that ``run`` and ``trajectory`` refuse the same programs.
MAX_SAMPLES = 50_000_000

__all__ = ["program_trajectory", "check_program_samples", "DEFAULT_TOLERANCE",
           "DEFAULT_ORIENTATION_TOLERANCE", "MARGIN", "MAX_SAMPLES"]


def program_trajectory(program, machine, *, ts: float | None = None,
                       dwell: float = DEFAULT_DWELL,
                       tolerance: float | None = DEFAULT_TOLERANCE,
                       orientation_tolerance: float | None = DEFAULT_ORIENTATION_TOLERANCE,
                       max_samples: int | None = None) -> Trajectory:
    """Axis commands at the servo period that execute ``program`` on ``machine``.

    Parameters
    ----------
    program : Program
        From :func:`precontour.toolpath.read_program`.
    machine : Machine
        Kinematics (``forward``) and drive limits ``v_max``, ``a_max``, ``j_max`` (a rapid
        needs ``v_max`` on the axes it moves).
    ts : float, optional
        Sampling period, s (default: the machine's servo period).
    dwell : float
        Seconds the axes are held at rest at a program stop (M0, M1, M6) and at the end, so
        that the drives settle inside the trajectory; G4 holds its own time.
    tolerance : float or None
        Largest distance, mm, by which the blend of a corner between two blocks may leave
        the programmed path (at the tool tip for TCP blocks, in the linear axes otherwise),
        where the program sets none; ``None``: blend as the limits allow there. The
        program's own G64 P, and G61/G61.1 (exact path: stop at every corner), take
        precedence.
    orientation_tolerance : float or None
        Largest angle, rad, between the tool orientation and the programmed one where the
        blend of a corner passes within ``tolerance`` of it (default: the rotary decimation
        tolerance, :data:`~precontour.defaults.GCODE_TOL_ROTARY`): the corner is passed as a
        pose, tip and orientation at once, so a rotation cannot start before the tip has
        reached the point. ``None``: the orientation is not bounded there. Under G61/G61.1
        the axes stop at the corner, and pass it exactly.
    max_samples : int, optional
        Refuse programs whose trajectory would be longer (memory guard; default
        :func:`~precontour.trajectory.generate.default_max_samples`, as for CL data), on an
        estimate before any sample is made (:func:`check_program_samples`).

    Returns
    -------
    Trajectory
        ``t`` from 0 at step ``ts``; ``q`` the filtered axis commands; ``P``, ``O`` their
        direct kinematics; ``line`` the source line of the block executing at each sample
        (the block whose nominal motion the filter window is centred on; a stop's line while
        it holds).

    Raises
    ------
    PrecontourError
        A rapid on an axis without a velocity limit, a trajectory longer than
        ``max_samples``, or limits that could not be met (naming the program line).
    """
    ts = _check_period(machine, ts, dwell)
    limits = np.stack(axis_limits(machine))          # (3, 5): v, a, j
    points = program.points
    dq = np.diff(points, axis=0)
    durations = _nominal_durations(program, dq, limits[0])

    holds = _holds(program, dwell, ts)
    bounds = _segment_bounds(program)
    _check_estimate(program, durations, holds, bounds, ts, max_samples)

    if tolerance is not None and not (math.isfinite(tolerance) and tolerance > 0):
        raise ValueError(f"tolerance must be positive and finite (or None), got {tolerance!r}")
    if orientation_tolerance is not None and not (math.isfinite(orientation_tolerance)
                                                  and orientation_tolerance > 0):
        raise ValueError("orientation_tolerance must be positive and finite (or None), got "
                         f"{orientation_tolerance!r}")
    context = _Context(program, machine.kinematics, points, dq, limits, ts, tolerance,
                       orientation_tolerance)
    pieces_q, pieces_line = [np.asarray(points[:1])], [np.array([program.start_line])]
    hold_at = {}
    for index, n_hold, line in holds:
        hold_at.setdefault(index, []).append((n_hold, line))

    def hold(index):
        for n_hold, line in hold_at.get(index, ()):
            if n_hold:
                pieces_q.append(np.repeat(pieces_q[-1][-1:], n_hold, axis=0))
                pieces_line.append(np.full(n_hold, line, dtype=np.int64))

    hold(0)
    for k0, k1 in bounds:
        q_seg, line_seg = context.segment(k0, k1, durations[k0:k1].copy())
        # The first sample is the previous one, at rest; two more samples at rest after the
        # segment keep the jerk of one segment's stop and the next one's start apart (each
        # was checked against rest on its own).
        pieces_q.append(np.concatenate([q_seg[1:], np.repeat(q_seg[-1:], 2, axis=0)]))
        pieces_line.append(np.concatenate([line_seg[1:], np.repeat(line_seg[-1:], 2)]))
        hold(k1)
    q = np.concatenate(pieces_q)
    line = np.concatenate(pieces_line)
    P, O = machine.kinematics.forward(q)
    t = np.arange(q.shape[0]) * ts
    return Trajectory(t=t, q=q, P=P, O=O, line=line)


def check_program_samples(program, machine, *, ts: float | None = None,
                          dwell: float = DEFAULT_DWELL, max_samples: int | None = None) -> None:
    """Refuse, before planning, a program whose trajectory would have more than
    ``max_samples`` samples (the estimate and message :func:`program_trajectory` uses): a
    reader of the program can call it before any progress is shown."""
    ts = _check_period(machine, ts, dwell)
    dq = np.diff(program.points, axis=0)
    durations = _nominal_durations(program, dq, axis_limits(machine)[0])
    _check_estimate(program, durations, _holds(program, dwell, ts), _segment_bounds(program),
                    ts, max_samples)


def _check_period(machine, ts, dwell) -> float:
    ts = float(machine.servo_period if ts is None else ts)
    if not (math.isfinite(ts) and ts > 0):
        raise ValueError(f"ts must be positive and finite, got {ts!r}")
    if not (math.isfinite(dwell) and dwell >= 0):
        raise ValueError(f"dwell must be a finite number >= 0, got {dwell!r}")
    return ts


def _check_estimate(program, durations, holds, bounds, ts, max_samples) -> None:
    """The sample estimate: the nominal block times, the holds, and about 50 samples of
    filter start-up and run-out per segment; above ``max_samples`` (default
    :func:`~precontour.trajectory.generate.default_max_samples`) the program is refused."""
    limit = default_max_samples() if max_samples is None else int(max_samples)
    estimate = (durations.sum() + sum(h for _, h, _ in holds) * ts) / ts + len(bounds) * 50
    if not estimate <= limit:
        raise PrecontourError(f"{program.source}: the program's trajectory would have about "
                              f"{estimate:.3g} samples at ts = {ts:g} s, more than "
                              f"{limit}; raise ts or split the program")


def _nominal_durations(program, dq, v_max):
    """Each move's time before jerk limiting: programmed, or longer where an axis would
    exceed its velocity limit; a rapid as fast as its slowest axis allows."""
    moving = dq != 0.0
    rapid = program.rapid
    unlimited = moving & ~np.isfinite(v_max)
    bad = rapid & unlimited.any(axis=1)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        axis = program.axes[int(np.flatnonzero(unlimited[k])[0])]
        raise PrecontourError(f"{program.source}, line {program.line[k]}: a rapid (G0) "
                              f"moves axis {axis}, which has no velocity limit v_max in the "
                              "machine file (the rapid rate)")
    with np.errstate(divide="ignore", invalid="ignore"):
        by_limit = np.where(moving, np.abs(dq) / (MARGIN * v_max), 0.0).max(axis=1)
    programmed = np.where(rapid, 0.0, np.nan_to_num(program.duration, nan=0.0))
    return np.maximum(programmed, by_limit)


def _holds(program, dwell, ts):
    """(move index, samples to hold, line) for every stop, and the final dwell."""
    holds = []
    for stop in program.stops:
        if stop.index == 0 and stop.line < program.start_line:
            continue  # before the start (e.g. the first tool change): not part of the motion
        seconds = stop.seconds if stop.kind == "dwell" else dwell
        holds.append((stop.index, int(round(seconds / ts)), stop.line))
    ends_with_hold = any(s.index == program.n_moves and s.kind != "dwell"
                         for s in program.stops)
    if not ends_with_hold:
        holds.append((program.n_moves, int(round(dwell / ts)), int(program.line[-1])))
    return holds


def _segment_bounds(program):
    """(first move, end move) of each segment: split where rapid and feed moves meet and at
    every stop."""
    n = program.n_moves
    split = np.zeros(n + 1, dtype=bool)
    split[0] = split[n] = True
    split[1:n] |= program.rapid[1:] != program.rapid[:-1]
    for stop in program.stops:
        split[stop.index] = True
    edges = np.flatnonzero(split)
    return list(zip(edges[:-1].tolist(), edges[1:].tolist()))


@dataclass(frozen=True)
class _Corners:
    """Nodes of a segment's pieces whose blend is checked: node index, tolerance (mm; inf:
    none), whether it is measured at the tool tip (TCP) or in the linear axes, and the
    orientation tolerance (rad; inf: none)."""

    node: np.ndarray
    tolerance: np.ndarray
    tcp: np.ndarray
    orientation: float = math.inf


class _Context:
    """What every segment needs: the program's moves, the kinematics and the limits."""

    def __init__(self, program, kinematics, points, dq, limits, ts, tolerance,
                 orientation_tolerance=None):
        self.program, self.kinematics = program, kinematics
        self.points, self.dq, self.limits, self.ts = points, dq, limits, ts
        default = math.inf if tolerance is None else tolerance
        self.tolerance = np.where(np.isnan(program.path_tolerance), default,
                                  program.path_tolerance)
        # one orientation tolerance for the whole program: G64 P bounds the path only
        self.orientation_tolerance = (math.inf if orientation_tolerance is None
                                      else float(orientation_tolerance))
        self.tcp = program.tcp_move
        self.tips, _ = kinematics.forward(points)

    def filter_lengths(self, k0, k1, durations):
        """Samples n1, n2 of the two moving averages: the shortest that keep the segment's
        largest velocity step within every axis's acceleration and jerk limit."""
        v_lim, a_lim, j_lim = self.limits * MARGIN
        velocity = self.dq[k0:k1] / np.where(durations > 0, durations, np.inf)[:, None]
        padded = np.concatenate([np.zeros((1, 5)), velocity, np.zeros((1, 5))])
        step = np.abs(np.diff(padded, axis=0)).max(axis=0)
        with np.errstate(divide="ignore", invalid="ignore"):
            t1 = max(np.nanmax(np.where(step > 0, step / a_lim, 0.0)),
                     np.nanmax(np.where(step > 0, np.sqrt(step / j_lim), 0.0)))
            t2 = np.nanmax(np.where(step > 0, step / j_lim, 0.0)) / t1 if t1 > 0 else 0.0
        return (max(1, math.ceil(t1 / self.ts - 1e-9)),
                max(1, math.ceil(t2 / self.ts - 1e-9)))

    def pieces(self, k0, k1, durations, window):
        """Cut every move longer than three filter windows at one window from each end, so
        that a slow-down at a corner stays near the corner. Returns the pieces' durations,
        their move, and the nodes (axes, tool tip) at their ends, start node first."""
        long = durations > 3.0 * window
        count = np.where(long, 3, 1)
        move = np.repeat(np.arange(k0, k1), count)
        first = np.cumsum(count) - count
        u_end = np.ones(move.size)
        with np.errstate(divide="ignore", invalid="ignore"):
            edge = window / durations[long]
        u_end[first[long]] = edge
        u_end[first[long] + 1] = 1.0 - edge
        u_start = np.zeros(move.size)
        inner = np.ones(move.size, dtype=bool)
        inner[first] = False
        u_start[inner] = u_end[np.flatnonzero(inner) - 1]
        piece_durations = (u_end - u_start) * durations[move - k0]
        node_q = self.points[move] + u_end[:, None] * self.dq[move]
        node_tip = self.tips[move] + u_end[:, None] * (self.tips[move + 1] - self.tips[move])
        cut = u_end < 1.0
        tcp = self.tcp[move]
        if (cut & tcp).any():
            k = cut & tcp
            node_q[k, :3] = self.kinematics.linear_axes(node_tip[k], node_q[k, 3:])
        if (cut & ~tcp).any():
            k = cut & ~tcp
            node_tip[k] = self.kinematics.forward(node_q[k])[0]
        node_q = np.concatenate([self.points[k0:k0 + 1], node_q])
        node_tip = np.concatenate([self.tips[k0:k0 + 1], node_tip])
        return piece_durations, move, node_q, node_tip

    def corner_factors(self, durations, node_path, reach, tolerance, node_ori=None,
                       node_q=None):
        """Per corner between consecutive pieces, the speed factor (<= 1) that keeps its blend
        within the tolerance. The moving averages displace a corner by dv * reach (dv the
        velocity step, reach = integral of tau h(tau) over tau > 0 for their combined kernel
        h), so the blend leaves each leg by at most ``reach`` times the part of dv across
        that leg, and passes the corner point at about ``reach`` times the part of dv across
        the corner's bisector (:func:`_across`); a speed change along a straight line leaves
        the path alone. The factor aims at :data:`MARGIN` of the tolerance; what corners near
        each other add up to is measured on the filtered path (:meth:`corner_excess`).
        ``node_path`` is the tool tip (TCP pieces) or the linear axes (the others) at the
        pieces' ends.

        With ``node_ori`` (the tool orientation at the nodes) and an orientation tolerance,
        the same estimate is made for the pose: the path over its tolerance and the
        orientation over the orientation tolerance, one path in six dimensions whose blend
        must pass within 1 of the corner. A move that only turns the rotary axes after one
        that only moves the tip is a right-angle corner there (the rotation would start
        before the tip arrives), and a change of the rotary speed shifts the moment the
        orientation passes its programmed value away from the moment the tip does."""
        with np.errstate(divide="ignore", invalid="ignore"):
            velocity = np.diff(node_path, axis=0) / durations[:, None]
        velocity[~(durations > 0)] = 0.0
        speed = np.linalg.norm(velocity, axis=1)
        factor = np.ones(max(durations.size - 1, 0))
        # Pieces at rest in this frame (a pure rotation, a repeated point) are passed over:
        # the corner is between the moving pieces on either side of them.
        moving = np.flatnonzero(speed > 0)
        if moving.size >= 2:
            blend = _across(velocity[moving[:-1]], velocity[moving[1:]]) * reach
            blend[blend < BLEND_ROUND_OFF] = 0.0   # round-off of a straight line cut in pieces
            span = moving[1:] - moving[:-1]        # corners from one moving piece to the next
            corner_tolerance = np.minimum.reduceat(tolerance[moving[0]:moving[-1]],
                                                   np.cumsum(span) - span)
            with np.errstate(divide="ignore", invalid="ignore"):
                pair = np.where(blend > 0,
                                np.minimum(1.0, MARGIN * corner_tolerance / blend), 1.0)
            factor[moving[0]:moving[-1]] = np.repeat(pair, span)
        if node_ori is None or node_q is None or not math.isfinite(self.orientation_tolerance):
            return factor
        # the rotary axes move linearly in time along every piece, TCP or not
        with np.errstate(divide="ignore", invalid="ignore"):
            rotary = np.diff(node_q[:, 3:], axis=0) / durations[:, None]
        rotary[~(durations > 0)] = 0.0
        moving = np.flatnonzero((speed > 0) | rotary.any(axis=1))
        if moving.size < 2:
            return factor
        # The orientation's velocity where each leg meets the corner: the rotary velocity
        # through the orientation's Jacobian at the corner (a chord of a long rotation can
        # point far from its tangent there). Pieces at rest between the legs do not move the
        # pose, so the corner is the node where the next leg starts.
        corner = node_q[moving[1:]]
        jacobian = self.kinematics.orientation_jacobian(corner[:, 3], corner[:, 4])
        turning_in = np.einsum("nik,nk->ni", jacobian, rotary[moving[:-1]])
        turning_out = np.einsum("nik,nk->ni", jacobian, rotary[moving[1:]])
        span = moving[1:] - moving[:-1]
        corner_tolerance = np.minimum.reduceat(tolerance[moving[0]:moving[-1]],
                                               np.cumsum(span) - span)
        # in units of the tolerances (a corner without a path tolerance: orientation only; a
        # zero one is a stop already, by the factor above)
        with np.errstate(divide="ignore"):
            to_path = np.where(np.isfinite(corner_tolerance) & (corner_tolerance > 0),
                               1.0 / corner_tolerance, 0.0)[:, None]
        to_ori = 1.0 / self.orientation_tolerance
        v = np.concatenate([velocity[moving[:-1]] * to_path, turning_in * to_ori], axis=1)
        w = np.concatenate([velocity[moving[1:]] * to_path, turning_out * to_ori], axis=1)
        blend = _across(v, w) * reach
        blend[blend < POSE_ROUND_OFF] = 0.0
        with np.errstate(divide="ignore"):
            pair = np.where(blend > 0, np.minimum(1.0, MARGIN / blend), 1.0)
        factor[moving[0]:moving[-1]] = np.minimum(factor[moving[0]:moving[-1]],
                                                  np.repeat(pair, span))
        return factor

    def blend_within_tolerance(self, durations, node_path, reach, tolerance, node_ori=None,
                               node_q=None):
        """Slow the pieces on both sides of each corner by its factor (a few rounds: slowing
        one corner changes its neighbours' steps)."""
        for _ in range(4):
            # a corner that cannot be a stop (the segment's own ends) slows at most this much
            factor = np.maximum(self.corner_factors(durations, node_path, reach, tolerance,
                                                    node_ori, node_q), SHARP_CORNER)
            if factor.min(initial=1.0) >= 1.0 - 1e-12:
                break
            slow = np.ones(durations.size)
            slow[:-1] = factor
            slow[1:] = np.minimum(slow[1:], factor)
            durations = durations / slow
        return durations

    def nominal(self, node_t, node_q, node_tip, piece_tcp, n):
        """Nominal axis commands at n + 1 samples j*ts over the segment, axis-major (5, n + 1)
        so that every per-axis pass runs over contiguous memory; the piece each sample is in;
        and, where the segment has TCP pieces, the nominal tool tip (3, n + 1) (None
        otherwise): straight between the nodes in TCP pieces, the direct kinematics of the
        axes in the others."""
        tau = np.arange(n + 1) * self.ts
        q = np.empty((5, n + 1))
        for i in range(5):
            q[i] = np.interp(tau, node_t, node_q[:, i])
        piece = np.searchsorted(node_t[1:-1], tau, side="right")
        tcp = piece_tcp[piece]
        tip = None
        if tcp.any():
            tip = np.empty((3, n + 1))
            for i in range(3):
                tip[i] = np.interp(tau, node_t, node_tip[:, i])
            q[:3, tcp] = self.kinematics.linear_axes(tip[:, tcp].T, q[3:, tcp].T).T
            if not tcp.all():
                tip[:, ~tcp] = self.kinematics.forward(q[:, ~tcp].T)[0].T
        q[:, -1] = node_q[-1]
        return q, piece, tip

    def filtered(self, q_nom, tip_nom, tcp, n1, n2):
        """The jerk filters applied to the nominal motion. Outside TCP each axis is averaged
        on its own. In TCP the tool tip and the rotary axes are averaged and the linear axes
        come from the kinematics (``linear_axes``), as a TCP controller computes its joints:
        the tip then follows the averaged tip path (it stands still while only the rotary
        axes turn), where averaging the linear axes themselves would let it wander as the
        table turns. Where the filter window spans TCP and other pieces, the two are mixed
        by the averaged share of TCP samples."""
        def box(x):
            return _box(_box(x, n1, n1 + n2 - 2), n2, 0)

        if tip_nom is None:
            return box(q_nom)
        q = np.empty((5, q_nom.shape[1] + n1 + n2 - 2))
        q[3:] = box(q_nom[3:])
        q[:3] = self.kinematics.linear_axes(box(tip_nom).T, q[3:].T).T
        if not tcp.all():
            share = box(tcp.astype(float)[None])[0]
            q[:3] = share * q[:3] + (1.0 - share) * box(q_nom[:3])
        # the ends at rest exactly where they were programmed (not through the kinematics'
        # round-off)
        q[:, 0], q[:, -1] = q_nom[:, 0], q_nom[:, -1]
        return q

    def segment(self, k0, k1, durations, lengths=None):
        """Filtered commands and line numbers of moves k0..k1-1, from rest to rest; with
        ``lengths``, the filters' (n1, n2) of the segment it was split from."""
        ts = self.ts
        if durations.sum() <= 0.0:  # nothing moves (zero-length rapids)
            return (np.repeat(self.points[k1][None], 2, axis=0),
                    np.full(2, self.program.line[k1 - 1]))
        n1, n2 = self.filter_lengths(k0, k1, durations) if lengths is None else lengths
        window = (n1 + n2) * ts
        reach = _reach(n1, n2) * ts
        durations, move, node_q, node_tip = self.pieces(k0, k1, durations, window)
        programmed = durations
        piece_tcp = self.tcp[move]
        piece_tolerance = self.tolerance[move]
        node_ori = None
        if math.isfinite(self.orientation_tolerance) and np.ptp(node_q[:, 3:], axis=0).any():
            # (a segment whose rotary axes stand still keeps its orientation: nothing to bound)
            node_ori = self.kinematics.forward(node_q)[1]
        blended = bool(np.isfinite(piece_tolerance).any()) or node_ori is not None
        if blended:
            # the tighter tolerance of the two blocks meeting at a corner applies
            tolerance = np.minimum(piece_tolerance[:-1], piece_tolerance[1:])
            # each piece's path in the frame it is interpolated in (its end node decides)
            node_path = node_q[:, :3].copy()
            tcp_nodes = np.concatenate([piece_tcp[:1], piece_tcp])
            node_path[tcp_nodes] = node_tip[tcp_nodes]
            factor = self.corner_factors(durations, node_path, reach, tolerance, node_ori,
                                         node_q)
            sharp = np.flatnonzero(factor < SHARP_CORNER)
            if sharp.size:
                # Slowing down for a sharp corner costs more than stopping at it (about one
                # filter window): the segment stops there, with no blend at all.
                at = sorted({int(move[c]) + 1 for c in sharp} - {k0, k1})
                if at:
                    return self._split(k0, k1, at, durations, move, (n1, n2))
            durations = self.blend_within_tolerance(durations, node_path, reach, tolerance,
                                                    node_ori, node_q)
        lines = self.program.line[move]
        corners = (self._corners(move, piece_tcp, piece_tolerance, node_ori is not None)
                   if blended else None)
        for passes in range(1, MAX_PASSES + 1):
            total = durations.sum()
            n = max(1, math.ceil(total / ts - 1e-9))
            # stretch to a whole number of samples (never faster than planned)
            node_t = np.concatenate([[0.0], np.cumsum(durations * (n * ts / total))])
            q_nom, piece, tip_nom = self.nominal(node_t, node_q, node_tip, piece_tcp, n)
            q = self.filtered(q_nom, tip_nom, piece_tcp[piece], n1, n2)
            off = None
            if corners is not None:
                off = self.corner_excess(q, node_t, node_q, node_tip, corners, n1 + n2,
                                         node_ori)
            if off is None or not off.size:
                lag = (n1 + n2 - 2) // 2
                at = np.clip(np.arange(q.shape[1]) - lag, 0, n)
                return self.within_limits(q, lines[piece[at]])
            if passes > CORNER_PASSES:
                # still outside after several slow-downs: stop at those corners (the path
                # passes through a stop exactly)
                at = sorted({int(move[corners.node[c] - 1]) + 1 for c in off[:, 0]
                             .astype(int)} - {k0, k1})
                if at:
                    return self._split(k0, k1, at, programmed, move, (n1, n2))
            factor = np.ones(durations.size)
            for c, excess in off:
                # the pieces whose nominal motion the blend of the corner averages
                t_c = node_t[corners.node[int(c)]]
                lo = max(int(np.searchsorted(node_t, t_c - window, "right")) - 1, 0)
                hi = min(int(np.searchsorted(node_t, t_c + window, "left")), durations.size)
                factor[lo:hi] = np.maximum(factor[lo:hi], excess / MARGIN)
            durations = durations * factor
        raise PrecontourError(f"{self.program.source}, line {self.program.line[k0]}: the "
                              f"corner tolerance could not be met after {MAX_PASSES} passes")

    def within_limits(self, q, line):
        """The filtered commands ``q`` (axes, samples) slowed down locally and smoothly
        (:func:`~.retime.retime`) wherever a sample breaks an axis limit, until none does.

        Slowing the filtered samples on a new clock divides velocity, acceleration and jerk by
        rho, rho^2, rho^3: a jerk 10 % over its limit costs a stretch of 3 %. (Slowing the
        blocks' times instead leaves the filters as they are, so a kink's acceleration and jerk
        fall only like 1/rho, and each slowed window's edges are new velocity steps the
        filters were not sized for: on a 242-block output of ``run`` that made 6.03 s of
        programmed motion 91.9 s after 19 passes.) The path is the filtered one: a re-timing
        moves along it, so the corners keep their blends."""
        ts = self.ts
        ratio, order = _violations(q, ts, self.limits, orders=True)
        if ratio.max(initial=0.0) <= 1.0 + CHECK_RTOL:
            return q.T, line
        traj = Trajectory(t=np.arange(q.shape[1]) * ts, q=q.T)
        for _ in range(MAX_PASSES):
            over = ratio > 1.0 + CHECK_RTOL
            if not over.any():
                return traj.q, line
            stretch = np.where(over, (ratio / MARGIN) ** (1.0 / order), 1.0)
            retimed = retime(traj, stretch, line=line, ramp=LIMITS_RAMP, spread=LIMITS_SPREAD)
            traj, line = retimed.trajectory, retimed.line
            # the ends at rest exactly where they were
            traj.q[-1] = q[:, -1]
            ratio, order = _violations(traj.q.T, ts, self.limits, orders=True)
        raise self.limit_error(traj.q.T, line)

    def limit_error(self, q, line):
        """The axis limit still broken after :data:`MAX_PASSES` slow-downs, naming the axis,
        the quantity, its value and limit, and the program line."""
        ts = self.ts
        worst = (0.0, 0, 1, 0)
        ext = np.concatenate([np.repeat(q[:, :1], 3, axis=1), q,
                              np.repeat(q[:, -1:], 3, axis=1)], axis=1)
        for order in (1, 2, 3):
            d = np.abs(np.diff(ext, order, axis=1)) / ts**order
            r = d / self.limits[order - 1][:, None]
            i, k = np.unravel_index(int(np.argmax(r)), r.shape)
            if r[i, k] > worst[0]:
                worst = (float(r[i, k]), int(i), order, float(d[i, k]),
                         int(np.clip(k - 3, 0, q.shape[1] - 1)))
        _, i, order, value, k = worst
        axis = self.program.axes[i]
        unit = ("mm" if i < 3 else "rad") + ("/s", "/s^2", "/s^3")[order - 1]
        quantity = ("velocity", "acceleration", "jerk")[order - 1]
        limit = float(self.limits[order - 1][i])
        return MachineLimitError(
            f"{self.program.source}, line {int(line[k])}: axis {axis} {quantity} "
            f"{value:.6g} {unit} is above its limit {limit:.6g} {unit} "
            f"({100 * value / limit:.1f} %) after {MAX_PASSES} slow-downs; the program asks "
            "more of the machine there than its limits allow")

    def _corners(self, move, piece_tcp, piece_tolerance, oriented):
        """The nodes between pieces whose blend :meth:`corner_excess` checks: interior nodes
        with a positive tolerance (the tighter of the two pieces'), finite or, where the
        segment's orientation is ``oriented`` (bounded), any; and the frame each is measured
        in (the tool tip where the piece ending there is TCP)."""
        tolerance = np.minimum(piece_tolerance[:-1], piece_tolerance[1:])
        bounded = np.isfinite(tolerance) | oriented
        keep = np.flatnonzero(bounded & (tolerance > 0))
        return _Corners(node=keep + 1, tolerance=tolerance[keep], tcp=piece_tcp[keep],
                        orientation=self.orientation_tolerance if oriented else math.inf)

    def corner_excess(self, q, node_t, node_q, node_tip, corners, span, node_ori=None):
        """(corner, excess) of every corner that the filtered path passes farther than
        :data:`CORNER_CHECK` of its tolerance from: the distance from the corner point to the
        polyline of the samples whose filter window reaches the corner's time (the blend; the
        path is farther from the corner elsewhere), over the tolerance. Measured where the
        tolerance applies: at the tool tip for TCP pieces, in the linear axes otherwise.

        With an orientation tolerance (and ``node_ori``, the orientation at the nodes) the
        corner is a pose: along the polyline of the samples' (point, orientation), the
        smallest of the larger of the point's distance and the orientation's, each over its
        tolerance (:func:`_pose_distance`), so that the tip within its tolerance and the
        orientation within its own are found at the same moment."""
        if not corners.node.size:
            return np.zeros((0, 2))
        n_out = q.shape[1]
        tcp = corners.tcp
        oriented = node_ori is not None and math.isfinite(corners.orientation)
        if tcp.any() or oriented:
            tips, orientation = self.kinematics.forward(q.T)
        width = min(span + 4, n_out - 1)
        out = []
        chunk = max(1, 2_000_000 // ((6 if oriented else 3) * (width + 1)))
        for first in range(0, corners.node.size, chunk):
            part = slice(first, first + chunk)
            node = corners.node[part]
            point = np.where(tcp[part, None], node_tip[node], node_q[node, :3])
            start = np.clip(np.floor(node_t[node] / self.ts).astype(np.int64) - 2, 0,
                            n_out - 1 - width)
            index = start[:, None] + np.arange(width + 1)
            path = q[:3, index].transpose(1, 2, 0)
            if tcp[part].any():
                path[tcp[part]] = tips[index[tcp[part]]]
            tolerance = corners.tolerance[part, None, None]
            # a corner without a path tolerance is bounded in orientation only
            scale = np.where(np.isfinite(tolerance), 1.0 / tolerance, 0.0)
            rel = (path[:, :-1] - point[:, None, :]) * scale
            ab = np.diff(path, axis=1) * scale
            if oriented:
                turn = orientation[index]
                rel_o = (turn[:, :-1] - node_ori[node][:, None, :]) / corners.orientation
                ab_o = np.diff(turn, axis=1) / corners.orientation
                excess = _pose_distance(rel, ab, rel_o, ab_o).min(axis=1)
            else:
                excess = _segment_distance(rel, ab).min(axis=1)
            bad = np.flatnonzero(excess > CORNER_CHECK)
            out.append(np.column_stack([bad + first, excess[bad]]))
        return np.concatenate(out)

    def _split(self, k0, k1, at, durations, move, lengths):
        """Segments k0..at[0], at[0]..at[1], ..., each from rest to rest, joined like the
        program's own segments."""
        per_move = np.zeros(k1 - k0)
        np.add.at(per_move, move - k0, durations)  # the pieces' (programmed) times
        edges = [k0, *at, k1]
        parts_q, parts_line = [], []
        for a, b in zip(edges[:-1], edges[1:]):
            q, line = self.segment(a, b, per_move[a - k0:b - k0].copy(), lengths)
            if parts_q:
                parts_q.append(np.repeat(parts_q[-1][-1:], 2, axis=0))
                parts_line.append(np.repeat(parts_line[-1][-1:], 2))
                q, line = q[1:], line[1:]
            parts_q.append(q)
            parts_line.append(line)
        return np.concatenate(parts_q), np.concatenate(parts_line)
