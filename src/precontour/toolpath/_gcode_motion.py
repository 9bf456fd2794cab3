"""Motion in the G-code reader (the reader's :class:`~.gcode._Reader` mixes this in): a
block's target (absolute, incremental, polar), straight moves and arcs (G2/G3 in any plane,
helices, turns; cut into chords within the arc tolerance), feeds (G93 inverse time, G94 per
minute) and each move's duration, and the moves as programmed."""

from __future__ import annotations

import math

import numpy as np

from ._gcode_codes import (ARC_RADIUS_RTOL, ARC_RADIUS_TOLERANCE, MAX_ARC_CHORDS, MAX_COORDINATE,
                           _NO_CENTRE)


class MotionBlocks:
    """The reader's moves: targets, straight moves, arcs, feeds and durations."""

    # ------------------------------------------------------------------ motion
    def target(self, values, spelled, scale):
        """The end point of the block's axis words (absolute coordinates, mm and deg): G90
        words are in the work coordinates (work offset and G92 offset added), G91 words add
        to the position; an axis without a word stays."""
        target = list(self.prog)
        for i, letter in enumerate(self.axes):
            if letter in values:
                value = values[letter] * (scale if i < 3 else 1.0)
                if self.incremental:
                    if not math.isfinite(target[i]):
                        if value == 0.0:
                            continue  # no motion on an axis not known yet (G91 G28 Z0)
                        self.fail(f"incremental (G91) move of axis {letter} before its "
                                  "position is known", spelled[letter])
                    value += target[i]
                else:
                    value += self.g5x[i] + self.g92[i]
                if not abs(value) <= MAX_COORDINATE:
                    self.fail(f"coordinate {spelled[letter]!r} is out of range", spelled[letter])
                target[i] = value
        if "@" in values or "^" in values:
            target[0], target[1] = self.polar(values, spelled, scale)
        return target

    def polar(self, values, spelled, scale):
        """LinuxCNC's polar coordinates: X Y from a radius @ and an angle ^ (degrees) about
        the work origin, in any plane; G91 adds them to the current radius and angle."""
        word = spelled.get("@", spelled.get("^"))
        if "X" in values or "Y" in values:
            self.fail("polar coordinates (@ ^) and X or Y in one block", word)
        x, y = self.program_position()[:2]
        if not (math.isfinite(x) and math.isfinite(y)):
            self.fail("polar coordinates (@ ^) before the X and Y position is known", word)
        radius, angle = math.hypot(x, y), math.degrees(math.atan2(y, x))
        if self.incremental:
            radius += values.get("@", 0.0)
            angle += values.get("^", 0.0)
        else:
            radius = values.get("@", radius)
            angle = values.get("^", angle)
        angle = math.radians(angle)
        return (radius * math.cos(angle) * scale + self.g5x[0] + self.g92[0],
                radius * math.sin(angle) * scale + self.g5x[1] + self.g92[1])

    def move(self, values, spelled, scale, g_codes):
        if self.motion is None:
            word = next((spelled[a] for a in self.axes if a in spelled), None)
            if self.cancelled:
                self.fail("axis words after G80 without a motion code (G0, G1, G2, G3)", word)
            self.fail("axis words before any motion code (G0, G1, G2, G3)", word)
        target = self.target(values, spelled, scale)
        arc = self.motion in (2, 3)
        if self.start is None:
            target = self.first_move(target, self.motion == 0, arc, g_codes)
            if target is None:
                return
        if arc:
            self.arc(target, values, spelled, scale)
        else:
            self.go(target, self.motion == 0, spelled)

    def first_move(self, target, rapid, arc=False, g_codes=()):
        """Before the start: None where the move only positions (a rapid, or the block that
        completes the axes: the machine starts from its end), else the target of the first
        feed move with the axes not known yet taken as 0."""
        if all(math.isfinite(v) for v in target):
            if arc:
                self.fail("the first block that sets all axes is an arc: its start point is "
                          "unknown; position with G0 first", g_codes[0][1] if g_codes else None)
            self.prog = list(target)
            self.deferred = []
            self.begin(self.row)
            return None
        if rapid:
            self.prog = list(target)
            return None
        target = self.resolve(target)
        self.begin(self.row)
        return target

    def go(self, target, rapid, spelled):
        """A straight move to ``target`` (absolute coordinates in the current mode)."""
        if self.start is None:
            target = self.first_move(target, rapid)
            if target is None:
                return
        duration, feed = math.nan, math.nan
        if not rapid:
            duration, feed = self.timing(self.prog, target, 1, spelled)
        self.add(target, rapid, duration, feed)

    def begin(self, row):
        self.start = list(self.to_workpiece(self.prog)) if self.framed else list(self.prog)
        self.start_line = row
        self.start_tcp = self.tcp
        self.start_length = self.length

    def timing(self, start, end, n_pieces, spelled, length=None):
        """(duration s, feed mm/s) of each of ``n_pieces`` equal pieces of a feed move."""
        if self.inverse_time:
            if "F" not in spelled:
                self.fail("inverse-time feed (G93) needs F on every G1/G2/G3 block", "F")
            return 60.0 / self.block_f / n_pieces, math.nan
        if not math.isfinite(self.feed):
            self.fail("feed move without a feed rate: program F (G94, per minute)",
                      f"G{self.motion}")
        if length is None:
            length = math.dist(start[:3], end[:3])
        if length <= 0.0:
            length = math.dist(start[3:], end[3:])  # rotary only: F in degrees per minute
        return 60.0 * length / self.feed / n_pieces, self.feed / 60.0

    def programmed_feed(self, rapid):
        """F as programmed for a move: mm/min in G94, 1/min in G93, NaN for a rapid."""
        if rapid:
            return math.nan
        return self.block_f if self.inverse_time else self.feed

    def add(self, target, rapid, duration, feed, tcp=None):
        # machine axes (tcp given: G53, G53.1) are no program coordinates
        end = self.to_workpiece(target).tolist() if tcp is None and self.framed \
            else list(target)
        tcp = self.tcp if tcp is None else tcp
        self.programmed.append((0 if rapid else 1, end, _NO_CENTRE, 0, 0,
                                self.inverse_time, self.programmed_feed(rapid), self.row, tcp,
                                self.n_moves))
        self.moves.append((end, rapid, duration, feed, self.row, tcp, self.path_tolerance,
                           self.length))
        self.prog = list(target)
        self.n_moves += 1

    def add_many(self, ends, rapid, duration, feed, lines, programmed):
        """Append k moves at once (arrays of k rows; scalars are broadcast), with their
        programmed moves (the columns of :attr:`programmed`, or one arc's row)."""
        k = ends.shape[0]
        self.prog = ends[-1].tolist()
        if self.framed:
            ends = self.to_workpiece(ends)
            if isinstance(programmed, tuple) and not isinstance(programmed[0], np.ndarray):
                # an arc: its end, and its centre as a point (all three axes) of the plane
                kind, end, centre, *rest = programmed
                programmed = (kind, self.to_workpiece(end).tolist(),
                              self.to_workpiece(centre).tolist(), *rest)
            else:
                programmed = (programmed[0], ends, *programmed[2:])
        self.moves.extend((np.asarray(ends, dtype=float),
                           np.broadcast_to(np.asarray(rapid, dtype=bool), (k,)),
                           np.broadcast_to(np.asarray(duration, dtype=float), (k,)),
                           np.broadcast_to(np.asarray(feed, dtype=float), (k,)),
                           np.broadcast_to(np.asarray(lines, dtype=np.int64), (k,)),
                           np.full(k, self.tcp), np.full(k, self.path_tolerance),
                           np.full(k, self.length)))
        if isinstance(programmed, tuple) and not isinstance(programmed[0], np.ndarray):
            self.programmed.append(programmed)
        else:
            self.programmed.extend(programmed)
        self.n_moves += k

    def arc(self, target, values, spelled, scale):
        a, b, n = self.plane
        centre_words = ("IJK"[a], "IJK"[b])
        start = self.prog
        sa, sb, ea, eb = start[a], start[b], target[a], target[b]
        if "R" in values:
            if any(w in spelled for w in "IJK"):
                self.fail("an arc is given by R or by I J K, not both", spelled["R"])
            radius = values["R"] * scale
            chord = math.hypot(ea - sa, eb - sb)
            if chord == 0.0:
                self.fail("an R arc cannot be a full circle (start = end); use I J K",
                          spelled["R"])
            h2 = radius * radius - 0.25 * chord * chord
            if h2 < 0.0:
                if 0.5 * chord - abs(radius) > max(ARC_RADIUS_TOLERANCE,
                                                   ARC_RADIUS_RTOL * abs(radius)):
                    self.fail(f"arc radius {abs(radius):g} mm is shorter than half the chord "
                              f"({0.5 * chord:g} mm)", spelled["R"])
                h2 = 0.0
            h = math.sqrt(h2) / chord
            # centre on the left of the chord for a counter-clockwise short arc
            side = (1.0 if self.motion == 3 else -1.0) * (1.0 if radius > 0 else -1.0)
            ca = 0.5 * (sa + ea) - side * h * (eb - sb)
            cb = 0.5 * (sb + eb) + side * h * (ea - sa)
        else:
            offsets = [values.get(w) for w in centre_words]
            if offsets[0] is None and offsets[1] is None:
                self.fail(f"arc without centre: G{self.motion} in this plane needs "
                          f"{centre_words[0]}/{centre_words[1]} or R",
                          f"G{self.motion}")
            oa, ob = ((o or 0.0) * scale for o in offsets)
            ca, cb = (oa, ob) if self.arc_absolute else (sa + oa, sb + ob)
            normal_word = "IJK"[n]
            if normal_word in spelled:
                self.fail(f"word {spelled[normal_word]!r} is not in the arc's plane",
                          spelled[normal_word])
        r0 = math.hypot(sa - ca, sb - cb)
        r1 = math.hypot(ea - ca, eb - cb)
        if r0 == 0.0:
            self.fail("arc radius is zero (the centre is the start point)", f"G{self.motion}")
        if abs(r1 - r0) > max(ARC_RADIUS_TOLERANCE, ARC_RADIUS_RTOL * r0):
            self.fail(f"arc start and end radii differ by {abs(r1 - r0):.6g} mm (start "
                      f"{r0:.6g}, end {r1:.6g}; tolerance {ARC_RADIUS_TOLERANCE:g} mm or "
                      f"{ARC_RADIUS_RTOL:g} of the radius)", f"G{self.motion}")
        theta0 = math.atan2(sb - cb, sa - ca)
        theta1 = math.atan2(eb - cb, ea - ca)
        ccw = self.motion == 3
        sweep = (theta1 - theta0) % (2 * math.pi) if ccw else -((theta0 - theta1) % (2 * math.pi))
        if math.hypot(ea - sa, eb - sb) <= 1e-12 * max(1.0, r0):
            sweep = 2 * math.pi if ccw else -2 * math.pi
        turns = values.get("P")
        if turns is not None:
            if turns != int(turns) or turns < 1:
                self.fail(f"arc turns {spelled['P']!r} must be a whole number >= 1",
                          spelled["P"])
            sweep += math.copysign(2 * math.pi * (turns - 1), sweep)
        r_max = max(r0, r1)
        tol = min(self.arc_tolerance, 0.5 * r_max)
        step = 2.0 * math.acos(1.0 - tol / r_max)
        n_chords = max(1, math.ceil(abs(sweep) / step - 1e-9))
        if abs(sweep) > math.pi / 2:
            n_chords = max(n_chords, math.ceil(abs(sweep) / (math.pi / 2)))
        if n_chords > MAX_ARC_CHORDS:
            self.fail(f"arc needs {n_chords} chords (more than {MAX_ARC_CHORDS}) within "
                      f"{self.arc_tolerance:g} mm", f"G{self.motion}")
        u = np.arange(1, n_chords + 1) / n_chords
        angle = theta0 + sweep * u
        radius = r0 + (r1 - r0) * u
        points = np.array(start, dtype=float) + u[:, None] * (np.array(target) - start)
        points[:, a] = ca + radius * np.cos(angle)
        points[:, b] = cb + radius * np.sin(angle)
        points[-1] = target
        helix = math.hypot(0.5 * (r0 + r1) * abs(sweep), target[n] - start[n])
        duration, feed = self.timing(start, target, n_chords, spelled, length=helix)
        centre = [math.nan] * 3
        centre[a], centre[b] = ca, cb
        if self.framed:
            centre[n] = start[n]   # a point of the tilted plane, given in all three axes
        rotation = (1 if ccw else -1) * int(turns or 1)
        plane = {(0, 1, 2): 17, (2, 0, 1): 18, (1, 2, 0): 19}[self.plane]
        self.add_many(points, False, duration, feed, self.row,
                      (2, list(target), centre, plane, rotation, self.inverse_time,
                       self.programmed_feed(False), self.row, self.tcp, self.n_moves))
