"""Whether sampled axis commands keep the machine's axis limits.

The limits themselves (:class:`~precontour.machine.limits.AxisLimits`, re-exported here) are
the machine file's: travel, velocity, acceleration and jerk.
:func:`check_travel` names the first row of commands outside a travel.
:func:`check_limits` measures commands with finite differences at the sampling period (first,
second and third differences, as :func:`~precontour.trajectory.generate.summarize` does) and
returns, besides the worst excess of each axis and quantity, the time-stretch factor each
sample needs: slowing the motion by a factor rho divides velocity by rho, acceleration by
rho^2 and jerk by rho^3, so a quantity |x| over its limit L asks for rho = (|x| / L)^(1/order).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..machine.drives import AXES
from ..machine.limits import TILT_TRAVEL, AxisLimits, axis_limits  # noqa: F401 (re-exported)
from .feedplan import CHECK_RTOL

QUANTITIES: tuple[str, ...] = ("position", "velocity", "acceleration", "jerk")
_UNITS = {"position": "", "velocity": "/s", "acceleration": "/s^2", "jerk": "/s^3"}
#: Letters of rotary axes on any machine (slots 3 and 4 are rotary on every type).
ROTARY_LETTERS = ("A", "B", "C")


@dataclass(frozen=True)
class LimitExcess:
    """The worst excess of one axis over one limit: value, limit, when (s) and which sample."""

    axis: str
    quantity: str
    value: float
    limit: float
    time: float
    sample: int

    def format(self) -> str:
        unit = ("rad" if self.axis in ROTARY_LETTERS else "mm") + _UNITS[self.quantity]
        if self.quantity == "position":
            return (f"{self.axis} {self.quantity} {self.value:.6g} {unit} outside its travel "
                    f"(limit {self.limit:.6g}) at t = {self.time:.4f} s")
        return (f"{self.axis} {self.quantity} {self.value:.6g} {unit} > limit {self.limit:.6g} "
                f"({100 * self.value / self.limit:.1f} %) at t = {self.time:.4f} s")


@dataclass(frozen=True)
class LimitCheck:
    """What :func:`check_limits` found.

    Attributes
    ----------
    stretch : ndarray, shape (N,)
        Largest time-stretch factor any velocity, acceleration or jerk limit asks for at each
        sample ((|x| / L)^(1/order) of the differences that touch the sample); <= 1 is within.
    ratio : ndarray, shape (N,)
        Largest |x| / L at each sample, any order: the stretch needed where a quantity falls
        only like 1/rho when slowed by rho (a kink of the commands: a jump of velocity gives
        acceleration and jerk differences that fall like 1/rho, not 1/rho^2 or 1/rho^3).
    excesses : tuple of LimitExcess
        The worst excess of each axis and quantity beyond its limit (relative tolerance
        ``CHECK_RTOL``), position first.
    peaks : dict
        ``"velocity"``, ``"acceleration"``, ``"jerk"``: peak |difference| per axis, (5,).
    """

    stretch: np.ndarray
    ratio: np.ndarray
    excesses: tuple[LimitExcess, ...]
    peaks: dict

    @property
    def ok(self) -> bool:
        return not self.excesses

    @property
    def position_ok(self) -> bool:
        return not any(e.quantity == "position" for e in self.excesses)

    def format(self) -> str:
        return "within the machine's limits" if self.ok else "; ".join(
            e.format() for e in self.excesses)


def check_limits(q: np.ndarray, ts: float, limits: AxisLimits, *, t0: float = 0.0
                 ) -> LimitCheck:
    """Check commands ``q`` (N, 5) sampled every ``ts`` s (first at ``t0``) against
    ``limits``; see :class:`LimitCheck`."""
    q = np.asarray(q, dtype=float)
    n = q.shape[0]
    stretch = np.zeros(n)
    worst = np.zeros(n)
    excesses: list[LimitExcess] = []
    tol = 1.0 + CHECK_RTOL

    below = q < limits.position_min
    above = q > limits.position_max
    for i, axis in enumerate(limits.axis_names):
        for mask, bound in ((below[:, i], limits.position_min[i]),
                            (above[:, i], limits.position_max[i])):
            if mask.any():
                k = int(np.argmax(np.where(mask, np.abs(q[:, i] - bound), -1.0)))
                excesses.append(LimitExcess(axis, "position", float(q[k, i]), float(bound),
                                            t0 + k * ts, k))

    peaks = {}
    for order, name, limit in ((1, "velocity", limits.velocity),
                               (2, "acceleration", limits.acceleration),
                               (3, "jerk", limits.jerk)):
        if n <= order:
            peaks[name] = np.zeros(len(AXES))
            continue
        value = np.abs(np.diff(q, order, axis=0)) / ts**order   # (N - order, 5)
        peaks[name] = value.max(axis=0)
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = value / limit
        for i, axis in enumerate(limits.axis_names):
            k = int(np.argmax(ratio[:, i]))
            if ratio[k, i] > tol:
                # Difference k spans samples k .. k + order; name its middle.
                sample = k + order // 2
                excesses.append(LimitExcess(axis, name, float(value[k, i]), float(limit[i]),
                                            t0 + (k + 0.5 * order) * ts, sample))
        largest = np.max(ratio, axis=1)
        need = largest ** (1.0 / order)
        # A difference touches samples k .. k + order: each of them gets its need.
        for shift in range(order + 1):
            part = slice(shift, shift + need.size)
            np.maximum(stretch[part], need, out=stretch[part])
            np.maximum(worst[part], largest, out=worst[part])
    return LimitCheck(stretch=stretch, ratio=worst, excesses=tuple(excesses), peaks=peaks)


def check_travel(q: np.ndarray, limits: AxisLimits, *, source: str | None = None,
                 axis_names=AXES, first_row: int = 1) -> None:
    """Raise :class:`~precontour.errors.InputError` naming the first row (``first_row`` for
    the first sample) and axis of commands ``q`` (N, 5) outside the axis's travel, with the
    value and the travel; for a rotary axis whose values would fit in degrees, say that
    degrees seem to have been given where radians are expected."""
    q = np.asarray(q, dtype=float)
    out = (q < limits.position_min) | (q > limits.position_max)
    if not out.any():
        return
    rows = np.flatnonzero(out.any(axis=1))
    k = int(rows[0])
    i = int(np.flatnonzero(out[k])[0])
    name, value = axis_names[i], float(q[k, i])
    low, high = float(limits.position_min[i]), float(limits.position_max[i])
    rotary = i >= 3            # slots 3 and 4 are rotary on every machine
    unit = "rad" if rotary else "mm"
    message = (f"{name} = {value:.6g} {unit} is outside the {name} axis's travel "
               f"[{low:.6g}, {high:.6g}] {unit}")
    if rotary:
        message += f" ({np.degrees(low):.6g} to {np.degrees(high):.6g} deg)"
        column = np.radians(q[:, i])
        if np.all((column >= low) & (column <= high)):
            message += (f"; the file gives {name} in rad: were degrees given? ({value:.6g} deg "
                        f"would be {np.radians(value):.6g} rad)")
    if rows.size > 1:
        message += f"; {rows.size} rows are outside"
    raise InputError(message, source=source, row=k + first_row, field=name)
