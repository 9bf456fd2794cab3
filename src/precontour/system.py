"""The servo system, made once, and the library's entry points, each taking it first.

A :class:`Servo` is a machine with one chosen controller: its kinematics, its drives, the
controller's closed-loop error models (spec section 2), the axis limits and the servo period,
built once by :func:`load_servo`. Every job then takes it first, as python-control's functions
take their system first, and its strategy is a keyword, not another function:

    servo = load_servo("zhang2013", "pid-high")
    traj = generate_trajectory(builtin_path("paper"), servo.machine)
    predicted = predict(servo, traj)                    # closed form, any length
    comp = compensate(servo, traj, learn=4)             # within the limits unless limits=False
    # or learn=LearningOptions(passes=4, controller=...), limits=LimitOptions(min_speed=0.5)
    sim = simulate(servo, comp.commands)                # realism="realistic" or "exact"
    errors = contour_errors(servo, comp.reference, sim)

Long programs are handled inside (in overlapping pieces above
:data:`~precontour.compensation.pieces.AT_ONCE_SAMPLES` samples, and learning within the
limits segment by segment); the stage functions these
call stay where they are, for the stages themselves and the command line.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from .errors import InputError
from .machine import Machine, load_machine
from .options import (LearningOptions, LimitOptions, learning_options, limit_options,
                      with_former_spellings)
from .prediction.contour import ContourErrors, ReferencePath
from .prediction.contour import contour_errors as _contour_errors
from .trajectory.limits import AxisLimits
from .trajectory.retime import Slowdown
from .trajectory.sampled import Trajectory

__all__ = ["Servo", "load_servo", "predict", "compensate", "simulate", "contour_errors",
           "Compensation", "REALISM", "learning_controller", "plot_contour_errors"]

#: The virtual machine's settings by name (``simulate(..., realism=...)``): ``realistic`` is
#: the discrete controller at the servo period with Stribeck friction and its feed-forward;
#: ``exact`` the continuous linear loops the closed-form prediction models.
REALISM = {
    "realistic": dict(mode="discrete", friction=True, ff_friction=True),
    "exact": dict(mode="continuous", friction=False, ff_friction=False),
}

#: Compensation methods (:func:`compensate`).
METHODS = ("contour", "tracking")


@dataclass(frozen=True)
class Servo:
    """A machine with one chosen controller, made once (:func:`load_servo`).

    Attributes
    ----------
    machine : Machine
        The machine file's contents: kinematics, drives, controllers, servo period.
    controller : str
        The chosen controller's name.
    models : tuple of LinearErrorModel
        The controller's closed-loop error models of the five axes (spec section 2).
    limits : AxisLimits
        The axis limits (travel, velocity, acceleration, jerk).
    """

    machine: Machine
    controller: str
    models: tuple
    limits: AxisLimits

    @property
    def kinematics(self):
        return self.machine.kinematics

    @property
    def drives(self):
        return self.machine.drives

    @property
    def servo_period(self) -> float:
        return self.machine.servo_period

    @property
    def axis_names(self) -> tuple[str, ...]:
        return tuple(self.machine.axis_names)

    def __repr__(self) -> str:
        return (f"Servo(machine={self.machine.name!r}, controller={self.controller!r}, "
                f"servo_period={self.servo_period:g})")


def load_servo(machine: str | Path | Machine, controller: str) -> Servo:
    """The :class:`Servo` of ``machine`` (a built-in name, a machine file or a
    :class:`~precontour.machine.Machine`) running ``controller``. A controller without
    closed-loop models (a nonlinear one) is refused here, with the file and the name."""
    machine_obj = machine if isinstance(machine, Machine) else load_machine(machine)
    models = machine_obj.error_models(controller)
    return Servo(machine=machine_obj, controller=controller, models=tuple(models),
                 limits=AxisLimits.from_machine(machine_obj))


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
        from .reports.plots import plot_contour_errors

        return plot_contour_errors(self.reference.t, {"uncompensated": self.before,
                                                      "compensated": self.after},
                                   title="predicted contour errors", axes=axes)


def predict(servo: Servo, trajectory: Trajectory):
    """The tracking errors e(t) of every axis at every sample, in closed form (spec sections
    3-5), and the contour errors where ``trajectory`` carries its reference; returns a
    :class:`~precontour.compensation.pieces.ProgramPrediction` (``e``, ``contour``)."""
    from .compensation.pieces import predict_program

    return predict_program(trajectory, servo.models,
                           servo.kinematics if trajectory.has_reference else None)


def compensate(servo: Servo, trajectory: Trajectory, *, method: str = "contour",
               limits: bool | LimitOptions = True, learn: int | LearningOptions = 0,
               iterations: int = 1, tol_linear: float | None = None,
               tol_rotary: float | None = None, progress=None, learning_progress=None,
               min_speed: float | None = None, ensemble=None,
               learn_controller: str | None = None) -> Compensation:
    """Pre-compensated commands for ``trajectory`` (which must carry its reference).

    ``method``: ``"contour"`` (the paper's, spec section 6) or ``"tracking"`` (each axis's
    own predicted tracking error added). ``limits`` (:class:`~precontour.options.
    LimitOptions`, or ``True`` / ``False`` for its ``keep``): keep the machine's axis
    limits, slowing the motion down locally (never below its ``min_speed`` of the speed)
    and compensating again where needed, as ``precontour run`` and ``compensate`` do;
    ``False`` gives the unconstrained commands, which may break them. ``learn``
    (:class:`~precontour.options.LearningOptions`, or a number of passes): learning
    (contour method) against the realistic virtual machine running the options'
    ``controller`` (default: :func:`learning_controller`), every decision on the worst of
    its ensemble's draws (default :class:`~precontour.simulation.ensemble.MachineEnsemble`),
    the command kept nowhere worse than uncompensated (within the limits, segment by segment
    above :data:`~precontour.compensation.pieces.AT_ONCE_SAMPLES` samples). Learning is
    skipped, with a one-line notice, where it cannot run: a trajectory not sampled at the
    servo period, or, with the limits not kept, one longer than that (compensated in
    pieces). ``tol_linear``, ``tol_rotary``: the spline fits' tolerances (defaults: the
    compensation's). ``progress(pass, summary)``: each pass of the (first) compensation;
    ``learning_progress(label, summary)``: each command learning tries. ``min_speed``,
    ``ensemble``, ``learn_controller``: the former spellings of ``LimitOptions.min_speed``,
    ``LearningOptions.ensemble`` and ``LearningOptions.controller``, kept (beside a plain
    ``limits`` / ``learn``)."""
    from .errors import notice
    from .machine.controllers import is_closed_loop
    from .workflow import can_learn

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
    learn = learning.passes
    if learn and method == "contour":
        if not can_learn(trajectory, servo.machine, whole=not limit.keep):
            learn = 0
        elif is_closed_loop(learner):
            notice(f"learning against controller {learner.name!r}, a transfer function "
                   "without drives or friction (learn_controller: the controller the drives "
                   "run, on the machine file's drives)")
    else:
        learn = 0
    learning = replace(learning, passes=learn, controller=learner.name)
    fits = dict(method=method, iterations=iterations, tol_linear=tol_linear,
                tol_rotary=tol_rotary)
    if limit.keep:
        from .workflow import compensate_keeping_limits

        limited = compensate_keeping_limits(trajectory, servo.machine, servo.controller,
                                            learn=learning, limits=limit,
                                            pass_progress=progress,
                                            learning_progress=learning_progress, **fits)
        result = limited.result
        return Compensation(commands=result.trajectory, reference=limited.reference,
                            before=result.before, after=result.after,
                            passes=result.iterations, slowdowns=limited.slowdowns,
                            learning=result.learning, within_limits=True,
                            left_out=limited.uncompensated, learning_controller=learner)
    from .compensation.pieces import compensate_program
    from .compensation.programmed_end import required_final_rest, with_final_rest

    # the final rest the corrections need to taper to zero at the programmed end point (the
    # limits' route gives it too, compensate_keeping_limits)
    trajectory = with_final_rest(trajectory, required_final_rest(servo.models))
    machine_model = {}
    if learn:
        from .simulation.ensemble import ensemble_actual

        machine_model = dict(machine_actual=ensemble_actual(trajectory.t, servo.machine,
                                                            learner, learning.ensemble),
                             learning_passes=learn, learning_progress=learning_progress)
    result = compensate_program(trajectory, servo.kinematics, servo.models, progress=progress,
                                **fits, **machine_model)
    return Compensation(commands=result.trajectory, reference=trajectory, before=result.before,
                        after=result.after, passes=result.iterations, slowdowns=(),
                        learning=result.learning, within_limits=False,
                        learning_controller=learner)


def learning_controller(servo: Servo, name: str | None = None):
    """The controller the virtual machine runs when compensation learns: ``name`` when given,
    else a closed loop's (``tf``, e.g. identified) ``base`` controller, else the servo's own
    controller (a :class:`~precontour.machine.controllers.Controller`)."""
    from .machine.controllers import is_closed_loop

    machine = servo.machine
    if name is not None:
        return machine.controller(name)
    controller = machine.controller(servo.controller)
    if is_closed_loop(controller) and controller.base is not None:
        return machine.controller(controller.base)
    return controller


def simulate(servo: Servo, commands, *, realism: str = "realistic",
             friction_scale=1.0, inertia_scale=1.0, damping_scale=1.0,
             encoder_resolution=None, encoder_offset=None, encoder_noise=None):
    """The drives of ``servo`` following ``commands`` (a Trajectory, a :class:`Compensation`
    or an (N, 5) array sampled at the servo period) on the virtual machine; ``realism``: a
    key of :data:`REALISM`. The rest: a true machine's departures from the machine file
    (``friction_scale``, ``inertia_scale``, ``damping_scale``, the encoder's; as for
    :func:`precontour.simulation.simulate`). Returns a
    :class:`~precontour.simulation.SimulationResult`."""
    from .simulation.virtual_machine import simulate as _simulate

    if realism not in REALISM:
        raise InputError(f"unknown realism {realism!r}; choose one of {', '.join(REALISM)}",
                         field="realism")
    t, q = _time_and_commands(servo, commands)
    return _simulate(t, q, servo.machine, servo.controller, **REALISM[realism],
                     friction_scale=friction_scale, inertia_scale=inertia_scale,
                     damping_scale=damping_scale, encoder_resolution=encoder_resolution,
                     encoder_offset=encoder_offset, encoder_noise=encoder_noise)


def plot_contour_errors(servo: Servo, reference, actuals: dict, *, axes=None):
    """Contour errors of several actual motions (label -> SimulationResult or axis positions)
    against ``reference``, tip and orientation against time, in one figure; returns it."""
    from .reports.plots import plot_contour_errors as plot

    return plot(np.asarray(reference.t), {label: contour_errors(servo, reference, actual)
                                for label, actual in actuals.items()}, axes=axes)


def contour_errors(servo: Servo, reference, actual) -> ContourErrors:
    """Contour errors (tool tip, mm; orientation, rad; spec section 1) of the actual motion
    ``actual`` (a SimulationResult, or axis positions (N, 5) at the reference's samples)
    against ``reference`` (a Trajectory with its reference, or a ReferencePath)."""
    path = reference if isinstance(reference, ReferencePath) else \
        ReferencePath.from_trajectory(reference)
    q_act = getattr(actual, "q_act", actual)
    return _contour_errors(path, np.asarray(q_act, dtype=float), servo.kinematics)


def _time_and_commands(servo: Servo, commands) -> tuple[np.ndarray, np.ndarray]:
    if isinstance(commands, Compensation):
        commands = commands.commands
    if isinstance(commands, Trajectory):
        return commands.t, commands.q
    q = np.asarray(commands, dtype=float)
    return np.arange(q.shape[0]) * servo.servo_period, q
