"""What every kinematics type shares: the orientation map O = Rz(turn) R(tilt) ez of a
tilt-then-turn table, and the path-mode inverse for it (C unwrapped, the pole A = 0 bridged,
the tilt sign chosen within the tilt axis's travel).

The same map describes the head families in their workpiece frames: a B-C fork head (tool axis
Rz(c) Ry(b) ez, the workpiece frame being the machine frame) and a B head over a C table (tool
axis Rz(-c) Ry(b) ez in the frame turning with the table), with their own senses of rotation.
A type module defines the tool tip equations and, through :class:`TrunnionKinematics`'s hooks,
how its commanded rotary angles map to the physical tilt and turn. On a table the tool axis is
O = dP/dZ (spec section 1); on every type it is O = -dP/dt for the tool length t.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ...kernels import jit

#: |horizontal part of O| below which C is treated as undefined (tool along z); the
#: orientation error this can cause is below this value in rad.
POLE_TOLERANCE = 1e-10
#: Samples per block of the inverse kinematics' element-wise last step.
_BLOCK = 32768


def tilt_x_orientation(a: np.ndarray, c: np.ndarray) -> np.ndarray:
    """O = Rz(c) Rx(a) z = (sin a sin c, -sin a cos c, cos a): the tool axis in the frame of a
    table tilted by ``a`` about x, then turned by ``c`` about its own z (physical angles)."""
    sa = np.sin(a)
    return np.stack([sa * np.sin(c), -sa * np.cos(c), np.cos(a)], axis=-1)


def tilt_x_jacobian(a: np.ndarray, c: np.ndarray) -> np.ndarray:
    """d(:func:`tilt_x_orientation`)/d(a, c), shape ``a.shape + (3, 2)``."""
    sa, ca, sc, cc = np.sin(a), np.cos(a), np.sin(c), np.cos(c)
    d_a = np.stack([ca * sc, -ca * cc, -sa], axis=-1)
    d_c = np.stack([sa * cc, sa * sc, np.zeros_like(sa)], axis=-1)
    return np.stack([d_a, d_c], axis=-1)


def tilt_x_turn(O: np.ndarray) -> np.ndarray:
    """The turn c of :func:`tilt_x_orientation` for a tilt a >= 0: atan2(Oi, -Oj)."""
    return np.arctan2(O[..., 0], -O[..., 1])


def tilt_y_orientation(b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """O = Rz(c) Ry(b) z = (sin b cos c, sin b sin c, cos b): table tilted by ``b`` about y,
    then turned by ``c`` about its own z (physical angles)."""
    sb = np.sin(b)
    return np.stack([sb * np.cos(c), sb * np.sin(c), np.cos(b)], axis=-1)


def tilt_y_jacobian(b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """d(:func:`tilt_y_orientation`)/d(b, c), shape ``b.shape + (3, 2)``."""
    sb, cb, sc, cc = np.sin(b), np.cos(b), np.sin(c), np.cos(c)
    d_b = np.stack([cb * cc, cb * sc, -sb], axis=-1)
    d_c = np.stack([-sb * sc, sb * cc, np.zeros_like(sb)], axis=-1)
    return np.stack([d_b, d_c], axis=-1)


def tilt_y_turn(O: np.ndarray) -> np.ndarray:
    """The turn c of :func:`tilt_y_orientation` for a tilt b >= 0: atan2(Oj, Oi)."""
    return np.arctan2(O[..., 1], O[..., 0])


def rotary_pair(rotary, C=None) -> tuple[np.ndarray, np.ndarray]:
    """(tilt, turn) from either ``rotary[..., 2]``, the axis vector ``q[..., 5]``, or two
    arrays ``rotary, C`` -- the call forms the kinematics methods accept."""
    if C is not None:
        return np.asarray(rotary, dtype=float), np.asarray(C, dtype=float)
    rotary = np.asarray(rotary, dtype=float)
    if rotary.shape[-1] == 5:
        return rotary[..., 3], rotary[..., 4]
    if rotary.shape[-1] == 2:
        return rotary[..., 0], rotary[..., 1]
    raise ValueError(f"expected q[..., 5] or rotary[..., 2] axis values, got shape {rotary.shape}")


class TiltAboutX:
    """The hooks of a table tilted about x (A), then turned about its own z (C), for
    :class:`TrunnionKinematics`."""

    axis_names = ("X", "Y", "Z", "A", "C")
    _TILT_FIELDS = ("a_min", "a_max")
    _physical_orientation = staticmethod(tilt_x_orientation)
    _physical_jacobian = staticmethod(tilt_x_jacobian)
    _physical_turn = staticmethod(tilt_x_turn)


class TiltAboutY:
    """The hooks of a table tilted about y (B), then turned about its own z (C), for
    :class:`TrunnionKinematics`."""

    axis_names = ("X", "Y", "Z", "B", "C")
    _TILT_FIELDS = ("b_min", "b_max")
    _physical_orientation = staticmethod(tilt_y_orientation)
    _physical_jacobian = staticmethod(tilt_y_jacobian)
    _physical_turn = staticmethod(tilt_y_turn)


class TrunnionKinematics:
    """Mixin of the trunnion types (frozen dataclasses). A subclass provides

    - ``axis_names``: the five axis letters, slot 3 being the tilt axis (A or B);
    - ``_TILT_FIELDS``: names of its tilt-travel fields (lower, upper; rad, ``None`` = free);
    - ``tilt_direction``, ``turn_direction``: +1 or -1, commanded angle = direction x physical
      angle of :func:`tilt_x_orientation` / :func:`tilt_y_orientation`;
    - ``_physical_orientation``, ``_physical_jacobian``, ``_physical_turn`` (one of the pairs
      above), ``forward(q)`` and ``linear_axes(P, A, C)``.

    :class:`TiltAboutX` and :class:`TiltAboutY` give the axis names, the tilt fields and the
    three ``_physical_*`` functions of their tilt axis.
    """

    axis_names: tuple[str, ...] = ("X", "Y", "Z", "A", "C")
    _TILT_FIELDS: tuple[str, str] = ("a_min", "a_max")
    tilt_direction: float = 1.0
    turn_direction: float = 1.0

    @property
    def tilt_limits(self) -> tuple[float | None, float | None]:
        """(lower, upper) travel of the tilt axis in rad, ``None`` where unlimited."""
        return tuple(getattr(self, name) for name in self._TILT_FIELDS)

    def with_tilt_limits(self, lower: float | None, upper: float | None):
        """A copy whose unset tilt travel limits are ``lower``, ``upper`` (rad)."""
        current = self.tilt_limits
        values = {name: value if old is None else old
                  for name, old, value in zip(self._TILT_FIELDS, current, (lower, upper))}
        return dataclasses.replace(self, **values)

    def _tilt_signs_allowed(self) -> tuple[bool, bool]:
        lower, upper = self.tilt_limits
        return (upper is None or upper > 0.0), (lower is None or lower < 0.0)

    # ------------------------------------------------------------------ orientation
    def orientation(self, rotary, C=None) -> np.ndarray:
        """Unit tool orientation O[..., 3] = dP/dZ for the rotary axes: ``orientation(q)``
        with axis positions ``q[..., 5]``, or ``orientation(A, C)`` (``A`` is B on a B-C
        machine)."""
        tilt, turn = rotary_pair(rotary, C)
        return self._physical_orientation(self.tilt_direction * tilt, self.turn_direction * turn)

    def orientation_jacobian(self, A, C) -> np.ndarray:
        """dO/d(A, C), shape ``A.shape + (3, 2)``; the C column vanishes at the pole."""
        jac = self._physical_jacobian(self.tilt_direction * np.asarray(A, dtype=float),
                                      self.turn_direction * np.asarray(C, dtype=float))
        return jac * np.array([self.tilt_direction, self.turn_direction])

    # ------------------------------------------------------------------ inverse
    def inverse(self, P: np.ndarray, O: np.ndarray, c_near=None) -> np.ndarray:
        """Inverse kinematics: tool tip ``P[..., 3]`` and unit orientation ``O[..., 3]``
        (workpiece frame) -> axis positions ``q[..., 5]``.

        Parameters
        ----------
        P, O : array_like
            Tool tip (mm) and unit tool orientation. ``O`` must already be unit length (see
            :func:`precontour.machine.kinematics.normalize_orientations`).
        c_near : None, float or array_like
            ``None``: the samples are a path; C is unwrapped along it, and where the tilt axis
            may go both ways the whole path takes the tilt sign that keeps it inside the tilt
            travel with the most room (ties: tilt >= 0 at the start). A scalar: a path whose
            C starts at the branch nearest ``c_near``. An array of the samples' shape: each
            sample takes the branch whose C is nearest its ``c_near`` (keeps a corrected
            command on the branch of its reference).
        """
        P = np.asarray(P, dtype=float)
        O = np.asarray(O, dtype=float)
        horizontal = np.hypot(O[..., 0], O[..., 1])
        defined = horizontal > POLE_TOLERANCE
        tilt_abs = np.arctan2(horizontal, O[..., 2])  # = arccos(Ok), accurate near the pole
        # commanded C for which the physical tilt is >= 0; the other branch is c_up + pi
        c_up = self.turn_direction * self._physical_turn(O)
        positive, negative = self._tilt_signs_allowed()
        both = positive and negative
        # the branch paths start on: the only allowed one, or physical tilt >= 0
        c_plus = c_up + np.pi if not both and not (positive if self.tilt_direction > 0
                                                   else negative) else c_up
        period = np.pi if both else 2.0 * np.pi

        def tilt_of(C):
            return _tilt(C, c_up, tilt_abs, defined, self.tilt_direction)

        if c_near is None or np.ndim(c_near) == 0:
            if c_near is not None:
                C = _unwrap_path(c_plus, defined, period, float(c_near))
            elif both:
                C = self._best_path_branch(c_up, defined, tilt_of)
            else:
                C = _unwrap_path(c_plus, defined, period, None)
            C = C.reshape(c_plus.shape)
        else:
            c_near = np.broadcast_to(np.asarray(c_near, dtype=float), c_plus.shape)
            C = c_plus + period * np.round((c_near - c_plus) / period)
            C = np.where(defined, C, c_near)
        q = np.empty(np.broadcast_shapes(P.shape[:-1], C.shape) + (5,))
        if P.ndim == 2 and C.shape == P.shape[:1]:
            # a path: the tilt and the linear axes block by block, whose temporaries stay
            # in cache
            for start in range(0, P.shape[0], _BLOCK):
                block = slice(start, start + _BLOCK)
                tilt = _tilt(C[block], c_up[block], tilt_abs[block], defined[block],
                             self.tilt_direction)
                q[block, 3] = tilt
                q[block, 4] = C[block]
                q[block, :3] = self.linear_axes(P[block], tilt, C[block])
        else:
            tilt = tilt_of(C)
            q[..., 3] = tilt
            q[..., 4] = C
            q[..., :3] = self.linear_axes(P, tilt, C)
        return q

    def _best_path_branch(self, c_up, defined, tilt_of) -> np.ndarray:
        """C along a path for a tilt axis that may go both ways.

        Candidates: C continuous with period pi (the tilt changes sign where the path crosses
        the pole), starting with either tilt sign; and C with period 2 pi on one tilt sign
        only (C turns by pi where the path crosses the pole). Preferred: least overrun of the
        tilt travel, then no such half-turn, then the most room inside the travel, then
        tilt >= 0 at the start. A half-turn exactly at the pole is a jump of C between two
        samples, which the feed planner refuses: such a path cannot be cut within the travel
        without stopping at the pole.
        """
        if all(limit is None for limit in self.tilt_limits):
            # free travel: the commanded tilt is >= 0 at the start
            return _unwrap_path(c_up if self.tilt_direction > 0 else c_up + np.pi, defined,
                                np.pi, None)
        first = _first_defined(c_up, defined)
        candidates = [(_unwrap_path(c_up, defined, np.pi, first + shift), 0)
                      for shift in (0.0, np.pi)]
        candidates += [(_unwrap_path(c_up + shift, defined, 2.0 * np.pi, None), 1)
                       for shift in (0.0, np.pi)]
        best = min(candidates,
                   key=lambda item: self._branch_rank(tilt_of(item[0]), defined, item[1]))
        return best[0]

    def _branch_rank(self, tilt: np.ndarray, defined: np.ndarray,
                     half_turns: int) -> tuple[float, int, float, int]:
        """Order of preference of a whole-path branch (see :meth:`_best_path_branch`)."""
        lower, upper = self.tilt_limits
        below = (lower - tilt) if lower is not None else np.full(tilt.shape, -np.inf)
        above = (tilt - upper) if upper is not None else np.full(tilt.shape, -np.inf)
        worst = float(np.max(np.maximum(below, above), initial=-np.inf))
        start = tilt[np.flatnonzero(np.atleast_1d(defined))[:1]]
        return max(worst, 0.0), half_turns, worst, int(start.size > 0 and start[0] < 0.0)


def _tilt(C, c_up, tilt_abs, defined, direction):
    """The commanded tilt on the branch of C: C differs from c_up by a multiple of pi, and
    an odd multiple means the physical tilt is negative."""
    flipped = defined & (np.cos(C - c_up) < 0.0)
    return direction * np.where(flipped, -tilt_abs, tilt_abs)


def _first_defined(c: np.ndarray, defined: np.ndarray) -> float:
    index = np.flatnonzero(np.atleast_1d(defined))
    return float(np.atleast_1d(c)[index[0]]) if index.size else 0.0


def _unwrap_path(c_raw: np.ndarray, defined: np.ndarray, period: float,
                 c_start: float | None) -> np.ndarray:
    """Unwrap C along a path (1-D), filling undefined samples (tool along z) by linear
    interpolation between their defined neighbours, held constant at the ends."""
    c_raw = np.atleast_1d(c_raw)
    defined = np.atleast_1d(defined)
    if c_raw.ndim != 1:
        raise ValueError("path inverse kinematics needs 1-D samples (P, O of shape (N, 3))")
    if not defined.any():
        return np.full(c_raw.shape, 0.0 if c_start is None else c_start)
    everywhere = bool(defined.all())
    index = None if everywhere else np.flatnonzero(defined)
    c_defined = _unwrap(np.ascontiguousarray(c_raw if everywhere else c_raw[index], dtype=float),
                        float(period))
    if c_start is not None:
        c_defined += period * np.round((c_start - c_defined[0]) / period)
    if everywhere:
        return c_defined
    return np.interp(np.arange(c_raw.size), index, c_defined)


@jit
def _unwrap(p, period):
    """:func:`numpy.unwrap` ``(p, period=period)`` of a 1-D array, to the last bit (the same
    operations in the same order), in one pass instead of seven array passes."""
    up = p.copy()
    high = period / 2
    low = -high
    total = 0.0
    for i in range(1, p.size):
        step = p[i] - p[i - 1]
        wrapped = np.mod(step - low, period) + low
        if wrapped == low and step > 0:
            wrapped = high
        # numpy adds the zero corrections too; adding 0.0 leaves the running sum unchanged
        correction = 0.0 if abs(step) < high else wrapped - step
        total += correction
        up[i] = p[i] + total
    return up


def read_direction(table, key: str) -> float:
    """A rotary axis direction from the machine file: +1 or -1."""
    value = table.get_float(key)
    if value not in (1.0, -1.0):
        raise table.error(key, f"must be +1 or -1 (the axis's sense of rotation), got {value:g}")
    return value


class LinuxcncTrunnion(TrunnionKinematics):
    """Mixin of LinuxCNC's trunnion geometries (``xyzac-trt-kins``, ``xyzbc-trt-kins``): a
    subclass has the fields ``x_rot_point``, ``y_rot_point``, ``z_rot_point`` (the rotary
    centre) and those named by ``_GEOMETRY_KEYS`` (read from the machine file as they are) and
    ``_DIRECTION_KEYS`` (tilt, turn: +1 or -1)."""

    _GEOMETRY_KEYS: tuple[str, ...] = ()
    _DIRECTION_KEYS: tuple[str, str] = ("a_direction", "c_direction")

    @classmethod
    def from_table(cls, table):
        geometry = {key: table.get_float(key) for key in cls._GEOMETRY_KEYS}
        directions = {key: read_direction(table, key) for key in cls._DIRECTION_KEYS}
        return cls(**geometry, **directions)

    @property
    def tilt_direction(self) -> float:
        return getattr(self, self._DIRECTION_KEYS[0])

    @property
    def turn_direction(self) -> float:
        return getattr(self, self._DIRECTION_KEYS[1])

    @property
    def _rot_point(self) -> np.ndarray:
        return np.array([self.x_rot_point, self.y_rot_point, self.z_rot_point])
