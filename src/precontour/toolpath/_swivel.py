"""The rotary axes that turn the tool onto a tilted working plane's Z, for every reader that
swivels a plane (Fanuc's ``G53.1``, Sinumerik's ``CYCLE800``, Heidenhain's ``PLANE``).

A two-rotary machine reaches one tool orientation on two branches (on a trunnion ``A, C`` and
``-A, C + 180``; on a two-tilt head ``(alpha, beta)`` and ``(alpha + 180, 180 - beta)``), each
up to whole turns. The controllers choose the branch within the rotary axes' travel, and of
two within travel the preferred one (Fanuc: the one nearest where the axes stand; Sinumerik:
the direction ``_DIR`` of CYCLE800, "if one of the two positions cannot be reached for
mechanical reasons, the alternative position is automatically selected irrespective of the
setting of the Direction parameter", SINUMERIK Operate manual, CYCLE800). :func:`swivel`
does the same and says when the preferred branch was out of travel.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["Swivel", "swivel", "rotary_travel"]

#: Two solutions closer than this (rad) in both rotary axes are one.
_SAME = 1e-9
#: A solution's orientation must be the requested one within this (its length, rad).
_ORIENTATION_TOLERANCE = 1e-9


@dataclass(frozen=True)
class Swivel:
    """The chosen rotary axes and, when the preferred branch was out of travel, that one.

    Attributes
    ----------
    rotary : ndarray, shape (2,)
        Slots 3 and 4 (rad) of the chosen solution.
    passed_over : ndarray, shape (2,), or None
        The preferred solution (rad), when it was outside the travel and ``rotary`` is not.
    outside : float
        How far (rad) the chosen solution lies outside the travel (0: within).
    """

    rotary: np.ndarray
    passed_over: np.ndarray | None
    outside: float


def rotary_travel(kinematics) -> tuple[tuple[float, float], tuple[float, float]]:
    """((low, high), (low, high)) travel (rad) of slots 3 and 4; the tilt axis within +-180
    deg where the machine gives none, the other axis free."""
    low, high = getattr(kinematics, "tilt_limits", (None, None))
    tilt = (-math.pi if low is None else low, math.pi if high is None else high)
    limits = getattr(kinematics, "rotary_limits", None)
    if limits is None:
        return tilt, (-math.inf, math.inf)
    b_low, b_high = limits[1]
    return tilt, (-math.inf if b_low is None else b_low, math.inf if b_high is None else b_high)


def swivel(kinematics, tip, direction, current, prefer: int = 0) -> Swivel:
    """The rotary axes (slots 3, 4) that turn the tool along ``direction`` at ``tip``.

    Parameters
    ----------
    kinematics
        The machine's kinematics (``inverse(P, O, c_near=array)`` and ``forward(q)``).
    tip, direction : array_like, shape (3,)
        Tool tip (mm) and unit tool direction in the workpiece frame.
    current : array_like, shape (2,)
        Where the rotary axes stand (rad).
    prefer : int
        0: the solution nearest ``current`` (slot 4 first, then slot 3: the branch of slot 4
        nearest where it stands); -1 / +1: the one whose slot 3 (rotary axis 1, the direction
        reference) is lower / higher, then the nearest.

    Returns
    -------
    Swivel
        The solution within travel that is preferred; the preferred one and how far it lies
        outside when none is within.
    """
    tip = np.asarray(tip, dtype=float).reshape(3)
    direction = np.asarray(direction, dtype=float).reshape(3)
    current = np.asarray(current, dtype=float).reshape(2)
    # every branch, with the whole turns of slot 4 nearest where it stands: the inverse
    # takes the branch nearest its c_near, so asking around the circle finds them all
    near = current[1] + np.arange(-2, 3) * (0.5 * math.pi)
    q = kinematics.inverse(np.tile(tip, (near.size, 1)), np.tile(direction, (near.size, 1)),
                           c_near=near)
    solutions = []
    for candidate in q[:, 3:]:
        if any(np.all(np.abs(candidate - s) < _SAME) for s in solutions):
            continue
        full = np.concatenate([np.zeros(3), candidate])
        _, o = kinematics.forward(full[None, :])
        if np.linalg.norm(np.asarray(o).reshape(3) - direction) > _ORIENTATION_TOLERANCE:
            continue
        # the nearest whole turn of slot 4 on this branch
        candidate = candidate.copy()
        candidate[1] += 2 * math.pi * round((current[1] - candidate[1]) / (2 * math.pi))
        if not any(np.all(np.abs(candidate - s) < _SAME) for s in solutions):
            solutions.append(candidate)
    travel = rotary_travel(kinematics)

    def outside(s):
        return max(0.0, *(max(low - v, v - high) for v, (low, high) in zip(s, travel)))

    def preference(s):
        nearest = (round(abs(s[1] - current[1]), 9), round(abs(s[0] - current[0]), 9))
        return ((-prefer * round(s[0], 9),) if prefer else ()) + nearest

    preferred = min(solutions, key=preference)
    chosen = min(solutions, key=lambda s: (outside(s),) + preference(s))
    passed_over = None if chosen is preferred else preferred
    return Swivel(chosen, passed_over, outside(chosen))
