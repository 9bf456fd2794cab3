"""The compensated commands' end: exactly the programmed end point, reached at rest.

A compensated command is the reference plus a correction, and the correction is what the axes
still lag by: where the plan ends before the slowest loop has settled (``pid-low`` of
``zhang2013`` decays like exp(-6.1 t), a time constant of 0.16 s, against the default final
dwell of 0.2 s), the last command is off the programmed end point, and the controller holds
that last command after the program: the axes settle off the end (issue 42 item 5: a
three-block program turning C through 720 deg with ``pid-low`` ended commanded 32.7 um off
in Y and 32 urad in A, the linear axes correcting C's lag at the pole A = 0).

This module owns the remedy, used by every route that produces compensated commands
(:func:`~.precompensate.compensate`, the limits' loop of :mod:`.within_limits`, learning):

- :func:`required_final_rest`, :func:`with_final_rest`: the final rest a plan needs, and a
  plan given it where it is shorter (a dwell at the end position, which the controller holds
  after the program anyway, so it changes no motion);
- :func:`end_at_programmed_end`: the corrections tapered to zero over the final rest with a
  C2 weight, so that the last samples are the programmed end point to the last digit.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..trajectory.sampled import Trajectory
from .blend import c2_step

#: The final rest a compensated plan needs, in time constants of its slowest error model
#: (1 / sigma, sigma the least -Re(pole) over the axes), the taper included. The corrections
#: are held for the first part of the rest, while the compensated motion settles on the end
#: point, and taper to zero over the last :data:`END_TAPER` and :data:`END_HOLD`: whatever the
#: axes still lag by when the taper starts is left to settle after the program, at the end
#: point, and is what the contour errors during the rest grow by. Five time constants are
#: 0.82 s for ``pid-low`` (the taper starting after 4.3 of them, exp(-4.3) = 1.4 % of the lag
#: at the rest's start left) and 0.12 s for ``pid-high`` of ``zhang2013``, whose default
#: final dwell of 0.2 s is kept. Measured on the built-in paths and the test paths ``fan25``,
#: ``flank`` (``tests/compensation/test_programmed_end.py``): with four time constants after
#: the rest's start and the taper after them, ``cone`` / ``pid-low`` had 10.26 urad of
#: predicted orientation error during the taper against 7.76 urad during the motion; with
#: five as here no path's predicted max grows by more than 6.7 nm / 0.0 urad.
END_REST_TIME_CONSTANTS = 5.0
#: Width (s) of the C2 taper at the end of the final rest; also the shortest final rest. Over
#: 0.1 s a correction of c adds at most 1.9 c / 0.1 s of velocity, 5.8 c / 0.1^2 s^2 of
#: acceleration and 60 c / 0.1^3 s^3 of jerk (the quintic step's peaks): 6 mm/s^3 of jerk per
#: 0.1 um.
END_TAPER = 0.1
#: The last samples (s) hold the programmed end point exactly (weight 0), so that a learning
#: update smoothed over a few milliseconds (:data:`~.stops.LIMITED_SMOOTHING`) or a blend into
#: another command that ends there keeps the end.
END_HOLD = 0.02
#: A reference sample within these (mm, rad) of the last one is at rest: re-timing leaves
#: round-off far below them (1e-24 mm seen) on a reference that is in fact at rest.
REST_TOLERANCE_LINEAR = 1e-9
REST_TOLERANCE_ROTARY = 1e-12
#: A trajectory whose last step moves an axis by more than this fraction of that axis's
#: largest step is cut in motion (a truncated file, a trace that ends moving), not planned to
#: a stop: a rest appended to it would be a velocity step the plan never had, which no
#: correction can follow within the limits, so it gets none and its commands are left as they
#: are. A plan decelerated to a stop without a dwell (``--dwell 0``) ends with a step of at
#: most 5e-5 of its largest (measured on the built-in paths).
END_SPEED_FRACTION = 0.01


def slowest_time_constant(models) -> float:
    """1 / sigma, sigma the least -Re(pole) of the error models' poles over the axes (s)."""
    sigma = min(float(-np.max(np.roots(model.den).real)) for model in models)
    if not sigma > 0:
        raise ValueError("an error model is not stable: it has a pole with Re >= 0")
    return 1.0 / sigma


def required_final_rest(models) -> float:
    """The final rest (s) a plan compensated for ``models`` needs:
    :data:`END_REST_TIME_CONSTANTS` time constants of the slowest loop, the taper and the hold
    at its end included, and at least those."""
    return max(END_REST_TIME_CONSTANTS * slowest_time_constant(models), END_TAPER + END_HOLD)


def final_rest_start(q: np.ndarray) -> int:
    """First sample of the final rest of the commands ``q`` (N, 5): every later one within
    :data:`REST_TOLERANCE_LINEAR` / :data:`REST_TOLERANCE_ROTARY` of the last; N - 1 when the
    commands still move at their last sample."""
    tolerance = np.array([REST_TOLERANCE_LINEAR] * 3 + [REST_TOLERANCE_ROTARY] * 2)
    moving = np.flatnonzero(np.any(np.abs(q - q[-1]) > tolerance, axis=1))
    return 0 if moving.size == 0 else int(moving[-1]) + 1


def ends_in_motion(q: np.ndarray) -> bool:
    """Whether the commands ``q`` (N, 5) are cut in motion: see :data:`END_SPEED_FRACTION`."""
    if q.shape[0] < 2:
        return False
    steps = np.abs(np.diff(q, axis=0))
    largest = steps.max(axis=0)
    return bool(np.any(steps[-1] > END_SPEED_FRACTION * largest))


def with_final_rest(traj: Trajectory, duration: float) -> Trajectory:
    """``traj`` with a final rest of at least ``duration`` (s): held samples at its last
    position appended where its own final rest is shorter (its line, tip and orientation held
    too); ``traj`` itself otherwise. Why a dwell may be added: the compensated commands need
    the rest to taper their corrections to zero (:func:`end_at_programmed_end`), and a
    controller holds the last command after a program anyway, so the dwell adds no motion and
    the reference's motion keeps its timing. ``traj`` itself where it is cut in motion
    (:func:`ends_in_motion`)."""
    if ends_in_motion(traj.q):
        return traj
    ts = traj.ts
    n = traj.n_samples
    rest = (n - 1 - final_rest_start(traj.q)) * ts
    missing = int(np.ceil((duration - rest) / ts - 1e-9))
    if missing <= 0:
        return traj
    index = np.concatenate([np.arange(n), np.full(missing, n - 1)])
    t = traj.t[0] + np.arange(n + missing) * ts
    t[:n] = traj.t
    return replace(traj, t=t, q=traj.q[index],
                   P=None if traj.P is None else traj.P[index],
                   O=None if traj.O is None else traj.O[index],
                   line=None if traj.line is None else traj.line[index])


def end_weight(n: int, rest_start: int, ts: float) -> np.ndarray:
    """Weight of the corrections, shape (n,): 1 until the taper, a C2 step down to 0 over
    :data:`END_TAPER` ending :data:`END_HOLD` before the last sample, 0 after. The taper sits
    at the end of the final rest (samples ``rest_start`` on), and within it where the rest is
    shorter than the taper and the hold."""
    hold = int(round(END_HOLD / ts))
    width = int(round(END_TAPER / ts))
    room = n - 1 - rest_start
    if room < hold + width:
        # a rest too short for both (a piece of a long program cut in a stop, a plan given
        # no rest): the taper and the hold share it, the hold a fifth
        hold = room // 5
        width = room - hold
    last = n - 1 - hold              # the first sample of weight 0
    first = last - width             # the last sample of weight 1
    index = np.arange(n)
    if width <= 0:
        return (index < last).astype(float)
    return 1.0 - c2_step((index - first) / width)


def end_at_programmed_end(q_reference: np.ndarray, q: np.ndarray, ts: float) -> np.ndarray:
    """Commands ``q`` whose corrections ``q - q_reference`` taper to zero over the final rest
    of ``q_reference`` (:func:`end_weight`): the last samples equal the reference's last
    sample exactly. ``q`` itself where its last sample already does (tapered before, or a
    tail that learning settled at the end point), so that applying it again changes nothing,
    and where ``q_reference`` is cut in motion (:func:`ends_in_motion`: no end point was
    programmed there)."""
    if np.array_equal(q[-1], q_reference[-1]) or ends_in_motion(q_reference):
        return q
    weight = end_weight(q.shape[0], final_rest_start(q_reference), ts)
    out = q_reference + weight[:, None] * (q - q_reference)
    # before the taper, the commands to the last digit (the sum above is off by round-off)
    whole = weight == 1.0
    out[whole] = q[whole]
    return out
