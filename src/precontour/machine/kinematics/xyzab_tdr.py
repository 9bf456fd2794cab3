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
G-code has A and B words); trajectory files keep the column names ``X,Y,Z,A,C``, so on an A-B
machine column ``C`` holds B. Machine-file keys (mm) and the LinuxCNC HAL pins they equal:

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
solution at the start.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ._trunnion import POLE_TOLERANCE, _first_defined, _unwrap, _unwrap_path, rotary_pair

#: Machine-file keys of the geometry, in the order of :class:`XYZABTableDualRotary`'s fields.
GEOMETRY_KEYS: tuple[str, ...] = ("x_rot_point", "y_rot_point", "z_rot_point", "x_offset",
                                  "z_offset", "tool_offset")
TWO_PI = 2.0 * np.pi


def tdr_orientation(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """O = Rx(a) Ry(b) ez = (sin b, -sin a cos b, cos a cos b)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    cb = np.cos(b)
    return np.stack(np.broadcast_arrays(np.sin(b), -np.sin(a) * cb, np.cos(a) * cb), axis=-1)


def tdr_jacobian(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """d(:func:`tdr_orientation`)/d(a, b), shape ``a.shape + (3, 2)``."""
    a, b = np.broadcast_arrays(np.asarray(a, dtype=float), np.asarray(b, dtype=float))
    sa, ca, sb, cb = np.sin(a), np.cos(a), np.sin(b), np.cos(b)
    d_a = np.stack([np.zeros_like(a), -ca * cb, -sa * cb], axis=-1)
    d_b = np.stack([cb, sa * sb, -ca * sb], axis=-1)
    return np.stack([d_a, d_b], axis=-1)


def _travel(low, high) -> tuple[float, float]:
    return (-np.inf if low is None else low), (np.inf if high is None else high)


def _turns(x: np.ndarray, low: float, high: float, near: float | None) -> float:
    """The multiple of 2 pi to add to the path ``x`` (1-D): nearest ``near`` at the start when
    given, else the one least outside [low, high], then with the most room, then the start
    nearest 0."""
    if near is not None:
        return TWO_PI * np.round((near - x[0]) / TWO_PI)
    lo, hi = float(x.min()), float(x.max())
    ks = {float(np.round(-x[0] / TWO_PI))}
    if np.isfinite(low) and np.isfinite(high):
        centre = 0.5 * ((low + high) - (lo + hi)) / TWO_PI
        ks |= {float(np.floor(centre)), float(np.ceil(centre))}
    elif np.isfinite(low):
        ks.add(float(np.ceil((low - lo) / TWO_PI)))
    elif np.isfinite(high):
        ks.add(float(np.floor((high - hi) / TWO_PI)))

    def rank(k):
        shift = TWO_PI * k
        outside = max(low - (lo + shift), (hi + shift) - high)
        return max(outside, 0.0), outside, abs(x[0] + shift)

    return TWO_PI * min(ks, key=rank)


@dataclass(frozen=True)
class XYZABTableDualRotary:
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

    axis_names = ("X", "Y", "Z", "A", "B")

    @classmethod
    def from_table(cls, table) -> "XYZABTableDualRotary":
        return cls(**{key: table.get_float(key) for key in GEOMETRY_KEYS})

    # ---------------------------------------------------------------- travel
    @property
    def tilt_limits(self) -> tuple[float | None, float | None]:
        """(lower, upper) travel of the slot-3 axis (A) in rad, ``None`` where unlimited: what
        the limit checks and LinuxCNC's joint limits read for slot 3."""
        return self.a_min, self.a_max

    @property
    def rotary_limits(self) -> tuple[tuple[float | None, float | None], ...]:
        """((a_min, a_max), (b_min, b_max)) in rad."""
        return (self.a_min, self.a_max), (self.b_min, self.b_max)

    def with_tilt_limits(self, lower: float | None, upper: float | None):
        """A copy whose unset A travel limits are ``lower``, ``upper`` (rad)."""
        return self.with_rotary_travel((lower, upper), (None, None))

    def with_rotary_travel(self, a_travel, b_travel):
        """A copy whose unset travel limits are ``a_travel`` = (lower, upper) for A and
        ``b_travel`` for B (rad, ``None``: none)."""
        names = ("a_min", "a_max", "b_min", "b_max")
        given = (*a_travel, *b_travel)
        return dataclasses.replace(self, **{
            name: value if getattr(self, name) is None else getattr(self, name)
            for name, value in zip(names, given)})

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

    def orientation(self, rotary, B=None) -> np.ndarray:
        """Unit tool orientation O[..., 3] = dP/dZ: ``orientation(q)`` with axis positions
        ``q[..., 5]``, or ``orientation(A, B)``."""
        A, B = rotary_pair(rotary, B)
        return tdr_orientation(A, B)

    def orientation_jacobian(self, A, B) -> np.ndarray:
        """dO/d(A, B), shape ``A.shape + (3, 2)``; the A column vanishes where cos B = 0."""
        return tdr_jacobian(A, B)

    def pole_distance(self, A, B) -> np.ndarray:
        """|cos B|: how far the pose is from the singularity (tool parallel to the A axis),
        where the orientation's A column vanishes (for singularity-robust corrections)."""
        return np.abs(np.cos(np.asarray(B, dtype=float)))

    # ---------------------------------------------------------------- inverse
    def inverse(self, P: np.ndarray, O: np.ndarray, c_near=None) -> np.ndarray:
        """Inverse kinematics: tool tip ``P[..., 3]`` and unit orientation ``O[..., 3]``
        (workpiece frame) -> axis positions ``q[..., 5]`` = X, Y, Z, A, B.

        ``c_near`` (the other types' name for the slot-4 axis, here B): ``None``, the samples
        are a path (see the module docstring for the choice of solution); a scalar, a path
        whose B starts nearest ``c_near``; an array of the samples' shape, each sample on the
        solution whose B is nearest its ``c_near``, A within (-pi, pi] (0 where undefined).
        ``O`` must already be unit length.
        """
        P = np.asarray(P, dtype=float)
        O = np.asarray(O, dtype=float)
        h = np.hypot(O[..., 1], O[..., 2])
        defined = h > POLE_TOLERANCE
        a_up = np.where(defined, np.arctan2(-O[..., 1], O[..., 2]), 0.0)  # cos B >= 0
        b_up = np.arctan2(O[..., 0], h)                                   # in [-pi/2, pi/2]
        if c_near is None or np.ndim(c_near) == 0:
            shape = a_up.shape
            A, B = self._path(a_up.reshape(-1), b_up.reshape(-1), defined.reshape(-1),
                              None if c_near is None else float(c_near))
            A, B = A.reshape(shape), B.reshape(shape)
        else:
            near = np.broadcast_to(np.asarray(c_near, dtype=float), a_up.shape)
            b_other = np.pi - b_up
            b1 = b_up + TWO_PI * np.round((near - b_up) / TWO_PI)
            b2 = b_other + TWO_PI * np.round((near - b_other) / TWO_PI)
            second = np.abs(b2 - near) < np.abs(b1 - near)
            B = np.where(second, b2, b1)
            A = np.where(second, a_up + np.pi, a_up)
            A = np.where(defined, np.mod(A + np.pi, TWO_PI) - np.pi, 0.0)
            A = np.where(A == -np.pi, np.pi, A)
        q = np.empty(np.broadcast_shapes(P.shape[:-1], A.shape) + (5,))
        q[..., 3] = A
        q[..., 4] = B
        q[..., :3] = self.linear_axes(P, A, B)
        return q

    def _path(self, a_up, b_up, defined, b_near):
        """(A, B) along a 1-D path: the best of the candidate solutions (module docstring)."""
        if a_up.size == 0:
            return a_up.copy(), b_up.copy()
        a_low, a_high = _travel(self.a_min, self.a_max)
        b_low, b_high = _travel(self.b_min, self.b_max)
        first = _first_defined(a_up, defined)
        candidates = [(_unwrap_path(a_up, defined, np.pi, first + shift), 0)
                      for shift in (0.0, np.pi)]
        candidates += [(_unwrap_path(a_up + shift, defined, TWO_PI, None), 1)
                       for shift in (0.0, np.pi)]
        best, best_rank = None, None
        for A, half_turns in candidates:
            second = defined & (np.cos(A - a_up) < 0.0)
            B = _unwrap(np.ascontiguousarray(np.where(second, np.pi - b_up, b_up)), TWO_PI)
            B = B + _turns(B, b_low, b_high, b_near)
            A = A + _turns(A, a_low, a_high, None)
            rank = self._rank(A, B, half_turns, bool(second[np.argmax(defined)]), b_near)
            if best_rank is None or rank < best_rank:
                best, best_rank = (A, B), rank
        return best

    def _rank(self, A, B, half_turns, starts_second, b_near):
        """Order of preference of a whole-path solution (module docstring)."""
        outside = -np.inf
        for x, (low, high) in ((A, _travel(self.a_min, self.a_max)),
                               (B, _travel(self.b_min, self.b_max))):
            outside = max(outside, low - float(x.min()), float(x.max()) - high)
        near = 0.0 if b_near is None else round(abs(B[0] - b_near), 9)
        return near, max(outside, 0.0), half_turns, outside, int(starts_second)
