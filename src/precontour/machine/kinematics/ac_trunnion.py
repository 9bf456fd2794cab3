"""A-C trunnion table kinematics of Zhang et al. (spec section 1, paper Fig. 1, Eqs. 4-5),
machine-file type ``ac-trunnion``.

The workpiece sits on a C table carried by a tilting A trunnion; X, Y, Z move the tool. ``L_ac``
is the offset from the A to the C axis and ``L_ty`` from the A axis to the tool, both along z.
The tool axis is O = dP/dZ = (sinA sinC, -sinA cosC, cosA), C = atan2(Oi, -Oj): the paper's
printed Eq. 5 has +sinA cosC, the mirror image of what its own tip equations give (spec
section 1). Inverse kinematics along a path is :class:`~._trunnion.TrunnionKinematics`'s:
C unwrapped, the pole A = 0 bridged, the A sign chosen within ``a_min``/``a_max``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._trunnion import POLE_TOLERANCE, TiltAboutX, TrunnionKinematics, rotary_pair

__all__ = ["ACTrunnion", "POLE_TOLERANCE"]


@dataclass(frozen=True)
class ACTrunnion(TiltAboutX, TrunnionKinematics):
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
        unit orientation ``O[..., 3]``, in the workpiece frame (spec section 1)."""
        q = np.asarray(q, dtype=float)
        X, Y, Z, A, C = np.moveaxis(q, -1, 0)
        sA, cA, sC, cC = np.sin(A), np.cos(A), np.sin(C), np.cos(C)
        Px = -cC * X + sC * cA * Y + sA * sC * Z - sC * sA * self.L_ty
        Py = -sC * X - cC * cA * Y - sA * cC * Z + cC * sA * self.L_ty
        Pz = -sA * Y + cA * Z - cA * self.L_ty - self.L_ac
        return np.stack([Px, Py, Pz], axis=-1), self.orientation(A, C)

    def linear_axes(self, P: np.ndarray, A, C=None) -> np.ndarray:
        """X, Y, Z (mm, shape ``P.shape``) that put the tool tip at ``P`` when the rotary
        axes stand at ``A``, ``C`` (or ``linear_axes(P, rotary[..., 2])``); spec section 1,
        the inverse kinematics' last three rows."""
        A, C = rotary_pair(A, C)
        Px, Py, Pz = np.moveaxis(np.asarray(P, dtype=float), -1, 0)
        sA, cA, sC, cC = np.sin(A), np.cos(A), np.sin(C), np.cos(C)
        X = -cC * Px - sC * Py
        Y = cA * sC * Px - cA * cC * Py - sA * Pz - sA * self.L_ac
        Z = sA * sC * Px - sA * cC * Py + cA * Pz + cA * self.L_ac + self.L_ty
        return np.stack([X, Y, Z], axis=-1)
