"""Contour blocks of Heidenhain TNC conversational programs (the reader's
:class:`~.heidenhain._Heidenhain` mixes this in): ``L`` and ``LN`` straight blocks (absolute
and incremental words, ``FMAX``/``F``, ``R0``, ``M``; ``LN``'s tool vector ``TX TY TZ`` under
``M128`` / ``FUNCTION TCPM``), machine-coordinate moves (``M91``), the circle centre ``CC``
and the arcs ``C`` (about CC), ``CR`` (by radius) and ``CT`` (tangential), each translated
into the words of one RS274/NGC block for the G-code reader's interpreter."""

from __future__ import annotations

import math

import numpy as np

from ._common import INCH
from ._ngc import format_number

#: Vector components below this length are no direction.
_TINY = 1e-12


class ContourBlocks:
    """The Heidenhain reader's contour blocks: straight moves, tool vectors, circles."""

    # ------------------------------------------------------------------ contour blocks
    def contour(self, kind: str, rest: str, comments) -> bool:
        words = self.words(rest)
        names = [n for n, _ in words]
        for name, written in words:
            if name in ("RL", "RR") or name == "R" and kind != "CR" and written not in ("0",
                                                                                   "+0"):
                self.fail(f"radius compensation {name}{written or ''} is not read; post-process "
                          "the tool centre path with R0", f"{name}{written or ''}")
        if self.shift_pending is not None:
            construct, row = self.shift_pending
            self.fail(f"a move after the datum shift {construct} on line {row}, given under "
                      "an active PLANE function (a shift in the tilted frame), is not read; "
                      "post-process the datum shift before PLANE", kind)
        if kind == "CC":
            return self.circle_centre(words)
        m = self.m_words(words)
        machine = "M" in names and any(n == "M" and self.value("M", w) == 91
                                       for n, w in words)
        rapid = "FMAX" in names
        if "FAUTO" in names:
            if self.auto_feed is None:
                self.fail("FAUTO without a feed in TOOL CALL", "FAUTO")
            self.feed = self.auto_feed
        for name, written in words:
            if name == "F" and written is not None:
                self.feed = self.value("F", written)
        allowed = {"L": "XYZABCUVW", "LN": "XYZ", "C": "XYZ", "CR": "XYZ", "CT": "XYZ"}[kind]
        targets = {}
        for name, written in words:
            axis = name[1:] if name.startswith("I") and len(name) == 2 else name
            if len(axis) == 1 and axis in "XYZABCUVW":
                if axis not in allowed:
                    self.fail(f"{name}{written} in a {kind} block is not read", name + written)
                if axis not in self.index:
                    self.fail(f"axis {axis} ({name}{written}): the machine's axes are "
                              f"{' '.join(self.axes)}", name + written)
                if axis in targets:
                    self.fail(f"axis {axis} twice in one block", name + written)
                # under a PLANE function the rotary words are its angles (Q120-Q122), read
                # by turn_to_plane
                under_plane = self.plane is not None and axis in self.axes[3:]
                targets[axis] = (name.startswith("I"),
                                 None if under_plane else self.value(name, written),
                                 f"{name}{written}")
            elif name not in ("R", "F", "FMAX", "FAUTO", "M", "DR", "NX", "NY", "NZ", "TX",
                              "TY", "TZ"):
                self.fail(f"word {name}{written or ''} is not read in an {kind} block",
                          f"{name}{written or ''}")
        feed = [] if rapid or self.feed is None else [
            ("F", self.feed * (0.1 if self.inch else 1.0), _format(self.feed),
             next((f"F{w}" for n, w in words if n == "F" and w), "F"))]
        motion = ("G", 0.0 if rapid else 1.0, "0" if rapid else "1", kind)
        if kind == "L" and machine:
            return self.machine_move(targets, motion, feed, m, comments)
        if kind == "L" and self.plane is not None and any(a in targets for a in self.axes[3:]):
            self.turn_to_plane(targets, "L")
            for letter in self.axes[3:]:
                targets.pop(letter, None)
            if not targets:
                return self.execute(m, comments) if m or comments else False
        start = list(self.g.prog)
        end_words = self.absolute_words(targets, kind)
        if kind == "LN":
            end_words += self.tool_vector(words, end_words)
        if kind in ("L", "LN"):
            done = self.execute([motion] + end_words + feed + m, comments)
            self.tangent = self.direction(start, self.g.prog)
            return done
        if rapid:
            self.fail(f"FMAX on a circular block ({kind}) is not read", "FMAX")
        return self.arc(kind, words, start, end_words, feed, m, comments)

    def absolute_words(self, targets, kind) -> list:
        """G-code words (G90, program units) of the block's axis words: incremental ones
        from where the axis is, rotary ones under M126 the shorter way."""
        scale = INCH if self.inch else 1.0
        out = []
        for i, letter in enumerate(self.axes):
            if letter not in targets:
                continue
            incremental, value, spelled = targets[letter]
            unit = scale if i < 3 else 1.0
            offset = self.g.g5x[i] + self.g.g92[i]
            current = self.g.prog[i]
            if incremental:
                if not math.isfinite(current):
                    self.fail(f"incremental {spelled} before the position of {letter} is known",
                              spelled)
                absolute = current + value * unit
            else:
                absolute = value * unit + offset
                if i == 4 and self.shortest and math.isfinite(current):
                    absolute = current + (absolute - current + 180.0) % 360.0 - 180.0
            word = (absolute - offset) / unit
            out.append((letter, word, _format(word), spelled))
        return out

    def machine_move(self, targets, motion, feed, m, comments) -> bool:
        """L ... M91: the coordinates of this block are the machine's (G53)."""
        if any(incremental for incremental, _, _ in targets.values()):
            self.fail("incremental words with M91 are not read", "M91")
        words = [("G", 53.0, "53", "M91"), motion]
        for letter, (_, value, spelled) in targets.items():
            words.append((letter, value, _format(value), spelled))
        return self.execute(words + feed + m, comments)

    def tool_vector(self, words, end_words) -> list:
        """LN ... TX TY TZ: the rotary axes that put the tool along the vector (through the
        kinematics' inverse, C on the branch nearest where it is)."""
        vector = {n: self.value(n, w) for n, w in words if n in ("TX", "TY", "TZ")}
        if not vector:
            return []
        if not self.tcp:
            self.fail("LN with a tool vector (TX TY TZ) outside tool centre point mode: the "
                      "TNC then does not tilt the tool; post-process with M128 or FUNCTION "
                      "TCPM before it", "TX")
        o = np.array([vector.get("TX", 0.0), vector.get("TY", 0.0), vector.get("TZ", 0.0)])
        length = float(np.linalg.norm(o))
        if length < _TINY:
            self.fail("the tool vector TX TY TZ is zero", "TX")
        current = self.g.prog
        if not all(math.isfinite(v) for v in current[3:]):
            self.fail("LN with a tool vector before the rotary axes' positions are known",
                      "TX")
        q = self.g.kinematics.inverse(np.zeros((1, 3)), (o / length)[None, :],
                                      c_near=np.array([math.radians(current[4])]))[0]
        return [(letter, math.degrees(q[3 + k]), _format(math.degrees(q[3 + k])),
                 "TX TY TZ") for k, letter in enumerate(self.axes[3:])]

    def circle_centre(self, words) -> bool:
        """CC X Y: the centre of the following C blocks (XY plane)."""
        scale = INCH if self.inch else 1.0
        centre = [self.g.prog[0], self.g.prog[1]]
        for name, written in words:
            axis = name[1:] if name.startswith("I") and len(name) == 2 else name
            if axis not in ("X", "Y"):
                self.fail(f"CC {name}{written or ''}: only circle centres in the XY plane (X "
                          "Y) are read; post-process arcs in other planes as straight "
                          "blocks", f"{name}{written or ''}")
            k = "XY".index(axis)
            value = self.value(name, written) * scale
            if name.startswith("I"):
                if not math.isfinite(self.g.prog[k]):
                    self.fail(f"incremental CC {name}{written} before the position is known",
                              name + written)
                centre[k] = self.g.prog[k] + value
            else:
                centre[k] = value + self.g.g5x[k] + self.g.g92[k]
        if not all(math.isfinite(c) for c in centre):
            self.fail("CC before the position is known: give both X and Y", "CC")
        self.centre = tuple(centre)
        return False

    def arc(self, kind, words, start, end_words, feed, m, comments) -> bool:
        scale = INCH if self.inch else 1.0
        if not all(math.isfinite(v) for v in start[:2]):
            self.fail(f"{kind} before the position is known: position with L first", kind)
        direction = [w for n, w in words if n == "DR"]
        target = list(start)
        for letter, value, _, _ in end_words:
            i = self.index[letter]
            target[i] = value * (scale if i < 3 else 1.0) + self.g.g5x[i] + self.g.g92[i]
        if kind == "CT":
            if direction:
                self.fail("CT takes no direction DR (it follows from the tangent)", "DR")
            if self.tangent is None:
                self.fail("CT without a previous contour block to be tangent to", "CT")
            t = self.tangent
            n = (-t[1], t[0])
            d = (target[0] - start[0], target[1] - start[1])
            dn = d[0] * n[0] + d[1] * n[1]
            if abs(dn) <= 1e-9 * max(1.0, math.hypot(*d)):
                self.fail("CT end point on the tangent: that is a straight line, not an arc",
                          "CT")
            s = (d[0] ** 2 + d[1] ** 2) / (2.0 * dn)
            centre = (start[0] + s * n[0], start[1] + s * n[1])
            ccw = s > 0
        else:
            if len(direction) != 1 or direction[0] not in ("+", "-"):
                self.fail(f"{kind} needs its direction, DR+ (counter-clockwise) or DR- "
                          "(clockwise)", "DR")
            ccw = direction[0] == "+"
            centre = self.centre
            if kind == "C" and centre is None:
                self.fail("C without a circle centre: program CC first", "C")
        code = ("G", 3.0 if ccw else 2.0, "3" if ccw else "2", kind)
        g_words = [code] + end_words
        if kind == "CR":
            radius = [(n, w) for n, w in words if n == "R"]
            if not radius:
                self.fail("CR needs its radius R", "CR")
            r = self.value(*radius[0])
            g_words.append(("R", r, _format(r), f"R{radius[0][1]}"))
        else:
            i, j = ((centre[0] - start[0]) / scale, (centre[1] - start[1]) / scale)
            g_words += [("I", i, _format(i), kind), ("J", j, _format(j), kind)]
        done = self.execute(g_words + feed + m, comments)
        end = self.g.prog
        if kind == "CR":
            centre = _radius_centre(start, end, r * scale, ccw)
        if centre is not None and all(math.isfinite(v) for v in centre):
            radial = (end[0] - centre[0], end[1] - centre[1])
            self.tangent = _unit((-radial[1], radial[0]) if ccw else (radial[1], -radial[0]))
        return done

    def direction(self, start, end):
        d = (end[0] - start[0], end[1] - start[1])
        if not all(math.isfinite(v) for v in d) or math.hypot(*d) < _TINY:
            return self.tangent
        return _unit(d)


def _radius_centre(start, end, radius, ccw):
    """The centre of an arc given by its radius (G-code's R rule: R > 0 the shorter arc),
    for the tangent at its end; None for a full circle."""
    chord = math.hypot(end[0] - start[0], end[1] - start[1])
    if chord == 0.0:
        return None
    h = math.sqrt(max(radius * radius - 0.25 * chord * chord, 0.0)) / chord
    side = (1.0 if ccw else -1.0) * (1.0 if radius > 0 else -1.0)
    return (0.5 * (start[0] + end[0]) - side * h * (end[1] - start[1]),
            0.5 * (start[1] + end[1]) + side * h * (end[0] - start[0]))


def _unit(v):
    length = math.hypot(v[0], v[1])
    return (v[0] / length, v[1] / length) if length > _TINY else None


def _format(value: float) -> str:
    return format_number(float(value))
