"""Axis controllers named in a machine file, and their linear closed-loop error models.

A :class:`Controller` is a named set of five per-axis controllers of one ``type``. Each
controller type registers a parser in :data:`CONTROLLER_TYPES`; linear types also give a
:class:`~precontour.drives.LinearErrorModel` per axis for the closed-form predictor.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

from ._config import ConfigTable
from .drives import AXES, Drive, LinearErrorModel, pid_error_model
from .errors import UnsupportedControllerError


@dataclass(frozen=True)
class PIDGains:
    """PID position controller of one axis: u = kp e + ki int(e) + kd e' (volts).

    Gains per mm (linear axes) or per rad (rotary axes), as in the paper's Table 1.
    """

    kp: float
    ki: float
    kd: float

    def error_model(self, drive: Drive) -> LinearErrorModel:
        return pid_error_model(drive, self.kp, self.ki, self.kd)

    @classmethod
    def from_table(cls, table: ConfigTable) -> "PIDGains":
        gains = cls(kp=table.get_float("kp", above=0.0),
                    ki=table.get_float("ki", minval=0.0),
                    kd=table.get_float("kd", minval=0.0))
        table.finish()
        return gains


@dataclass(frozen=True)
class Controller:
    """A named controller set: one per-axis controller for each of X, Y, Z, A, C."""

    name: str
    type: str
    axes: tuple

    @property
    def is_linear(self) -> bool:
        return all(hasattr(axis, "error_model") for axis in self.axes)

    def error_models(self, drives: tuple[Drive, ...]) -> tuple[LinearErrorModel, ...]:
        """Closed-loop error transfer functions of the five axes (stable, else an error)."""
        if not self.is_linear:
            raise UnsupportedControllerError(
                f"controller {self.name!r} (type {self.type!r}) is nonlinear; the closed-form "
                "predictor needs a linear controller")
        models = tuple(ctrl.error_model(drive) for ctrl, drive in zip(self.axes, drives))
        for model in models:
            model.check_stable()
        return models


def _parse_per_axis(gains_cls) -> Callable[[str, ConfigTable], Controller]:
    def parse(name: str, table: ConfigTable) -> Controller:
        kind = table.get_str("type")
        axes = tuple(gains_cls.from_table(table.get_table(axis)) for axis in AXES)
        table.finish()
        return Controller(name=name, type=kind, axes=axes)
    return parse


CONTROLLER_TYPES: dict[str, Callable[[str, ConfigTable], Controller]] = {
    "pid": _parse_per_axis(PIDGains),
}
