"""Axes the reference does not move keep their reference command.

On an axis whose reference command stands still for the whole trajectory, the contour
correction can still come out at nanometres (the other axes' predicted errors seen through the
kinematics, the spline fits' residuals). Commanded, such a correction makes the axis's command
velocity nonzero, so a controller with friction feed-forward from the commanded velocity (paper
Fig. 10) pushes the resting axis with its full static friction torque; with a quantised encoder
the feedback cannot see the nanometres it was asked for, and the axis breaks away by
micrometres. Measured on the built-in ``circle`` (X never moves) with ``pid-high`` on the
realistic machine with a 0.1 um encoder: X corrections of at most 13 nm turned a 8.7 um tip
maximum into 45 um (docs/identification.md).

A correction below the prediction's own resolution (its spline fit tolerance, what
compensation passes as ``tol_linear``/``tol_rotary``) is not a model result, so such an axis is
left at its reference command. A larger correction of a resting axis (a rotary axis's lag seen
at the tool tip, corrected with a linear axis) is kept by the linear passes; whether it helps on
a machine with friction is for learning to decide on its draws
(:func:`hold_resting_axes` gives the variant in which every resting axis is held). Measured on
``circle`` / ``pid-low`` within the limits: X corrections of up to 1 um left X resting a
different micrometre off on each draw; the command learning kept removed 88.2 % of the worst
draw's mean tip error, 15 rows worse than uncompensated, and learning with X held 94.1 %,
no row worse (issue 21).
"""

from __future__ import annotations

import numpy as np


def idle_axes(q_reference: np.ndarray, q: np.ndarray, tolerance) -> np.ndarray:
    """Mask of shape (5,): axes whose reference command stays within ``tolerance`` (per axis,
    mm or rad, shape (5,) or scalar) of its first sample, and whose command ``q`` stays within
    ``tolerance`` of the reference."""
    q_reference = np.asarray(q_reference, dtype=float)
    q = np.asarray(q, dtype=float)
    tol = np.broadcast_to(np.asarray(tolerance, dtype=float), q.shape[1:])
    small = np.all(np.abs(q - q_reference) <= tol, axis=0)
    return resting_axes(q_reference, tol) & small


def resting_axes(q_reference: np.ndarray, tolerance) -> np.ndarray:
    """Mask of shape (5,): axes whose reference command stays within ``tolerance`` (per axis,
    mm or rad, shape (5,) or scalar) of its first sample over the whole trajectory."""
    q_reference = np.asarray(q_reference, dtype=float)
    tol = np.broadcast_to(np.asarray(tolerance, dtype=float), q_reference.shape[1:])
    return np.all(np.abs(q_reference - q_reference[0]) <= tol, axis=0)


def hold_resting_axes(q_reference: np.ndarray, q: np.ndarray, tolerance) -> np.ndarray:
    """``q`` with every axis of :func:`resting_axes` set back to its reference command, however
    large its correction, where one of them departs from it by more than ``tolerance``; ``q``
    itself (not a copy) otherwise: corrections within the tolerance are
    :func:`hold_idle_axes`' to hold (round-off there is no reason to learn a variant)."""
    q_reference = np.asarray(q_reference, dtype=float)
    tol = np.broadcast_to(np.asarray(tolerance, dtype=float), q_reference.shape[1:])
    resting = resting_axes(q_reference, tol)
    if not np.any(np.abs(q[:, resting] - q_reference[:, resting]) > tol[resting]):
        return q
    return _held(q_reference, q, resting)


def hold_idle_axes(q_reference: np.ndarray, q: np.ndarray, tolerance) -> np.ndarray:
    """``q`` with every axis of :func:`idle_axes` set back to its reference command; ``q``
    itself (not a copy) when that changes nothing."""
    q_reference = np.asarray(q_reference, dtype=float)
    return _held(q_reference, q, idle_axes(q_reference, q, tolerance))


def _held(q_reference: np.ndarray, q: np.ndarray, axes: np.ndarray) -> np.ndarray:
    """``q`` with the ``axes`` (mask of shape (5,)) set to ``q_reference``; ``q`` itself (not
    a copy) when that changes nothing."""
    if not axes.any() or np.array_equal(q[:, axes], q_reference[:, axes]):
        return q
    held = np.array(q, dtype=float, copy=True)
    held[:, axes] = q_reference[:, axes]
    return held
