"""Learning from the machine's own traces: part-program iterative learning.

What no model holds (friction at stops and reversals, the controller's own discretisation) is
learned from traces of the program run on the machine. Each iteration takes the latest trace
(commanded and actual positions of a run of the program, uncompensated or compensated) and
the controller's trace of the uncompensated program (the timing and the reference path), and
gives the next commands at that timing:

1. The latest trace is matched to the reference point by point of the program, not by time
   (:func:`align`): between the starts of each block (the trace's ``line`` column) time is
   mapped linearly, so that a run whose blocks started a period earlier or later is compared
   where it was in the program.
2. The *contour-relevant* error is measured (spec section 5): each actual tool tip and
   orientation against its closest point on the reference path; the axes that would put the
   tool there (inverse kinematics) minus the actual axes is the error to remove. Lag along the
   path is no contour error and is left alone, which also keeps the blocks' timing.
3. An inverse-model step shapes the update (:func:`inverse_model_step`): the axis error
   passed through 1 + E(s) (E the identified loop's error model e/X, spec section 2; to first
   order the inverse of the closed loop x/X = 1 - E), scaled by :data:`LEARNING_GAIN` and
   filtered forwards and backwards by a Butterworth low pass at :data:`LEARNING_CUTOFF`
   (no phase lag; the blocks cannot carry faster corrections anyway).
4. The update is added to the commands the latest trace carried, over the program's moves
   (and the settling after the last one), not before them.

The commands a trace carried are its own commanded positions, so each iteration needs only
the latest trace besides the timing.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import signal

from ..compensation.programmed_end import end_at_programmed_end
from ..errors import InputError
from ..prediction.contour import ContourErrors, ReferencePath
from .blocks import block_starts
from .trace import ControllerTrace

__all__ = ["LEARNING_GAIN", "LEARNING_CUTOFF", "Measured", "align",
           "commands_learned_from", "inverse_model_step", "learned_commands", "measure_trace",
           "reference_path"]

#: Fraction of the inverse-model update taken per iteration. 1: the whole measured error,
#: which the deterministic loop of a controller repeats from run to run (two uncompensated
#: LinuxCNC runs gave the same positions to the last recorded digit).
LEARNING_GAIN = 1.0
#: Corner frequency of the zero-phase low pass on the update, Hz: below the blocks' rate
#: (blocks of 10-20 ms on the paper path's G-code), above the loops' bandwidth (50-60 Hz).
LEARNING_CUTOFF = 60.0
#: Order of that low pass (applied forwards and backwards: twice the order, no phase).
LEARNING_ORDER = 2
#: Time after the last block's start that still counts as the program (its end and the
#: settling at the final rest), and after the first block's start that the tables leave out
#: (the approach's settling), s.
SETTLE_TIME = 0.3


@dataclass(frozen=True)
class Measured:
    """A trace's actual motion against the reference, point by point of the program.

    Attributes
    ----------
    errors : ContourErrors
        Contour errors of the actual positions at each reference sample of the program.
    span : slice
        The reference's samples of the program (first move's start to the settling after the
        last one), which ``errors`` covers.
    line : ndarray of int
        Program line at each of those samples (the reference's).
    commands, actual : ndarray, shape (N, 5)
        The trace's commanded and actual axes at every reference sample (mm, rad).
    tip_closest, orientation_closest : ndarray, shape (N, 3)
        The closest reference tip and unit orientation to each actual one (what learning
        moves the tool to).
    period : float
        The reference's sample period, s.
    """

    errors: ContourErrors
    span: slice
    line: np.ndarray
    commands: np.ndarray
    actual: np.ndarray
    tip_closest: np.ndarray
    orientation_closest: np.ndarray
    period: float = 1e-3

    @property
    def cutting(self) -> slice:
        """The samples of ``errors`` that the tables report: from :data:`SETTLE_TIME` after
        the first move's start (the approach rapid still settles there, and the first blocks,
        shorter than :data:`~precontour.cnc.blocks.MIN_BLOCK`, keep their end points) to the
        end of the commanded motion."""
        moving = np.flatnonzero(np.any(np.diff(self.commands, axis=0) != 0, axis=1))
        end = int(moving[-1]) + 2 if moving.size else self.commands.shape[0]
        start = min(int(round(SETTLE_TIME / self.period)), max(end - 1, 0))
        return slice(start, end)

    def summary(self):
        """Max and mean contour errors over :attr:`cutting` (um, mrad)."""
        part = self.cutting
        return ContourErrors(tip=self.errors.tip[part],
                             orientation=self.errors.orientation[part],
                             tip_parameter=self.errors.tip_parameter[part],
                             orientation_parameter=self.errors.orientation_parameter[part]
                             ).summary()


def align(reference: ControllerTrace, trace: ControllerTrace, move_lines) -> np.ndarray:
    """For every sample of ``reference``, the (fractional) sample of ``trace`` at the same
    point of the program: linear in time between the starts of the blocks both reach."""
    lines = np.asarray(move_lines)
    s_ref = block_starts(reference.line, lines)
    s_run = block_starts(trace.line, lines)
    both = (s_ref >= 0) & (s_run >= 0)
    if not np.any(both):
        raise InputError("the trace never executes one of the program's moves: a trace of "
                         "another program?", source=trace.source, field="line")
    k_ref, k_run = s_ref[both].astype(float), s_run[both].astype(float)
    n = reference.n_samples
    knots_ref = np.concatenate([[k_ref[0] - 1e9], k_ref, [k_ref[-1] + 1e9]])
    knots_run = np.concatenate([[k_run[0] - 1e9], k_run, [k_run[-1] + 1e9]])
    position = np.interp(np.arange(n, dtype=float), knots_ref, knots_run)
    return np.clip(position, 0.0, trace.n_samples - 1.0)


def _at(values: np.ndarray, position: np.ndarray) -> np.ndarray:
    """``values`` (M, 5) linearly interpolated at fractional samples ``position``."""
    i = np.minimum(np.floor(position).astype(np.int64), values.shape[0] - 2)
    f = (position - i)[:, None]
    return values[i] * (1.0 - f) + values[i + 1] * f


def program_span(reference: ControllerTrace, move_lines) -> slice:
    """The reference's samples of the program: from its first move's start to
    :data:`SETTLE_TIME` after its last move's start (at most the trace's end)."""
    starts = block_starts(reference.line, np.asarray(move_lines))
    reached = starts[starts >= 0]
    if reached.size == 0:
        raise InputError("the timing trace never executes one of the program's moves",
                         source=reference.source, field="line")
    settle = int(round(SETTLE_TIME / reference.period))
    return slice(int(reached[0]), min(int(reached[-1]) + settle, reference.n_samples))


def measure_trace(servo, reference: ControllerTrace, trace: ControllerTrace, move_lines,
                  path: ReferencePath | None = None) -> Measured:
    """The contour errors of ``trace``'s actual positions against ``reference``'s commanded
    path (spec section 5), point by point of the program; ``path``: that path
    (:func:`reference_path`), when the caller has it already."""
    if trace.actual is None:
        raise InputError("the trace has no actual positions (X_act..C_act): learning and "
                         "measuring need them", source=trace.source, field="X_act")
    span = program_span(reference, move_lines)
    position = align(reference, trace, move_lines)[span]
    commands = _at(trace.command, position)
    actual = _at(trace.actual, position)
    path = path or reference_path(servo, reference)
    P, O = servo.kinematics.forward(actual)
    errors, P_closest, O_closest = path.errors(P, O, reference.t[span] - reference.t[0],
                                               with_points=True)
    O_closest = O_closest / np.linalg.norm(O_closest, axis=1, keepdims=True)
    return Measured(errors=errors, span=span, line=reference.line[span], commands=commands,
                    actual=actual, tip_closest=P_closest, orientation_closest=O_closest,
                    period=reference.period)


def reference_path(servo, reference: ControllerTrace) -> ReferencePath:
    """The tool tip and orientation curves of ``reference``'s commands (spec section 5)."""
    return ReferencePath.from_trajectory(reference.reference(servo.kinematics))


def inverse_model_step(servo, error: np.ndarray, period: float) -> np.ndarray:
    """The command change (N, 5) that removes the axis error ``error`` (N, 5) to first order:
    each axis through 1 + E(s) (its error model, discretised by the bilinear transform), then
    :data:`LEARNING_GAIN` and the zero-phase low pass."""
    step = np.empty_like(error)
    for axis, model in enumerate(servo.models):
        num = np.polyadd(model.den, model.num)       # 1 + E = (den + num) / den
        b, a, _ = signal.cont2discrete((num, model.den), period, method="bilinear")
        step[:, axis] = signal.lfilter(np.ravel(b), np.ravel(a), error[:, axis])
    nyquist = 0.5 / period
    if LEARNING_CUTOFF < nyquist:
        sos = signal.butter(LEARNING_ORDER, LEARNING_CUTOFF, fs=1.0 / period, output="sos")
        if error.shape[0] > 3 * (2 * sos.shape[0] + 1):
            step = signal.sosfiltfilt(sos, step, axis=0)
    return LEARNING_GAIN * step


def learned_commands(servo, reference: ControllerTrace, trace: ControllerTrace,
                     move_lines, *, path: ReferencePath | None = None
                     ) -> tuple[np.ndarray, Measured]:
    """The next commands (N, 5; mm, rad) at ``reference``'s samples, learned from
    ``trace`` (a run of the program with actual positions), and what was measured on it;
    ``path``: :func:`reference_path` of ``reference``, when the caller has it already."""
    measured = measure_trace(servo, reference, trace, move_lines, path)
    return commands_learned_from(servo, reference, measured), measured


def commands_learned_from(servo, reference: ControllerTrace,
                          measured: Measured) -> np.ndarray:
    """The next commands (N, 5; mm, rad) at ``reference``'s samples from a trace's
    measurement (:func:`measure_trace`): the axes that put the tool at its closest
    reference points minus the actual axes, through :func:`inverse_model_step`, added to
    the commands the trace carried."""
    span = measured.span
    target = servo.kinematics.inverse(measured.tip_closest, measured.orientation_closest,
                                      c_near=measured.actual[:, 4])
    error = np.zeros_like(reference.command)
    error[span] = target - measured.actual
    step = inverse_model_step(servo, error, reference.period)
    commands = reference.command.copy()
    commands[span] = measured.commands + step[span]
    # the controller holds the last command after the program: where the span reaches the
    # trace's end, the update tapers to zero over the final rest (issue 42 item 5)
    return end_at_programmed_end(reference.command, commands, reference.period)
