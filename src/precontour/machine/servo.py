"""The servo system: a machine with one chosen controller, made once.

A :class:`Servo` holds the machine's kinematics, its drives, the chosen controller's
closed-loop error models (spec section 2), the axis limits and the servo period, built once
by :func:`load_servo`. Every job of the library takes it first, as python-control's
functions take their system first; no stage builds error models itself.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ..errors import warn_former

from .limits import AxisLimits
from .machine_file import Machine, load_machine

__all__ = ["Servo", "load_servo", "learning_controller"]


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
    axis_limits : AxisLimits
        The axis limits (travel, velocity, acceleration, jerk).
    """

    machine: Machine
    controller: str
    models: tuple
    axis_limits: AxisLimits

    @property
    def limits(self) -> AxisLimits:
        """The former name of :attr:`axis_limits` ("limits" is also compensation's
        :class:`~precontour.compensation.LimitOptions`), with a DeprecationWarning."""
        warn_former("Servo.limits", "use Servo.axis_limits")
        return self.axis_limits

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
    """The servo system of a machine running one controller, made once.

    Parameters
    ----------
    machine : str, Path or Machine
        A built-in machine's name, a machine file, or a loaded
        :class:`~precontour.machine.Machine`.
    controller : str
        The name of one of its controllers. A controller without closed-loop models (a
        nonlinear one) is refused here, with the file and the name.

    Returns
    -------
    Servo
        The machine, the controller's closed-loop error models (spec section 2), the axis
        limits and the servo period.
    """
    machine_obj = machine if isinstance(machine, Machine) else load_machine(machine)
    models = machine_obj.error_models(controller)
    return Servo(machine=machine_obj, controller=controller, models=tuple(models),
                 axis_limits=AxisLimits.from_machine(machine_obj))


def learning_controller(servo: Servo, name: str | None = None):
    """The controller the virtual machine runs when compensation learns: ``name`` when given,
    else a closed loop's (``tf``, e.g. identified) ``base`` controller, else the servo's own
    controller (a :class:`~precontour.machine.controllers.Controller`)."""
    from .controllers import is_closed_loop

    machine = servo.machine
    if name is not None:
        return machine.controller(name)
    controller = machine.controller(servo.controller)
    if is_closed_loop(controller) and controller.base is not None:
        return machine.controller(controller.base)
    return controller
