"""B-C fork head on the spindle side (head-head), the geometry of LinuxCNC's ``5axiskins``
(src/emc/kinematics/5axiskins.c, the bridge mill of configs/sim/axis/vismach/5axis/bridgemill),
machine-file type ``xyzbc-head-head``.

X, Y, Z move the head; the workpiece stands still on the machine table, so the workpiece frame
is the machine frame and neither rotary axis moves it. C turns the fork about a line parallel
to z, B tilts the spindle about the fork's own y; both axes meet in the pivot, ``pivot_length``
above the spindle nose. Machine-file keys (mm; directions +1/-1):

================= ==================================== ========================================
key               LinuxCNC                             meaning
================= ==================================== ========================================
``pivot_length``  ``5axiskins.pivot-length``          pivot to the spindle nose (gauge line),
                  (less the tool length, see below)    along the tool axis
``tool_offset``   ``motion.tooloffset.z``              tool length, spindle nose to tip
``b_direction``   none: 5axiskins has -1               sense of rotation of B
``c_direction``   none: 5axiskins has +1               sense of rotation of C
================= ==================================== ========================================

The tilt travel (``b_min``, ``b_max``, rad, for the inverse's choice of sign) is the B drive's
position limits.

Equations. With the physical angles b = b_direction B, c = c_direction C, the pivot length p,
the tool length t and M = (X, Y, Z) (the spindle nose when B = 0), the tool axis (tip towards
spindle) and the tip are

    O = Rz(c) Ry(b) ez = (sin b cos c, sin b sin c, cos b),
    P = M + p ez - (p + t) O,

5axiskins.c's ``fiveaxis_KinematicsForward`` (its s2r(L, C, 180 - B) is -L O with b = -B,
c = C) with its pivot-length pin at p + t, as its notes ask, and the tip one tool length below
its Cartesian position, as under G43. ``linear_axes`` is M = P - p ez + (p + t) O. The tool
axis is not dP/dZ on a head (Z moves the tip along z whatever the tilt) but, on every family,
the direction in which a shorter tool moves the tip: O = -dP/dt.

The inverse (B from O up to its sign, C unwrapped along a path, the pole B = 0 where the tool
is parallel to the C axis bridged, the sign chosen within the B travel) is the trunnions'
(:class:`~._trunnion.TrunnionKinematics`): the orientation map is the same Rz(c) Ry(b) ez.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._trunnion import LinuxcncTrunnion, TiltAboutY, rotary_pair, tilt_y_orientation

#: Machine-file keys of the geometry, in the order of :class:`XYZBCHeadHead`'s fields.
GEOMETRY_KEYS: tuple[str, ...] = ("pivot_length", "tool_offset")


@dataclass(frozen=True)
class XYZBCHeadHead(TiltAboutY, LinuxcncTrunnion):
    """LinuxCNC ``5axiskins`` head-head geometry (see the module docstring); lengths in mm,
    directions +1/-1 (defaults: 5axiskins's), ``b_min``/``b_max`` the B travel in rad
    (``None``: free)."""

    pivot_length: float
    tool_offset: float
    b_direction: float = -1.0
    c_direction: float = 1.0
    b_min: float | None = None
    b_max: float | None = None

    _GEOMETRY_KEYS = GEOMETRY_KEYS
    _DIRECTION_KEYS = ("b_direction", "c_direction")

    def forward(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Direct kinematics: axis positions ``q[..., 5]`` = X, Y, Z, B, C (mm, rad) -> tool
        tip ``P[..., 3]`` (mm) and unit orientation ``O[..., 3]`` in the workpiece frame (here
        the machine frame)."""
        q = np.asarray(q, dtype=float)
        O = tilt_y_orientation(self.b_direction * q[..., 3], self.c_direction * q[..., 4])
        P = q[..., :3] - (self.pivot_length + self.tool_offset) * O
        P[..., 2] += self.pivot_length
        return P, O

    def linear_axes(self, P: np.ndarray, B, C=None) -> np.ndarray:
        """X, Y, Z (mm, shape ``P.shape``) that put the tool tip at ``P`` when the rotary
        axes stand at ``B``, ``C`` (rad; or ``linear_axes(P, rotary[..., 2])``): what
        tool-centre-point control computes."""
        B, C = rotary_pair(B, C)
        O = tilt_y_orientation(self.b_direction * B, self.c_direction * C)
        M = np.asarray(P, dtype=float) + (self.pivot_length + self.tool_offset) * O
        M[..., 2] -= self.pivot_length
        return M
