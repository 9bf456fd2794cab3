"""Compensation at stops and reversals under friction: learning against a nonlinear machine.

The linear error model of spec section 3 has no friction. On a machine with Stribeck friction
and feed-forward friction compensation from the *commanded* velocity, the compensated command
leads the axis, so near every zero-velocity point (an axis reversal, the final stop) its
velocity changes sign before the axis's does; the feed-forward then pushes with the full static
friction torque the wrong way, and static friction holds the axis wherever it comes to rest.
The largest remaining contour error sits there, often in the final dwell.

This module owns the remedy, measured as the best of the ideas tried (see
``scripts/measure_compensation.py``): model-based iterative learning. The contour correction of
spec section 6 is re-run with the actual motion of a nonlinear machine model in place of the
linear prediction (a callable, in practice the virtual machine with friction, passed in because
compensation comes before simulation in the pipeline), in two sequences: the plain update, and
one whose step along each update is line-searched on the machine. Each iterate is also tried
with its final-dwell tail settled (held exactly at the end position from a delay after the stop
on, so that a slowly creeping command does not switch the friction feed-forward on). The command kept
is the one with the smallest largest error on that machine among those that are nowhere worse
than the uncompensated command (max and mean, tip and orientation), so compensation never makes
a maximum worse on the machine it learned against. Where the commands must keep the axis
limits, each update and settling is smoothed and a command beyond a limit is not kept.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
from scipy.ndimage import gaussian_filter1d

from ..defaults import DEFAULT_LEARNING_PASSES
from ..errors import PrecontourError
from ..files import check_signals

# DEFAULT_LEARNING_PASSES (CLI ``compensate --learn``) is defined in precontour.defaults.
#: Delays after the final stop (s) from which an iterate's tail is settled, tried per iterate:
#: every 10 ms from 0 to 100 ms. Why a grid (issue 13 section 1, "a settling criterion for the
#: final dwell"): static friction holds each axis wherever it comes to rest, and while the
#: learned command still moves in the dwell the feed-forward keeps switching the full static
#: friction torque; settling the tail stops both, and *when* decides which axes are already at
#: rest and on which side of the end point. That outcome changes abruptly with the delay (on
#: the test path `fan25` with `pid-high`, pass 2 settled at 30 / 60 / 80 ms removes 65 / 82 /
#: 88 % of the max tip error), so the delay is searched on the machine model itself, at one
#: machine run and one contour evaluation per delay. With the former three delays (0, 30,
#: 60 ms) `fan25` / `pid-high` ended at 82.3 %, with this grid at 87.7 % (plain sequence; a
#: 5 ms grid changed no built-in or test path with the line search below, at twice the cost).
SETTLE_DELAYS: tuple[float, ...] = tuple(0.01 * k for k in range(11))
#: Steps along each learning update tried by the line-searched sequence, as fractions of the
#: full update; the best on the machine model is the next iterate. Why (issue 13 section 1,
#: "iterate the compensation against the nonlinear virtual machine"): the update re-applies
#: the whole measured contour error, as if the machine answered a command change linearly;
#: near a reversal under friction it does not, the full step can overshoot, and the iterates
#: oscillate (on a fan whose largest learned error sits at interior reversals,
#: ``_fan_reversals`` in ``tests/compensation/test_stops.py``, `pid-high`, the plain
#: sequence's maximum jumps between the reversals near 0.98 s and 1.46 s from pass to pass and
#: ends at 79.1 % of the max tip error removed); a half step damps that (91.1 %). No fixed step
#: suits every path (with step 1/2 alone `cone` / `pid-high` ends at 85.7 % instead of
#: 87.2 %), so the plain sequence is kept and this one added; `fan25` / `pid-high` 87.7 ->
#: 92.9 % (measured on the realistic machine, 4 passes; 91.9 % once the faster closest-point
#: search changed the round-off).
LINE_SEARCH_STEPS: tuple[float, ...] = (0.5, 1.0)
#: Standard deviation (s) of the Gaussian filter that smooths each learning update and each
#: settling where the commands must keep the axis limits (``precontour run --learn``). Why: the
#: update carries the machine's stick-slip response sample by sample, and a settled tail steps;
#: unsmoothed, the learned commands' peak jerk was 1.6-184 times the jerk limit on the built-in
#: and test paths (the linear pass's 0.25-161 times). Smoothed over 3 ms (the Q-filter of
#: iterative learning control) the peak jerk stayed within 5 % of the limit from the linear
#: pass's on the seven paths with `pid-high` (below the limit wherever the linear pass was),
#: and learning still removed 89.0 % of the max tip error on `fan25` and 98.7 % on `paper`
#: (linear pass 72.6 and 88.2 %).
LIMITED_SMOOTHING = 0.003
#: Weight of the orientation error against the tip error in the selection, mm/rad (about a
#: tool length, as in the linear passes' score).
ORIENTATION_WEIGHT = 100.0

#: A nonlinear machine model: axis commands (N, 5) in, actual axis positions (N, 5) out.
MachineActual = Callable[[np.ndarray], np.ndarray]


@dataclass(frozen=True)
class LearningCandidate:
    """One command tried on the machine model: its label and measured contour errors
    (``ContourErrors.summary``: tip max/mean in um, orientation max/mean in mrad)."""

    label: str
    summary: dict
    accepted: bool


@dataclass(frozen=True)
class LearningReport:
    """What learning against the machine model tried and kept.

    Attributes
    ----------
    chosen : str
        Label of the command kept: ``"uncompensated"``, ``"linear"`` (the linear passes'
        result), ``"pass n"`` (plain update) or ``"line-searched pass n (step s)"``, optionally
        with ``", settled d ms"``.
    uncompensated, linear, kept : dict
        Contour errors on the machine model (``ContourErrors.summary``) of the reference
        command, of the linear compensation, and of the command kept.
    candidates : tuple of LearningCandidate
        Every command tried, in order.
    machine_runs : int
        Calls of the machine model.
    """

    chosen: str
    uncompensated: dict
    linear: dict
    kept: dict
    candidates: tuple
    machine_runs: int


def final_rest_index(q: np.ndarray) -> int | None:
    """First sample of the final rest: ``q[k:]`` all equal ``q[-1]``; None when the command
    still moves at its last sample (no dwell)."""
    moving = np.flatnonzero(np.any(q[1:] != q[:-1], axis=1))
    if moving.size == 0:
        return 0
    first = int(moving[-1]) + 1
    return None if first >= q.shape[0] - 1 else first


def settle_final_dwell(q: np.ndarray, q_reference: np.ndarray, start: int) -> np.ndarray:
    """``q`` with samples ``start`` on held exactly at the reference's final position."""
    settled = np.array(q, dtype=float, copy=True)
    settled[start:] = q_reference[-1]
    return settled


def learn_at_stops(q_reference: np.ndarray, q_linear: np.ndarray, ts: float,
                   machine_actual: MachineActual, errors_of, contour_step, *,
                   passes: int = DEFAULT_LEARNING_PASSES,
                   settle_delays: tuple[float, ...] = SETTLE_DELAYS,
                   line_search_steps: tuple[float, ...] = LINE_SEARCH_STEPS,
                   smoothing: float = 0.0, admissible: Callable[[np.ndarray], bool] | None = None,
                   progress=None) -> tuple[np.ndarray, LearningReport]:
    """Improve the linear compensation ``q_linear`` against a nonlinear machine model.

    Parameters
    ----------
    q_reference, q_linear : ndarray, shape (N, 5)
        The reference commands and their linear compensation.
    ts : float
        Sample period, s.
    machine_actual : callable
        The machine model, commands (N, 5) -> actual axis positions (N, 5).
    errors_of : callable
        Actual axis positions -> ``ContourErrors`` against the reference.
    contour_step : callable
        ``contour_step(q_cmd, q_act, actual)`` -> corrected commands: one contour correction
        (spec section 6) of ``q_cmd`` whose actual motion is ``q_act``, ``actual`` giving the
        actual motion of any other command.
    passes : int
        Learning passes per sequence (a plain pass costs two machine runs plus one per
        settling delay, a line-searched pass one more per step size tried beyond the first).
    settle_delays : tuple of float
        Delays after the final stop (s) from which each iterate's tail is settled; none when
        the reference has no final dwell.
    line_search_steps : tuple of float
        Steps along the update (fractions of it) tried by the line-searched sequence; empty:
        the plain sequence alone.
    smoothing : float
        Standard deviation (s) of a Gaussian filter applied to each learning update and to
        each settling (0: none); see :data:`LIMITED_SMOOTHING`.
    admissible : callable, optional
        ``admissible(q) -> bool``: commands it refuses (e.g. beyond the axis limits) are not
        kept; the uncompensated command is taken as admissible.
    progress : callable, optional
        ``progress(label, summary)`` after each command tried.

    Returns
    -------
    q : ndarray, shape (N, 5)
        The command kept.
    report : LearningReport
    """
    if passes < 0:
        raise ValueError(f"learning passes must be >= 0, got {passes}")
    runs = 0

    def actual(q):
        nonlocal runs
        runs += 1
        return machine_actual(q)

    rest = final_rest_index(q_reference)
    settle_starts = []
    if rest is not None:
        for delay in settle_delays:
            start = rest + int(round(delay / ts))
            if start < q_reference.shape[0] - 1:
                settle_starts.append((delay, start))

    sigma = smoothing / ts

    def towards(q, q_new):
        """``q_new``, or with smoothing ``q`` plus the smoothed change to ``q_new``."""
        if sigma <= 0:
            return q_new
        return q + gaussian_filter1d(q_new - q, sigma, axis=0, mode="nearest")

    reference_errors = errors_of(actual(q_reference))
    limit = reference_errors.summary()
    candidates = []

    def consider(label, q):
        """Run ``q`` on the machine model and keep it as a candidate; None (and a candidate
        never kept) when it diverged: a command or its motion that is not finite, or that
        the machine model or the contour errors refuse (e.g. coordinates out of range)."""
        check_signals()  # between machine runs: where a SIGTERM or Ctrl-C stops learning
        q_act = summary = None
        if np.all(np.isfinite(q)):
            try:
                with np.errstate(all="ignore"):
                    q_act = actual(q)
                    if np.all(np.isfinite(q_act)):
                        errors = errors_of(q_act)
                        summary = errors.summary()
            except PrecontourError:
                q_act = None
        if summary is None or not all(np.isfinite(v) for v in summary.values()):
            candidates.append((LearningCandidate(label + " (diverged)", limit, False), q,
                               np.inf))
            return None
        ok = (all(summary[key] <= limit[key] for key in limit)
              and (admissible is None or admissible(q)))
        candidates.append((LearningCandidate(label, summary, ok), q, _max_score(errors)))
        if progress is not None:
            progress(label, summary)
        return q_act

    def step_from(q_cmd, q_act):
        """The next iterate, or None when the update diverged."""
        try:
            with np.errstate(all="ignore"):
                q_new = towards(q_cmd, contour_step(q_cmd, q_act, actual))
        except PrecontourError:
            return None
        return q_new if np.all(np.isfinite(q_new)) else None

    def consider_settled(label, q):
        for delay, start in settle_starts:
            consider(f"{label}, settled {1e3 * delay:.0f} ms",
                     towards(q, settle_final_dwell(q, q_reference, start)))

    candidates.append((LearningCandidate("uncompensated", limit, True), q_reference,
                       _max_score(reference_errors)))
    q_act_linear = consider("linear", q_linear)
    consider_settled("linear", q_linear)
    # The plain sequence: each pass applies the whole update. A sequence that diverges (an
    # iterate not finite, or refused by the machine model) ends there: what it tried before
    # stays a candidate, the diverged iterate is never kept.
    q_cmd, q_act = q_linear, q_act_linear
    for n in range(1, passes + 1):
        q_cmd = None if q_act is None else step_from(q_cmd, q_act)
        if q_cmd is None:
            break
        q_act = consider(f"pass {n}", q_cmd)
        if q_act is None:
            break
        consider_settled(f"pass {n}", q_cmd)
    # The line-searched sequence: each pass continues from the best step along the update.
    if line_search_steps:
        q_cmd, q_act = q_linear, q_act_linear
        for n in range(1, passes + 1):
            q_full = None if q_act is None else step_from(q_cmd, q_act)
            if q_full is None:
                break
            tried = []
            for step in line_search_steps:
                label = f"line-searched pass {n} (step {step:g})"
                with np.errstate(all="ignore"):
                    q_try = q_full if step == 1.0 else q_cmd + step * (q_full - q_cmd)
                q_act_try = consider(label, q_try)
                if q_act_try is not None:
                    tried.append((candidates[-1][2], label, q_try, q_act_try))
            if not tried:
                break
            _, label, q_cmd, q_act = min(tried, key=lambda entry: entry[0])
            consider_settled(label, q_cmd)
    linear = next(c for c, _, _ in candidates if c.label in ("linear", "linear (diverged)"))
    chosen, q_kept, _ = min((entry for entry in candidates if entry[0].accepted),
                            key=lambda entry: entry[2])
    report = LearningReport(chosen=chosen.label, uncompensated=limit, linear=linear.summary,
                            kept=chosen.summary,
                            candidates=tuple(c for c, _, _ in candidates), machine_runs=runs)
    return q_kept, report


def _max_score(errors) -> float:
    """The largest errors, tip (mm) plus orientation weighted by ORIENTATION_WEIGHT; the mean
    errors break ties only (the linear passes already make them small)."""
    return (float(errors.tip.max()) + ORIENTATION_WEIGHT * float(errors.orientation.max())
            + 1e-3 * (float(errors.tip.mean())
                      + ORIENTATION_WEIGHT * float(errors.orientation.mean())))
