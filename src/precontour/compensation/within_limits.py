"""Pre-compensation that keeps the machine's axis limits (paper Sec. 4).

Compensated commands lead the reference, and their corrections add velocity, acceleration
and above all jerk (up to +91 % peak jerk on the built-in paths). Where the compensated
commands break an axis limit, the reference is slowed down locally
(:func:`precontour.trajectory.retime.retime`, by the stretch the limit check asks for, with
a margin) and compensated again, until every axis keeps every limit; after the first
round only the stretches around the slowed windows are compensated again and spliced into
the commands (compensation is local in time). The slowed windows are reported in the time of
the original reference.

Before any slowing, kinks of the corrections are smoothed: where the closest reference point
of the predicted actual tool tip jumps from one leg of a corner to the other (a stop between
two blocks that meet at an angle, e.g. a rapid's end and the next feed move), the contour error
vector turns abruptly, and so does the tip correction. Slowing the motion does not remove such
a jump (its jerk falls like 1/rho, not 1/rho^3). There the commands blend into axis
tracking-error pre-compensation (each command plus its own predicted tracking error; spec
section 7's baseline), which is continuous and cancels the same lag to second order.

Then, where the commands still break a limit in the first round, the same blend is tried
instead of slowing down, window by window, and kept where its predicted contour errors stay
within the block margins of the compensated commands' (:func:`smooth_instead_of_slowing`).
Where the reference itself uses little of a limit, what breaks it is the corrections' own
roughness (on a smooth five-axis path the tool axis's contour correction turns within tens of
milliseconds where the rotary axis C reverses), and slowing down is a costly cure: on the
18-minute synthetic path of ``benchmarks/bench_run.py`` it added 16.8 % to the program, the
blend nothing, with the predicted contour errors no larger.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cache, partial
from typing import Callable

import numpy as np
from scipy.ndimage import minimum_filter1d

from ..defaults import DEFAULT_MIN_SPEED
from ..errors import MachineLimitError, notice
from ..machine.servo import Servo
from ..trajectory.feedplan import CHECK_RTOL
from ..trajectory.limits import LimitCheck, check_limits
from ..trajectory.retime import (Slowdown, held_through_stops, retime, slowdowns_of,
                                 stretch_reach)
from ..trajectory.sampled import Trajectory
from ..prediction.contour import ReferencePath, contour_errors
from .blend import taper_corrections, taper_weight
from .blocks import ORIENTATION_MARGIN, TIP_MARGIN, margin_bound
from .idle_axes import hold_idle_axes, hold_resting_axes
from .pieces import compensate_program, predict_program
from .programmed_end import end_at_programmed_end
from .precompensate import (CompensationResult, compensation_axis_tolerances, compensate,
                            compensation_tolerances, learning_step, predicted_actual)
from .stops import (LIMITED_SMOOTHING, SETTLE_DELAYS, Learner, LearningProblem, LearningReport,
                    LearningSettings, MachineActual)

#: Re-timing rounds before giving up.
MAX_ROUNDS = 16
#: Round from which a window still over a limit is slowed by its whole ratio.
LATE_ROUND = 4
#: Each round slows down to this fraction of what the limit check asks for. Compensating the
#: slowed reference again changes the corrections a little, so aiming just at the limit
#: (the feed planner's 0.98) needed 4 compensation rounds on a 2-minute test path, 0.9
#: needed 3; each round is a compensation, the costliest step of ``run``. But on programs
#: whose reference already runs at the limits, every window is slowed, and the margin is
#: time: measured (2026-12-03, ``pid-high``, with the 0.1 s ramps of
#: :data:`LIMITS_RAMP`) LinuxCNC's boats took +4.9 / +5.7 % (A-C / B-C)
#: with 0.9 and +3.8 / +4.3 % with 0.97 (issue 21: at most 5 %), in 6 rounds each; the eight
#: built-in and test paths that slow added 89.5 percentage points in sum, against 94.1 with
#: 0.9 (and 100.3 with the former 0.2 s ramps). ``circle`` / ``pid-high``, slowed at its final
#: stop, paid for it: 69.7-69.9 % of the max tip error removed on the worst draw with
#: learning (three nanometre draws of its points) instead of 76.0 % with 0.9.
RETIME_MARGIN = 0.97
#: Ramp and hold (s) of the re-timing (:func:`~..trajectory.retime.retime`'s ``ramp`` and
#: ``spread``). A slowed window costs about (2 ramp + 2 spread) h for a stretch 1 + h, most of
#: it in the ramps, so they are short here; the limit check after each round sees the terms
#: they add. Measured (2026-12-03, ``run`` with ``pid-high``): the re-timing's defaults (0.2
#: and 0.05 s) made LinuxCNC's boat examples +6.8 % (A-C) and +7.4 % (B-C) longer; 0.1 and
#: 0.02 s alone +4.2 / +4.5 %, but the speed then fell *during* ``circle``'s deceleration to
#: its final stop (its Y deceleration 888 instead of 664 mm/s^2) and its worst draw's max tip
#: error removed went from 76-79 % to 0.0-0.1 % on three nanometre draws of its points: hence
#: :func:`~..trajectory.retime.held_through_stops` (76.0 % with it).
LIMITS_RAMP = 0.1
LIMITS_SPREAD = 0.02
#: Default lowest speed of a slowed window, as a fraction of the planned speed there: where
#: keeping a limit would need a slower motion, the corrections there taper to the planned
#: commands instead (which keep the limits) and the motion keeps this speed.
MIN_SPEED = DEFAULT_MIN_SPEED
#: The whole-sample rounding of a slowed window (:func:`~..trajectory.retime.added_stretch`)
#: adds up to one sample to it: the stretch aims this far inside the floor.
_FLOOR_MARGIN = 0.98
#: A first check asking for more time stretch than this marks a kink of the corrections, not
#: their dynamics. The corrections' own derivatives add up to 91 % to the peak jerk on the
#: built-in paths (stretch 1.91^(1/3) = 1.24); a jump of the tip correction between two
#: samples, as at a corner's closest-point switch, asks for 3-8 (LinuxCNC's impeller example:
#: 7.8, a 2.7 um jump at a rapid's end).
KINK_STRETCH = 1.5


@dataclass(frozen=True)
class LimitedCompensation:
    """Compensated commands within the machine's limits, and what it took.

    Attributes
    ----------
    result : CompensationResult
        The final compensation, on ``reference``.
    reference : Trajectory
        The reference after re-timing (the input itself when nothing was slowed), with its
        source lines where the input had them (:attr:`line`).
    slowdowns : tuple of Slowdown
        Slowed windows, in the time of the original reference.
    planned_index : ndarray, shape (M,)
        Sample index (fractional) of the original reference for each sample of
        ``reference``: the time map of all the slow-downs together.
    rounds : int
        Compensations computed (1 = the first one kept the limits).
    first_check, check : LimitCheck
        The limit check of the first and of the final compensated commands.
    uncompensated : tuple of (float, float)
        Windows (s, time of ``reference``) where slowing down could not bring the corrections
        within the limits, so the commands there taper to the uncompensated ones
        (:func:`taper_corrections`).
    kinks : tuple of (float, float)
        Windows (s, time of the original reference) where a kink of the corrections was
        smoothed by blending into axis tracking-error pre-compensation (:data:`KINK_STRETCH`).
    smoothed : tuple of (float, float)
        Windows (s, time of the original reference) where the corrections broke a limit and
        were blended into axis tracking-error pre-compensation instead of being slowed down
        (:func:`smooth_instead_of_slowing`).
    min_speed : float
        The floor of the slow-downs, a fraction of the planned speed (:data:`MIN_SPEED`).
    """

    result: CompensationResult
    reference: Trajectory
    slowdowns: tuple[Slowdown, ...]
    planned_index: np.ndarray
    rounds: int
    first_check: LimitCheck
    check: LimitCheck
    uncompensated: tuple[tuple[float, float], ...] = ()
    kinks: tuple[tuple[float, float], ...] = ()
    min_speed: float = MIN_SPEED
    smoothed: tuple[tuple[float, float], ...] = ()

    @property
    def line(self) -> np.ndarray | None:
        """Source line of each sample of :attr:`reference`, when known (its own)."""
        return self.reference.line

    @property
    def added_time(self) -> float:
        return float(sum(s.added for s in self.slowdowns))


def compensate_within_limits(servo: Servo, reference: Trajectory, *,
                             line: np.ndarray | None = None, max_rounds: int = MAX_ROUNDS,
                             progress=None, splice: bool = True, min_speed: float = MIN_SPEED,
                             method: str = "contour", iterations: int = 1,
                             tol_linear: float | None = None, tol_rotary: float | None = None,
                             pass_progress=None) -> LimitedCompensation:
    """Compensate ``reference`` (with :func:`~.precompensate.compensate`: ``method``,
    ``iterations``, ``tol_linear``, ``tol_rotary``; ``pass_progress(pass, summary)`` after
    each pass of the first round), slowing it down locally and compensating again until the
    commands keep the servo's limits. ``line``: the source line of each sample where
    ``reference`` does not carry them itself (they travel with it through every re-timing).

    The first round compensates the whole reference. After a re-timing, ``splice=True``
    compensates again only around the slowed windows and splices the result into the
    previous commands (:func:`splice_recompensation`); ``False`` compensates everything again.
    No sample is slowed below ``min_speed`` (a fraction of its planned speed, 0 < min_speed
    <= 1; 1: never slowed): where a limit would need more, the corrections there taper to the
    planned commands (:func:`taper_corrections`; reported in ``uncompensated``).
    ``progress``, if given, is called as ``progress(round, message)``. Raises
    :class:`~precontour.errors.MachineLimitError` when a command leaves an axis's travel
    (slowing down cannot help) or the limits still fail after ``max_rounds`` compensations.
    """
    if not 0.0 < min_speed <= 1.0:
        raise ValueError(f"min_speed must be in (0, 1], got {min_speed!r}")
    limits = servo.axis_limits
    options = dict(method=method, iterations=iterations, tol_linear=tol_linear,
                   tol_rotary=tol_rotary)
    ts = reference.ts
    t0 = float(reference.t[0])
    if line is not None:
        # the lines given travel with the reference (and through its re-timings)
        reference = replace(reference, line=np.asarray(line))
    original_line = reference.line
    # samples (of the current reference) whose corrections taper to the planned commands
    # because the floor stops the slowing there; kept through every later re-timing
    floored = np.zeros(reference.n_samples, dtype=bool)
    floored_windows: list[tuple[int, int]] = []
    to_original = np.arange(reference.n_samples, dtype=float)
    current = reference
    first_check = None
    if progress is not None:
        progress(1, f"compensate ({current.n_samples} samples)")
    result = compensate_program(servo, current, progress=pass_progress, **options)
    q = result.trajectory.q
    kinks, smoothed = [], []
    for round_ in range(1, max_rounds + 1):
        # every route's commands end at the programmed end point (the compensation's own
        # already do, and so do the blends below, of commands that end there): this keeps
        # it for any other, before the limit check judges the taper too
        q = end_at_programmed_end(current.q, q, ts)
        check = check_limits(q, ts, limits, t0=t0)
        first_check = first_check or check
        if not check.ok and method == "contour":
            # what kinks and rough corrections blend into: predicted at most once a round
            tracking = cache(partial(_tracking, servo, current, options))
            q, windows = smooth_kinks(current, q, check, tracking)
            if windows:
                kinks += [(t0 + to_original[a] * ts, t0 + to_original[b] * ts)
                          for a, b in windows]
                check = check_limits(q, ts, limits, t0=t0)
            if round_ == 1 and not check.ok:
                # judged against the commands as they stand, their kinks smoothed: slowing
                # down would start from these
                predicted = result.after if q is result.trajectory.q else _predicted(
                    servo, current.with_axes(q), options, contour=True).contour
                q, windows = smooth_instead_of_slowing(servo, current, q, check, predicted,
                                                       tracking, options)
                if windows:
                    smoothed += [(t0 + a * ts, t0 + b * ts) for a, b in windows]
                    check = check_limits(q, ts, limits, t0=t0)
        over = check.ratio > 1.0 + CHECK_RTOL
        # the largest further stretch each sample may take and keep the floor: its speed now
        # (original samples per sample) over the floor, the least of it over the samples its
        # stretch reaches (the re-timing holds a stretch and fades it in and out around the
        # sample, so where an earlier round slowed a neighbour, that neighbour's room counts)
        room = minimum_filter1d(_FLOOR_MARGIN * _speed(to_original) / min_speed,
                                2 * stretch_reach(ts, ramp=LIMITS_RAMP, spread=LIMITS_SPREAD)
                                + 1, mode="nearest")
        stuck = over & (room <= 1.0 + CHECK_RTOL)
        if check.position_ok and (floored.any() or stuck.any()):
            floored |= stuck
            q, floored_windows = taper_corrections(current.q, q, floored, ts)
            check = check_limits(q, ts, limits, t0=t0)
            over = check.ratio > 1.0 + CHECK_RTOL
        if check.ok:
            # q differs from the compensation's own commands after a re-timing, a taper, or
            # kinks smoothed in the first round (which kept the limits: the smoothed commands
            # are the ones that keep them)
            if round_ > 1 or floored.any() or q is not result.trajectory.q:
                result = _result_for(servo, current, q, result, options)
            return LimitedCompensation(
                result=result, reference=current,
                slowdowns=slowdowns_of(to_original, ts, t0=t0, line=original_line),
                planned_index=to_original, rounds=round_, first_check=first_check, check=check,
                uncompensated=tuple((t0 + a * ts, t0 + b * ts) for a, b in floored_windows),
                kinks=_merged(kinks), min_speed=min_speed, smoothed=tuple(smoothed))
        if not check.position_ok:
            raise MachineLimitError("the compensated commands leave an axis's travel, which "
                                    "slowing down cannot cure: " + check.format())
        if round_ == max_rounds:
            break
        # The first round assumes a limit's quantity falls like rho^order when slowed by rho.
        # What still exceeds a limit after that falls more slowly (kinks of the corrections
        # fall like 1/rho): later rounds slow it by at least the square root of its ratio. On
        # the 18-minute test path the cube root alone had not converged after 8 rounds; the
        # whole ratio converged in 6 but lengthened the program by 82 %, the square root in 7
        # (the last 4 of them on a few windows, seconds each) by 69 %. From the fourth round on,
        # what is left is a few short windows (spliced in seconds): the whole ratio ends them
        # sooner (LinuxCNC's boat example: still 191 % over after 8 rounds with the square root).
        ratio = np.sqrt(check.ratio) if round_ < LATE_ROUND else check.ratio
        need = check.stretch if round_ == 1 else np.maximum(check.stretch, ratio)
        stretch = np.where(need > 1.0 + CHECK_RTOL, need / RETIME_MARGIN, 1.0)
        # the speed does not change while the axes decelerate to a rest or leave it
        stretch = held_through_stops(stretch, current.q, levels=limits.velocity)
        stretch = np.minimum(stretch, np.maximum(room, 1.0))
        retimed = retime(current, stretch, ramp=LIMITS_RAMP, spread=LIMITS_SPREAD)
        floored = floored[np.clip(np.rint(retimed.old_index).astype(int), 0, floored.size - 1)]
        to_original = np.interp(retimed.old_index, np.arange(current.n_samples), to_original)
        current = retimed.trajectory
        if progress is not None:
            progress(round_ + 1, f"compensate again ({current.n_samples} samples, "
                                 f"{len(retimed.slowdowns)} slowed window(s))")
        if splice:
            q = splice_recompensation(servo, current, retimed.old_index, q,
                                      passes=result.iterations, method=method,
                                      tol_linear=tol_linear, tol_rotary=tol_rotary)
        else:
            result = compensate_program(servo, current, **options)
            q = result.trajectory.q
    # Slowing down no longer helps where a correction has a kink (its jerk does not fall when
    # the motion slows): there the commands go back to the planned ones, which keep the limits.
    tapered, windows = taper_corrections(current.q, q, floored | (check.ratio > 1.0 + CHECK_RTOL),
                                         ts)
    final = check_limits(tapered, ts, limits, t0=t0)
    if not final.ok:
        raise MachineLimitError(f"the compensated commands still exceed the machine's limits "
                                f"after {max_rounds} compensation round(s): {check.format()}")
    result = _result_for(servo, current, tapered, result, options)
    return LimitedCompensation(
        result=result, reference=current,
        slowdowns=slowdowns_of(to_original, ts, t0=t0, line=original_line),
        planned_index=to_original, rounds=max_rounds, first_check=first_check, check=final,
        uncompensated=tuple((t0 + a * ts, t0 + b * ts) for a, b in windows),
        kinks=_merged(kinks), min_speed=min_speed, smoothed=tuple(smoothed))


def _speed(to_original: np.ndarray) -> np.ndarray:
    """Speed at each sample as a fraction of the planned one: original samples per sample
    of the time map (the slower of the two intervals at each sample)."""
    if to_original.size < 2:
        return np.ones_like(to_original)
    rate = np.diff(to_original)
    return np.minimum(np.r_[rate[0], rate], np.r_[rate, rate[-1]])


def _merged(windows: list[tuple[float, float]]) -> tuple[tuple[float, float], ...]:
    """Time windows sorted, overlapping ones merged (a kink smoothed again in a later round
    overlaps its first window)."""
    out: list[list[float]] = []
    for a, b in sorted(windows):
        if out and a <= out[-1][1]:
            out[-1][1] = max(out[-1][1], b)
        else:
            out.append([a, b])
    return tuple((float(a), float(b)) for a, b in out)


def _tracking(servo: Servo, reference: Trajectory, options) -> np.ndarray:
    """Axis tracking-error pre-compensation of ``reference``: each command plus its own
    predicted tracking error (spec section 7's baseline), ending at the programmed end point
    (:func:`~.programmed_end.end_at_programmed_end`), so that blends into it keep the end."""
    return end_at_programmed_end(reference.q,
                                 reference.q + _predicted(servo, reference, options).e,
                                 reference.ts)


def smooth_kinks(reference: Trajectory, q: np.ndarray, check: LimitCheck,
                 tracking: Callable[[], np.ndarray]
                 ) -> tuple[np.ndarray, list[tuple[int, int]]]:
    """Commands ``q`` (compensated on ``reference``) blended into axis tracking-error
    pre-compensation (``tracking()``, :func:`_tracking`) around the samples whose limit check
    asks for more than :data:`KINK_STRETCH` (with the weights of :func:`taper_corrections`);
    returns them and the blended windows as sample index pairs (none: ``q`` itself)."""
    kinks = check.stretch > KINK_STRETCH
    if not kinks.any():
        return q, []
    return taper_corrections(tracking(), q, kinks, reference.ts)


def smooth_instead_of_slowing(servo: Servo, reference: Trajectory, q: np.ndarray,
                              check: LimitCheck, predicted, tracking: Callable[[], np.ndarray],
                              options) -> tuple[np.ndarray, list[tuple[int, int]]]:
    """Commands ``q`` (compensated on ``reference``, predicted contour errors ``predicted``)
    blended into axis tracking-error pre-compensation (``tracking()``, :func:`_tracking`)
    around the samples over a limit in
    ``check``, in each window of the blend (:func:`~.blend.taper_weight`) whose predicted
    contour errors, tip and orientation, stay within the block margins
    (:func:`~.blocks.margin_bound`: 0.1 um / 1 urad or 5 %) of ``predicted`` there; returns
    them and the blended windows as sample index pairs (none: ``q`` itself).

    Why judged on the prediction: blending a leading command into a lagging one over 0.1 s
    on a curved path leaves the path. On the built-in ``circle`` with ``pid-high`` the blend
    would leave 2.96 um where the compensated commands leave 0.11 um (slowing that window
    down costs 3.3 % of the program), while on the synthetic path of
    ``benchmarks/bench_run.py`` every one of its 599 windows is predicted no worse, most of
    them better."""
    over = check.ratio > 1.0 + CHECK_RTOL
    if not over.any():
        return q, []
    ts = reference.ts
    blended, _ = taper_corrections(tracking(), q, over, ts)
    after = _predicted(servo, reference.with_axes(blended), options, contour=True).contour
    # the windows where the blend changes the commands
    weight, _ = taper_weight(over, ts)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], (weight > 0).astype(np.int8), [0]])))
    keep = np.zeros(q.shape[0], dtype=bool)
    for a, b in zip(edges[::2], edges[1::2]):       # one per window: few
        near = slice(a, b)
        if after.tip[near].max() <= margin_bound(predicted.tip[near].max(), TIP_MARGIN) and \
                after.orientation[near].max() <= margin_bound(
                    predicted.orientation[near].max(), ORIENTATION_MARGIN):
            keep[near] = True
    if not keep.any():
        return q, []
    return taper_corrections(tracking(), q, over & keep, ts)


def learn_within_limits(servo: Servo, limited: LimitedCompensation,
                        machine_actual: MachineActual, passes: int, *,
                        progress=None, update: str = "mean",
                        local: bool = True) -> LimitedCompensation:
    """``limited`` improved by ``passes`` passes of learning against the nonlinear machine
    model ``machine_actual`` (:func:`~.stops.learn_at_stops`, from its commands on its
    reference; one machine, or better an ensemble of draws of it,
    :func:`precontour.simulation.ensemble_actual`), keeping only commands within the servo's
    limits:
    each learning update and each settling is smoothed (:data:`~.stops.LIMITED_SMOOTHING`)
    and a command beyond a limit is not kept; nowhere worse than the uncompensated command on
    every draw, in whole and block by block (each source line of ``limited.line``, else
    windows), falling back locally to axis tracking-error pre-compensation or the planned
    command where needed (:mod:`.blocks`). ``update``, ``local``: as for
    :func:`~.stops.learn_at_stops`. ``result.learning`` reports what was tried and kept."""
    kinematics, models, limits = servo.kinematics, servo.models, servo.axis_limits
    reference = limited.reference
    q_start = limited.result.trajectory.q
    path = ReferencePath.from_trajectory(reference)
    q, report = learn_commands(servo, reference, q_start, machine_actual, passes,
                               progress=progress, path=path, update=update, local=local)
    result = replace(limited.result, learning=report)
    if q is not q_start:
        after = contour_errors(path, predicted_actual(reference.t, q, models), kinematics)
        result = replace(result, trajectory=reference.with_axes(q), after=after,
                         iterations=0 if report.chosen == "uncompensated" else result.iterations)
    return replace(limited, result=result,
                   check=check_limits(q, reference.ts, limits, t0=float(reference.t[0])))


def planned_if_uncompensated(servo: Servo, limited: LimitedCompensation,
                             planned: Trajectory) -> LimitedCompensation:
    """``limited`` as learning left it; but where learning kept the uncompensated command
    everywhere (``result.learning.chosen``), the planned trajectory ``planned`` (the one
    ``limited`` was compensated from) as it was planned: its slow-downs were made for the
    corrections, and with no correction kept they would only cost cycle time (issue 42 item
    4; LinuxCNC's ``xyzac_switchkins_test_3.ngc``: 4.955 s instead of the planned 4.791 s).
    Said in one notice. Kept as learning left it where ``planned`` itself breaks a limit."""
    learning = limited.result.learning
    if learning is None or learning.chosen != "uncompensated" or not limited.slowdowns:
        return limited
    check = check_limits(planned.q, planned.ts, servo.axis_limits, t0=float(planned.t[0]))
    if not check.ok:
        return limited
    notice(f"learning kept the uncompensated commands everywhere: the "
           f"{len(limited.slowdowns)} slow-down(s) made for the corrections are dropped "
           f"({limited.added_time:.3g} s)")
    errors = _predicted(servo, planned, {}, contour=True).contour
    result = replace(limited.result, trajectory=planned, before=errors, after=errors,
                     iterations=0)
    return replace(limited, result=result, reference=planned, slowdowns=(),
                   planned_index=np.arange(planned.n_samples, dtype=float), check=check,
                   uncompensated=(), kinks=(), smoothed=())


def learn_commands(servo: Servo, reference: Trajectory, q_start: np.ndarray,
                   machine_actual: MachineActual, passes: int, *,
                   line: np.ndarray | None = None, progress=None,
                   scored: tuple[int, int] | None = None, project=None,
                   path: ReferencePath | None = None, update: str = "mean", local: bool = True,
                   settle_delays: tuple[float, ...] = SETTLE_DELAYS,
                   programmed_end: bool = True) -> tuple[np.ndarray, LearningReport]:
    """The learning of :func:`learn_within_limits` on ``reference`` from the commands
    ``q_start``: the command kept and the report (:func:`~.stops.learn_at_stops`).

    For learning by segment (:mod:`.segments`): ``scored = (first, stop)`` judges only the
    contour errors of those samples (the others count as zero for every command, so they
    neither choose nor fall back), and ``project(q)`` is the command that is in fact run for
    a command ``q`` learning proposes (its lead-in held at the commands already decided); the
    machine model, the limit check and the fallbacks see projected commands, the
    uncompensated ``reference.q`` itself excepted. The command returned is not projected.
    ``line``: the blocks' source lines where ``reference`` does not carry them.
    ``path``: the reference's curves, where already built. ``update``, ``local``,
    ``settle_delays``: as for :func:`~.stops.learn_at_stops` (a segment that does not hold the
    program's final dwell tries no settled tails). ``programmed_end``: ``reference`` ends where
    the program does, so the command kept ends at its last sample, its corrections tapered
    over the final rest (:func:`~.programmed_end.end_at_programmed_end`; False for an earlier
    segment).
    """
    kinematics, limits = servo.kinematics, servo.axis_limits
    ts, t0 = reference.ts, float(reference.t[0])
    line = reference.line if line is None else line
    path = ReferencePath.from_trajectory(reference) if path is None else path
    project = (lambda q: q) if project is None else project

    def errors_of(q_actual):
        return _scored(contour_errors(path, q_actual, kinematics), scored, 0)

    def tail_errors_of(q_actual, first):
        return _scored(contour_errors(path, q_actual, kinematics, t=path.t[first:]), scored,
                       first)

    def within_limits(q):
        return check_limits(project(q), ts, limits, t0=t0).ok

    idle_tolerance = compensation_axis_tolerances()

    def ended(q):
        return end_at_programmed_end(reference.q, q, ts)

    def hold(q):
        return hold_idle_axes(reference.q, q, idle_tolerance)

    def run_as(q):
        """The command in fact run for ``q``: the uncompensated one as it is, others
        projected."""
        return q if q is reference.q else project(q)

    def machine(q):
        return machine_actual(run_as(q))

    if hasattr(machine_actual, "draw"):
        machine.draw = lambda q, index: machine_actual.draw(run_as(q), index)

    def hold_resting(q):
        return hold_resting_axes(reference.q, q, idle_tolerance)

    tracking = hold(reference.q + _predicted(servo, reference, {}).e)
    tracking = project(ended(tracking) if programmed_end else tracking)
    problem = LearningProblem(reference.q, ts, machine, errors_of,
                              learning_step(reference, path, kinematics, hold=hold),
                              line=line, t0=t0, tail_errors_of=tail_errors_of,
                              repeat_actual=getattr(machine_actual, "repeat", None))
    settings = LearningSettings(passes=passes, settle_delays=tuple(settle_delays),
                                smoothing=LIMITED_SMOOTHING, update=update, local=local)
    learner = Learner(problem, settings, admissible=within_limits, progress=progress,
                      fallbacks=(("tracking-error pre-compensation", tracking),),
                      variants=(("resting axes held", hold_resting),))
    q, report = learner.learn(q_start)
    # The command kept ends at the programmed end (a segment's own end is not the program's):
    # its corrections tapered over the final rest, where the axes have settled. Only the
    # command kept: tapering every command learning tries (its judgements on the tapered
    # ones) made the choice on `circle` / `pid-low` turn on the last digit (with the oldest
    # allowed dependency versions one of 5 nanometre draws of its points kept a command that
    # moves the resting X, mean tip error 13.4 % of the uncompensated instead of 5.1 %; with
    # the taper applied after, all 5 keep X held on both version sets). The limits are
    # checked on the command returned (learn_within_limits).
    return (ended(q) if programmed_end else q), report


def _scored(errors, scored: tuple[int, int] | None, first: int):
    """``errors`` (of samples ``first`` on) with the tip and orientation errors outside the
    samples ``scored`` = (first, stop) set to zero; ``errors`` itself when None."""
    if scored is None:
        return errors
    index = first + np.arange(errors.tip.size)
    outside = (index < scored[0]) | (index >= scored[1])
    return replace(errors, tip=np.where(outside, 0.0, errors.tip),
                   orientation=np.where(outside, 0.0, errors.orientation))


#: The splice margins (spec section 6 compensation is local in time):
#: the influence of a change of the command decays with the error models' slowest pole to
#: SPLICE_DECAY of its size over ``decay_time``; compensation looks ahead along the reference
#: by SPLICE_LOOKAHEAD s (closest-point windows, the lead blend); the previous and the new
#: commands are blended over SPLICE_BLEND s with a C2 weight (their spline fits differ by up to
#: the fit tolerance); SPLICE_END s at a stretch's end absorb the fit's end conditions.
SPLICE_DECAY = 1e-6
SPLICE_LOOKAHEAD = 0.1
SPLICE_BLEND = 0.1
SPLICE_END = 0.2


def decay_time(models) -> float:
    """Seconds over which every error model's response decays to :data:`SPLICE_DECAY`."""
    slowest = min(float(np.min(-np.roots(m.den).real)) for m in models)
    return float(np.log(1.0 / SPLICE_DECAY) / slowest)


def splice_recompensation(servo: Servo, reference: Trajectory, old_index: np.ndarray,
                          q_previous: np.ndarray, *, passes: int, method: str = "contour",
                          tol_linear: float | None = None,
                          tol_rotary: float | None = None) -> np.ndarray:
    """Compensated commands for a re-timed ``reference``, computing only around its slowed
    windows: elsewhere they are ``q_previous`` (the compensated commands before re-timing) at
    the old sample ``old_index`` of each new sample.

    Each slowed window [a, b] is compensated on the stretch
    [a - G - B - L, b + L + B + E] (L = :func:`decay_time`, G = SPLICE_LOOKAHEAD,
    B = SPLICE_BLEND, E = SPLICE_END, in samples); its first L samples, where the stretch's
    start from rest has not yet decayed, and its last E are discarded, and over B before
    a - G and after b + L the new commands are blended in and out with a C2 weight. Stretches
    that overlap are merged. ``passes`` compensation passes of ``method`` at the fit
    tolerances ``tol_linear``, ``tol_rotary`` are applied, as in the whole trajectory's
    compensation (0: the commands stay uncompensated).
    """
    n = reference.n_samples
    ts = reference.ts
    whole = np.clip(np.rint(old_index).astype(int), 0, q_previous.shape[0] - 1)
    if passes == 0:
        return reference.q.copy()
    q = q_previous[whole].copy()
    slow = np.diff(old_index) < 1.0 - 1e-9
    if not slow.any():
        return q
    L, G, B, E = (int(np.ceil(x / ts)) for x in (decay_time(servo.models), SPLICE_LOOKAHEAD,
                                                   SPLICE_BLEND, SPLICE_END))
    edges = np.flatnonzero(np.diff(np.concatenate([[0], slow.astype(np.int8), [0]])))
    starts, ends = edges[::2], edges[1::2]          # window samples a .. b (b = end index)
    s0 = np.maximum(starts - G - B - L, 0)
    s1 = np.minimum(ends + L + B + E, n - 1)
    # Merge overlapping stretches (running maximum of the ends).
    reach = np.maximum.accumulate(s1)
    new_group = np.concatenate([[True], s0[1:] > reach[:-1]])
    first = np.flatnonzero(new_group)
    lo = s0[first]
    hi = np.maximum.reduceat(s1, first)
    a = starts[first]
    b = np.maximum.reduceat(ends, first)
    for lo_k, hi_k, a_k, b_k in zip(lo.tolist(), hi.tolist(), a.tolist(), b.tolist()):
        part = slice(lo_k, hi_k + 1)
        sub = Trajectory(t=reference.t[part], q=reference.q[part], P=reference.P[part],
                         O=reference.O[part])
        new = compensate(servo, sub, method=method, iterations=passes,
                         min_passes=passes, tol_linear=tol_linear, tol_rotary=tol_rotary,
                         # only the stretch that reaches the program's end ends where it does
                         programmed_end=hi_k == n - 1).trajectory.q
        index = np.arange(lo_k, hi_k + 1)
        up = _ramp((index - (a_k - G - B)) / B) if lo_k > 0 else np.ones(index.size)
        down = _ramp(((b_k + L + B) - index) / B) if hi_k < n - 1 else np.ones(index.size)
        weight = np.minimum(up, down)[:, None]
        q[part] = weight * new + (1.0 - weight) * q[part]
    return q


def _ramp(x: np.ndarray) -> np.ndarray:
    """C2 step from 0 (x <= 0) to 1 (x >= 1): 6x^5 - 15x^4 + 10x^3."""
    x = np.clip(x, 0.0, 1.0)
    return x * x * x * (10.0 + x * (-15.0 + 6.0 * x))


def _result_for(servo: Servo, reference: Trajectory, q: np.ndarray, last: CompensationResult,
                options) -> CompensationResult:
    """The CompensationResult of spliced commands: predicted contour errors before and after
    on the whole re-timed reference."""
    before = _predicted(servo, reference, options, contour=True).contour
    after = _predicted(servo, reference.with_axes(q), options, contour=True).contour
    return CompensationResult(trajectory=reference.with_axes(q), before=before, after=after,
                              iterations=last.iterations,
                              history=(before.summary(), after.summary()), method=last.method)


def _predicted(servo: Servo, traj: Trajectory, options, contour: bool = False):
    """Prediction of ``traj`` at the compensation's fit tolerances, whole up to
    :data:`~.pieces.AT_ONCE_SAMPLES` samples and in overlapping pieces above, so that a long
    program's re-timing rounds stay in bounded memory (``contour``: also its contour
    errors)."""
    tol_linear, tol_rotary = compensation_tolerances(options.get("tol_linear"),
                                                     options.get("tol_rotary"))
    return predict_program(
        servo, traj if contour else Trajectory(t=traj.t, q=traj.q),
        tol_linear=tol_linear, tol_rotary=tol_rotary)
