"""Errors measured from what LinuxCNC's closed loop recorded, independently of precontour's
contour code: a k-d tree on the uncompensated run's commanded tip path, then the two segments
beside the nearest sample. Used by test_closed_loop.py and scripts/measure_controller.py."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from precontour.cnc.blocks import block_starts
from precontour.compensation.blocks import ORIENTATION_MARGIN, RELATIVE_MARGIN, TIP_MARGIN
from precontour.tables import read_columns

#: Seconds after the first move's start left out of every measure: the approach rapid (G0,
#: not corrected: rapids do not cut) still settles there, and the first blocks, shorter than
#: precontour.cnc.blocks.MIN_BLOCK, keep their end points.
SETTLE = 0.3
#: Reference samples either side of the tip's closest one searched for the closest
#: orientation (0.2 s at 1 ms).
ORIENTATION_WINDOW = 200


def read_log(path, letters="XYZAC"):
    """(commands, actual positions, line) of a servo log linuxcnc-record wrote (mm, rad);
    ``letters``: the machine's axis letters."""
    names = tuple(letters)
    columns = read_columns(path, ("t", *names, *(f"{a}_act" for a in names), "line"))
    q = np.column_stack([columns[a] for a in names])
    actual = np.column_stack([columns[f"{a}_act"] for a in names])
    return q, actual, columns["line"].astype(int)


def errors(reference, run, moves, kinematics, settle=SETTLE, *, with_lines=False):
    """Tip (um) and orientation (mrad) errors of ``run``'s actual positions against the
    commanded path of ``reference`` (the uncompensated run), from ``settle`` (s) after the
    first move's start to the end of the commanded motion: the distance of each actual tip to
    the commanded tip polyline, and the angle between the actual orientation and the closest
    commanded one near the tip's closest sample. ``with_lines``: also the program line
    ``run`` was executing at each of those samples."""
    q0, _, line0 = reference
    q, actual, line = run
    start0 = block_starts(line0, moves.line)[0]
    P_ref, O_ref = kinematics.forward(q0[start0:])
    start = block_starts(line, moves.line)[0] + int(settle / 1e-3)
    moving = np.flatnonzero(np.any(np.diff(q, axis=0) != 0, axis=1))
    P, O = kinematics.forward(actual[start:moving[-1] + 1])
    _, i = cKDTree(P_ref).query(P)
    tip = np.full(P.shape[0], np.inf)
    for offset in (-1, 0):
        j = np.clip(i + offset, 0, P_ref.shape[0] - 2)
        a, v = P_ref[j], P_ref[j + 1] - P_ref[j]
        u = np.clip(np.einsum("ij,ij->i", P - a, v)
                    / np.maximum(np.einsum("ij,ij->i", v, v), 1e-30), 0, 1)
        tip = np.minimum(tip, np.linalg.norm(a + u[:, None] * v - P, axis=1))
    # orientation: the closest reference orientation within ORIENTATION_WINDOW samples of
    # the tip's closest one (spec section 5 searches the orientation curve on its own, near
    # the same point of the path)
    best = np.full(O.shape[0], -1.0)
    nearest = i.copy()
    for offset in range(-ORIENTATION_WINDOW, ORIENTATION_WINDOW + 1):
        j = np.clip(i + offset, 0, O_ref.shape[0] - 1)
        dot = np.einsum("ij,ij->i", O, O_ref[j])
        better = dot > best
        best[better], nearest[better] = dot[better], j[better]
    # then the closest point of the two chords beside that sample, normalised
    for offset in (-1, 0):
        j = np.clip(nearest + offset, 0, O_ref.shape[0] - 2)
        a, v = O_ref[j], O_ref[j + 1] - O_ref[j]
        u = np.clip(np.einsum("ij,ij->i", O - a, v)
                    / np.maximum(np.einsum("ij,ij->i", v, v), 1e-30), 0, 1)
        point = a + u[:, None] * v
        point /= np.linalg.norm(point, axis=1, keepdims=True)
        best = np.maximum(best, np.einsum("ij,ij->i", O, point))
    orientation = np.arccos(np.clip(best, -1.0, 1.0))
    if with_lines:
        return 1e3 * tip, 1e3 * orientation, line[start:moving[-1] + 1]
    return 1e3 * tip, 1e3 * orientation


def line_maxima(tip, orientation, line):
    """{program line: (tip max, orientation max)} over the samples executing it."""
    order = np.argsort(line, kind="stable")
    ordered = line[order]
    first = np.concatenate([[0], np.flatnonzero(np.diff(ordered)) + 1])
    return {int(ordered[i]): (float(a), float(b)) for i, a, b in
            zip(first, np.maximum.reduceat(tip[order], first),
                np.maximum.reduceat(orientation[order], first)) if ordered[i] > 0}


def line_maxima_of(reference, run, moves, kinematics, settle=SETTLE):
    """:func:`line_maxima` of ``run``'s :func:`errors` against ``reference``."""
    return line_maxima(*errors(reference, run, moves, kinematics, settle, with_lines=True))


def worse_lines(ours, base, repeat):
    """Program lines on which ``ours`` (:func:`line_maxima` of a run) is worse than ``base``
    (of the uncompensated run) in tip or orientation max beyond the margins precontour judges
    by (:data:`~precontour.compensation.blocks.TIP_MARGIN` /
    :data:`~precontour.compensation.blocks.ORIENTATION_MARGIN`, or
    :data:`~precontour.compensation.blocks.RELATIVE_MARGIN` of the line's uncompensated max)
    or beyond the line's repeatability (its difference between ``base`` and ``repeat``, of a
    second uncompensated run), whichever is larger."""
    worse = []
    for number, (tip, ori) in sorted(ours.items()):
        if number not in base:
            continue
        b_tip, b_ori = base[number]
        r_tip, r_ori = repeat.get(number, base[number])
        # errors() gives um and mrad, the margins are mm and rad
        if (tip > b_tip + max(1e3 * TIP_MARGIN, RELATIVE_MARGIN * b_tip, abs(r_tip - b_tip))
                or ori > b_ori + max(1e3 * ORIENTATION_MARGIN, RELATIVE_MARGIN * b_ori,
                                     abs(r_ori - b_ori))):
            worse.append(number)
    return worse


def late(reference, run, moves):
    """Servo periods each block started off the reference run's, from the first block."""
    a = block_starts(reference[2], moves.line)
    b = block_starts(run[2], moves.line)
    assert np.all(a >= 0) and np.all(b >= 0)
    return (b - b[0]) - (a - a[0])
