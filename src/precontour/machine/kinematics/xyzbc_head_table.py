"""Tilting B head on the spindle side and a rotary C table carrying the workpiece (head-table,
as on many vertical machining centres), machine-file type ``xyzbc-head-table``.

X, Y, Z move the head relative to the machine frame; B tilts the spindle about a line parallel
to y through the pivot, ``pivot_length`` above the spindle nose; the workpiece sits on a C table
turning about a line parallel to z through (x_rot_point, y_rot_point). The workpiece frame has
its origin at (x_rot_point, y_rot_point, z_rot_point) and turns with C, not with B: that is the
frame of the tool tip and orientation, hence of the contour errors. Machine-file keys (mm;
directions +1/-1):

================= ========================================================================
key               meaning
================= ========================================================================
``x_rot_point``   C axis centre in the machine frame, x
``y_rot_point``   ... y
``z_rot_point``   height of the workpiece origin on the C axis (the table face, say)
``pivot_length``  B pivot to the spindle nose (gauge line), along the tool axis
``tool_offset``   tool length, spindle nose to tip
``b_direction``   +1: B turns the tool right-handed about +y (ISO 841, a head axis)
``c_direction``   -1: C turns the table left-handed about +z, i.e. the tool right-handed
                  relative to the workpiece (ISO 841's C of a rotary table); +1 the other way
================= ========================================================================

The tilt travel (``b_min``, ``b_max``, rad) is the B drive's position limits.

Equations. With the physical angles b = b_direction B (the head's tilt) and c = c_direction C
(the table's turn), the C centre r, the pivot length p, the tool length t and M = (X, Y, Z)
(the spindle nose when B = 0): in the machine frame the tool axis is Ry(b) ez and the tip
M + p ez - (p + t) Ry(b) ez; a point w of the workpiece is at r + Rz(c) w. In the workpiece
frame therefore

    O = Rz(-c) Ry(b) ez = (sin b cos c, -sin b sin c, cos b),
    P = Rz(-c) (M + p ez - (p + t) Ry(b) ez - r),

and ``linear_axes`` is M = r + Rz(c) P - p ez + (p + t) Ry(b) ez. With the ISO directions
(+1, -1), O = Rz(C) Ry(B) ez: the orientation map of the B-C trunnion and of the fork head, so
the path inverse (:class:`~._trunnion.TrunnionKinematics`: C unwrapped, the pole B = 0 where the
tool is parallel to the C axis bridged, the sign of B chosen within its travel) is theirs. As on
every family, O = -dP/dt; on a head it is not dP/dZ.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._trunnion import LinuxcncTrunnion, TiltAboutY, rotary_pair

#: Machine-file keys of the geometry, in the order of :class:`XYZBCHeadTable`'s fields.
GEOMETRY_KEYS: tuple[str, ...] = ("x_rot_point", "y_rot_point", "z_rot_point", "pivot_length",
                                  "tool_offset")


@dataclass(frozen=True)
class XYZBCHeadTable(TiltAboutY, LinuxcncTrunnion):
    """Head-table B-C geometry (see the module docstring); lengths in mm, directions +1/-1
    (defaults ISO 841's), ``b_min``/``b_max`` the B travel in rad (``None``: free)."""

    x_rot_point: float
    y_rot_point: float
    z_rot_point: float
    pivot_length: float
    tool_offset: float
    b_direction: float = 1.0
    c_direction: float = -1.0
    b_min: float | None = None
    b_max: float | None = None

    _GEOMETRY_KEYS = GEOMETRY_KEYS
    _DIRECTION_KEYS = ("b_direction", "c_direction")

    @property
    def turn_direction(self) -> float:
        # O = Rz(-c) Ry(b) ez: the table's turn enters the tool axis with the opposite sign
        return -self.c_direction

    def _machine_tip_offset(self, b: np.ndarray) -> np.ndarray:
        """Tip minus M in the machine frame: p ez - (p + t) Ry(b) ez."""
        length = self.pivot_length + self.tool_offset
        return np.stack([-length * np.sin(b), np.zeros_like(b),
                         self.pivot_length - length * np.cos(b)], axis=-1)

    def forward(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Direct kinematics: axis positions ``q[..., 5]`` = X, Y, Z, B, C (mm, rad) -> tool
        tip ``P[..., 3]`` (mm) and unit orientation ``O[..., 3]`` in the workpiece frame."""
        q = np.asarray(q, dtype=float)
        b = self.tilt_direction * q[..., 3]
        c = self.c_direction * q[..., 4]
        g = q[..., :3] + self._machine_tip_offset(b) - self._rot_point
        sc, cc = np.sin(c), np.cos(c)
        P = np.stack([cc * g[..., 0] + sc * g[..., 1], -sc * g[..., 0] + cc * g[..., 1],
                      g[..., 2]], axis=-1)
        return P, self.orientation(q[..., 3], q[..., 4])

    def linear_axes(self, P: np.ndarray, B, C=None) -> np.ndarray:
        """X, Y, Z (mm, shape ``P.shape``) that put the tool tip at ``P`` (workpiece frame)
        when the rotary axes stand at ``B``, ``C`` (rad; or ``linear_axes(P, rotary[..., 2])``):
        what tool-centre-point control computes."""
        B, C = rotary_pair(B, C)
        b, c = self.tilt_direction * B, self.c_direction * C
        P = np.asarray(P, dtype=float)
        sc, cc = np.sin(c), np.cos(c)
        machine = np.stack([cc * P[..., 0] - sc * P[..., 1], sc * P[..., 0] + cc * P[..., 1],
                            np.broadcast_to(P[..., 2], np.broadcast_shapes(P[..., 2].shape,
                                                                           c.shape))], axis=-1)
        return machine + self._rot_point - self._machine_tip_offset(b)
