"""Five-axis machine kinematics, one module per machine type, picked by name.

Each type registers a factory in :data:`KINEMATICS_TYPES` that takes the machine file's
``[kinematics]`` table and returns an object with ``axis_names`` (slot 3 is A or B) and
vectorized ``inverse(P, O)`` (tool tip and orientation in the workpiece frame to axis
positions q = [X, Y, Z, A, C]), ``forward(q)``, ``orientation(q)`` (or ``orientation(A, C)``),
``orientation_jacobian(A, C)`` and ``linear_axes(P, A, C)`` (the tool-centre-point map).

- ``ac-trunnion`` (:mod:`.ac_trunnion`): Zhang et al.'s A-C trunnion, offsets L_ac, L_ty;
- ``xyzac-trt`` (:mod:`.xyzac_trt`): A-C trunnion with LinuxCNC xyzac-trt-kins's offsets;
- ``xyzbc-trt`` (:mod:`.xyzbc_trt`): B-C trunnion with LinuxCNC xyzbc-trt-kins's offsets;
- ``xyzbc-head-table`` (:mod:`.xyzbc_head_table`): tilting B head, rotary C table;
- ``xyzbc-head-head`` (:mod:`.xyzbc_head_head`): B-C fork head, LinuxCNC 5axiskins's geometry;
- ``chain`` (:mod:`.chain`): any of these families as a chain of rotary axes (direction, point,
  carried by the table or the head); the types above are its presets (:func:`.chain.chain_of`).

The tool tip and orientation are in the workpiece frame: on a table it turns with the table's
rotary axes, on a head machine it is the machine frame. On the trunnions the tool orientation is
also dP/dZ; on every type it is -dP/dt for the tool length t (a shorter tool moves the tip along
the tool axis, towards the spindle).
"""

from __future__ import annotations

import numpy as np

from ...errors import InputError, notice
from .ac_trunnion import ACTrunnion
from .chain import ChainKinematics, RotaryAxis, chain_of
from .xyzac_trt import XYZACTrunnion
from .xyzbc_head_head import XYZBCHeadHead
from .xyzbc_head_table import XYZBCHeadTable
from .xyzbc_trt import XYZBCTrunnion

#: Tolerance on | |O| - 1 | below which orientations are normalized (with one notice) instead
#: of being rejected. CAM output rounds components to 4 decimals (|O| off by up to 1e-4), some
#: to 3 (up to 9e-4); a larger deviation is no rounding but a wrong vector.
UNIT_TOLERANCE = 1e-3
#: | |O| - 1 | up to which normalizing is silent (round-off of 12 or more digits).
SILENT_TOLERANCE = 1e-12

KINEMATICS_TYPES = {
    "ac-trunnion": ACTrunnion.from_table,
    "xyzac-trt": XYZACTrunnion.from_table,
    "xyzbc-trt": XYZBCTrunnion.from_table,
    "xyzbc-head-table": XYZBCHeadTable.from_table,
    "xyzbc-head-head": XYZBCHeadHead.from_table,
    "chain": ChainKinematics.from_table,
}

__all__ = ["ACTrunnion", "ChainKinematics", "KINEMATICS_TYPES", "RotaryAxis", "UNIT_TOLERANCE",
           "XYZACTrunnion", "XYZBCHeadHead", "XYZBCHeadTable", "XYZBCTrunnion", "angle_between",
           "chain_of", "normalize_orientations"]


def angle_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle (rad) between vectors along the last axis, not necessarily unit.

    atan2 of |a x b| and a . b is accurate for small and large angles alike, where arccos of
    the dot product loses half the digits near 0.
    """
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.sum(a * b, axis=-1))


def normalize_orientations(O: np.ndarray, *, source: str | None = None,
                           first_row: int = 1) -> np.ndarray:
    """Return unit orientation vectors, or raise naming the first non-unit row.

    Rows whose length is within :data:`UNIT_TOLERANCE` of one are normalized (with one notice,
    :func:`precontour.errors.notice`, when any needed more than round-off); others raise
    :class:`InputError`.
    """
    O = np.asarray(O, dtype=float)
    norm = np.linalg.norm(O, axis=-1)
    deviation = np.abs(norm - 1.0)
    bad = ~(deviation <= UNIT_TOLERANCE)  # NaN counts as bad
    if np.any(bad):
        row = int(np.flatnonzero(np.atleast_1d(bad))[0])
        value = np.atleast_1d(norm)[row]
        raise InputError(f"orientation vector is not unit length (|O| = {value:.9g})",
                         source=source, row=row + first_row, field="O")
    changed = deviation > SILENT_TOLERANCE
    if np.any(changed):
        notice(f"{source or 'orientations'}: normalized {int(np.count_nonzero(changed))} "
               f"orientation vectors with |O| off by up to {float(deviation.max()):.2g} "
               f"(tolerance {UNIT_TOLERANCE:g})")
    return O / norm[..., None]
