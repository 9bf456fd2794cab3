"""Time-stamped five-axis trajectories: the object every stage after path planning passes on.

A :class:`Trajectory` holds axis commands q(t) = [X, Y, Z, A, C] sampled uniformly at the servo
period, and optionally the reference tool tip P(t) and orientation O(t) they were made from
(needed for contour errors) and, for a trajectory made from an NC program, the source line of
the block executing at each sample. Compensation returns a Trajectory too, with new q and the same
reference.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..machine.drives import AXES
from ..errors import InputError

#: Relative spread of time steps tolerated as "uniform" (CSV round-off of t).
UNIFORM_TIME_RTOL = 1e-6

#: Fewest samples of a trajectory file: the reference curves are quintic interpolating
#: splines (6 samples) and the spline fit needs 4; one number for every command.
MIN_SAMPLES = 6


@dataclass(frozen=True)
class Trajectory:
    """Uniformly sampled axis commands with optional reference tool tip and orientation.

    Attributes
    ----------
    t : ndarray, shape (N,)
        Time stamps in s, uniformly spaced.
    q : ndarray, shape (N, 5)
        Axis commands X, Y, Z (mm), A, C (rad).
    P : ndarray, shape (N, 3), optional
        Reference tool tip in the workpiece frame, mm.
    O : ndarray, shape (N, 3), optional
        Reference unit tool orientation in the workpiece frame.
    line : ndarray of int, shape (N,), optional
        Source line of the NC-program block executing at each sample (trajectories made
        from a program); kept by :meth:`with_axes`.
    """

    t: np.ndarray
    q: np.ndarray
    P: np.ndarray | None = None
    O: np.ndarray | None = None
    line: np.ndarray | None = None

    def __post_init__(self):
        t = np.asarray(self.t, dtype=float)
        q = np.asarray(self.q, dtype=float)
        if t.ndim != 1 or q.shape != (t.size, len(AXES)):
            raise ValueError(f"Trajectory needs t of shape (N,) and q of shape (N, 5); got "
                             f"{t.shape} and {q.shape}")
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "q", q)
        for name in ("P", "O"):
            value = getattr(self, name)
            if value is not None:
                value = np.asarray(value, dtype=float)
                if value.shape != (t.size, 3):
                    raise ValueError(f"Trajectory.{name} must have shape (N, 3), got {value.shape}")
                object.__setattr__(self, name, value)
        if self.line is not None:
            line = np.asarray(self.line)
            if line.shape != t.shape:
                raise ValueError(f"Trajectory.line must have shape (N,), got {line.shape}")
            object.__setattr__(self, "line", line.astype(np.int64, copy=False))
        if (self.P is None) != (self.O is None):
            raise ValueError("Trajectory needs both P and O, or neither")

    @property
    def n_samples(self) -> int:
        return self.t.size

    @property
    def ts(self) -> float:
        """Sampling period in s."""
        return float((self.t[-1] - self.t[0]) / (self.t.size - 1)) if self.t.size > 1 else 0.0

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0])

    @property
    def has_reference(self) -> bool:
        return self.P is not None

    def axis(self, name: str) -> np.ndarray:
        return self.q[:, AXES.index(name)]

    def with_axes(self, q: np.ndarray) -> "Trajectory":
        """The same trajectory (time stamps, reference) with new axis commands."""
        return replace(self, q=q)


def check_uniform_time(t: np.ndarray, *, source: str | None = None, first_row: int = 1,
                       min_samples: int = 2) -> float:
    """Check that ``t`` is finite, strictly increasing and uniformly spaced; return the step.

    Raises :class:`InputError` naming the first offending row (``first_row`` is the row
    number of ``t[0]`` in the file). Steps are compared with the first one, so a step that
    changes at some row is reported at that row.
    """
    t = np.asarray(t, dtype=float)
    if t.size < min_samples:
        raise InputError(f"too few samples: {t.size}, need at least {min_samples}",
                         source=source, field="t")
    bad = ~np.isfinite(t)
    if bad.any():
        row = int(np.flatnonzero(bad)[0])
        raise InputError(f"time is not finite ({float(t[row])})", source=source,
                         row=row + first_row, field="t")
    dt = np.diff(t)
    nonincreasing = dt <= 0
    if nonincreasing.any():
        row = int(np.flatnonzero(nonincreasing)[0]) + 1
        raise InputError(f"time is not increasing ({float(t[row - 1])!r} then "
                         f"{float(t[row])!r})",
                         source=source, row=row + first_row, field="t")
    # Round-off of printed time stamps grows with |t|; the step is judged against it too.
    slack = UNIFORM_TIME_RTOL * dt[0] + 1e-12 + 4 * np.spacing(np.abs(t[1:]).max())
    off = np.abs(dt - dt[0]) > slack
    if off.any():
        row = int(np.flatnonzero(off)[0]) + 1
        raise InputError(f"time is not uniformly sampled (step {float(dt[row - 1]):.9g} s, "
                         f"the first step is {float(dt[0]):.9g} s)", source=source,
                         row=row + first_row, field="t")
    return float((t[-1] - t[0]) / (t.size - 1))
