"""The compensation's one public entry, :func:`compensate`, and the routes it takes.

:func:`compensate` takes the :class:`~precontour.machine.servo.Servo` first and its strategy
as keywords: the method (contour or tracking), keeping the axis limits
(:func:`keep_limits`, the default, the route ``precontour run`` takes too) or not (the
unconstrained commands, in pieces above
:data:`~precontour.compensation.pieces.AT_ONCE_SAMPLES` samples), and learning against the
draws of the realistic virtual machine (:func:`learn_on_ensemble`; the picking of the kept
command is :class:`~precontour.compensation.stops.Learner`'s). Every route ends the commands
at the programmed end point (:mod:`.programmed_end`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from ..defaults import COMPENSATION_METHODS as METHODS
from ..errors import InputError, notice, with_former_spellings
from ..machine.controllers import is_closed_loop
from ..machine.servo import Servo, learning_controller
from ..simulation.ensemble import MachineEnsemble, ensemble_actual
from ..trajectory.retime import Slowdown
from ..trajectory.sampled import Trajectory
from ..prediction.contour import ContourErrors
from .options import LearningOptions, LimitOptions, learning_options, limit_options
from .pieces import AT_ONCE_SAMPLES, compensate_program
from .programmed_end import required_final_rest, with_final_rest
from .segments import learn_by_segments
from .within_limits import (LimitedCompensation, compensate_within_limits, learn_within_limits,
                            planned_if_uncompensated)

__all__ = ["compensate", "Compensation", "METHODS", "keep_limits", "learn_on_ensemble",
           "can_learn"]


@dataclass(frozen=True)
class Compensation:
    """What :func:`compensate` gives.

    Attributes
    ----------
    commands : Trajectory
        The compensated axis commands, with the reference they were computed for.
    reference : Trajectory
        The reference on the commands' timing: the input, or the input slowed down locally
        where the limits asked for it (``slowdowns``), with a longer final rest where its own
        was too short for the corrections to taper to zero at the programmed end point
        (:func:`~precontour.compensation.programmed_end.with_final_rest`).
    before, after : ContourErrors
        Predicted contour errors of the uncompensated and the compensated commands.
    passes : int
        Compensation passes kept.
    slowdowns : tuple of Slowdown
        Windows slowed to keep the limits (time of the input).
    learning : LearningReport or None
        What learning against the virtual machine tried and kept (None: no learning).
    within_limits : bool
        Whether the commands were kept within the limits.
    left_out : tuple of (float, float)
        Windows (s, time of ``reference``) where the compensation was left out because
        slowing down (to ``min_speed`` or more) could not keep the limits.
    learning_controller : Controller or None
        The controller the virtual machine ran when learning.
    """

    commands: Trajectory
    reference: Trajectory
    before: ContourErrors
    after: ContourErrors
    passes: int
    slowdowns: tuple[Slowdown, ...]
    learning: object | None
    within_limits: bool
    left_out: tuple[tuple[float, float], ...] = ()
    learning_controller: object | None = None

    @property
    def added_time(self) -> float:
        return float(sum(s.added for s in self.slowdowns))

    def plot(self, axes=None):
        """The predicted contour errors before and after against time, tip and orientation
        (:func:`precontour.reports.plots.plot_contour_errors`); returns the figure."""
        # drawing is the report stage's: a result's plot() is the one place a stage reaches
        # it (lazily, as pandas' .plot does; tests/test_layout.py allows exactly this)
        from ..reports.plots import plot_contour_errors

        return plot_contour_errors(self.reference.t, {"uncompensated": self.before,
                                                      "compensated": self.after},
                                   title="predicted contour errors", axes=axes)


def compensate(servo: Servo, trajectory: Trajectory, *, method: str = "contour",
               limits: bool | LimitOptions = True, learn: int | LearningOptions = 0,
               iterations: int = 1, tol_linear: float | None = None,
               tol_rotary: float | None = None, progress=None, learning_progress=None,
               min_speed: float | None = None, ensemble=None,
               learn_controller: str | None = None) -> Compensation:
    """Pre-compensated commands for ``trajectory`` (which must carry its reference).

    Parameters
    ----------
    servo : Servo
        The machine with its controller (:func:`~precontour.machine.servo.load_servo`).
    trajectory : Trajectory
        The planned commands with their reference tool path.
    method : {"contour", "tracking"}
        The paper's contour method (spec section 6), or each axis's own predicted tracking
        error added (spec section 7's baseline).
    limits : LimitOptions or bool
        Keep the machine's axis limits, slowing the motion down locally (never below
        ``min_speed`` of the speed) and compensating again where needed, as ``precontour
        run`` does (:func:`keep_limits`); ``False`` gives the unconstrained commands, which
        may break them.
    learn : LearningOptions or int
        Learning (contour method) against the realistic virtual machine running the options'
        ``controller`` (default: :func:`~precontour.machine.servo.learning_controller`),
        every decision on the worst of its ensemble's draws, the command kept nowhere worse
        than uncompensated (within the limits, segment by segment above
        :data:`~precontour.compensation.pieces.AT_ONCE_SAMPLES` samples). Skipped, with a
        one-line notice, where it cannot run (:func:`can_learn`).
    iterations : int
        Compensation passes (>= 1).
    tol_linear, tol_rotary : float, optional
        The spline fits' tolerances (defaults: the compensation's).
    progress : callable, optional
        ``progress(pass, summary)`` after each pass of the (first) compensation.
    learning_progress : callable, optional
        ``learning_progress(label, summary)`` after each command learning tries.
    min_speed, ensemble, learn_controller
        Former spellings of ``LimitOptions.min_speed``, ``LearningOptions.ensemble`` and
        ``LearningOptions.controller``, accepted with a DeprecationWarning.

    Returns
    -------
    Compensation
        The commands, the reference on their timing, the predicted errors before and after.
    """
    if not isinstance(servo, Servo):
        raise InputError("compensate takes the servo first: compensate(load_servo(machine, "
                         "controller), trajectory, ...); the former compensate(trajectory, "
                         "kinematics, models), one pass at once, is precontour.compensation."
                         "precompensate.compensate(servo, trajectory)", field="servo")
    if method not in METHODS:
        raise InputError(f"unknown compensation method {method!r}; choose one of "
                         f"{', '.join(METHODS)}", field="method")
    learning = with_former_spellings(learn, LearningOptions, learning_options, "learn",
                                     controller=learn_controller, ensemble=ensemble)
    limit = with_former_spellings(limits, LimitOptions, limit_options, "limits",
                                  min_speed=min_speed)
    if iterations < 1:
        raise InputError(f"iterations must be >= 1, got {iterations}", field="--iterations")
    if not trajectory.has_reference:
        raise InputError("compensation needs the reference tool path columns "
                         "Px,Py,Pz,Oi,Oj,Ok (write the trajectory with 'precontour trajectory')",
                         field="Px")
    learner = learning_controller(servo, learning.controller)
    passes = learning.passes
    if passes and method == "contour":
        if not can_learn(servo, trajectory, whole=not limit.keep):
            passes = 0
        elif is_closed_loop(learner):
            notice(f"learning against controller {learner.name!r}, a transfer function "
                   "without drives or friction (learn_controller: the controller the drives "
                   "run, on the machine file's drives)")
    else:
        passes = 0
    learning = replace(learning, passes=passes, controller=learner.name)
    fits = dict(method=method, iterations=iterations, tol_linear=tol_linear,
                tol_rotary=tol_rotary)
    if limit.keep:
        limited = keep_limits(servo, trajectory, learn=learning, limits=limit,
                              pass_progress=progress, learning_progress=learning_progress,
                              **fits)
        result = limited.result
        return Compensation(commands=result.trajectory, reference=limited.reference,
                            before=result.before, after=result.after,
                            passes=result.iterations, slowdowns=limited.slowdowns,
                            learning=result.learning, within_limits=True,
                            left_out=limited.uncompensated, learning_controller=learner)
    # the final rest the corrections need to taper to zero at the programmed end point (the
    # limits' route gives it too, keep_limits)
    trajectory = with_final_rest(trajectory, required_final_rest(servo.models))
    machine_model = {}
    if passes:
        machine_model = dict(machine_actual=ensemble_actual(trajectory.t, servo.machine,
                                                            learner, learning.ensemble),
                             learning_passes=passes, learning_progress=learning_progress)
    result = compensate_program(servo, trajectory, progress=progress,
                                **fits, **machine_model)
    return Compensation(commands=result.trajectory, reference=trajectory, before=result.before,
                        after=result.after, passes=result.iterations, slowdowns=(),
                        learning=result.learning, within_limits=False,
                        learning_controller=learner)


def can_learn(servo: Servo, reference: Trajectory, *, whole: bool = False) -> bool:
    """Whether learning against the virtual machine can run on ``reference``; says why not,
    in one notice: the virtual machine runs at the servo period. Learning within the limits
    runs a trajectory of any length (segment by segment above
    :data:`~.pieces.AT_ONCE_SAMPLES` samples, :mod:`.segments`); ``whole``: learning that
    runs the whole trajectory at once (the unconstrained compensation's), refused above that
    many samples (compensated in pieces, linearly)."""
    machine = servo.machine
    if not machine.at_servo_period(reference.ts):
        notice(f"no learning: the trajectory's sample period {reference.ts:g} s is not the "
               f"servo period {machine.servo_period:g} s of the virtual machine")
        return False
    if whole and reference.n_samples > AT_ONCE_SAMPLES:
        notice(f"no learning: {reference.n_samples} samples are more than "
               f"{AT_ONCE_SAMPLES} (compensated in pieces)")
        return False
    return True


def learn_on_ensemble(servo: Servo, limited: LimitedCompensation, passes: int, *,
                      controller: str | None = None, ensemble: MachineEnsemble | None = None,
                      progress=None, planned: Trajectory | None = None
                      ) -> LimitedCompensation:
    """``limited`` improved by ``passes`` passes of learning within the servo's limits
    (:func:`~.within_limits.learn_within_limits`) against the draws of ``ensemble`` of the
    realistic virtual machine running ``controller`` (default: the servo's own;
    :func:`~precontour.simulation.ensemble.ensemble_actual`): every choice is taken on the
    worst draw, and the command kept is nowhere worse than the uncompensated one on every
    draw, in whole and block by block. Above :data:`~.pieces.AT_ONCE_SAMPLES` samples,
    segment by segment (:func:`~.segments.learn_by_segments`). ``planned``: the trajectory
    ``limited`` was compensated from; where learning keeps the uncompensated command
    everywhere, that trajectory is returned as it was planned, without the slow-downs made
    for the corrections (:func:`~.within_limits.planned_if_uncompensated`).
    """
    machine = servo.machine
    controller = servo.controller if controller is None else controller
    if limited.reference.n_samples > AT_ONCE_SAMPLES:
        learned = learn_by_segments(
            servo, limited,
            lambda t, start: ensemble_actual(t, machine, controller, ensemble, start=start),
            passes, progress=progress)
    else:
        actual = ensemble_actual(limited.reference.t, machine, controller, ensemble)
        learned = learn_within_limits(servo, limited, actual, passes, progress=progress)
    if planned is None:
        return learned
    return planned_if_uncompensated(servo, learned, planned)


def keep_limits(servo: Servo, trajectory: Trajectory, *, learn: int | LearningOptions = 0,
                limits: LimitOptions = LimitOptions(), method: str = "contour",
                iterations: int = 1, tol_linear: float | None = None,
                tol_rotary: float | None = None, progress=None, pass_progress=None,
                learning_progress=None) -> LimitedCompensation:
    """:func:`compensate`'s route within the axis limits, with what it took: compensate
    ``trajectory`` within the servo's limits (slowing it down locally, never below
    ``limits.min_speed``, and compensating again where needed;
    :func:`~.within_limits.compensate_within_limits` with ``method``, ``iterations``,
    ``tol_linear``, ``tol_rotary``), then, for ``learn`` passes, learn within them
    (:func:`learn_on_ensemble`, against the learning options' controller, default the
    servo's). ``progress(round, message)`` reports the compensation rounds,
    ``pass_progress(pass, summary)`` the first round's passes, ``learning_progress(label,
    summary)`` each command learning tries."""
    learning = learning_options(learn)
    # a final rest long enough for the corrections to taper to zero, so that the commands end
    # at the programmed end point (the controller holds the last command after them anyway)
    trajectory = with_final_rest(trajectory, required_final_rest(servo.models))
    limited = compensate_within_limits(servo, trajectory, progress=progress,
                                       min_speed=limits.min_speed, method=method,
                                       iterations=iterations, tol_linear=tol_linear,
                                       tol_rotary=tol_rotary, pass_progress=pass_progress)
    if learning.passes:
        limited = learn_on_ensemble(servo, limited, learning.passes,
                                    controller=learning.controller,
                                    ensemble=learning.ensemble, progress=learning_progress,
                                    planned=trajectory)
    return limited
