"""Canned cycles in the G-code reader (the reader's :class:`~.gcode._Reader` mixes this in):
a cycle block's heights (R, the bottom, G98/G99's retract), its sticky words, repeats (L),
increments (G91) and polar holes worked out from the words and the modal state, and its moves
from :func:`._cycles.cycle_moves` executed."""

from __future__ import annotations

import math

from ._common import INCH
from ._cycles import PECK_CLEARANCE_INCH, cycle_moves
from ._gcode_codes import _MOTION, _PLANES
from .program import Stop


class CycleBlocks:
    """The reader's canned cycles, expanded into moves."""

    def cycle(self, values, spelled, scale, previous, g_word):
        """A canned-cycle block (G73, G81-G83, G85-G87, G89), expanded into moves as LinuxCNC
        does (:mod:`._cycles`): the hole at the block's X Y (G91: every repeat L moves by
        them), R the retract plane, the bottom on the plane's normal axis; R, the bottom, P,
        Q, I J K carry over while the same cycle continues."""
        code = self.motion
        word = g_word.get(next((c for c in g_word if _MOTION.get(c) == code), None),
                          f"G{code}")
        a, b, n = self.plane
        axis, first, second = self.axes[n], self.axes[a], self.axes[b]
        if self.inverse_time:
            self.fail("canned cycles need feed per minute (G94), not inverse time (G93)", word)
        if not math.isfinite(self.feed):
            self.fail("canned cycle without a feed rate: program F (G94, per minute)", word)
        if "G43.4" in self.tcp_sources:
            self.fail("canned cycles under G43.4/G43.5 (tool centre point) are not supported",
                      word)
        rotary = [spelled[a] for a in self.axes[3:] if a in spelled]
        if rotary:
            self.fail(f"the rotary axes may not move in a canned cycle ({rotary[0]})", rotary[0])
        polar = "@" in values or "^" in values
        if polar and self.plane != _PLANES[170]:
            self.fail("polar coordinates (@ ^) in a canned cycle need the XY plane (G17)",
                      spelled.get("@", spelled.get("^")))
        same = previous == code
        sticky = self.cycle_words if same else {}
        given = dict(sticky)
        for letter, key in (("R", "R"), (axis, "Z"), ("P", "P"), ("Q", "Q"), ("I", "I"),
                            ("J", "J"), ("K", "K")):
            if letter in values:
                given[key] = values[letter]
        needs = {"R": "R (the retract plane)", "Z": f"{axis} (the bottom)"}
        if code in (82, 86, 89):
            needs["P"] = "P (the dwell, s)"
        if code in (73, 83):
            needs["Q"] = "Q (the peck depth)"
        if code == 87:
            needs.update(I="I", J="J", K="K")
        for key, what in needs.items():
            if key not in given:
                self.fail(f"G{code} needs {what} when the cycle begins", word)
        repeats = values.get("L", 1.0)
        if repeats != int(repeats) or repeats < 1:
            self.fail(f"canned cycle repeats {spelled.get('L')!r} must be a whole number >= 1 "
                      "(LinuxCNC refuses L0)", spelled.get("L", word))
        if code in (73, 83) and not given["Q"] > 0:
            self.fail(f"G{code} needs a peck depth Q > 0", spelled.get("Q", word))
        if code in (82, 86, 89) and not given["P"] >= 0:
            self.fail(f"G{code} needs a dwell P >= 0", spelled.get("P", word))
        current = list(self.prog)
        unknown = [self.axes[i] for i in (a, b, n) if not math.isfinite(current[i])]
        if unknown:
            self.fail(f"canned cycle before the position of axis {unknown[0]} is known", word)
        offset = [o + g for o, g in zip(self.g5x, self.g92)]
        height = current[n]
        if self.cycle_start is None:
            self.cycle_start = height
        initial = self.cycle_start
        if self.incremental:
            r = given["R"] * scale + initial
            bottom = r + given["Z"] * scale
        else:
            r = given["R"] * scale + offset[n]
            bottom = given["Z"] * scale + offset[n]
        if r < bottom:
            self.fail(f"the retract plane R is below the bottom {axis} of the cycle", word)
        holes = self.cycle_holes(values, spelled, scale, int(repeats), first, second, a, b,
                                 offset)
        if initial < r:
            # the preliminary move: up to R where the cycles begin below it
            up = list(current)
            up[n] = r
            self.go(up, True, spelled)
            current, initial, height = up, r, r
        clear = initial if self.retract_initial else r
        back_bore = None
        if code == 87:
            top = given["K"] * scale + (bottom if self.incremental else offset[n])
            back_bore = (given["I"] * scale, given["J"] * scale, top)
        peck_clearance = PECK_CLEARANCE_INCH * INCH
        moves = cycle_moves(code, self.plane, current, holes, r=r, bottom=bottom, clear=clear,
                            current=height, dwell=given.get("P", 0.0),
                            peck=given.get("Q", 0.0) * scale, peck_clearance=peck_clearance,
                            back_bore=back_bore)
        for kind, point in moves:
            if kind == "dwell":
                self.stops.append(Stop(self.n_moves, self.row, "dwell", float(point)))
                continue
            # the other axes where they are (a first feed move may just have made them known)
            target = list(self.prog)
            for i in (a, b, n):
                target[i] = point[i]
            self.go(target, kind == "rapid", spelled)
        self.cycle_words = {k: v for k, v in given.items() if k in "RZPQIJK"}

    def cycle_holes(self, values, spelled, scale, repeats, first, second, a, b, offset):
        """The hole of each repeat in the plane (absolute): G90 at the words (or where the
        axes are), G91 the words added once per repeat; polar @ ^ about the work origin."""
        x, y = self.prog[a], self.prog[b]
        if "@" in values or "^" in values:
            # in program coordinates (the work origin), as LinuxCNC's CYCLE_MACRO
            px, py = (x - offset[a]) / scale, (y - offset[b]) / scale
            holes = []
            if not self.incremental:
                radius = values.get("@", math.hypot(px, py))
                theta = math.radians(values["^"]) if "^" in values else math.atan2(py, px)
                px, py = radius * math.cos(theta), radius * math.sin(theta)
                holes = [(px, py)] * repeats
            else:
                for _ in range(repeats):
                    if px == 0.0 and py == 0.0:
                        self.fail("incremental polar coordinates at the origin have no "
                                  "direction", spelled.get("@", spelled.get("^")))
                    if "@" in values:
                        radius = math.hypot(px, py) + values["@"]
                        theta = math.atan2(py, px)
                        px, py = radius * math.cos(theta), radius * math.sin(theta)
                    if "^" in values:
                        radius = math.hypot(px, py)
                        theta = math.atan2(py, px) + math.radians(values["^"])
                        px, py = radius * math.cos(theta), radius * math.sin(theta)
                    holes.append((px, py))
            return [(hx * scale + offset[a], hy * scale + offset[b]) for hx, hy in holes]
        if not self.incremental:
            x = values[first] * scale + offset[a] if first in values else x
            y = values[second] * scale + offset[b] if second in values else y
            return [(x, y)] * repeats
        dx = values.get(first, 0.0) * scale
        dy = values.get(second, 0.0) * scale
        return [(x + dx * (k + 1), y + dy * (k + 1)) for k in range(repeats)]

