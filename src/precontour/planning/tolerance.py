"""The fastest motion whose contour errors keep a tolerance on the realistic virtual machine.

Finishing feeds are kept low so that the contour errors stay within the part's tolerance
(the paper's first paragraph). This module owns the search for the fastest timing of a
planned trajectory that keeps a tolerance (:class:`ContourTolerance`, tool tip and
optionally orientation) everywhere, with pre-compensation (:func:`search_feed` with
``compensate=True``) and without it (the honest baseline: the same search, the same local
retiming, the uncompensated commands), and the comparison of the two
(:func:`feed_within_tolerance`).

How: the search starts from the trajectory planned at the upper-bound feed, measures its
contour errors on the realistic virtual machine, and slows it down locally wherever an
error exceeds the tolerance, by the stretch ``(error / (AIM * tolerance))^(1/EXPONENT)``
(a lag's contour error grows about like the square of the speed: measured on ``paper`` /
``pid-low``, the uncompensated tip error falls 252.8 -> 112.2 -> 63.2 um for a uniform
stretch 1 -> 1.5 -> 2, the exponent 2.0; the compensated one 13.5 -> 5.4 -> 2.5 um, 2.3-2.6),
with the C2 windows of :func:`~precontour.trajectory.retime.retime` (every sample above
``AIM`` of it, the speed halving no faster than over :data:`HALVING_TIME`), compensates the slowed
reference again within the axis limits
(:func:`~precontour.compensation.within_limits.compensate_within_limits`) and measures again,
until the tolerance holds or a round slows nothing more. Only slowing: the result is the
upper-bound plan, slowed where the errors ask for it. The rounds measure on the machine
file's machine; a result that keeps the tolerance there is checked on every draw of a
:class:`~precontour.simulation.ensemble.MachineEnsemble` (friction, inertia, damping,
encoder), and where a draw exceeds it the rounds go on with the worst draw at each sample.
No sample is slowed below ``min_speed`` of the upper-bound plan's speed: where even that
exceeds the tolerance, the search says where (:class:`ToleranceMiss`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.ndimage import maximum_filter1d

from ..compensation.pieces import contour_errors_program
from ..compensation.programmed_end import required_final_rest, with_final_rest
from ..compensation.within_limits import (LimitedCompensation, MIN_SPEED,
                                          compensate_within_limits)
from ..defaults import DEFAULT_FEED_SCALE_MIN
from ..errors import InputError, MachineLimitError
from ..prediction.contour import ContourErrors
from ..trajectory.feedplan import CHECK_RTOL
from ..machine.servo import Servo
from ..trajectory.limits import AxisLimits, check_limits
from ..trajectory.retime import SPREAD_TIME, Slowdown, retime, slowdowns_of
from ..trajectory.sampled import Trajectory
from ..simulation.ensemble import MachineEnsemble, ensemble_actual
from ..simulation.virtual_machine import realistic_actual

#: Where an error exceeds the tolerance, the stretch aims at this fraction of it: the next
#: compensation and the drives' response to the new timing move the errors a little.
AIM = 0.8
#: Assumed growth of a contour error with the speed, error ~ speed^EXPONENT (see the module
#: docstring: 2.0 uncompensated, 2.3-2.6 compensated on ``paper``; the smaller one errs on
#: the slow side).
EXPONENT = 2.0
#: Shortest time (s) over which the speed of a slow-down halves (:func:`gentle`). The
#: retiming's ramps (:data:`~precontour.trajectory.retime.RAMP_TIME`) take 0.2 s whatever the
#: stretch, so slowing to 10 % within them decelerates the tool hard, and the deceleration
#: makes contour errors of its own at the slowed window's edge. Measured on the built-in and
#: test paths (zhang2013 / pid-low, 10 um, uncompensated): 0.1 s lengthened the programs by
#: 0-1.1 %, 0.25 s by 0.5-3.4 %; neither ended the creep of paper at 2 x the programmed feed
#: (a window's edge over the tolerance moving 0.1-0.3 s a round: 12 rounds).
HALVING_TIME = 0.1
#: Rounds (measurements on the virtual machine) before the search gives up.
MAX_ROUNDS = 16
#: The limit-keeping rounds of an uncompensated (baseline) retiming: the retiming's ramps
#: add small acceleration and jerk terms (:mod:`~precontour.trajectory.retime`).
LIMIT_ROUNDS = 6
#: Each limit-keeping retiming of the baseline slows to this fraction of what the check asks.
RETIME_MARGIN = 0.9
#: The whole-sample rounding of a slowed window adds up to one sample: the floor is aimed
#: this far inside.
_FLOOR_MARGIN = 0.98
#: A source line whose largest error did not fall although the speed at it fell by at least
#: this factor since the previous round in which it was over the tolerance is not slowed
#: further: its error is not the speed's. A lag's contour error falls about like the square of
#: the speed (the module docstring); one that does not fall at all is friction's, where an
#: axis stops, reverses or creeps (on LinuxCNC's impeller, uncompensated, 45 places stayed up
#: to 9 times over 5 um at 5 % of the programmed feed, the lowest allowed). Slowing there only
#: lengthens the program, and a slower creep sticks and slips no less.
FUTILE_SLOWING = 1.5


@dataclass(frozen=True)
class ContourTolerance:
    """A contour-error tolerance: ``tip`` (mm) and, optionally, ``orientation`` (rad; None:
    the orientation error is not bounded)."""

    tip: float
    orientation: float | None = None

    def __post_init__(self):
        for name in ("tip", "orientation"):
            value = getattr(self, name)
            if value is None and name == "orientation":
                continue
            if not (isinstance(value, (int, float, np.floating)) and np.isfinite(value)
                    and value > 0):
                raise InputError(f"the {name} tolerance must be positive and finite, got "
                                 f"{value!r}", field="--tolerance")
            object.__setattr__(self, name, float(value))

    @classmethod
    def in_um(cls, tip_um: float, ori_mrad: float | None = None) -> "ContourTolerance":
        """The tolerance of ``tip_um`` um at the tool tip and, optionally, ``ori_mrad`` mrad
        of orientation (the units of ``run --tolerance TIP_UM[,ORI_MRAD]``)."""
        return cls(tip=1e-3 * tip_um, orientation=None if ori_mrad is None else 1e-3 * ori_mrad)

    def ratios(self, errors: ContourErrors) -> np.ndarray:
        """Each sample's largest error over its tolerance (tip, and orientation if bounded)."""
        ratio = errors.tip / self.tip
        if self.orientation is not None:
            ratio = np.maximum(ratio, errors.orientation / self.orientation)
        return ratio

    def describe(self) -> str:
        """``10 um tip, 0.05 mrad orientation``."""
        text = f"{1e3 * self.tip:g} um tip"
        if self.orientation is not None:
            text += f", {1e3 * self.orientation:g} mrad orientation"
        return text


@dataclass(frozen=True)
class ToleranceMiss:
    """A place where the tolerance is not met: the worst sample of one window of samples
    over it, on the searched timing.

    ``time`` (s) and ``index``: the sample in the final trajectory; ``line``: its source
    line (None when unknown; ``where`` names it ``"line"`` or ``"row"``); ``quantity``:
    ``"tip"`` (``error`` and ``limit`` in mm) or ``"orientation"`` (rad); ``speed``: the
    speed there as a fraction of the upper-bound plan's; ``floor``: whether that is the
    search's lowest speed (slower is not allowed) rather than a search that ran out of
    rounds; ``at_rest``: the sample is at rest (a stop, the final dwell), where slowing
    down does not help; ``futile``: its line was slowed and its error did not fall with the
    speed (:data:`FUTILE_SLOWING`), so the search stopped slowing it."""

    time: float
    index: int
    line: int | None
    quantity: str
    error: float
    limit: float
    speed: float
    floor: bool
    where: str = "line"
    at_rest: bool = False
    futile: bool = False

    def format(self) -> str:
        """``line 57, t = 1.234 s: tip error 12.3 um, 23.0 % over 10 um, at 5.0 % speed``."""
        unit, scale = ("um", 1e3) if self.quantity == "tip" else ("mrad", 1e3)
        at = f"{self.where} {self.line}, " if self.line is not None else ""
        how = ("at rest (a stop: slowing down does not help)" if self.at_rest else
               f"at {100 * self.speed:.1f} % of the planned speed"
               + (" (slowing down did not lower it)" if self.futile else
                  " (the lowest allowed)" if self.floor else ""))
        return (f"{at}t = {self.time:.3f} s: {self.quantity} error {scale * self.error:.4g} "
                f"{unit}, {100 * (self.error / self.limit - 1):.1f} % over "
                f"{scale * self.limit:g} {unit}, {how}")


@dataclass(frozen=True)
class FeedSearch:
    """The fastest timing found for one variant (compensated or not) within a tolerance.

    Attributes
    ----------
    compensated : bool
        Whether the commands are pre-compensated (False: the reference itself, the
        baseline).
    reference : Trajectory
        The retimed reference.
    commands : Trajectory
        The commands on it (compensated within the limits, or ``reference``).
    line : ndarray, optional
        Source line of each sample of ``reference``.
    planned_index : ndarray, shape (M,)
        Fractional sample index of the upper-bound plan for each sample: the time map.
    errors : ContourErrors
        Contour errors of ``commands`` on the realistic virtual machine against
        ``reference``: at each sample the worst of ``draws`` machines (zero on the lines the
        tolerance does not apply to, ``exempt_lines``).
    draws : int
        Machines ``errors`` is the worst of (1: the machine file's machine).
    rounds : int
        Measurements on the virtual machine the search took (each of ``draws`` runs in the
        last rounds).
    machine_runs : int
        Virtual-machine runs in all.
    misses : tuple of ToleranceMiss
        Where the tolerance is not met (empty: met everywhere).
    limited : LimitedCompensation, optional
        The final compensation within the limits (compensated only).
    """

    compensated: bool
    reference: Trajectory
    commands: Trajectory
    line: np.ndarray | None
    planned_index: np.ndarray
    errors: ContourErrors
    draws: int
    rounds: int
    machine_runs: int
    misses: tuple[ToleranceMiss, ...]
    limited: LimitedCompensation | None = None
    planned_line: np.ndarray | None = None

    @property
    def met(self) -> bool:
        return not self.misses

    @property
    def duration(self) -> float:
        return self.reference.duration

    @property
    def slowdowns(self) -> tuple[Slowdown, ...]:
        """The slowed windows, in the time of the upper-bound plan."""
        return slowdowns_of(self.planned_index, self.reference.ts, t0=float(self.reference.t[0]),
                            line=self.planned_line)

    def speed(self) -> np.ndarray:
        """Speed at each sample as a fraction of the upper-bound plan's."""
        return _speed(self.planned_index)


@dataclass(frozen=True)
class FeedWithinTolerance:
    """Both searches and what they started from.

    ``programmed``: the trajectory at the programmed feed and ``programmed_errors`` its
    uncompensated contour errors on the realistic virtual machine (the machine file's);
    ``planned``: the upper bound the searches slow down (``feed_scale_max`` times the
    programmed feed); ``baseline``: the uncompensated search; ``compensated``: the
    compensated one."""

    tolerance: ContourTolerance
    programmed: Trajectory
    programmed_errors: ContourErrors
    planned: Trajectory
    feed_scale_max: float
    min_speed: float
    baseline: FeedSearch
    compensated: FeedSearch
    exempt_lines: tuple[int, ...] = ()

    @property
    def ratio(self) -> float:
        """Compensated cycle time over the baseline's."""
        return self.compensated.duration / self.baseline.duration

    @property
    def friction_lines(self) -> tuple[int, ...]:
        """Lines where the tolerance cannot be kept by slowing down: a miss on them, in either
        search, whose error did not fall with the speed (:data:`FUTILE_SLOWING`: friction at
        a stop, a reversal or a creeping axis holds it whatever the feed)."""
        return tuple(sorted({int(m.line) for search in (self.baseline, self.compensated)
                             for m in search.misses if m.futile and m.line is not None}))

    @property
    def ratio_where_kept(self) -> float:
        """:attr:`ratio` over the lines where a tolerance can be kept: the time each search
        spends on the :attr:`friction_lines` left out of both cycle times (the ratio itself
        where there are none)."""
        lines = self.friction_lines
        if not lines:
            return self.ratio
        return (_time_outside(self.compensated, lines)
                / _time_outside(self.baseline, lines))

    def table(self) -> str:
        """The three cycle times, the ratio and the errors of each."""
        draws = max(self.baseline.draws, self.compensated.draws)
        lines = [f"cycle time within the tolerance {self.tolerance.describe()} on the "
                 "realistic virtual machine"
                 + (f" (worst of {draws} machine draws)" if draws > 1 else ""),
                 f"{'':<34}{'cycle':>10}{'tip max':>10}{'ori max':>10}{'rounds':>8}",
                 f"{'':<34}{'s':>10}{'um':>10}{'mrad':>10}{'':>8}"]
        rows = [("as programmed, uncompensated", self.programmed.duration,
                 self.programmed_errors, "-", True),
                ("uncompensated within tolerance", self.baseline.duration,
                 self.baseline.errors, str(self.baseline.rounds), self.baseline.met),
                ("compensated within tolerance", self.compensated.duration,
                 self.compensated.errors, str(self.compensated.rounds), self.compensated.met)]
        for label, duration, errors, rounds, met in rows:
            lines.append(f"{label:<34}{duration:10.3f}{1e3 * errors.tip.max():10.3f}"
                         f"{1e3 * errors.orientation.max():10.4f}{rounds:>8}"
                         + ("" if met else "  NOT MET"))
        shorter = 100 * (1 - self.ratio)
        lines.append(f"compensated / uncompensated within tolerance: {self.ratio:.3f} "
                     f"({shorter:.1f} % shorter); / as programmed: "
                     f"{self.compensated.duration / self.programmed.duration:.3f}")
        friction = self.friction_lines
        if friction:
            shown = ", ".join(str(n) for n in friction[:10])
            more = f" and {len(friction) - 10} more" if len(friction) > 10 else ""
            kept = self.ratio_where_kept
            lines.append(f"over the lines where the tolerance can be kept: {kept:.3f} "
                         f"({100 * (1 - kept):.1f} % shorter); left out: {len(friction)} "
                         f"line(s) where slowing down did not lower the error (friction): "
                         f"{shown}{more}")
        lines.append(f"feed between {100 * self.min_speed * self.feed_scale_max:g} % and "
                     f"{100 * self.feed_scale_max:g} % of the programmed"
                     + (f"; the errors of the {len(self.exempt_lines)} rapid (G0) line(s) "
                        "not counted" if self.exempt_lines else ""))
        for search, name in ((self.baseline, "uncompensated"),
                             (self.compensated, "compensated")):
            if not search.met:
                lines.append(f"{name}: the tolerance is not met in {len(search.misses)} "
                             "place(s):")
                lines += ["  " + m.format() for m in search.misses[:5]]
                if len(search.misses) > 5:
                    lines.append(f"  ... and {len(search.misses) - 5} more")
        return "\n".join(lines)


def _time_outside(search: FeedSearch, lines: tuple[int, ...]) -> float:
    """Time (s) ``search``'s timing spends off ``lines``: its samples on them, each a servo
    period, taken from its duration (all of it when its samples carry no line)."""
    if search.line is None:
        return search.duration
    on = int(np.count_nonzero(np.isin(search.line, np.asarray(lines))))
    return search.duration - on * search.reference.ts


def _speed(index: np.ndarray) -> np.ndarray:
    """Speed at each sample as a fraction of the original: original samples per sample of
    the time map, the slower of each sample's two intervals."""
    if index.size < 2:
        return np.ones_like(index, dtype=float)
    rate = np.diff(index)
    return np.minimum(np.r_[rate[0], rate], np.r_[rate, rate[-1]])


def _measure(reference: Trajectory, q: np.ndarray, machine, controller,
             ensemble: MachineEnsemble | None) -> ContourErrors:
    """Contour errors of the commands ``q`` on the realistic virtual machine: the machine
    file's (``ensemble`` None), or at each sample the worst of the ensemble's draws."""
    if ensemble is None:
        q_act = realistic_actual(reference.t, machine, controller)(q)
        return contour_errors_program(reference, q_act, machine.kinematics)
    actual = ensemble_actual(reference.t, machine, controller, ensemble)(q)
    errors = [contour_errors_program(reference, a, machine.kinematics) for a in actual]
    tip = np.stack([e.tip for e in errors])
    ori = np.stack([e.orientation for e in errors])
    k_tip, k_ori = np.argmax(tip, axis=0), np.argmax(ori, axis=0)
    take = lambda values, k: np.take_along_axis(values, k[None], axis=0)[0]  # noqa: E731
    return ContourErrors(tip=take(tip, k_tip), orientation=take(ori, k_ori),
                         tip_parameter=take(np.stack([e.tip_parameter for e in errors]), k_tip),
                         orientation_parameter=take(
                             np.stack([e.orientation_parameter for e in errors]), k_ori))


def _counted(errors: ContourErrors, line, exempt_lines) -> ContourErrors:
    """``errors`` with those of the samples on ``exempt_lines`` set to zero."""
    if exempt_lines is None or line is None or not len(exempt_lines):
        return errors
    out = np.isin(line, np.asarray(list(exempt_lines)))
    if not out.any():
        return errors
    return replace(errors, tip=np.where(out, 0.0, errors.tip),
                   orientation=np.where(out, 0.0, errors.orientation))


def _keep_limits(traj: Trajectory, index: np.ndarray, limits: AxisLimits):
    """The uncompensated reference slowed further where the retiming's ramps broke a limit
    (a few rounds of :func:`~precontour.trajectory.retime.retime` by the check's stretch)."""
    for _ in range(LIMIT_ROUNDS):
        check = check_limits(traj.q, traj.ts, limits, t0=float(traj.t[0]))
        if check.ok:
            return traj, index
        if not check.position_ok:
            raise MachineLimitError("the retimed commands leave an axis's travel: "
                                    + check.format())
        stretch = np.where(check.stretch > 1.0 + CHECK_RTOL, check.stretch / RETIME_MARGIN, 1.0)
        retimed = retime(traj, stretch)
        index = np.interp(retimed.old_index, np.arange(traj.n_samples), index)
        traj = retimed.trajectory
    check = check_limits(traj.q, traj.ts, limits, t0=float(traj.t[0]))
    if not check.ok:
        raise MachineLimitError("the retimed uncompensated commands still exceed the "
                                f"machine's limits: {check.format()}")
    return traj, index


def search_feed(servo: Servo, planned: Trajectory, tolerance: ContourTolerance, *,
                compensate: bool, line: np.ndarray | None = None,
                min_speed: float = DEFAULT_FEED_SCALE_MIN,
                ensemble: MachineEnsemble | None = None, max_rounds: int = MAX_ROUNDS,
                aim: float = AIM, exponent: float = EXPONENT,
                limits_min_speed: float = MIN_SPEED, where: str = "line",
                refine=None, exempt_lines=None, progress=None,
                iterations: int = 1) -> FeedSearch:
    """The fastest local retiming of ``planned`` whose contour errors keep ``tolerance`` on
    the realistic virtual machine of the servo's machine running its controller; see the
    module docstring.

    ``compensate``: pre-compensate the commands within the servo's limits on each timing,
    with its error models, up to ``iterations`` passes
    (:func:`~precontour.compensation.within_limits.compensate_within_limits`, whose own
    slow-down floor is ``limits_min_speed``); False: the commands are the reference itself
    (kept within the limits). ``min_speed``: the lowest speed, a fraction
    of ``planned``'s, 0 < min_speed <= 1. ``ensemble``: the draws a timing that keeps the
    tolerance on the machine file's machine is checked on (None: that machine only).
    ``refine(limited) -> limited``, if given, improves each round's compensation on the same
    reference before it is measured (``run`` learns there against the ensemble with
    ``--learn``: at stops compensation without learning can leave more error than none).
    ``exempt_lines``: source lines (of ``line``) the tolerance does not apply to, e.g. a
    program's rapids (G0), which cut nothing; their errors count as zero.
    ``progress(message)``, if given, reports each round. The result says where the
    tolerance is not met (:attr:`FeedSearch.misses`); it raises only what compensating
    within the limits raises."""
    if not 0.0 < min_speed <= 1.0:
        raise ValueError(f"min_speed must be in (0, 1], got {min_speed!r}")
    machine, controller, limits = servo.machine, servo.controller, servo.axis_limits
    if line is not None:
        # the lines given travel with the trajectory (and through its re-timings)
        planned = replace(planned, line=np.asarray(line))
    planned_line = planned.line
    current = planned
    index = np.arange(planned.n_samples, dtype=float)       # current sample -> planned sample
    if not compensate:
        current, index = _keep_limits(current, index, limits)
    on_ensemble = False
    machine_runs = 0
    limited = None
    # per source line: its largest ratio and the speed at it in the last round it was over
    # the tolerance; the lines whose error did not fall with the speed (FUTILE_SLOWING)
    last_over: dict[int, tuple[float, float]] = {}
    futile_lines: set[int] = set()
    for round_ in range(1, max_rounds + 1):
        if compensate:
            if progress is not None:
                progress(f"compensated, round {round_}: compensate "
                         f"({current.n_samples} samples)")
            limited = compensate_within_limits(servo, current, min_speed=limits_min_speed,
                                               iterations=iterations)
            index = np.interp(limited.planned_index, np.arange(current.n_samples), index)
            current = limited.reference
            if refine is not None:
                if progress is not None:
                    progress(f"compensated, round {round_}: learn")
                limited = refine(limited)
            q = limited.result.trajectory.q
        else:
            q = current.q
        label = "compensated" if compensate else "uncompensated"
        if progress is not None:
            progress(f"{label}, round {round_}: virtual machine"
                     + (f", {ensemble.draws} draws" if on_ensemble else ""))
        errors = _counted(_measure(current, q, machine, controller,
                                   ensemble if on_ensemble else None), current.line,
                          exempt_lines)
        machine_runs += ensemble.draws if on_ensemble else 1
        ratio = tolerance.ratios(errors)
        over = ratio > 1.0
        if not over.any() and ensemble is not None and not on_ensemble:
            # within the tolerance on the machine file's machine: check it on every draw,
            # and go on with the worst draw where one exceeds it
            on_ensemble = True
            if progress is not None:
                progress(f"{label}, round {round_}: check on {ensemble.draws} draws")
            errors = _counted(_measure(current, q, machine, controller, ensemble),
                              current.line, exempt_lines)
            machine_runs += ensemble.draws
            ratio = tolerance.ratios(errors)
            over = ratio > 1.0
        speed = _speed(index)
        room = _FLOOR_MARGIN * speed / min_speed
        moves = moving(current)
        if current.line is not None and over.any():
            futile_lines |= _futile_lines(current.line, ratio, speed, moves, last_over)
        futile = (np.isin(current.line, np.fromiter(futile_lines, dtype=np.int64))
                  if futile_lines else np.zeros(current.n_samples, dtype=bool))
        if not over.any() or round_ == max_rounds:
            break
        # every sample above the aim, not only those over the tolerance: slowing one window
        # raises the errors next to it a little, and on a wide plateau of errors near the
        # tolerance slowing only the samples over it crept along it by a window per round
        # (paper / pid-low, 10 um uncompensated: not met after 12 rounds)
        above = (ratio > aim) & ~futile
        want = np.where(above, (ratio / aim) ** (1.0 / exponent), 1.0)
        # Samples at rest are not slowed: a longer stop does not lower the error of settling
        # under friction, and a stretched stop only lengthens the program. What a sample at
        # rest asks for goes to the moving samples within SPREAD_TIME of it: the approach.
        reach = 2 * max(1, int(round(SPREAD_TIME / current.ts))) + 1
        want = np.maximum(want, maximum_filter1d(np.where(moves, 1.0, want), reach))
        slowable = moves & ~futile & (room > 1.0 + CHECK_RTOL)
        stretch = np.where(slowable, np.minimum(want, room), 1.0)
        if not (over & (maximum_filter1d(stretch, reach) > 1.0)).any():
            break               # no sample over the tolerance can be slowed any more
        stretch = np.minimum(gentle(stretch, current.ts), np.maximum(room, 1.0))
        stretch[~slowable] = 1.0
        retimed = retime(current, stretch)
        index = np.interp(retimed.old_index, np.arange(current.n_samples), index)
        current = retimed.trajectory
        if not compensate:
            current, index = _keep_limits(current, index, limits)
    commands = limited.result.trajectory if compensate else current
    misses = _misses(current, errors, tolerance, current.line, speed, room, where,
                     moves, futile)
    return FeedSearch(compensated=compensate, reference=current, commands=commands,
                      line=current.line, planned_index=index, errors=errors,
                      draws=ensemble.draws if on_ensemble else 1, rounds=round_,
                      machine_runs=machine_runs, misses=misses, limited=limited,
                      planned_line=planned_line)


def _futile_lines(line: np.ndarray, ratio: np.ndarray, speed: np.ndarray, moves: np.ndarray,
                  last_over: dict[int, tuple[float, float]]) -> set[int]:
    """The source lines over the tolerance (``ratio`` > 1) that were over when last seen
    too, whose largest ratio has not fallen since although the speed at it (its worst moving
    sample's) fell by :data:`FUTILE_SLOWING` or more. ``last_over`` (line -> (largest ratio,
    speed there) in the last round it was over) is brought up to date."""
    over = (ratio > 1.0) & moves
    if not over.any():
        return set()
    k = np.flatnonzero(over)
    # each line's worst moving sample over the tolerance: the last of its samples in
    # ascending order of ratio (a stable sort keeps it deterministic on ties)
    order = k[np.lexsort((ratio[k], line[k]))]
    last = np.concatenate([line[order][1:] != line[order][:-1], [True]])
    worst = order[last]
    found = set()
    for key, r, s in zip(line[worst].tolist(), ratio[worst].tolist(), speed[worst].tolist()):
        before = last_over.get(key)
        if before is not None and before[1] >= FUTILE_SLOWING * s and r >= before[0]:
            found.add(key)
        last_over[key] = (r, s)
    return found


def gentle(stretch: np.ndarray, ts: float, halving: float | None = None) -> np.ndarray:
    """The least stretch >= ``stretch`` whose logarithm changes by at most ln 2 per
    ``halving`` s (default :data:`HALVING_TIME`): the speed halves or doubles no faster.
    max_j (ln rho_j - c |k - j|), as two running maxima (c = ln 2 ts / halving)."""
    halving = HALVING_TIME if halving is None else halving
    log = np.log(np.maximum(stretch, 1.0))
    c = np.log(2.0) * ts / halving
    ramp = c * np.arange(log.size)
    forward = np.maximum.accumulate(log + ramp) - ramp
    backward = np.maximum.accumulate((log - ramp)[::-1])[::-1] + ramp
    # the running maxima's sums round off: never below the stretch asked for
    return np.maximum(np.exp(np.maximum(forward, backward)), np.maximum(stretch, 1.0))


def moving(traj: Trajectory) -> np.ndarray:
    """Whether each sample moves: an axis command differs from the sample before or after
    it (a stop's held samples, and the final dwell, do not)."""
    step = np.any(np.diff(traj.q, axis=0) != 0.0, axis=1)
    if step.size == 0:
        return np.zeros(traj.n_samples, dtype=bool)
    return np.r_[step[0], step] | np.r_[step, step[-1]]


def _misses(traj: Trajectory, errors: ContourErrors, tolerance: ContourTolerance, line,
            speed: np.ndarray, room: np.ndarray, where: str,
            moves: np.ndarray, futile: np.ndarray) -> tuple[ToleranceMiss, ...]:
    """One :class:`ToleranceMiss` per window of consecutive samples over the tolerance
    (windows closer than 0.1 s merged), worst window first."""
    ratio = tolerance.ratios(errors)
    over = ratio > 1.0
    if not over.any():
        return ()
    gap = max(1, int(round(0.1 / traj.ts)))
    k = np.flatnonzero(over)
    starts = np.concatenate([[0], np.flatnonzero(np.diff(k) > gap) + 1])
    ends = np.concatenate([starts[1:], [k.size]])
    found = []
    for a, b in zip(starts.tolist(), ends.tolist()):       # one per window, few
        window = k[a:b]
        j = int(window[np.argmax(ratio[window])])
        tip_ratio = errors.tip[j] / tolerance.tip
        is_tip = tolerance.orientation is None or tip_ratio >= (errors.orientation[j]
                                                                / tolerance.orientation)
        found.append(ToleranceMiss(
            time=float(traj.t[j]), index=j, line=None if line is None else int(line[j]),
            quantity="tip" if is_tip else "orientation",
            error=float(errors.tip[j] if is_tip else errors.orientation[j]),
            limit=tolerance.tip if is_tip else tolerance.orientation,
            speed=float(speed[j]), floor=bool(room[j] <= 1.0 + CHECK_RTOL), where=where,
            at_rest=not bool(moves[j]), futile=bool(futile[j])))
    return tuple(sorted(found, key=lambda m: -m.error / m.limit))


def feed_within_tolerance(servo: Servo, planned: Trajectory, tolerance: ContourTolerance, *,
                          programmed: Trajectory | None = None,
                          feed_scale_max: float = 1.0, min_speed: float | None = None,
                          line: np.ndarray | None = None, ensemble: MachineEnsemble | None = None,
                          refine=None, exempt_lines=None, progress=None,
                          limits_min_speed: float = MIN_SPEED, iterations: int = 1,
                          where: str = "line", max_rounds: int = MAX_ROUNDS
                          ) -> FeedWithinTolerance:
    """The compensated search and the uncompensated baseline (:func:`search_feed`) from the
    upper-bound plan ``planned`` (``feed_scale_max`` times the programmed feed), and the
    program as programmed (``programmed``, default ``planned``) measured uncompensated.
    ``min_speed``: the lowest speed as a fraction of ``planned``'s (default
    :data:`~precontour.defaults.DEFAULT_FEED_SCALE_MIN` of the programmed feed, i.e. that
    over ``feed_scale_max``). ``refine``: the compensated search's, ``exempt_lines``: both
    searches' and the programmed errors'; ``limits_min_speed``,
    ``iterations``, ``where``, ``max_rounds``: both searches' (:func:`search_feed`)."""
    programmed = planned if programmed is None else programmed
    # both plans with the final rest the compensated commands need to end at the programmed
    # end point (:mod:`~..compensation.programmed_end`; ``run`` plans it already)
    machine, controller = servo.machine, servo.controller
    rest = required_final_rest(servo.models)
    n = planned.n_samples
    planned, programmed = with_final_rest(planned, rest), with_final_rest(programmed, rest)
    if line is not None and len(line) == n < planned.n_samples:
        line = np.concatenate([line, np.full(planned.n_samples - n, line[-1])])
    if min_speed is None:
        min_speed = min(1.0, DEFAULT_FEED_SCALE_MIN / feed_scale_max)
    if progress is not None:
        progress("as programmed: virtual machine")
    programmed_errors = _counted(_measure(programmed, programmed.q, machine, controller, None),
                                 programmed.line, exempt_lines)
    common = dict(line=line, min_speed=min_speed, ensemble=ensemble, progress=progress,
                  exempt_lines=exempt_lines, limits_min_speed=limits_min_speed,
                  iterations=iterations, where=where, max_rounds=max_rounds)
    baseline = search_feed(servo, planned, tolerance, compensate=False, **common)
    compensated = search_feed(servo, planned, tolerance, compensate=True,
                              refine=refine, **common)
    return FeedWithinTolerance(tolerance=tolerance, programmed=programmed,
                               programmed_errors=programmed_errors, planned=planned,
                               feed_scale_max=float(feed_scale_max), min_speed=float(min_speed),
                               baseline=baseline, compensated=compensated,
                               exempt_lines=tuple(sorted(int(k) for k in exempt_lines or ())))


__all__ = ["AIM", "EXPONENT", "FUTILE_SLOWING", "MAX_ROUNDS", "ContourTolerance", "FeedSearch",
           "FeedWithinTolerance", "ToleranceMiss", "feed_within_tolerance", "search_feed"]
