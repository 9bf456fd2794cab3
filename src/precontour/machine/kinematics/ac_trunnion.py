"""A-C trunnion table kinematics (spec section 1, paper Fig. 1, Eqs. 4-5).

The workpiece sits on a C table carried by a tilting A trunnion; X, Y, Z move the tool.
Inverse kinematics picks, along a path, the branch of (A, C) that keeps C continuous: C is
unwrapped, and where the A axis may tilt both ways the branch (-A, C + pi) is used when it avoids
a half-turn of C. At A = 0 (tool along z) C is undefined; it is interpolated from its
neighbours, so a path through the pole never produces a jump or a NaN.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: |(Oi, Oj)| below which C is treated as undefined (tool along z); the orientation error
#: this can cause is below this value in rad.
POLE_TOLERANCE = 1e-10


@dataclass(frozen=True)
class ACTrunnion:
    """A-C trunnion kinematics with offsets ``L_ac`` (A to C axis) and ``L_ty`` (A axis to
    tool), both in mm along z. ``a_min``/``a_max`` (rad) are the A axis travel, if limited."""

    L_ac: float
    L_ty: float
    a_min: float | None = None
    a_max: float | None = None

    @classmethod
    def from_table(cls, table) -> "ACTrunnion":
        kin = cls(L_ac=table.get_float("L_ac"), L_ty=table.get_float("L_ty"),
                  a_min=table.get_float("a_min", required=False),
                  a_max=table.get_float("a_max", required=False))
        if kin.a_min is not None and kin.a_max is not None and not kin.a_min < kin.a_max:
            raise table.error("a_max", f"must be > a_min ({kin.a_min:g}), got {kin.a_max:g}")
        return kin

    @property
    def negative_a_allowed(self) -> bool:
        return self.a_min is None or self.a_min < 0.0

    def forward(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Direct kinematics: axis positions ``q[..., 5]`` -> tool tip ``P[..., 3]`` (mm) and
        unit orientation ``O[..., 3]``, in the workpiece frame."""
        q = np.asarray(q, dtype=float)
        X, Y, Z, A, C = np.moveaxis(q, -1, 0)
        sA, cA, sC, cC = np.sin(A), np.cos(A), np.sin(C), np.cos(C)
        O = self.orientation(A, C)
        Px = -cC * X + sC * cA * Y + sA * sC * Z - sC * sA * self.L_ty
        Py = -sC * X - cC * cA * Y - sA * cC * Z + cC * sA * self.L_ty
        Pz = -sA * Y + cA * Z - cA * self.L_ty - self.L_ac
        return np.stack([Px, Py, Pz], axis=-1), O

    def inverse(self, P: np.ndarray, O: np.ndarray, c_near=None) -> np.ndarray:
        """Inverse kinematics: tool tip ``P[..., 3]`` and unit orientation ``O[..., 3]`` ->
        axis positions ``q[..., 5]``.

        Parameters
        ----------
        P, O : array_like
            Tool tip (mm) and unit tool orientation, workpiece frame. ``O`` must already be
            unit length (see :func:`precontour.machine.kinematics.normalize_orientations`).
        c_near : None, float or array_like
            ``None`` or a scalar: the samples are a path; C is unwrapped along it, starting
            at the branch nearest ``c_near`` (default: the branch with A >= 0). An array of the samples' shape:
            each sample independently takes the branch whose C is nearest its ``c_near``
            (used to keep a corrected command on the branch of its reference).
        """
        P = np.asarray(P, dtype=float)
        O = np.asarray(O, dtype=float)
        Oi, Oj, Ok = np.moveaxis(O, -1, 0)
        sin_a_abs = np.hypot(Oi, Oj)
        defined = sin_a_abs > POLE_TOLERANCE
        c_raw = np.arctan2(Oi, Oj)
        period = np.pi if self.negative_a_allowed else 2.0 * np.pi

        if c_near is None or np.ndim(c_near) == 0:
            c_start = None if c_near is None else float(c_near)
            C = _unwrap_path(c_raw, defined, period, c_start).reshape(c_raw.shape)
        else:
            c_near = np.broadcast_to(np.asarray(c_near, dtype=float), c_raw.shape)
            C = c_raw + period * np.round((c_near - c_raw) / period)
            C = np.where(defined, C, c_near)
        # C differs from atan2(Oi, Oj) by a multiple of pi; an odd multiple means A < 0.
        flipped = defined & (np.cos(C - c_raw) < 0.0)
        A = np.arctan2(sin_a_abs, Ok)  # = arccos(Ok), but accurate near the pole
        A = np.where(flipped, -A, A)

        return np.concatenate([self.linear_axes(P, A, C), np.stack([A, C], axis=-1)], axis=-1)

    def linear_axes(self, P: np.ndarray, A: np.ndarray, C: np.ndarray) -> np.ndarray:
        """X, Y, Z (mm, shape ``P.shape``) that put the tool tip at ``P`` when the rotary
        axes stand at ``A``, ``C`` (spec section 1, the inverse kinematics' last three rows)."""
        Px, Py, Pz = np.moveaxis(np.asarray(P, dtype=float), -1, 0)
        sA, cA, sC, cC = np.sin(A), np.cos(A), np.sin(C), np.cos(C)
        X = -cC * Px - sC * Py
        Y = cA * sC * Px - cA * cC * Py - sA * Pz - sA * self.L_ac
        Z = sA * sC * Px - sA * cC * Py + cA * Pz + cA * self.L_ac + self.L_ty
        return np.stack([X, Y, Z], axis=-1)

    def orientation(self, A: np.ndarray, C: np.ndarray) -> np.ndarray:
        """Unit tool orientation O[..., 3] for rotary axes A, C (spec section 1, first row)."""
        sA = np.sin(A)
        return np.stack([sA * np.sin(C), sA * np.cos(C), np.cos(A)], axis=-1)

    def orientation_jacobian(self, A: np.ndarray, C: np.ndarray) -> np.ndarray:
        """dO/d(A, C), shape ``A.shape + (3, 2)``; the C column vanishes at the pole A = 0."""
        sA, cA, sC, cC = np.sin(A), np.cos(A), np.sin(C), np.cos(C)
        d_a = np.stack([cA * sC, cA * cC, -sA], axis=-1)
        d_c = np.stack([sA * cC, -sA * sC, np.zeros_like(sA)], axis=-1)
        return np.stack([d_a, d_c], axis=-1)


def _unwrap_path(c_raw: np.ndarray, defined: np.ndarray, period: float,
                 c_start: float | None) -> np.ndarray:
    """Unwrap C along a path (1-D), filling undefined samples (tool along z) by linear
    interpolation between their defined neighbours, held constant at the ends."""
    c_raw = np.atleast_1d(c_raw)
    defined = np.atleast_1d(defined)
    if c_raw.ndim != 1:
        raise ValueError("path inverse kinematics needs 1-D samples (P, O of shape (N, 3))")
    index = np.flatnonzero(defined)
    if index.size == 0:
        return np.full(c_raw.shape, 0.0 if c_start is None else c_start)
    c_defined = np.unwrap(c_raw[index], period=period)
    if c_start is not None:
        c_defined += period * np.round((c_start - c_defined[0]) / period)
    if index.size == c_raw.size:
        return c_defined
    return np.interp(np.arange(c_raw.size), index, c_defined)
