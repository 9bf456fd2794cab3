"""The library's entry points, each taking the servo system first.

A :class:`~precontour.machine.servo.Servo` is a machine with one chosen controller: its
kinematics, its drives, the controller's closed-loop error models (spec section 2), the axis
limits and the servo period, built once by :func:`load_servo`. Every job then takes it first,
as python-control's functions take their system first, and its strategy is a keyword, not
another function; each is the stage's own entry, gathered here
(:func:`compensate` is :func:`precontour.compensation.compensate`):

    servo = load_servo("zhang2013", "pid-high")
    traj = generate_trajectory(builtin_path("paper"), servo.machine)
    predicted = predict(servo, traj)                    # closed form, any length
    comp = compensate(servo, traj, learn=4)             # within the limits unless limits=False
    # or learn=LearningOptions(passes=4, controller=...), limits=LimitOptions(min_speed=0.5)
    sim = simulate(servo, comp.commands)                # realism="realistic" or "exact"
    errors = contour_errors(servo, comp.reference, sim)

Long programs are handled inside (in overlapping pieces above
:data:`~precontour.compensation.pieces.AT_ONCE_SAMPLES` samples, and learning within the
limits segment by segment).
"""

from __future__ import annotations

import numpy as np

from .compensation import METHODS, Compensation, compensate
from .errors import InputError
from .machine.servo import Servo, learning_controller, load_servo
from .prediction.contour import ContourErrors, ReferencePath
from .prediction.contour import contour_errors as _contour_errors
from .trajectory.sampled import Trajectory

__all__ = ["Servo", "load_servo", "predict", "compensate", "simulate", "contour_errors",
           "Compensation", "METHODS", "REALISM", "learning_controller", "plot_contour_errors"]

#: The virtual machine's settings by name (``simulate(..., realism=...)``): ``realistic`` is
#: the discrete controller at the servo period with Stribeck friction and its feed-forward;
#: ``exact`` the continuous linear loops the closed-form prediction models.
REALISM = {
    "realistic": dict(mode="discrete", friction=True, ff_friction=True),
    "exact": dict(mode="continuous", friction=False, ff_friction=False),
}


def predict(servo: Servo, trajectory: Trajectory, *, tol_linear: float | None = None,
            tol_rotary: float | None = None):
    """The tracking errors of every axis at every sample, in closed form (spec sections 3-5).

    Parameters
    ----------
    servo : Servo
        The machine and controller (its closed-loop error models).
    trajectory : Trajectory
        The axis commands; where it carries its reference, the contour errors of the
        predicted motion too. Long programs are predicted in overlapping pieces.
    tol_linear, tol_rotary : float, optional
        The spline fits' tolerances, mm and rad (default 1 um, 1 urad; spec section 3).

    Returns
    -------
    ProgramPrediction
        ``e`` (N, 5), ``contour`` (or None), ``summary()``, ``plot()``.
    """
    from .compensation.pieces import predict_program

    return predict_program(servo, trajectory, tol_linear=tol_linear, tol_rotary=tol_rotary)


def simulate(servo: Servo, commands, *, realism: str = "realistic",
             friction_scale=1.0, inertia_scale=1.0, damping_scale=1.0,
             encoder_resolution=None, encoder_offset=None, encoder_noise=None):
    """The drives of ``servo`` following ``commands`` on the virtual machine.

    Parameters
    ----------
    servo : Servo
        The machine and controller.
    commands : Trajectory, Compensation or ndarray, shape (N, 5)
        The axis commands (an array: sampled at the servo period).
    realism : str
        A key of :data:`REALISM`: ``"realistic"`` (discrete control at the servo period,
        friction and its feed-forward) or ``"exact"`` (the continuous linear loops the
        prediction models).
    friction_scale, inertia_scale, damping_scale, encoder_resolution, encoder_offset, encoder_noise
        A true machine's departures from the machine file, as for
        :func:`precontour.simulation.simulate`.

    Returns
    -------
    SimulationResult
        ``t``, ``q_cmd``, ``q_act``, ``e``, ``summary()``, ``plot()``.
    """
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
    """Contour errors of several actual motions against one reference, in one figure.

    Parameters
    ----------
    servo : Servo
        The machine (its kinematics) and controller.
    reference : Trajectory or ReferencePath
        The reference tool path.
    actuals : dict
        Label -> actual motion (a SimulationResult, or axis positions (N, 5)).
    axes : sequence of two matplotlib axes, optional
        Where to draw tip and orientation (default: a new figure).

    Returns
    -------
    matplotlib.figure.Figure
        Tip (um) and orientation (mrad) contour errors against time.
    """
    from .reports.plots import plot_contour_errors as plot

    return plot(np.asarray(reference.t), {label: contour_errors(servo, reference, actual)
                                for label, actual in actuals.items()}, axes=axes)


def contour_errors(servo: Servo, reference, actual) -> ContourErrors:
    """Contour errors of an actual motion against its reference (spec section 1).

    Parameters
    ----------
    servo : Servo
        The machine (its kinematics) and controller.
    reference : Trajectory or ReferencePath
        The reference tool path (a Trajectory with its columns ``Px..Ok``).
    actual : SimulationResult or ndarray, shape (N, 5)
        The actual motion: a simulation, or axis positions at the reference's samples.

    Returns
    -------
    ContourErrors
        Tool tip (mm) and orientation (rad) contour errors at every sample; ``.summary()``
        in um and mrad.
    """
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
