"""What the machines with two tilts (an A axis about x and a B axis about y, no C) share: the
orientation map O = Ru(alpha) Rv(beta) ez of two rotations about perpendicular horizontal axes,
its Jacobian, and the path-mode inverse (the outer angle alpha unwrapped, its singularity
bridged, the solution and the whole turns of both axes chosen within their travels).

u is the outer axis (applied last to the tool axis: on an A-B table the axis nearer the part,
on a head the one nearer the ram), v the inner one; the tool is parallel to u where
cos(beta) = 0, and there alpha orients nothing. With u = x (A outer):

    O = Rx(alpha) Ry(beta) ez = (sin beta, -sin alpha cos beta, cos alpha cos beta),

with u = y (B outer):

    O = Ry(alpha) Rx(beta) ez = (sin alpha cos beta, -sin beta, cos alpha cos beta).

Each physical angle is a commanded one times +-1. The two solutions are (alpha, beta) with
cos beta >= 0 and (alpha + pi, pi - beta), each up to whole turns of either axis.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ._trunnion import POLE_TOLERANCE, _first_defined, _unwrap, _unwrap_path, rotary_pair

TWO_PI = 2.0 * np.pi


def two_tilt_orientation(alpha, beta, outer_x: bool) -> np.ndarray:
    """O = Rx(alpha) Ry(beta) ez (``outer_x``) or Ry(alpha) Rx(beta) ez."""
    alpha, beta = np.broadcast_arrays(np.asarray(alpha, dtype=float),
                                      np.asarray(beta, dtype=float))
    cb = np.cos(beta)
    if outer_x:
        return np.stack([np.sin(beta), -np.sin(alpha) * cb, np.cos(alpha) * cb], axis=-1)
    return np.stack([np.sin(alpha) * cb, -np.sin(beta), np.cos(alpha) * cb], axis=-1)


def two_tilt_jacobian(alpha, beta, outer_x: bool) -> np.ndarray:
    """d(:func:`two_tilt_orientation`)/d(alpha, beta), shape ``alpha.shape + (3, 2)``."""
    alpha, beta = np.broadcast_arrays(np.asarray(alpha, dtype=float),
                                      np.asarray(beta, dtype=float))
    sa, ca, sb, cb = np.sin(alpha), np.cos(alpha), np.sin(beta), np.cos(beta)
    zero = np.zeros_like(alpha)
    if outer_x:
        d_a = np.stack([zero, -ca * cb, -sa * cb], axis=-1)
        d_b = np.stack([cb, sa * sb, -ca * sb], axis=-1)
    else:
        d_a = np.stack([ca * cb, zero, -sa * cb], axis=-1)
        d_b = np.stack([-sa * sb, -cb, -ca * sb], axis=-1)
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


class TwoTiltKinematics:
    """Mixin of the two-tilt types (frozen dataclasses with ``a_min``, ``a_max``, ``b_min``,
    ``b_max``: the travel of A, slot 3, and B, slot 4, in rad, ``None`` where free). A subclass
    provides ``_outer_slot`` (3 or 4: the slot of the outer axis u), ``_outer_x`` (u is x,
    i.e. A), ``_outer_sign`` and ``_inner_sign`` (physical angle = sign x command), and
    ``forward(q)``, ``linear_axes(P, A, B)``.

    ``tilt_limits`` is the travel of slot 3 (A), what the limit checks, the G-code reader and
    LinuxCNC's joint limits read for that slot; ``rotary_limits`` has both.
    """

    axis_names = ("X", "Y", "Z", "A", "B")
    _outer_slot: int = 3
    _outer_x: bool = True
    _outer_sign: float = 1.0
    _inner_sign: float = 1.0

    # ---------------------------------------------------------------- travel
    @property
    def tilt_limits(self) -> tuple[float | None, float | None]:
        """(lower, upper) travel of the slot-3 axis (A) in rad, ``None`` where unlimited."""
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

    # ---------------------------------------------------------------- orientation
    def _physical(self, A, B):
        """(alpha, beta) of commanded A, B."""
        outer, inner = (A, B) if self._outer_slot == 3 else (B, A)
        return (self._outer_sign * np.asarray(outer, dtype=float),
                self._inner_sign * np.asarray(inner, dtype=float))

    def orientation(self, rotary, B=None) -> np.ndarray:
        """Unit tool orientation O[..., 3]: ``orientation(q)`` with axis positions
        ``q[..., 5]``, or ``orientation(A, B)``."""
        A, B = rotary_pair(rotary, B)
        return two_tilt_orientation(*self._physical(A, B), self._outer_x)

    def orientation_jacobian(self, A, B) -> np.ndarray:
        """dO/d(A, B), shape ``A.shape + (3, 2)``; the outer axis's column vanishes where
        the tool is parallel to it."""
        jac = two_tilt_jacobian(*self._physical(A, B), self._outer_x)
        jac = jac * np.array([self._outer_sign, self._inner_sign])
        return jac if self._outer_slot == 3 else jac[..., ::-1]

    def pole_distance(self, A, B) -> np.ndarray:
        """|cos beta|: how far the pose is from the singularity (tool parallel to the outer
        axis), for singularity-robust corrections."""
        return np.abs(np.cos(self._physical(A, B)[1]))

    # ---------------------------------------------------------------- inverse
    def inverse(self, P: np.ndarray, O: np.ndarray, c_near=None) -> np.ndarray:
        """Inverse kinematics: tool tip ``P[..., 3]`` and unit orientation ``O[..., 3]``
        (workpiece frame) -> axis positions ``q[..., 5]`` = X, Y, Z, A, B.

        ``c_near`` (the other types' name for the slot-4 axis, here B): ``None``, the samples
        are a path (the solution and whole turns chosen as in the module docstring); a
        scalar, a path whose B starts nearest ``c_near``; an array of the samples' shape, each
        sample on the solution whose B is nearest its ``c_near``, A within (-pi, pi] (0 where
        the outer axis is undefined). ``O`` must already be unit length.
        """
        P = np.asarray(P, dtype=float)
        O = np.asarray(O, dtype=float)
        if self._outer_x:   # O = (sin b, -sin a cos b, cos a cos b)
            along, s_other, c_other = O[..., 0], -O[..., 1], O[..., 2]
        else:               # O = (sin a cos b, -sin b, cos a cos b)
            along, s_other, c_other = -O[..., 1], O[..., 0], O[..., 2]
        h = np.hypot(s_other, c_other)
        defined = h > POLE_TOLERANCE
        alpha = np.where(defined, np.arctan2(s_other, c_other), 0.0)   # cos beta >= 0
        beta = np.arctan2(along, h)                                    # in [-pi/2, pi/2]
        if c_near is None or np.ndim(c_near) == 0:
            shape = alpha.shape
            A, B = self._path(alpha.reshape(-1), beta.reshape(-1), defined.reshape(-1),
                              None if c_near is None else float(c_near))
            A, B = A.reshape(shape), B.reshape(shape)
        else:
            near = np.broadcast_to(np.asarray(c_near, dtype=float), alpha.shape)
            first = self._commanded(alpha, beta)
            second = self._commanded(alpha + np.pi, np.pi - beta)
            B1 = first[1] + TWO_PI * np.round((near - first[1]) / TWO_PI)
            B2 = second[1] + TWO_PI * np.round((near - second[1]) / TWO_PI)
            use_second = np.abs(B2 - near) < np.abs(B1 - near)
            A = np.where(use_second, second[0], first[0])
            B = np.where(use_second, B2, B1)
            A = np.mod(A + np.pi, TWO_PI) - np.pi
            A = np.where(A == -np.pi, np.pi, A)
            if self._outer_slot == 3:
                A = np.where(defined, A, 0.0)
            else:
                B = np.where(defined, B, near)
        q = np.empty(np.broadcast_shapes(P.shape[:-1], A.shape) + (5,))
        q[..., 3] = A
        q[..., 4] = B
        q[..., :3] = self.linear_axes(P, A, B)
        return q

    def _commanded(self, alpha, beta):
        """Commanded (A, B) of physical (alpha, beta)."""
        outer, inner = self._outer_sign * alpha, self._inner_sign * beta
        return (outer, inner) if self._outer_slot == 3 else (inner, outer)

    def _path(self, alpha, beta, defined, b_near):
        """(A, B) along a 1-D path: the best of the candidate solutions (module docstring):
        alpha continuous with period pi through the singularity (the solution changing there),
        starting on either solution, or with period 2 pi on one solution (alpha turning by pi
        there); each with the whole turns of A and B that fit the travels best."""
        if alpha.size == 0:
            return alpha.copy(), beta.copy()
        a_travel = _travel(self.a_min, self.a_max)
        b_travel = _travel(self.b_min, self.b_max)
        first = _first_defined(alpha, defined)
        candidates = [(_unwrap_path(alpha, defined, np.pi, first + shift), 0)
                      for shift in (0.0, np.pi)]
        candidates += [(_unwrap_path(alpha + shift, defined, TWO_PI, None), 1)
                       for shift in (0.0, np.pi)]
        best, best_rank = None, None
        for outer, half_turns in candidates:
            second = defined & (np.cos(outer - alpha) < 0.0)
            inner = _unwrap(np.ascontiguousarray(np.where(second, np.pi - beta, beta)), TWO_PI)
            A, B = self._commanded(outer, inner)
            B = B + _turns(B, *b_travel, b_near)
            A = A + _turns(A, *a_travel, None)
            rank = self._rank(A, B, half_turns, bool(second[np.argmax(defined)]), b_near)
            if best_rank is None or rank < best_rank:
                best, best_rank = (A, B), rank
        return best

    def _rank(self, A, B, half_turns, starts_second, b_near):
        """Order of preference of a whole-path solution: B nearest ``b_near`` at the start
        (when given), least outside the travels, no half turn of the outer axis, most room
        inside the travels, the cos beta >= 0 solution at the start."""
        outside = -np.inf
        for x, (low, high) in ((A, _travel(self.a_min, self.a_max)),
                               (B, _travel(self.b_min, self.b_max))):
            outside = max(outside, low - float(x.min()), float(x.max()) - high)
        near = 0.0 if b_near is None else round(abs(B[0] - b_near), 9)
        return near, max(outside, 0.0), half_turns, outside, int(starts_second)
