"""Canned cycles G73, G81-G83, G85-G87, G89 expanded into moves as LinuxCNC 2.9 does.

This module owns the geometry of one cycle block: given the plane (its two axes and the
drilling axis), the hole positions of the block's repeats, the R plane, the bottom and the
retract height, :func:`cycle_moves` returns the traverses, feeds and dwells in order. The
reader (:mod:`.gcode`) works out those heights from the words and its modal state and
executes the moves.

The rules, from LinuxCNC's ``interp_cycles.cc`` (``CYCLE_MACRO`` and ``convert_cycle_*``),
checked against its ``rs274``:

- before the first hole, if the drilling axis is below R it rapids up to R (the caller does
  this preliminary move); each repeat then rapids in the plane to the hole -- at the current
  height on the first repeat if that is above R, then down to R; on later repeats at the
  retract height, then down to R if that is higher;
- G81: feed to the bottom, rapid out; G82: the same with a dwell at the bottom;
- G73 (chip break): feed down by Q, rapid up 0.010 in (0.254 mm), until the bottom, then
  rapid out; G83 (peck): feed down by Q, rapid out to R, rapid back to 0.010 in above the
  last depth, until the bottom, then rapid out;
- G85: feed to the bottom, feed out to R, rapid to the retract height; G89: feed to the
  bottom, dwell, feed out to the retract height; G86: feed to the bottom, dwell, (spindle
  stop) rapid out;
- G87 (back boring): rapid to the offset point (I, J) at R, down to the bottom, to the hole,
  feed up to K and back down, rapid to the offset point, out to the retract height, back to
  the hole.

"Out" is the retract height: R under G99, the drilling axis's height before the cycles
began (or R if higher) under G98.
"""

from __future__ import annotations

__all__ = ["cycle_moves", "PECK_CLEARANCE_INCH"]

#: How far above the last peck depth G73/G83 return (LinuxCNC's G83_RAPID_DELTA, inches).
PECK_CLEARANCE_INCH = 0.010


def cycle_moves(code: int, plane, position, holes, *, r: float, bottom: float, clear: float,
                current: float, dwell: float = 0.0, peck: float = 0.0,
                peck_clearance: float = 0.0, back_bore=None) -> list[tuple]:
    """The moves of one canned-cycle block.

    Parameters
    ----------
    code : int
        73, 81, 82, 83, 85, 86, 87 or 89.
    plane : (int, int, int)
        Indices of the plane's first and second axis and of the drilling axis.
    position : sequence of 5 floats
        The position the other axes keep (the rotary axes).
    holes : sequence of (float, float)
        The hole of each repeat in the plane's two axes.
    r, bottom, clear, current : float
        The R plane, the bottom, the retract height and the drilling axis's height before the
        first repeat (after the preliminary move to R).
    dwell : float
        Seconds at the bottom (G82, G86, G89).
    peck, peck_clearance : float
        Q, and the return above the last depth (G73, G83).
    back_bore : (float, float, float), optional
        G87: the offset of the entry point in the plane (I, J) and the top of the back bore
        (K, on the drilling axis).

    Returns
    -------
    list of tuple
        ``("rapid", point)``, ``("feed", point)`` and ``("dwell", seconds)`` in order.
    """
    a, b, n = plane
    moves = []

    def go(kind, x, y, z):
        p = list(position)
        p[a], p[b], p[n] = x, y, z
        moves.append((kind, p))

    for k, (x, y) in enumerate(holes):
        if k == 0 and current > r:
            go("rapid", x, y, current)
            go("rapid", x, y, r)
        else:
            go("rapid", x, y, clear)
            if clear > r:
                go("rapid", x, y, r)
        if code in (81, 82, 86):
            go("feed", x, y, bottom)
            if code != 81:
                moves.append(("dwell", dwell))
            go("rapid", x, y, clear)
        elif code in (73, 83):
            depth = r - peck
            while depth > bottom:
                go("feed", x, y, depth)
                if code == 83:
                    go("rapid", x, y, r)
                go("rapid", x, y, depth + peck_clearance)
                depth -= peck
            go("feed", x, y, bottom)
            go("rapid", x, y, clear)
        elif code == 85:
            go("feed", x, y, bottom)
            go("feed", x, y, r)
            go("rapid", x, y, clear)
        elif code == 89:
            go("feed", x, y, bottom)
            moves.append(("dwell", dwell))
            go("feed", x, y, clear)
        elif code == 87:
            i, j, top = back_bore
            go("rapid", x + i, y + j, r)
            go("rapid", x + i, y + j, bottom)
            go("rapid", x, y, bottom)
            go("feed", x, y, top)
            go("feed", x, y, bottom)
            go("rapid", x + i, y + j, bottom)
            go("rapid", x + i, y + j, clear)
            go("rapid", x, y, clear)
        else:  # pragma: no cover - the reader passes only the codes above
            raise ValueError(f"no canned cycle G{code}")
    return moves
