"""A-C tilting rotary table with general offsets: the geometry of LinuxCNC's
``xyzac-trt-kins`` (src/emc/kinematics/trtfuncs.c), machine-file type ``xyzac-trt``.

X, Y, Z move the tool relative to the machine frame; the workpiece sits on a C table carried by
an A trunnion that tilts about a line parallel to x. Machine-file keys (mm; directions +1/-1)
and the LinuxCNC HAL pins they equal:

================= ==================================== ========================================
key               LinuxCNC pin                         meaning
================= ==================================== ========================================
``x_rot_point``   ``xyzac-trt-kins.x-rot-point``       C axis centre in the machine frame, x
``y_rot_point``   ``xyzac-trt-kins.y-rot-point``       ... y
``z_rot_point``   ``xyzac-trt-kins.z-rot-point``       ... z
``y_offset``      ``xyzac-trt-kins.y-offset``          A axis centre relative to the C axis, y
``z_offset``      ``xyzac-trt-kins.z-offset``          A axis centre relative to the C axis, z
``tool_offset``   ``xyzac-trt-kins.tool-offset``       tool length (``motion.tooloffset.z``)
``a_direction``   ``conventional-directions``          -1 when that pin is false (LinuxCNC's
``c_direction``   (one pin for both axes)              default), +1 when true
================= ==================================== ========================================

The tilt travel (``a_min``, ``a_max``, rad, for the inverse's choice of sign) is the A drive's
position limits (``p_min``, ``p_max`` in ``[drives.A]``).

Equations. With the physical angles a = a_direction A, c = c_direction C, the C centre
r = (x_rot_point, y_rot_point, z_rot_point), d = (0, y_offset, z_offset) and the tool length
t = tool_offset, the tool tip in the workpiece frame is

    P = Rz(c) (Rx(a) (M - t ez - r - d) + d) + r,   M = (X, Y, Z),

which is trtfuncs.c's ``xyzacKinematicsForward`` (with conventional-directions true, or with
both angles negated when false) except that its Cartesian z carries + t: LinuxCNC's Cartesian
position is the controlled point, which under G43 is the tool tip plus the tool length along
z; precontour's P is the tip itself. ``linear_axes`` is the inverse of that map (trtfuncs.c's
``xyzacKinematicsInverse`` at P + t ez), and O = dP/dZ = Rz(c) Rx(a) ez.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._trunnion import LinuxcncTrunnion, TiltAboutX, rotary_pair, tilt_x_orientation

#: Machine-file keys of the geometry, in the order of :class:`XYZACTrunnion`'s fields.
GEOMETRY_KEYS: tuple[str, ...] = ("x_rot_point", "y_rot_point", "z_rot_point", "y_offset",
                                  "z_offset", "tool_offset")


@dataclass(frozen=True)
class XYZACTrunnion(TiltAboutX, LinuxcncTrunnion):
    """LinuxCNC ``xyzac-trt-kins`` geometry (see the module docstring); lengths in mm,
    directions +1/-1, ``a_min``/``a_max`` the A travel in rad (``None``: free)."""

    x_rot_point: float
    y_rot_point: float
    z_rot_point: float
    y_offset: float
    z_offset: float
    tool_offset: float
    a_direction: float = -1.0
    c_direction: float = -1.0
    a_min: float | None = None
    a_max: float | None = None

    _GEOMETRY_KEYS = GEOMETRY_KEYS
    _DIRECTION_KEYS = ("a_direction", "c_direction")

    def forward(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Direct kinematics: axis positions ``q[..., 5]`` (mm, rad) -> tool tip ``P[..., 3]``
        (mm) and unit orientation ``O[..., 3]`` in the workpiece frame."""
        q = np.asarray(q, dtype=float)
        a = self.a_direction * q[..., 3]
        c = self.c_direction * q[..., 4]
        sa, ca, sc, cc = np.sin(a), np.cos(a), np.sin(c), np.cos(c)
        # relative to the A axis centre: M - t ez - r - d
        u = q[..., 0] - self.x_rot_point
        v = q[..., 1] - self.y_offset - self.y_rot_point
        w = q[..., 2] - self.tool_offset - self.z_offset - self.z_rot_point
        # Rx(a), back to the C centre (+ d)
        ty = ca * v - sa * w + self.y_offset
        tz = sa * v + ca * w + self.z_offset
        P = np.stack([cc * u - sc * ty, sc * u + cc * ty, tz], axis=-1) + self._rot_point
        return P, tilt_x_orientation(a, c)

    def linear_axes(self, P: np.ndarray, A, C=None) -> np.ndarray:
        """X, Y, Z (mm, shape ``P.shape``) that put the tool tip at ``P`` (workpiece frame)
        when the rotary axes stand at ``A``, ``C`` (rad; or ``linear_axes(P, rotary[..., 2])``):
        what tool-centre-point control computes."""
        A, C = rotary_pair(A, C)
        a, c = self.a_direction * A, self.c_direction * C
        sa, ca, sc, cc = np.sin(a), np.cos(a), np.sin(c), np.cos(c)
        g = np.asarray(P, dtype=float) - self._rot_point
        # Rz(c)^T, minus d
        hx = cc * g[..., 0] + sc * g[..., 1]
        hy = -sc * g[..., 0] + cc * g[..., 1] - self.y_offset
        hz = g[..., 2] - self.z_offset
        # Rx(a)^T, plus d + r + t ez
        X = hx + self.x_rot_point
        Y = ca * hy + sa * hz + self.y_offset + self.y_rot_point
        Z = -sa * hy + ca * hz + self.z_offset + self.z_rot_point + self.tool_offset
        return np.stack([X, Y, Z], axis=-1)
