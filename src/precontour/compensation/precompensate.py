"""Pre-compensation: rewrite the axis commands so that the predicted contour errors cancel.

Spec section 6 (paper Sec. 3.2, Eqs. 22-27, Fig. 6). Orientation first, since the linear axes
do not change the tool orientation: the predicted actual orientation is reflected through the
centre of the spherical parallelogram it forms with its closest reference point and the
commanded orientation. Then the tool tip, after predicting again with the orientation-corrected
command: the predicted tip contour error vector is added to the commanded tip. Inverse
kinematics turns both into axis commands on the branch of the reference command.

Iterating applies the same correction to the corrected command (the commanded P and O of
iteration k take the place of the reference), until the predicted contour errors stop
improving. ``method="tracking"`` is the paper's baseline: add each axis's predicted tracking
error to its command.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import maximum_filter1d, uniform_filter1d

from ..defaults import COMPENSATION_METHODS as METHODS
from ..defaults import COMPENSATION_TOL_LINEAR, COMPENSATION_TOL_ROTARY
from ..files import check_signals
from ..prediction.contour import ContourErrors, ReferencePath
from ..machine.servo import Servo
from ..trajectory.sampled import Trajectory
from ..prediction.tracking import predict_tracking
from .idle_axes import hold_idle_axes, hold_resting_axes
from .programmed_end import end_at_programmed_end
from .stops import (DEFAULT_LEARNING_PASSES, Learner, LearningProblem, LearningReport,
                    LearningSettings, MachineActual)

# METHODS and COMPENSATION_TOL_* (the spline fit tolerances when compensating, ten times finer
# than for prediction alone) are defined in precontour.defaults, for the command line's help.


@dataclass(frozen=True)
class CompensationResult:
    """A compensated trajectory and the predicted contour errors before and after.

    Attributes
    ----------
    trajectory : Trajectory
        Compensated axis commands, same time stamps and reference as the input.
    before, after : ContourErrors
        Predicted contour errors of the original and the compensated commands.
    iterations : int
        Compensation passes kept (1 = the paper's single pass; 0 when learning against a
        machine model kept the uncompensated command).
    history : tuple of dict
        Predicted max/mean errors after each pass tried (``ContourErrors.summary``), the
        first entry being the uncompensated command.
    method : str
        ``"contour"`` or ``"tracking"``.
    learning : LearningReport or None
        What learning against the nonlinear machine model tried and kept
        (:mod:`precontour.compensation.stops`); None when no machine model was given.
    """

    trajectory: Trajectory
    before: ContourErrors
    after: ContourErrors
    iterations: int
    history: tuple
    method: str
    learning: LearningReport | None = None


def compensation_tolerances(tol_linear: float | None = None,
                            tol_rotary: float | None = None) -> tuple[float, float]:
    """The spline fit tolerances a compensation uses: those given, else
    :data:`COMPENSATION_TOL_LINEAR`, :data:`COMPENSATION_TOL_ROTARY`."""
    return (COMPENSATION_TOL_LINEAR if tol_linear is None else tol_linear,
            COMPENSATION_TOL_ROTARY if tol_rotary is None else tol_rotary)


def compensation_axis_tolerances(tol_linear: float | None = None,
                                 tol_rotary: float | None = None) -> np.ndarray:
    """:func:`compensation_tolerances` per axis X, Y, Z, A, C, shape (5,)."""
    linear, rotary = compensation_tolerances(tol_linear, tol_rotary)
    return np.array([linear] * 3 + [rotary] * 2)


def predicted_actual(traj_t: np.ndarray, q: np.ndarray, models, tol_linear=None,
                     tol_rotary=None) -> np.ndarray:
    """Predicted actual axis positions q - e(q) (spec section 6 step 1), shape (N, 5)."""
    tol_linear, tol_rotary = compensation_tolerances(tol_linear, tol_rotary)
    prediction = predict_tracking(traj_t, q, models, tol_linear=tol_linear,
                                  tol_rotary=tol_rotary)
    return q - prediction(traj_t)


def compensate(servo: Servo, traj: Trajectory, *, method: str = "contour",
               iterations: int = 1, tol_linear: float | None = None,
               tol_rotary: float | None = None, reference: ReferencePath | None = None,
               progress=None, min_passes: int = 0, machine_actual: MachineActual | None = None,
               learning_passes: int = DEFAULT_LEARNING_PASSES,
               learning_progress=None, hold_idle: bool = True,
               programmed_end: bool = True) -> CompensationResult:
    """Pre-compensate the axis commands of ``traj`` (which must carry its reference P, O).

    One compensation of the whole trajectory at once; :func:`precontour.compensation.
    compensate` is the entry that takes long programs, the limits and learning on draws.

    Parameters
    ----------
    servo : Servo
        The machine's kinematics (``forward``, ``inverse``) and the closed-loop error models
        of its axes (:func:`~precontour.machine.servo.load_servo`).
    traj : Trajectory
        Reference commands with the reference tool path.
    method : {"contour", "tracking"}
        Contour-error pre-compensation (spec section 6), or the baseline that adds the
        predicted axis tracking errors to the commands.
    iterations : int
        Largest number of passes; passing stops early when the predicted contour errors
        (max and mean of tip and orientation, taken together) stop improving, and the best
        pass is kept.
    tol_linear, tol_rotary : float, optional
        Spline fit tolerances of the predictions.
    reference : ReferencePath, optional
        Reuse already built reference curves.
    progress : callable, optional
        Called as ``progress(pass_index, summary_dict)`` after each pass.
    min_passes : int
        Passes kept even when they do not improve the prediction (0 to ``iterations``); 1
        applies the paper's single pass unconditionally, as a comparison of methods needs.
    machine_actual : callable, optional
        A nonlinear machine model, commands (N, 5) -> actual axis positions (N, 5), or one
        motion per draw of an ensemble (D, N, 5): best the draws of the realistic virtual
        machine, ``ensemble_actual(traj.t, machine, controller)``
        (:func:`precontour.simulation.ensemble_actual`; what ``precontour compensate
        --ignore-limits`` uses). With it (``method="contour"``), the linear result is
        improved by ``learning_passes`` passes of learning against it, where friction matters
        (stops, reversals, the final dwell; :func:`precontour.compensation.stops.learn_at_stops`):
        every choice is taken on the worst draw, and a command is kept only if it is nowhere
        worse than the uncompensated one on every draw, in whole and in every window of
        :data:`~precontour.compensation.blocks.BLOCK_WINDOW` (each source line for a
        trajectory made from a program), falling back locally where needed.
    learning_passes : int
        Passes of that learning (0: the linear result and its settled tails, only checked
        against the model).
    learning_progress : callable, optional
        Called as ``learning_progress(label, summary_dict)`` after each command tried on the
        machine model.
    hold_idle : bool
        Leave an axis whose reference command does not move, and whose correction stays
        within the fit tolerance (``tol_linear``, ``tol_rotary``), at its reference command
        (:mod:`precontour.compensation.idle_axes`: nanometre commands on a resting axis
        switch friction feed-forward on).
    programmed_end : bool
        End at the reference's last sample: the corrections taper to zero over its final
        rest (:func:`~.programmed_end.end_at_programmed_end`), as the controller holds the
        last command after the program. False only for a stretch of a longer trajectory
        whose end is not the program's (pieces, re-compensated windows).
    """
    if method not in METHODS:
        raise ValueError(f"unknown compensation method {method!r}; choose one of "
                         f"{', '.join(METHODS)}")
    if iterations < 1:
        raise ValueError(f"iterations must be >= 1, got {iterations}")
    if not 0 <= min_passes <= iterations:
        raise ValueError(f"min_passes must be within 0..{iterations}, got {min_passes}")
    kinematics, models = servo.kinematics, servo.models
    reference = reference or ReferencePath.from_trajectory(traj)
    t = traj.t
    tol_linear, tol_rotary = compensation_tolerances(tol_linear, tol_rotary)

    model = _PassModel(t, models, reference, kinematics, tol_linear, tol_rotary)
    predict, searched, errors_of = model.predict, model.searched, model.errors_of

    def ended(q):
        # the controller holds the last command after the program: each pass's commands end
        # at the programmed end point, their corrections tapered over the final rest
        return end_at_programmed_end(traj.q, q, traj.ts) if programmed_end else q

    q_cmd = traj.q
    q_act = predict(q_cmd)
    # axis tracking-error pre-compensation (spec section 7's baseline): a local fallback of
    # learning (compensation/blocks.py)
    q_tracking = traj.q + (traj.q - q_act)
    before, known = searched(q_act)
    best = (_score(before), q_cmd, before, 0)
    history = [before.summary()]
    for n in range(1, iterations + 1):
        check_signals()  # between passes: where a SIGTERM or Ctrl-C stops compensating
        if method == "tracking":
            q_new = q_cmd + (traj.q - q_act)
        else:
            q_new = _contour_pass(q_cmd, q_act, traj, reference, kinematics, predict, known)
        q_cmd = ended(q_new)
        q_act = predict(q_cmd)
        after, known = searched(q_act)
        history.append(after.summary())
        if progress is not None:
            progress(n, after.summary())
        if n <= min_passes or _score(after) < best[0]:
            best = (_score(after), q_cmd, after, n)
        else:
            break
    _, q_best, after_best, passes = best
    idle_tolerance = compensation_axis_tolerances(tol_linear, tol_rotary)

    def hold(q):
        return hold_idle_axes(traj.q, q, idle_tolerance) if hold_idle else q

    q_held = ended(hold(q_best))
    if q_held is not q_best:
        q_best, after_best = q_held, errors_of(predict(q_held))
    # ---- hook: stops and reversals under friction (compensation/stops.py) ----
    learning = None
    if machine_actual is not None and method == "contour":
        problem = LearningProblem(
            traj.q, traj.ts, machine_actual, errors_of,
            learning_step(traj, reference, kinematics, hold=hold), line=traj.line,
            t0=float(t[0]), tail_errors_of=model.tail_errors_of,
            repeat_actual=getattr(machine_actual, "repeat", None))
        learner = Learner(
            problem, LearningSettings(passes=learning_passes), progress=learning_progress,
            fallbacks=(("tracking-error pre-compensation", ended(hold(q_tracking))),),
            variants=(("resting axes held",
                       lambda q: hold_resting_axes(traj.q, q, idle_tolerance)),)
            if hold_idle else ())
        # only the command kept is ended at the programmed end point, as learning within the
        # limits does (within_limits.learn_commands): with every command tried tapered, the
        # choice turned on the taper, and on circle / pid-low kept the uncompensated command
        # (docs/compensation.md: 0 % where it now removes 93.8 % of the max tip error)
        q_learned, learning = learner.learn(q_best)
        q_learned = ended(q_learned)
        if q_learned is not q_best:
            q_best, after_best = q_learned, errors_of(predict(q_learned))
        if learning.chosen == "uncompensated":
            passes = 0
    # ---- end hook ----
    return CompensationResult(trajectory=traj.with_axes(q_best), before=before,
                              after=after_best, iterations=passes, history=tuple(history),
                              method=method, learning=learning)


def learning_step(traj: Trajectory, reference: ReferencePath, kinematics, hold=None):
    """The contour correction as a learning step against a machine model (the ``contour_step``
    of :func:`~precontour.compensation.stops.learn_at_stops`): ``step(q_cmd, q_act, actual)``
    corrects ``q_cmd`` whose actual motion is ``q_act``, ``actual`` giving any other's.
    ``hold``, if given, is applied to each corrected command (idle axes kept at rest)."""
    def step(q_cmd, q_act, actual):
        q = _contour_pass(q_cmd, q_act, traj, reference, kinematics, actual)
        return q if hold is None else hold(q)
    return step


class _PassModel:
    """What the passes of :func:`compensate` predict with: the linear error models' actual
    motion of a command (each fit starting from the knots of the previous one: a corrected
    command needs the knots of the command it corrects and more; issue 11: the corrected
    commands took three times the rounds of the original when fitted from scratch; and the
    step-5 command keeping the rotary axes of the step-3 one, whose predictions are reused),
    and the contour errors of a motion against the reference."""

    def __init__(self, t, models, reference, kinematics, tol_linear, tol_rotary):
        self.t, self.models, self.reference, self.kinematics = t, models, reference, kinematics
        self.tol_linear, self.tol_rotary = tol_linear, tol_rotary
        self.knots = None
        self.previous = None

    def predict(self, q):
        """The predicted actual motion of the commands ``q``."""
        prediction = predict_tracking(self.t, q, self.models, initial_knots=self.knots,
                                      previous=self.previous, tol_linear=self.tol_linear,
                                      tol_rotary=self.tol_rotary)
        self.knots = prediction.fits.knot_indices
        self.previous = (q, prediction)
        return q - prediction(self.t)

    def searched(self, q_actual):
        """Contour errors of q_actual, and what a pass needs of them: the actual
        orientations and their closest reference orientations."""
        P_act, O_act = self.kinematics.forward(q_actual)
        errors, _, O_closest = self.reference.errors(P_act, O_act, with_points=True)
        return errors, (O_act, errors.orientation_parameter, O_closest)

    def errors_of(self, q_actual):
        return self.searched(q_actual)[0]

    def tail_errors_of(self, q_actual, first):
        return self.reference.errors(*self.kinematics.forward(q_actual),
                                     t=self.reference.t[first:])


def _contour_pass(q_cmd, q_act, traj, reference, kinematics, predict, known=None):
    """One pass of spec section 6, steps 1-5, with the current command in place of the
    reference command (identical on the first pass). ``known``: the orientations of the
    predicted actual ``q_act``, their closest reference parameters and orientations, where
    already known (the contour errors of ``q_act`` found them)."""
    P_cmd, O_cmd = kinematics.forward(q_cmd)
    # Steps 1-2: orientation through the spherical parallelogram O1, O*, O_cmd, O_comp.
    if known is None:
        _, O1 = kinematics.forward(q_act)
        w, O_closest = reference.closest_orientation(O1, traj.t, with_points=True)
    else:
        O1, w, O_closest = known
    O_star = _unit(_lead_blend(_unit(O_closest), traj.O, w - traj.t, traj.ts))
    O_centre = _unit(O_cmd + O_star)
    O_comp = _unit(2.0 * np.einsum("ij,ij->i", O1, O_centre)[:, None] * O_centre - O1)
    rotary = _rotary_towards(kinematics, q_cmd[:, 3], q_cmd[:, 4], O_comp)
    # Step 3: orientation-corrected command, predicted again.
    q2 = np.concatenate([kinematics.linear_axes(P_cmd, *rotary.T), rotary], axis=1)
    P3, _ = kinematics.forward(predict(q2))
    # Step 4: add the predicted tip contour error vector to the commanded tip.
    u, P_closest = reference.closest_tip(P3, traj.t, with_points=True)
    P_star = _lead_blend(P_closest, traj.P, u - traj.t, traj.ts)
    P_comp = P_cmd + (P_star - P3)
    # Step 5: back to axis commands.
    return np.concatenate([kinematics.linear_axes(P_comp, *rotary.T), rotary], axis=1)


#: Where the predicted actual runs ahead of the reference (its closest point lies later on the
#: path than the time-corresponding point) it will overshoot wherever the reference stops or
#: turns back: the closest point runs into the turning point and stays there, and a correction
#: towards it alone comes too late and too abruptly. There the target blends smoothly from the
#: closest point to the time-corresponding reference point (tracking-error compensation), fully
#: once the lead reaches LEAD_TIME. An actual that lags, the usual case, is left to the contour
#: correction (spec section 6). Measured on the built-in paths, this lifts the one-pass
#: reduction of the largest tip / orientation errors at stops and reversals from 62-75 % to
#: 97-99 % and changes the others by less than 0.5 %.
LEAD_TIME = 0.005
BLEND_SPREAD = 0.02


def _lead_blend(closest: np.ndarray, reference_now: np.ndarray, lead: np.ndarray,
                ts: float) -> np.ndarray:
    """closest + beta (reference_now - closest), beta = smoothstep(lead / LEAD_TIME): 0 for no
    lead, 1 from LEAD_TIME on, with a continuous slope so the correction has no kink.

    Where the path retraces itself the closest point can jump to the returning branch; beta
    is therefore spread over time (a running maximum, then a running mean, each BLEND_SPREAD
    either side) so that it has reached 1 wherever the closest point jumps, and the blended
    target stays continuous and changes no faster than over 2 BLEND_SPREAD.
    """
    x = np.clip(lead / LEAD_TIME, 0.0, 1.0)
    beta = x * x * (3.0 - 2.0 * x)
    width = 2 * max(1, int(round(BLEND_SPREAD / ts))) + 1
    beta = uniform_filter1d(maximum_filter1d(beta, width, mode="nearest"), width, mode="nearest")
    return closest + beta[:, None] * (reference_now - closest)


#: Singularity-robust rotary correction near the pole A = 0 (tool along C; on an A-B table
#: B = +-90 deg, tool along A): damped least squares with damping that grows from 0 where
#: |sin A| (|cos B|) = POLE_ZONE to POLE_DAMPING at the pole.
POLE_ZONE = 0.1
POLE_DAMPING = 0.05
ROTARY_NEWTON_STEPS = 3


def _rotary_towards(kinematics, A, C, O_target):
    """A, C (shape (N, 2)) near the commanded ones that point the tool along ``O_target``.

    The corrections are small (below a milliradian), so a few Gauss-Newton steps from the
    command converge; they keep C continuous where an exact inverse kinematics would flip it by
    pi beside the pole. Inside the pole zone the damping gives up the part of the correction
    that only a fast C rotation could make, as singularity-robust inverses do.
    """
    A = np.array(A, dtype=float)
    C = np.array(C, dtype=float)
    for _ in range(ROTARY_NEWTON_STEPS):
        jac = kinematics.orientation_jacobian(A, C)                     # (N, 3, 2)
        residual = O_target - kinematics.orientation(A, C)
        d_a, d_c = jac[..., 0], jac[..., 1]
        sin_a = _pole_distance(kinematics, A, C)
        damping = np.where(sin_a < POLE_ZONE,
                           POLE_DAMPING**2 * (1.0 - (sin_a / POLE_ZONE) ** 2), 0.0)
        # the 2 x 2 normal equations, solved in closed form (positive definite: the A column
        # of the Jacobian is a unit vector)
        n_aa = np.einsum("nk,nk->n", d_a, d_a) + damping
        n_ac = np.einsum("nk,nk->n", d_a, d_c)
        n_cc = np.einsum("nk,nk->n", d_c, d_c) + damping
        r_a = np.einsum("nk,nk->n", d_a, residual)
        r_c = np.einsum("nk,nk->n", d_c, residual)
        det = n_aa * n_cc - n_ac * n_ac
        A += (n_cc * r_a - n_ac * r_c) / det
        C += (n_aa * r_c - n_ac * r_a) / det
    return np.stack([A, C], axis=1)


def _pole_distance(kinematics, A, C) -> np.ndarray:
    """How far the rotary axes stand from the singular pose, where one column of the
    orientation Jacobian vanishes: |sin A| of the tilt in slot 3 (the pole, tool along the
    turning axis), or the kinematics' own ``pole_distance`` (|cos B| on an A-B table)."""
    own = getattr(kinematics, "pole_distance", None)
    return np.abs(np.sin(A)) if own is None else own(A, C)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def _score(errors: ContourErrors) -> float:
    """One number that says whether a pass improved: max + mean of the tip error (mm) plus
    those of the orientation error (rad) weighted by 100 mm/rad, about a tool length, so that
    neither kind of error can grow unnoticed while the other shrinks."""
    return (float(errors.tip.max() + errors.tip.mean())
            + 100.0 * float(errors.orientation.max() + errors.orientation.mean()))
