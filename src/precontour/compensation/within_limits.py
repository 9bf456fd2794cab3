"""Pre-compensation that keeps the machine's axis limits (paper Sec. 4).

Compensated commands lead the reference, and their corrections add velocity, acceleration
and above all jerk (up to +91 % peak jerk on the built-in paths). Where the compensated
commands break an axis limit, the reference is slowed down locally
(:func:`precontour.trajectory.retime.retime`, by the stretch the limit check asks for, with
a margin) and compensated again, until every axis keeps every limit. The
slowed windows are reported in the time of the original reference.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import MachineLimitError
from ..trajectory.feedplan import CHECK_RTOL
from ..trajectory.limits import AxisLimits, LimitCheck, check_limits
from ..trajectory.retime import Slowdown, retime, slowdowns_of
from ..trajectory.sampled import Trajectory
from .precompensate import CompensationResult, compensate

#: Re-timing rounds before giving up.
MAX_ROUNDS = 8
#: Each round slows down to this fraction of what the limit check asks for. Compensating the
#: slowed reference again changes the corrections a little, so aiming just at the limit
#: (the feed planner's 0.98) needed 4 compensations on a 2-minute test path, 0.9 needs 2-3;
#: every round is a full compensation, the costliest step of ``run``.
RETIME_MARGIN = 0.9


@dataclass(frozen=True)
class LimitedCompensation:
    """Compensated commands within the machine's limits, and what it took.

    Attributes
    ----------
    result : CompensationResult
        The final compensation, on ``reference``.
    reference : Trajectory
        The reference after re-timing (the input itself when nothing was slowed).
    line : ndarray, optional
        Source line of each sample of ``reference``, when given.
    slowdowns : tuple of Slowdown
        Slowed windows, in the time of the original reference.
    planned_index : ndarray, shape (M,)
        Sample index (fractional) of the original reference for each sample of
        ``reference``: the time map of all the slow-downs together.
    rounds : int
        Compensations computed (1 = the first one kept the limits).
    first_check, check : LimitCheck
        The limit check of the first and of the final compensated commands.
    """

    result: CompensationResult
    reference: Trajectory
    line: np.ndarray | None
    slowdowns: tuple[Slowdown, ...]
    planned_index: np.ndarray
    rounds: int
    first_check: LimitCheck
    check: LimitCheck

    @property
    def added_time(self) -> float:
        return float(sum(s.added for s in self.slowdowns))


def compensate_within_limits(reference: Trajectory, kinematics, models, limits: AxisLimits, *,
                             line: np.ndarray | None = None, max_rounds: int = MAX_ROUNDS,
                             progress=None, **options) -> LimitedCompensation:
    """Compensate ``reference`` (with :func:`~.precompensate.compensate` and ``options``),
    slowing it down locally and compensating again until the commands keep ``limits``.

    ``progress``, if given, is called as ``progress(round, message)``. Raises
    :class:`~precontour.errors.MachineLimitError` when a command leaves an axis's travel
    (slowing down cannot help) or the limits still fail after ``max_rounds`` compensations.
    """
    ts = reference.ts
    t0 = float(reference.t[0])
    original_line = line
    to_original = np.arange(reference.n_samples, dtype=float)
    current, current_line = reference, line
    first_check = None
    for round_ in range(1, max_rounds + 1):
        if progress is not None:
            progress(round_, f"compensate ({current.n_samples} samples)")
        result = compensate(current, kinematics, models, **options)
        check = check_limits(result.trajectory.q, ts, limits, t0=t0)
        first_check = first_check or check
        if check.ok:
            return LimitedCompensation(
                result=result, reference=current, line=current_line,
                slowdowns=slowdowns_of(to_original, ts, t0=t0, line=original_line),
                planned_index=to_original, rounds=round_, first_check=first_check, check=check)
        if not check.position_ok:
            raise MachineLimitError("the compensated commands leave an axis's travel, which "
                                    "slowing down cannot cure: " + check.format())
        if round_ == max_rounds:
            break
        stretch = np.where(check.stretch > 1.0 + CHECK_RTOL, check.stretch / RETIME_MARGIN, 1.0)
        retimed = retime(current, stretch, line=current_line)
        to_original = np.interp(retimed.old_index, np.arange(current.n_samples), to_original)
        current, current_line = retimed.trajectory, retimed.line
    raise MachineLimitError(f"the compensated commands still exceed the machine's limits after "
                            f"{max_rounds} compensation round(s): {check.format()}")
