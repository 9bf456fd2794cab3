"""A-B table dual rotary (two tilts, table-table): the geometry of LinuxCNC's ``xyzab_tdr_kins``
(src/hal/components/xyzab_tdr_kins.comp, the sim configs/sim/axis/vismach/5axis/
table-dual-rotary), machine-file type ``xyzab-tdr``.

X, Y, Z move the tool relative to the machine frame. The workpiece sits on a rotary table A
turning about a line parallel to x, and the A assembly is carried by a B trunnion tilting about
a line parallel to y: B carries A, A carries the part. Unlike the trunnions, neither rotary axis
is along the tool at the zero pose, so the tool along z is a regular pose; the singular pose is
B = +-90 deg, where the tool is parallel to the A axis and A orients nothing.

The axis vector keeps its five slots, q = [X, Y, Z, A, B]: slot 3 holds A, slot 4 holds B (the
machine file describes [drives.A] and [drives.B], controllers give A = {...} and B = {...}, and
G-code has A and B words, trajectory and command files have the columns ``X,Y,Z,A,B``).
Machine-file keys (mm) and the LinuxCNC HAL pins they equal:

================= ==================================== ========================================
key               LinuxCNC pin                         meaning
================= ==================================== ========================================
``x_rot_point``   ``xyzab_tdr_kins.x-rot-point``       rotation point: where the B axis meets
``y_rot_point``   ``xyzab_tdr_kins.y-rot-point``       the A axis at zero offsets (machine
``z_rot_point``   ``xyzab_tdr_kins.z-rot-point``       frame, from the machine's home)
``x_offset``      ``xyzab_tdr_kins.x-offset``          A table face centre relative to the
``z_offset``      ``xyzab_tdr_kins.z-offset``          rotation point, x and z
``tool_offset``   ``xyzab_tdr_kins.tool-offset-z``     tool length (``motion.tooloffset.z``)
================= ==================================== ========================================

The module has no direction pins: A and B turn as its equations say (below), the part
left-handed about +x and +y (the tool right-handed relative to it). ``x_offset`` moves a point
of the A axis along the A axis itself, so it changes nothing in the kinematics (LinuxCNC's
forward map does not read it and its inverse adds and subtracts it); it is kept because
LinuxCNC has the pin and its sim draws the table face with it. Travel (``a_min``, ``a_max``,
``b_min``, ``b_max``, rad): the A and B drives' position limits, which the inverse's choice of
branch keeps to.

Equations. With a = A, b = B, the rotation point r, d = (x_offset, 0, z_offset), the tool length
t and M = (X, Y, Z), the tool tip and tool axis in the workpiece frame are

    P = Rx(a) (Ry(b) (M - t ez - r) - d) + r + d,
    O = Rx(a) Ry(b) ez = (sin b, -sin a cos b, cos a cos b),

xyzab_tdr_kins's ``kinematicsForward`` (type 1, TCP) with its Cartesian z less the tool length
(LinuxCNC's Cartesian position is the controlled point, under G43 the tip plus t along z; see
``xyzac_trt``). ``linear_axes`` is its ``kinematicsInverse`` at P + t ez:

    M = Ry(-b) (Rx(-a) (P - r - d) + d) + r + t ez.

O = dP/dZ = -dP/dt. The orientation Jacobian is dO/dA = (0, -cos a cos b, -sin a cos b),
dO/dB = (cos b, sin a sin b, -cos a sin b).

Inverse kinematics from (P, O): B = atan2(Ox, +-hypot(Oy, Oz)), A = atan2(-Oy, Oz) (+ pi): the
two solutions are (A, B) with cos B >= 0 and (A + pi, pi - B), each up to whole turns. Where
hypot(Oy, Oz) vanishes (B = +-90 deg) A is undefined and bridged along a path by interpolation;
a path may cross that pose continuously (A continuous with period pi, the solution changing
there) or with A turning by pi on one solution. Along a path the inverse picks, among these
candidates and the whole turns of A and of B, the one least outside the A and B travels, then
without a half turn of A, then with the most room inside the travels, then on the cos B >= 0
solution at the start (:class:`~._two_tilt.TwoTiltKinematics`, which the generic chain's
two-tilt machines share).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._two_tilt import TwoTiltKinematics, two_tilt_orientation
from ._trunnion import rotary_pair

#: Machine-file keys of the geometry, in the order of :class:`XYZABTableDualRotary`'s fields.
GEOMETRY_KEYS: tuple[str, ...] = ("x_rot_point", "y_rot_point", "z_rot_point", "x_offset",
                                  "z_offset", "tool_offset")


def tdr_orientation(a, b) -> np.ndarray:
    """O = Rx(a) Ry(b) ez = (sin b, -sin a cos b, cos a cos b)."""
    return two_tilt_orientation(a, b, True)


@dataclass(frozen=True)
class XYZABTableDualRotary(TwoTiltKinematics):
    """LinuxCNC ``xyzab_tdr_kins`` geometry (see the module docstring); lengths in mm,
    ``a_min``/``a_max``, ``b_min``/``b_max`` the A and B travel in rad (``None``: free)."""

    x_rot_point: float
    y_rot_point: float
    z_rot_point: float
    x_offset: float
    z_offset: float
    tool_offset: float
    a_min: float | None = None
    a_max: float | None = None
    b_min: float | None = None
    b_max: float | None = None

    # the A table (x) is the outer axis, applied last; both turn as the commands say
    _outer_slot = 3
    _outer_x = True

    @classmethod
    def from_table(cls, table) -> "XYZABTableDualRotary":
        return cls(**{key: table.get_float(key) for key in GEOMETRY_KEYS})

    @property
    def _rot_point(self) -> np.ndarray:
        return np.array([self.x_rot_point, self.y_rot_point, self.z_rot_point])

    @property
    def _offset(self) -> np.ndarray:
        return np.array([self.x_offset, 0.0, self.z_offset])

    # ---------------------------------------------------------------- forward
    def forward(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Direct kinematics: axis positions ``q[..., 5]`` = X, Y, Z, A, B (mm, rad) -> tool
        tip ``P[..., 3]`` (mm) and unit orientation ``O[..., 3]`` in the workpiece frame."""
        q = np.asarray(q, dtype=float)
        a, b = q[..., 3], q[..., 4]
        sa, ca, sb, cb = np.sin(a), np.cos(a), np.sin(b), np.cos(b)
        # relative to the rotation point: M - t ez - r
        u = q[..., 0] - self.x_rot_point
        v = q[..., 1] - self.y_rot_point
        w = q[..., 2] - self.tool_offset - self.z_rot_point
        # Ry(b), minus d
        hx = cb * u + sb * w - self.x_offset
        hz = -sb * u + cb * w - self.z_offset
        # Rx(a), plus r + d
        P = np.stack([hx + self.x_offset + self.x_rot_point,
                      ca * v - sa * hz + self.y_rot_point,
                      sa * v + ca * hz + self.z_offset + self.z_rot_point], axis=-1)
        return P, tdr_orientation(a, b)

    def linear_axes(self, P: np.ndarray, A, B=None) -> np.ndarray:
        """X, Y, Z (mm, shape ``P.shape``) that put the tool tip at ``P`` (workpiece frame)
        when the rotary axes stand at ``A``, ``B`` (rad; or ``linear_axes(P, rotary[..., 2])``):
        what tool-centre-point control computes."""
        A, B = rotary_pair(A, B)
        sa, ca, sb, cb = np.sin(A), np.cos(A), np.sin(B), np.cos(B)
        g = np.asarray(P, dtype=float) - self._rot_point - self._offset
        # Rx(-a), plus d
        hx = g[..., 0] + self.x_offset
        hy = ca * g[..., 1] + sa * g[..., 2]
        hz = -sa * g[..., 1] + ca * g[..., 2] + self.z_offset
        # Ry(-b), plus r + t ez
        X = cb * hx - sb * hz + self.x_rot_point
        Z = sb * hx + cb * hz + self.z_rot_point + self.tool_offset
        return np.stack(np.broadcast_arrays(X, hy + self.y_rot_point, Z), axis=-1)
