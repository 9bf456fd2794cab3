"""B-C tilting rotary table with general offsets: the geometry of LinuxCNC's
``xyzbc-trt-kins`` (src/emc/kinematics/trtfuncs.c), machine-file type ``xyzbc-trt``.

As ``xyzac-trt`` but the trunnion tilts about a line parallel to y (the B axis). The axis
vector keeps its five slots, q = [X, Y, Z, B, C]: slot 3 holds B, the machine file describes
its drive as ``[drives.B]`` and controllers give ``B = {...}``; trajectory files keep the column
names ``X,Y,Z,A,C``, so on a B-C machine column ``A`` holds B. Machine-file keys (mm;
directions +1/-1) and the LinuxCNC HAL pins they equal:

================= ==================================== ========================================
key               LinuxCNC pin                         meaning
================= ==================================== ========================================
``x_rot_point``   ``xyzbc-trt-kins.x-rot-point``       C axis centre in the machine frame, x
``y_rot_point``   ``xyzbc-trt-kins.y-rot-point``       ... y
``z_rot_point``   ``xyzbc-trt-kins.z-rot-point``       ... z
``x_offset``      ``xyzbc-trt-kins.x-offset``          B axis centre relative to the C axis, x
``z_offset``      ``xyzbc-trt-kins.z-offset``          B axis centre relative to the C axis, z
``tool_offset``   ``xyzbc-trt-kins.tool-offset``       tool length (``motion.tooloffset.z``)
``b_direction``   ``conventional-directions``          -1 when that pin is false (LinuxCNC's
``c_direction``   (one pin for both axes)              default), +1 when true
================= ==================================== ========================================

The tilt travel (``b_min``, ``b_max``, rad) is the B drive's position limits.

Equations. With b = b_direction B, c = c_direction C, r the C centre, d = (x_offset, 0,
z_offset) and t = tool_offset:

    P = Rz(c) (Ry(b) (M - t ez - r - d) + d) + r,   M = (X, Y, Z),

trtfuncs.c's ``xyzbcKinematicsForward`` less the tool length on z (see ``xyzac_trt``), and
O = dP/dZ = Rz(c) Ry(b) ez = (sin b cos c, sin b sin c, cos b).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._trunnion import LinuxcncTrunnion, TiltAboutY, rotary_pair, tilt_y_orientation

#: Machine-file keys of the geometry, in the order of :class:`XYZBCTrunnion`'s fields.
GEOMETRY_KEYS: tuple[str, ...] = ("x_rot_point", "y_rot_point", "z_rot_point", "x_offset",
                                  "z_offset", "tool_offset")


@dataclass(frozen=True)
class XYZBCTrunnion(TiltAboutY, LinuxcncTrunnion):
    """LinuxCNC ``xyzbc-trt-kins`` geometry (see the module docstring); lengths in mm,
    directions +1/-1, ``b_min``/``b_max`` the B travel in rad (``None``: free)."""

    x_rot_point: float
    y_rot_point: float
    z_rot_point: float
    x_offset: float
    z_offset: float
    tool_offset: float
    b_direction: float = -1.0
    c_direction: float = -1.0
    b_min: float | None = None
    b_max: float | None = None

    _GEOMETRY_KEYS = GEOMETRY_KEYS
    _DIRECTION_KEYS = ("b_direction", "c_direction")

    def forward(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Direct kinematics: axis positions ``q[..., 5]`` = X, Y, Z, B, C (mm, rad) -> tool
        tip ``P[..., 3]`` (mm) and unit orientation ``O[..., 3]`` in the workpiece frame."""
        q = np.asarray(q, dtype=float)
        b = self.b_direction * q[..., 3]
        c = self.c_direction * q[..., 4]
        sb, cb, sc, cc = np.sin(b), np.cos(b), np.sin(c), np.cos(c)
        # relative to the B axis centre: M - t ez - r - d
        u = q[..., 0] - self.x_offset - self.x_rot_point
        v = q[..., 1] - self.y_rot_point
        w = q[..., 2] - self.tool_offset - self.z_offset - self.z_rot_point
        # Ry(b), back to the C centre (+ d)
        tx = cb * u + sb * w + self.x_offset
        tz = -sb * u + cb * w + self.z_offset
        P = np.stack([cc * tx - sc * v, sc * tx + cc * v, tz], axis=-1) + self._rot_point
        return P, tilt_y_orientation(b, c)

    def linear_axes(self, P: np.ndarray, B, C=None) -> np.ndarray:
        """X, Y, Z (mm, shape ``P.shape``) that put the tool tip at ``P`` (workpiece frame)
        when the rotary axes stand at ``B``, ``C`` (rad; or ``linear_axes(P, rotary[..., 2])``):
        what tool-centre-point control computes."""
        B, C = rotary_pair(B, C)
        b, c = self.b_direction * B, self.c_direction * C
        sb, cb, sc, cc = np.sin(b), np.cos(b), np.sin(c), np.cos(c)
        g = np.asarray(P, dtype=float) - self._rot_point
        # Rz(c)^T, minus d
        hx = cc * g[..., 0] + sc * g[..., 1] - self.x_offset
        hy = -sc * g[..., 0] + cc * g[..., 1]
        hz = g[..., 2] - self.z_offset
        # Ry(b)^T, plus d + r + t ez
        X = cb * hx - sb * hz + self.x_offset + self.x_rot_point
        Y = hy + self.y_rot_point
        Z = sb * hx + cb * hz + self.z_offset + self.z_rot_point + self.tool_offset
        return np.stack([X, Y, Z], axis=-1)
