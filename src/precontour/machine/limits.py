"""The machine's axis limits as a machine file gives them.

:class:`AxisLimits` gathers each drive's travel (``p_min``/``p_max``, and the kinematics'
tilt travel ``tilt_limits``; a tilt axis never travels beyond +-180 deg, :data:`TILT_TRAVEL`,
as the G-code reader holds too), velocity, acceleration and jerk limits (``v_max``,
``a_max``, ``j_max``); ``inf`` where none is given. Whether commands keep them is checked by
:mod:`precontour.trajectory.limits`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .drives import AXES

__all__ = ["AxisLimits", "TILT_TRAVEL", "axis_limits"]

#: Largest |tilt| (rad) on every machine, whatever its file says: half a turn either way (a
#: tilt axis beyond it is no tilt; the G-code reader refuses programs beyond it too).
TILT_TRAVEL = np.pi


def axis_limits(machine) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Velocity, acceleration and jerk limits of the five drives, shape (5,) each (mm or rad
    per s, s^2, s^3); ``inf`` where the machine file gives none."""
    get = lambda name: np.array([np.inf if getattr(d, name) is None else getattr(d, name)  # noqa: E731
                                 for d in machine.drives], dtype=float)
    return get("v_max"), get("a_max"), get("j_max")


@dataclass(frozen=True)
class AxisLimits:
    """Per-axis limits, shape (5,) each, mm or rad (per s, s^2, s^3); ``inf`` where none;
    ``axis_names``: the machine's letters of the five slots, for messages."""

    position_min: np.ndarray
    position_max: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    jerk: np.ndarray
    axis_names: tuple[str, ...] = AXES

    @classmethod
    def from_machine(cls, machine) -> "AxisLimits":
        get = lambda name, default: np.array(  # noqa: E731
            [default if getattr(d, name, None) is None else getattr(d, name)
             for d in machine.drives], dtype=float)
        low, high = get("p_min", -np.inf), get("p_max", np.inf)
        tilt_low, tilt_high = getattr(machine.kinematics, "tilt_limits", (None, None))
        low[3] = max(low[3], -TILT_TRAVEL if tilt_low is None else tilt_low, -TILT_TRAVEL)
        high[3] = min(high[3], TILT_TRAVEL if tilt_high is None else tilt_high, TILT_TRAVEL)
        v, acc, j = axis_limits(machine)
        return cls(position_min=low, position_max=high, velocity=v, acceleration=acc, jerk=j,
                   axis_names=tuple(getattr(machine, "axis_names", AXES)))
