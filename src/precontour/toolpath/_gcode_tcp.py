"""Tool centre point and tilted planes in the G-code reader (the reader's
:class:`~.gcode._Reader` mixes this in): TCP switched on and off (the position carried over
through the kinematics), programmed coordinates resolved to machine axes, Fanuc's G68.2 /
G53.1 / G69 tilted working plane (the solution within travel from :mod:`._swivel`), and the
frames that map the program's coordinates to the workpiece's."""

from __future__ import annotations

import math

import numpy as np

from ..errors import ProgramError
from ._gcode_codes import _ZERO, _euler_zxz, _tilt_travel
from ._swivel import rotary_travel, swivel


class TcpBlocks:
    """The reader's TCP mode, machine axes of programmed points, tilted planes."""

    # ------------------------------------------------------------------ coordinates
    def convert(self, pos, from_tcp: bool, to_tcp: bool) -> list[float]:
        """A complete position (mm, deg) from one frame to the other: the tool tip in the
        workpiece frame (TCP) or the machine axes."""
        if from_tcp == to_tcp:
            return list(pos)
        q = np.array(pos, dtype=float)
        q[3:] = np.radians(q[3:])
        if from_tcp:
            xyz = self.kinematics.linear_axes(q[None, :3], q[None, 3:])
        else:
            xyz, _ = self.kinematics.forward(q[None, :])
        return [*map(float, np.asarray(xyz).reshape(3)), *pos[3:]]

    def set_tcp(self, on: bool):
        if on == self.tcp:
            return
        if all(math.isfinite(v) for v in self.prog):
            self.prog = self.from_workpiece(self.convert(self.to_workpiece(self.prog),
                                                         self.tcp, on))
        else:
            # the linear axes' meaning changes; they follow from this partial position once
            # the unknown axes are taken as 0 (see resolve)
            self.deferred.append((list(self.prog), self.tcp))
            self.prog = [math.nan] * 3 + self.prog[3:]
        self.tcp = on

    def resolve(self, target=None):
        """Take the axes never programmed as 0 (before the first feed move): in the frame they
        were unknown in, carried through the TCP switches since; one notice names them."""
        chain = self.deferred + [(list(self.prog), self.tcp)]
        first = chain[0][0]
        missing = [self.axes[i] for i in range(5) if not math.isfinite(first[i])]
        full = [0.0 if not math.isfinite(v) else v for v in first]
        for (_, frame), (pos, next_frame) in zip(chain[:-1], chain[1:]):
            full = self.convert(full, frame, next_frame)
            full = [v if math.isfinite(v) else f for v, f in zip(pos, full)]
        self.deferred = []
        if missing:
            self.notices.append(f"{self.source}, line {self.row}: axes {' '.join(missing)} "
                                "were not programmed before the first feed move; taken as 0")
        self.prog = list(full)
        if target is not None:
            target = [t if math.isfinite(t) else r for t, r in zip(target, full)]
        return target

    def machine_axes(self, prog: np.ndarray, tcp: np.ndarray, length: np.ndarray
                     ) -> np.ndarray:
        """Machine axes (mm, rad) of programmed coordinates (mm, deg) in either mode; TCP
        tips through the kinematics of each move's tool length (NaN: the file's)."""
        q = np.array(prog, dtype=float)
        q[:, 3:] = np.radians(q[:, 3:])
        if tcp.any():
            key = np.where(np.isnan(length), -np.inf, length)
            for value in np.unique(key[tcp]):
                rows = tcp & (key == value)
                kinematics = self.kinematics_of(math.nan if value == -np.inf else value)
                q[rows, :3] = kinematics.linear_axes(q[rows, :3], q[rows, 3:])
        return q

    def tilted_plane(self, codes, values, spelled, scale, g_word):
        """Fanuc's tilted working plane. ``G68.2 X Y Z I J K``: the program's coordinates are
        those of a frame with its origin at X Y Z (work coordinates) turned by the Euler
        angles I, J, K (degrees; about Z, then the new X, then the new Z); its moves are tool
        tip positions (as in TCP mode) with the rotary axes where they stand. ``G53.1``: the
        rotary axes turn (a rapid in joint space) until the tool is along the frame's +Z
        (:func:`._swivel.swivel`: the solution within travel, of two the one whose C is
        nearest where it stands). ``G69``: back to the work coordinates."""
        if 682 in codes:
            word = g_word[682]
            if values.get("P", 0.0) != 0.0:
                self.fail(f"G68.2 {spelled['P']}: only the Euler-angle form (P0: I J K about "
                          "Z, X, Z) is supported", spelled["P"])
            extra = [spelled[a] for a in self.axes[3:] if a in spelled]
            if extra:
                self.fail(f"axis word {extra[0]!r} in a G68.2 block", extra[0])
            origin = [values.get(a, 0.0) * scale for a in self.axes[:3]]
            rotation = _euler_zxz(values.get("I", 0.0), values.get("J", 0.0),
                                  values.get("K", 0.0))
            self.enter_tilt(origin, rotation, word, "G68.2")
        if 531 in codes:
            word = g_word[531]
            if self.tilt is None:
                self.fail("G53.1 needs a tilted working plane (G68.2)", word)
            self.align_tool(word)
        if 690 in codes:
            self.leave_tilt()

    def enter_tilt(self, origin, rotation, word, name, cancel="G69"):
        """A tilted working plane (G68.2, CYCLE800): its ``origin`` (work coordinates, mm)
        and ``rotation`` (columns: the plane's axes); the position becomes the tool tip in
        the plane's frame."""
        if self.tilt is not None:
            self.fail(f"{name} again before {cancel} (a tilted plane on a tilted plane is "
                      "not supported)", word)
        if self.tcp_sources:
            self.fail(f"{name} in TCP mode is not supported", word)
        known = all(math.isfinite(v) for v in self.prog)
        if not known and (name == "G68.2" or self.start is not None):
            self.fail(f"{name} before the position of every axis is known", word)
        origin = np.add(origin, np.add(self.g5x, self.g92)[:3])
        self.tcp_sources.add("G68.2")
        if known:
            self.set_tcp(True)                   # the position as a tool tip
            tip = np.array(self.prog[:3])
            self.prog = [*map(float, (tip - origin) @ rotation), *self.prog[3:]]
        else:
            # before the first move (a swivel after the tool change): the tip in the plane
            # becomes known from the plane's moves
            self.tcp, self.deferred = True, []
            self.prog = [math.nan] * 3 + self.prog[3:]
        self.tilt = (origin, rotation)
        self.tilt_offsets = (self.g5x, self.g92)
        self.g5x, self.g92 = list(_ZERO), list(_ZERO)   # in the frame's origin now

    def align_tool(self, word, prefer=0):
        """G53.1 (and CYCLE800's swivel): the rotary axes turn, a rapid in joint space, until
        the tool is along the plane's +Z; of the two branches the one within travel (then
        ``prefer``, see :func:`._swivel.swivel`), said when the preferred one is not."""
        origin, rotation = self.tilt
        tip = origin + rotation @ np.array(self.prog[:3])
        current = np.radians(self.prog[3:])
        known = np.isfinite(tip).all() and np.isfinite(current).all()
        chosen = swivel(self.kinematics, np.nan_to_num(tip), rotation[:, 2],
                        np.nan_to_num(current), prefer)
        if chosen.passed_over is not None:
            a, c = self.axes[3:]
            (pa, pc), (ca, cc) = np.degrees(chosen.passed_over), np.degrees(chosen.rotary)
            low, high = np.degrees(rotary_travel(self.kinematics)[0])
            self.notices.append(
                f"{self.source}, line {self.row}: {word}: {a}{pa:.6g} {c}{pc:.6g} is outside "
                f"the travel ({a} [{low:g}, {high:g}] deg); the other solution {a}{ca:.6g} "
                f"{c}{cc:.6g} turns the tool onto the same plane")
        if not known:
            # before the first move: the axes are where the plane's first moves put them
            self.prog = self.prog[:3] + [*map(math.degrees, chosen.rotary)]
            return
        linear = self.kinematics.linear_axes(tip[None, :], current[None, :])[0]
        target = [*map(float, linear), *map(math.degrees, chosen.rotary)]
        if self.start is not None:
            self.add(target, True, math.nan, math.nan, tcp=False)
        new_tip, _ = self.kinematics.forward(np.array([*target[:3],
                                                       *np.radians(target[3:])]))
        self.prog = [*map(float, (np.asarray(new_tip).reshape(3) - origin) @ rotation),
                     *target[3:]]

    def leave_tilt(self):
        """G69 (CYCLE800()): back to the work coordinates."""
        if self.tilt is None:
            return
        origin, rotation = self.tilt
        tip = origin + rotation @ np.array(self.prog[:3])
        self.prog = [*map(float, tip), *self.prog[3:]]
        self.g5x, self.g92 = self.tilt_offsets
        self.tilt = None
        self.tcp_sources.discard("G68.2")
        self.set_tcp(bool(self.tcp_sources))

    # ------------------------------------------------------------------ result
    def check_tilt(self, tilt: np.ndarray, lines: np.ndarray) -> None:
        """The tilt axis (A, or B on a B-C machine) stays within its travel."""
        low, high = _tilt_travel(self.kinematics)
        slack = 1e-9
        out = (tilt < low - slack) | (tilt > high + slack)
        if out.any():
            k = int(np.flatnonzero(out)[0])
            letter = self.axes[3]
            raise ProgramError(f"{letter} = {math.degrees(tilt[k]):.6g} deg is outside the tilt "
                               f"axis's travel [{math.degrees(low):g}, {math.degrees(high):g}] "
                               "deg", source=self.source, row=int(lines[k]), field=letter)

    @property
    def framed(self) -> bool:
        """A frame turns or shifts the program's coordinates (G68.2, CYCLE800, Sinumerik's
        TRANS/ROT/ATRANS/AROT)."""
        return self.tilt is not None or self.pframe is not None

    def to_workpiece(self, points):
        """Points in the program's coordinates -> the coordinates of the current mode: the
        programmable frame (Sinumerik's TRANS/ROT ...) applied, then the tilted plane's
        (G68.2, CYCLE800: to the workpiece frame, the tool tip as a TCP move); without either,
        the points themselves."""
        if not self.framed:
            return points
        points = np.array(points, dtype=float)
        for frame in (self.pframe, self.tilt):
            if frame is not None:
                origin, rotation = frame
                points[..., :3] = origin + points[..., :3] @ rotation.T
        return points

    def from_workpiece(self, position):
        """The inverse of :meth:`to_workpiece` for one position."""
        position = list(position)
        for frame in (self.tilt, self.pframe):
            if frame is not None:
                origin, rotation = frame
                position[:3] = map(float, (np.array(position[:3]) - origin) @ rotation)
        return position
