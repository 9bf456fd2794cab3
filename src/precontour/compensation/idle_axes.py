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

The same holds for an axis that rests for a stretch only, between its moves (a zigzag's Y
during each pass along X): there the reference itself rests, the correction comes out at
picometres to nanometres, and commanded, it switches the friction feed-forward on as on a
resting axis (:func:`idle_stretches`).
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import binary_dilation

from .blend import taper_reach, taper_weight

#: Speeds below which the reference rests on an axis for :func:`idle_stretches` (mm/s on X Y Z,
#: rad/s on A C). Why these: they are what the spline fits and the kinematics leave of a
#: resting axis's reference as round-off (at most 4e-9 mm/s on a zigzag's resting Y), far
#: below any motion a program asks for, and near the speed (1e-8 rad/s at a motor, 1.6e-8
#: mm/s on the built-in machine's ball screws) below which the friction feed-forward counts a
#: commanded speed as zero.
STILL_SPEED = np.array([1e-6] * 3 + [1e-8] * 2)
#: Width (s) of the C2 taper (:func:`~.blend.taper_weight`) at each end of a held stretch,
#: inside it (the commands around it are left as they are): the correction there is within
#: the tolerance, so the taper adds a jerk of the order of the tolerance over its cube.
STILL_TAPER = 0.01


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


def idle_stretches(q_reference: np.ndarray, q: np.ndarray, tolerance, ts: float
                   ) -> np.ndarray:
    """Mask of shape (N, 5): the stretches (runs of samples) over which an axis's reference
    rests (its steps into and out of each sample below :data:`STILL_SPEED`) and the command
    ``q`` stays within ``tolerance`` (per axis, mm or rad, shape (5,) or scalar) of it
    throughout: :func:`idle_axes` stretch by stretch.

    Why whole stretches: a stretch whose correction grows beyond the tolerance somewhere
    (a lead before the axis starts) carries a model result, which the linear passes keep.

    Measured on a zigzag of 1 mm CL points along X, a 4 mm step in Y and back, with a
    vertical tool (`run`, `pid-high`, the realistic machine's five draws): the linear passes
    asked the resting Y for at most 0.095 nm during the first pass along X, which left the tip
    0.05-0.27 um off the line on two draws where the uncompensated command has no contour
    error at all (21 of the pass's rows worse than uncompensated; none with Y held there)."""
    q_reference = np.asarray(q_reference, dtype=float)
    q = np.asarray(q, dtype=float)
    tol = np.broadcast_to(np.asarray(tolerance, dtype=float), q.shape[1:])
    still_step = np.abs(np.diff(q_reference, axis=0)) <= STILL_SPEED * ts
    still = np.zeros(q_reference.shape, dtype=bool)
    still[1:-1] = still_step[1:] & still_step[:-1]
    still[0], still[-1] = still_step[0], still_step[-1]
    out = np.zeros(q_reference.shape, dtype=bool)
    beyond = np.concatenate([np.zeros((1, q.shape[1]), dtype=int),
                             np.cumsum(np.abs(q - q_reference) > tol, axis=0)])
    for axis in np.flatnonzero(still.any(axis=0)):
        edges = np.flatnonzero(np.diff(np.concatenate([[0], still[:, axis].astype(np.int8),
                                                       [0]])))
        first, stop = edges[0::2], edges[1::2]
        # a stretch qualifies where no sample of it is beyond the tolerance
        idle = beyond[stop, axis] == beyond[first, axis]
        marks = np.zeros(q.shape[0] + 1, dtype=int)
        np.add.at(marks, first[idle], 1)
        np.add.at(marks, stop[idle], -1)
        out[:, axis] = np.cumsum(marks[:-1]) > 0
    return out


def hold_idle_axes(q_reference: np.ndarray, q: np.ndarray, tolerance,
                   ts: float | None = None) -> np.ndarray:
    """``q`` with every axis of :func:`idle_axes` set back to its reference command, and with
    ``ts`` (the sample period, s) also every :func:`idle_stretches` of the other axes: the
    reference exactly, blended in and out over :data:`STILL_TAPER` at the stretch's ends
    inside it (C2, :func:`~.blend.taper_weight`; a stretch too short for both tapers is left
    as it is); ``q`` itself (not a copy) when that changes nothing."""
    q_reference = np.asarray(q_reference, dtype=float)
    whole = idle_axes(q_reference, q, tolerance)
    held = _held(q_reference, q, whole)
    if ts is None:
        return held
    stretches = idle_stretches(q_reference, held, tolerance, ts)
    stretches[:, whole] = False
    out = held
    reach = taper_reach(ts, hold=0.0, width=STILL_TAPER)
    for axis in np.flatnonzero(stretches.any(axis=0)):
        # the stretch eroded by the taper's reach (not at the trajectory's ends): the weight is
        # zero outside the stretch
        core = ~binary_dilation(~stretches[:, axis], iterations=reach)
        if not core.any():
            continue
        weight, _ = taper_weight(core, ts, hold=0.0, width=STILL_TAPER)
        column = out[:, axis] - weight * (out[:, axis] - q_reference[:, axis])
        column[weight == 1.0] = q_reference[weight == 1.0, axis]
        if np.array_equal(column, out[:, axis]):
            continue
        if out is q:
            out = np.array(q, dtype=float, copy=True)
        out[:, axis] = column
    return out


def _held(q_reference: np.ndarray, q: np.ndarray, axes: np.ndarray) -> np.ndarray:
    """``q`` with the ``axes`` (mask of shape (5,)) set to ``q_reference``; ``q`` itself (not
    a copy) when that changes nothing."""
    if not axes.any() or np.array_equal(q[:, axes], q_reference[:, axes]):
        return q
    held = np.array(q, dtype=float, copy=True)
    held[:, axes] = q_reference[:, axes]
    return held
