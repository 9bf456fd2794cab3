"""Long programs in pieces: prediction and compensation of any length in bounded memory.

A program of hours (10^7 samples and more) is cut into pieces of about PIECE_SAMPLES samples,
each processed on its own with an overlap either side that is thrown away. Cuts are put in the
middle of a stop (all axes at rest) where the program has one near the planned cut.

Why the overlap makes the seams invisible: the tracking error is the response of a stable
linear system (spec section 4), so whatever a piece gets wrong at its start (it sees the axes
at rest before its first sample, where they were in fact moving) dies out like the slowest
pole, exp(-sigma t): after ln(1 / DECAY) / sigma it has fallen by DECAY = 1e-9, from 1 m (more
than any axis travels) to 1 nm. A compensation pass chains its predictions (the commands it
corrects depend on predicted errors, which depend on earlier commands), so the overlap is that
decay time once per prediction in the chain, plus the closest-point search's widest window
and the smoothing of the correction. The same length is kept after a piece's end, where the
spline fit's end conditions (at rest) bend the last few knots. ``tests/compensation/
test_pieces.py`` checks that cutting changes nothing beyond the fit tolerance.
"""

from __future__ import annotations

from dataclasses import dataclass
from math import ceil, log

import numpy as np

from ..defaults import DEFAULT_LEARNING_PASSES
from ..machine.drives import AXES, LinearErrorModel, TrackingSummary
from ..machine.servo import Servo
from ..parallel import map_ordered
from ..prediction.contour import (DEFAULT_WINDOW, MAX_WINDOW_FACTOR, ContourErrors,
                                  ReferencePath)
from ..prediction.splinefit import INITIAL_SAMPLES_PER_SEGMENT
from ..prediction.tracking import predict_tracking
from ..trajectory.sampled import Trajectory
from .precompensate import BLEND_SPREAD, CompensationResult, compensate

#: Samples kept per piece (the piece itself is longer by its overlaps).
PIECE_SAMPLES = 250_000
#: Trajectories up to this many samples are processed at once.
AT_ONCE_SAMPLES = 500_000
#: Factor by which a start-up transient must have decayed inside the overlap.
DECAY = 1e-9
#: Extra overlap for the spline fits' end effects, s (a few knots).
SPLINE_MARGIN = 0.5
#: A stop: every axis within these (mm, rad) of its value for at least STOP_TIME.
STOP_TOLERANCE_LINEAR = 1e-9
STOP_TOLERANCE_ROTARY = 1e-12
STOP_TIME = 0.05


@dataclass(frozen=True)
class Piece:
    """Samples [start, stop) are processed; [keep_start, keep_stop) of them are kept."""

    start: int
    stop: int
    keep_start: int
    keep_stop: int


def slowest_decay_rate(models: tuple[LinearErrorModel, ...]) -> float:
    """sigma = min over the axes of -Re(pole) of the error models, 1/s."""
    rates = [-np.max(np.roots(model.den).real) for model in models]
    sigma = float(min(rates))
    if not sigma > 0:
        raise ValueError("an error model is not stable: it has a pole with Re >= 0")
    return sigma


def overlap_samples(models: tuple[LinearErrorModel, ...], ts: float, chained: int) -> int:
    """Overlap (samples) for ``chained`` predictions in a row (1 for a prediction and its
    contour errors, 2 per compensation pass + 1): see the module docstring."""
    seconds = (chained * log(1.0 / DECAY) / slowest_decay_rate(models)
               + MAX_WINDOW_FACTOR * DEFAULT_WINDOW + 2 * BLEND_SPREAD + SPLINE_MARGIN)
    return int(ceil(seconds / ts))


def plan_pieces(n_samples: int, overlap: int, q_of=None,
                piece_samples: int = PIECE_SAMPLES, ts: float = 1e-3) -> list[Piece]:
    """Cut [0, n_samples) into pieces of about ``piece_samples`` kept samples.

    ``q_of(start, stop)`` returns the axis commands of those samples; where given, each cut is
    moved to the middle of the longest stop within the last quarter before it, if any.
    """
    if n_samples <= piece_samples + piece_samples // 2:
        return [Piece(0, n_samples, 0, n_samples)]
    cuts = [0]
    while n_samples - cuts[-1] > piece_samples + piece_samples // 2:
        planned = cuts[-1] + piece_samples
        cut = planned
        if q_of is not None:
            lo = planned - piece_samples // 4
            stop = _longest_stop(q_of(lo, planned), ts)
            if stop is not None:
                cut = lo + (stop[0] + stop[1]) // 2
        cuts.append(cut)
    cuts.append(n_samples)
    # pieces start on the spline fit's first knot grid (every INITIAL_SAMPLES_PER_SEGMENT-th
    # sample), so that they start from the knots the whole program would start from
    grid = INITIAL_SAMPLES_PER_SEGMENT
    return [Piece(max(0, (a - overlap) // grid * grid), min(n_samples, b + overlap), a, b)
            for a, b in zip(cuts[:-1], cuts[1:])]


def _longest_stop(q: np.ndarray, ts: float):
    """(first, last) sample of the longest stretch in which no axis moves, or None."""
    tolerance = np.array([STOP_TOLERANCE_LINEAR] * 3 + [STOP_TOLERANCE_ROTARY] * 2)
    still = np.all(np.abs(np.diff(q, axis=0)) <= tolerance, axis=1)
    if not still.any():
        return None
    edges = np.diff(np.concatenate([[0], still.astype(np.int8), [0]]))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    longest = int(np.argmax(ends - starts))
    if (ends[longest] - starts[longest]) * ts < STOP_TIME:
        return None
    return int(starts[longest]), int(ends[longest])


def _slice(traj: Trajectory, start: int, stop: int) -> Trajectory:
    """Samples [start, stop) of ``traj``, with its reference and source lines where it has
    them."""
    line = traj.line
    return Trajectory(traj.t[start:stop], traj.q[start:stop],
                      None if traj.P is None else traj.P[start:stop],
                      None if traj.O is None else traj.O[start:stop],
                      line=None if line is None else line[start:stop])


@dataclass(frozen=True)
class ProgramPrediction:
    """What ``predict`` gives: the predicted tracking errors (and contour errors where the
    reference is known) of a whole program, and the knots each axis needed.

    Attributes
    ----------
    e : ndarray, shape (N, 5)
        Tracking errors of the axes, mm and rad (spec section 4).
    contour : ContourErrors or None
        Contour errors of the predicted actual motion (None: no reference).
    n_knots : tuple of int
        Spline knots each axis's fit needed (summed over the pieces).
    pieces : int
        Pieces the program was predicted in (1: at once).
    t : ndarray, shape (N,), or None
        Sample times, s.
    axis_names : tuple of str
        The machine's letters of the five slots.
    """

    e: np.ndarray
    contour: ContourErrors | None
    n_knots: tuple[int, ...]
    pieces: int
    t: np.ndarray | None = None
    axis_names: tuple[str, ...] = AXES

    @property
    def max_abs_error(self) -> np.ndarray:
        """max |e| of each axis over the program, shape (5,)."""
        return np.abs(self.e).max(axis=0)

    def summary(self) -> TrackingSummary:
        """The largest tracking error of each axis (um, urad); the contour errors' own:
        ``contour.summary()``."""
        return TrackingSummary.of(self.e, self.axis_names)

    def plot(self, axes=None):
        """The predicted tracking errors against time (and the contour errors where the
        reference is known; :func:`precontour.reports.plots.plot_tracking_errors`); returns
        the figure."""
        from ..reports.plots import plot_tracking_errors

        t = np.arange(self.e.shape[0], dtype=float) if self.t is None else self.t
        return plot_tracking_errors(t, self.e, axis_names=self.axis_names,
                                    contour=self.contour, axes=axes,
                                    title="predicted tracking errors")


def predict_pieces(servo: Servo, read, n_samples: int, ts: float, *,
                   tol_linear: float | None = None, tol_rotary: float | None = None,
                   piece_samples: int = PIECE_SAMPLES):
    """Predict a program given only ``read(start, stop) -> Trajectory`` of its samples, piece
    by piece; yields ``(piece, e, contour, n_knots)`` for the kept samples of each piece
    (``contour`` None without a reference). Memory is bounded by the piece size."""
    kinematics, models = servo.kinematics, servo.models
    pieces = plan_pieces(n_samples, overlap_samples(models, ts, 1),
                         lambda a, b: read(a, b).q, piece_samples, ts)

    def one(piece):
        part = read(piece.start, piece.stop)
        prediction = predict_tracking(part.t, part.q, models, tol_linear=tol_linear,
                                      tol_rotary=tol_rotary)
        keep = slice(piece.keep_start - piece.start, piece.keep_stop - piece.start)
        e = prediction(part.t)
        n_knots = tuple(int(np.count_nonzero((fit.knot_index >= keep.start)
                                             & (fit.knot_index < keep.stop)))
                        for fit in prediction.fits)
        contour = None
        if part.has_reference:
            contour = _kept(ReferencePath.from_trajectory(part).errors(
                *kinematics.forward(part.q - e)), keep)
        return piece, e[keep].copy(), contour, n_knots

    # the pieces are independent: side by side on the jobs' threads, as many in memory
    yield from map_ordered(one, pieces)


def predict_program(servo: Servo, traj: Trajectory, *, tol_linear: float | None = None,
                    tol_rotary: float | None = None, piece_samples: int = PIECE_SAMPLES,
                    at_once_samples: int = AT_ONCE_SAMPLES) -> ProgramPrediction:
    """Tracking errors e(t) at every sample (and contour errors if ``traj`` has its
    reference), at once up to ``at_once_samples`` samples, in pieces above."""
    n = traj.n_samples
    e = np.empty_like(traj.q)
    parts = []
    knots = np.zeros(len(servo.models), dtype=np.int64)
    pieces = 0
    for piece, e_kept, contour, n_knots in predict_pieces(
            servo, lambda a, b: _slice(traj, a, b), n, traj.ts, tol_linear=tol_linear,
            tol_rotary=tol_rotary, piece_samples=n if n <= at_once_samples else piece_samples):
        e[piece.keep_start:piece.keep_stop] = e_kept
        knots += n_knots
        pieces += 1
        if contour is not None:
            parts.append(contour)
    return ProgramPrediction(e=e, contour=_join(parts) if parts else None,
                             n_knots=tuple(int(k) for k in knots), pieces=pieces, t=traj.t,
                             axis_names=servo.axis_names)


def contour_errors_program(reference: Trajectory, q_act: np.ndarray, kinematics, *,
                           piece_samples: int = PIECE_SAMPLES,
                           at_once_samples: int = AT_ONCE_SAMPLES) -> ContourErrors:
    """Contour errors of the actual axis positions ``q_act`` against ``reference`` (with its
    P, O), at once up to ``at_once_samples`` samples, in overlapping pieces above: each
    piece's reference curves and searches reach no further than the widest search window and
    the splines' end effects, so the overlap (those two) leaves the kept samples unchanged."""
    n = reference.n_samples
    if n <= at_once_samples:
        return ReferencePath.from_trajectory(reference).errors(*kinematics.forward(q_act))
    overlap = int(ceil((MAX_WINDOW_FACTOR * DEFAULT_WINDOW + SPLINE_MARGIN) / reference.ts))

    def one(piece):
        part = _slice(reference, piece.start, piece.stop)
        errors = ReferencePath.from_trajectory(part).errors(
            *kinematics.forward(q_act[piece.start:piece.stop]))
        return _kept(errors, slice(piece.keep_start - piece.start,
                                   piece.keep_stop - piece.start))

    return _join(list(map_ordered(one, plan_pieces(n, overlap, None, piece_samples,
                                                   reference.ts))))


def compensate_pieces(servo: Servo, read, n_samples: int, ts: float, *,
                      method: str = "contour",
                      iterations: int = 1, tol_linear: float | None = None,
                      tol_rotary: float | None = None, min_passes: int = 0,
                      hold_idle: bool = True, piece_samples: int = PIECE_SAMPLES):
    """:func:`compensate` a program given only ``read(start, stop) -> Trajectory`` (with its
    reference), piece by piece; yields ``(piece, result)`` where ``result`` is the piece's
    :class:`CompensationResult` cut to its kept samples. Each piece keeps its own best
    number of passes. Memory is bounded by the piece size. The options are
    :func:`compensate`'s; learning against a machine model is not among them (it runs the
    whole trajectory at once)."""
    chained = 2 * iterations + 1
    pieces = plan_pieces(n_samples, overlap_samples(servo.models, ts, chained),
                         lambda a, b: read(a, b).q, piece_samples, ts)

    def one(piece):
        result = compensate(servo, read(piece.start, piece.stop), method=method,
                            iterations=iterations, tol_linear=tol_linear,
                            tol_rotary=tol_rotary, min_passes=min_passes, hold_idle=hold_idle,
                            # only the last piece ends where the program does
                            programmed_end=piece.stop == n_samples)
        keep = slice(piece.keep_start - piece.start, piece.keep_stop - piece.start)
        return piece, CompensationResult(
            trajectory=_slice(result.trajectory, keep.start, keep.stop),
            before=_kept(result.before, keep), after=_kept(result.after, keep),
            iterations=result.iterations, history=result.history, method=result.method)

    # the pieces are independent: side by side on the jobs' threads, as many in memory
    yield from map_ordered(one, pieces)


def compensate_program(servo: Servo, traj: Trajectory, *, method: str = "contour",
                       iterations: int = 1, tol_linear: float | None = None,
                       tol_rotary: float | None = None,
                       min_passes: int = 0, hold_idle: bool = True, progress=None,
                       machine_actual=None, learning_passes: int = DEFAULT_LEARNING_PASSES,
                       learning_progress=None, piece_samples: int = PIECE_SAMPLES,
                       at_once_samples: int = AT_ONCE_SAMPLES) -> CompensationResult:
    """:func:`compensate` of a whole program, at once up to ``at_once_samples`` samples, in
    pieces above (the options as for :func:`compensate`).

    In pieces, each piece keeps its own best number of passes (``iterations`` is the largest
    of them), ``history`` holds the joined before and after, and ``progress(passes,
    summary)`` is called once, with that largest number and the joined prediction after;
    learning (``machine_actual``) runs the whole trajectory at once, and is refused.
    """
    n = traj.n_samples
    fits = dict(method=method, iterations=iterations, tol_linear=tol_linear,
                tol_rotary=tol_rotary, min_passes=min_passes, hold_idle=hold_idle)
    if n <= at_once_samples:
        return compensate(servo, traj, progress=progress,
                          machine_actual=machine_actual, learning_passes=learning_passes,
                          learning_progress=learning_progress, **fits)
    if machine_actual is not None:
        raise ValueError(f"learning runs the whole trajectory at once: {n} samples are more "
                         f"than {at_once_samples}")
    q = np.empty_like(traj.q)
    before, after, passes = [], [], 0
    for piece, result in compensate_pieces(servo, lambda a, b: _slice(traj, a, b), n, traj.ts,
                                           piece_samples=piece_samples, **fits):
        q[piece.keep_start:piece.keep_stop] = result.trajectory.q
        before.append(result.before)
        after.append(result.after)
        passes = max(passes, result.iterations)
    before_all, after_all = _join(before), _join(after)
    if progress is not None:
        progress(passes, after_all.summary())
    return CompensationResult(trajectory=traj.with_axes(q), before=before_all,
                              after=after_all, iterations=passes,
                              history=(before_all.summary(), after_all.summary()),
                              method=method)


def _kept(errors: ContourErrors, keep: slice) -> ContourErrors:
    return ContourErrors(tip=errors.tip[keep], orientation=errors.orientation[keep],
                         tip_parameter=errors.tip_parameter[keep],
                         orientation_parameter=errors.orientation_parameter[keep])


def _join(parts: list[ContourErrors]) -> ContourErrors:
    return ContourErrors(*(np.concatenate([getattr(p, name) for p in parts])
                           for name in ("tip", "orientation", "tip_parameter",
                                        "orientation_parameter")))
