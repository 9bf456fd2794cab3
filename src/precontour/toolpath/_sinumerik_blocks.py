"""Executing Sinumerik 840D blocks in the G-code reader: what the constructs of a five-axis
post's program do to the motion (the reader's :class:`~.gcode._Reader` mixes this in).

- ``DEF`` declarations, R parameters and variables (``_camtolerance=.02``), addresses set by
  expressions (``Z=_Z_HOME``) and ``AC``/``IC``/``DC``/``ACP``/``ACN`` values;
- ``SUPA``: the block's axis words are machine coordinates (as ``G53``), every frame left out;
- programmable frames (one block each): ``TRANS``/``ROT`` replace the frame, ``ATRANS``/
  ``AROT`` add to it in its own coordinates; ``ROT``/``AROT`` turn about X, Y, Z (several in
  one block: Z first, then the new Y, then the new X: the RPY order, Siemens's default) or by
  ``RPL=`` in the working plane; ``TRANS``/``ROT`` alone clear it. The program's X Y Z are then
  the frame's: the frame maps them to the machine axes, or under ``TRAORI`` to the tool tip;
- ``CYCLE800(_FR, _TC, _ST, _MODE, _X0, _Y0, _Z0, _A, _B, _C, _X1, _Y1, _Z1, _DIR, _FR_I,
  _DMODE)``: the swivelled plane as Fanuc's G68.2 + G53.1 (the same code): axis-by-axis
  (``_MODE`` bits 7-6 = 0; bits 1-0, 3-2, 5-4 the axes of the 1st, 2nd, 3rd rotation, each
  about the already turned axes), origin ``X0 Y0 Z0`` then the rotation then ``X1 Y1 Z1``;
  ``_DIR`` -1/+1 swivels the rotary axes (the solution with the lower/higher rotary axis 1,
  the other one when it is out of travel; 0 turns only the coordinates); ``CYCLE800()`` or
  ``_TC`` "0" ends it. The retract ``_FR`` is not made (a post moves away before it);
- ``CYCLE832(tol, ...)``: its tolerance is the corner tolerance (as ``G64 P``; said once),
  ``CYCLE832()`` resets it; ``CTOL=`` likewise; ``G60``/``G9`` exact stop, ``G64`` continuous
  path, ``G641``-``G645`` blending with that tolerance;
- ``T="name"``, ``MSG(...)``, ``WORKPIECE(...)``, ``G601``-``G603``, the compressor and
  feed-forward keywords, ``ORIWKS``/``ORIMKS``/``ORIAXES`` (rotary axes as programmed,
  interpolated axis by axis: as the reader does) are kept as comments;
- ``G500`` (no settable offset), ``G70``/``G700`` (inch), ``G71``/``G710`` (mm),
  ``M17``/``RET`` (end).

What changes the motion otherwise (``ORIVECT`` great-circle orientation, orientation vectors
``A3=``, other cycles, ``SCALE``/``MIRROR``, jumps) is refused by name and line.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import ForeignSyntaxError
from ._dialects import SINUMERIK
from ._ngc import format_number
from ._sinumerik import (NUMERIC_TYPES, SinumerikError, compile_expression, parse_line,
                         split_arguments, strip_comment)
from .program import Stop

#: Keywords read and left as comments: they change no axis command (compressor, jerk and
#: feed-forward modes, feed of the contour, preprocessing stop; the orientation's reference
#: and axis-by-axis interpolation, which is how the reader interpolates the rotary axes).
IGNORED_KEYWORDS = frozenset([
    "SOFT", "BRISK", "FFWON", "FFWOF", "COMPCAD", "COMPCURV", "COMPSURF", "COMPOF", "UPATH",
    "SPATH", "FNORM", "CFC", "CFTCP", "CFIN", "STOPRE", "DIAMOF", "ORIWKS", "ORIMKS",
    "ORIAXES"])
#: Keywords that change the motion in a way the reader does not follow, and why.
REFUSED_KEYWORDS = {
    "ORIVECT": "the orientation interpolated on a great circle, not axis by axis",
    "ORIEULER": "orientation angles as Euler angles", "ORIRPY": "orientation angles as RPY",
    "ORIPLANE": "the orientation interpolated in a plane",
    "ORICONCW": "the orientation on a cone", "ORICONCCW": "the orientation on a cone",
    "ORICONIO": "the orientation on a cone", "ORICONTO": "the orientation on a cone",
    "ORICURVE": "the orientation along a second curve",
    "SCALE": "a scaling frame", "ASCALE": "a scaling frame", "MIRROR": "a mirroring frame",
    "AMIRROR": "a mirroring frame", "GOTOF": "a jump", "GOTOB": "a jump", "GOTO": "a jump",
    "GOTOC": "a jump", "DIAMON": "diameter programming", "TRAFOOF": None, "TRAORI": None}
_FRAMES = ("TRANS", "ATRANS", "ROT", "AROT")
#: Sinumerik's own G codes (in tenths, as the reader keeps G numbers).
_EXACT_STOP, _NON_MODAL_STOP, _CONTINUOUS = 600, 90, 640
_BLENDING = frozenset([6410, 6420, 6430, 6440, 6450])
_STOP_WINDOWS = frozenset([6010, 6020, 6030])
_AXIS_ROTATION = {1: "X", 2: "Y", 3: "Z"}
#: The G codes only a Sinumerik line has (read here, not by the RS274 path).
#: G70/G700 inch, G71/G710 metric (G700/G710 also for feeds; the reader converts both).
_UNITS = frozenset([700, 710, 7000, 7100])
_OWN_G = (frozenset([_EXACT_STOP, _NON_MODAL_STOP, 5000]) | _UNITS | _BLENDING
          | _STOP_WINDOWS)


def _rotation(axis: str, degrees: float) -> np.ndarray:
    c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    i = "XYZ".index(axis)
    j, k = (i + 1) % 3, (i + 2) % 3
    r = np.eye(3)
    r[j, j], r[j, k], r[k, j], r[k, k] = c, -s, s, c
    return r


class SinumerikBlocks:
    """The Sinumerik part of the reader's state and blocks (mixed into the reader)."""

    def sinumerik_setup(self):
        self.variables = {}            # DEF'd variables and R parameters (upper case)
        self.text_variables = set()    # DEF STRING/CHAR/AXIS/FRAME: never a number
        self.blend_tolerance = math.nan   # CYCLE832 / CTOL (mm)
        self.said_cycle832 = False
        self.said_retract = False
        self.supa = False

    # ------------------------------------------------------------------ errors
    def refuse_sinumerik(self, message, construct):
        raise ForeignSyntaxError(f"{construct!r} is {SINUMERIK} syntax ({message}), which this "
                                 "reader does not read; post-process without it",
                                 source=self.source, row=self.row, field=construct)

    def variable(self, name):
        if name in self.variables:
            return self.variables[name]
        if name[0] == "R" and name[1:].isdigit():
            return 0.0
        if name in self.text_variables:
            raise SinumerikError(f"variable {name} is not a number")
        raise SinumerikError(f"variable {name} is not defined (DEF REAL {name})")

    def value_of(self, expr, construct):
        try:
            value = float(expr(self.variable))
        except SinumerikError as exc:
            self.fail(f"{exc.message} in {construct!r}", construct)
        if not math.isfinite(value):
            self.fail(f"value is not finite in {construct!r}", construct)
        return value

    # ------------------------------------------------------------------ lines
    def sinumerik_prepare(self, raw: str):
        """The parsed items of a line with Sinumerik constructs, or None for a line the
        RS274 path reads (plain words, a ``( )`` comment)."""
        s = self.block_text(raw)
        if s is None:
            return None
        code = strip_comment(s)
        if not any(c.isalpha() for c in code):
            return None
        try:
            items = parse_line(code)
        except SinumerikError as exc:
            if "(" in code and not any(ch in code for ch in '="'):
                return None        # a ( ) comment: the RS274 path reads it
            self.refuse_foreign(raw)
            self.fail(exc.message, exc.construct)
        if all(item.kind == "word" and item.expr is None and not (
                item.name == "G" and int(round(item.value * 10)) in _OWN_G
                or item.name == "M" and item.value == 17.0) for item in items):
            return None
        comment = s[len(code) + 1:].strip() if len(code) < len(s) else ""
        return items, comment

    def sinumerik_block(self, items, comment, raw) -> bool:
        """Execute one line of Sinumerik items; True after the program's end."""
        frame = [item for item in items if item.kind == "keyword" and item.name in _FRAMES]
        if frame:
            self.frame_block(frame[0], [i for i in items if i is not frame[0]])
            return False
        words, comments, end = [], [comment] if comment else [], False
        traori = trafoof = False
        self.supa = False
        exact_stop_once = False
        absolute = not self.incremental
        for item in items:
            if item.kind == "word" and item.name == "G" and item.expr is None:
                if item.value in (90.0, 91.0):
                    absolute = item.value == 90.0
        for item in items:
            kind, name = item.kind, item.name
            if kind == "word":
                value = item.value if item.expr is None else self.value_of(item.expr, item.text)
                if item.mode is not None:
                    value = self.value_mode(name, value, item.mode, item.text, absolute)
                if name == "G":
                    code = int(round(value * 10))
                    if code == _EXACT_STOP:
                        self.path_tolerance = 0.0
                    elif code == _NON_MODAL_STOP:
                        exact_stop_once = True
                    elif code in _BLENDING:
                        self.path_tolerance = self.blend_tolerance
                    elif code in _STOP_WINDOWS:
                        self.skipped[f"G{code // 10}"] += 1
                    elif code == 5000:
                        self.work_offset = "G500"
                        self.g5x = list(self.offsets.get("G500", (0.0,) * 5))
                    elif code in _UNITS:
                        inch = code in (700, 7000)
                        words.append(("G", 20.0 if inch else 21.0, "20" if inch else "21",
                                      item.text))
                    else:
                        words.append(("G", value, format_number(value), item.text))
                    continue
                if name == "M" and value == 17.0:
                    end = True
                    continue
                number = format_number(value) if item.expr is not None or item.mode \
                    else item.text[1:].strip()
                words.append((name, value, number, item.text))
            elif kind == "extended":
                value = self.value_of(item.expr, item.text)
                if name == "CR":
                    words.append(("R", value, format_number(value), item.text))
                elif name == "CTOL":
                    self.blend_tolerance = value * (25.4 if self.inch else 1.0)
                elif name in ("OTOL", "ADIS", "ADISPOS"):
                    self.skipped[name] += 1      # orientation tolerance, blending distances
                    comments.append(item.text)
                else:
                    self.refuse_foreign(raw)
                    self.refuse_sinumerik("an extended address", item.text)
            elif kind == "assign":
                if name in self.text_variables:
                    self.fail(f"variable {name} is not a number", item.text)
                self.variables[name] = self.value_of(item.expr, item.text)
                self.skipped["="] += 1
            elif kind == "def":
                for variable, expr in item.value:
                    if name in NUMERIC_TYPES:
                        self.variables[variable] = (0.0 if expr is None
                                                    else self.value_of(expr, item.text))
                    else:
                        self.text_variables.add(variable)
                self.skipped["DEF"] += 1
            elif kind == "call":
                end_here = self.sinumerik_call(item, comments)
                traori = traori or end_here == "TRAORI"
            elif kind == "tool":
                self.skipped["T"] += 1
                comments.append(item.text)
            else:   # a keyword
                if name == "TRAORI":
                    traori = True
                elif name == "TRAFOOF":
                    trafoof = True
                elif name == "SUPA":
                    self.supa = True
                    words.append(("G", 53.0, "53", "SUPA"))
                elif name == "RET":
                    end = True
                elif name in IGNORED_KEYWORDS:
                    self.skipped[name] += 1
                    comments.append(item.text)
                else:
                    if not REFUSED_KEYWORDS.get(name):
                        self.refuse_foreign(raw)
                    self.refuse_sinumerik(REFUSED_KEYWORDS.get(name) or "a keyword",
                                          item.text)
        saved_tolerance = self.path_tolerance
        if exact_stop_once:
            self.path_tolerance = 0.0
        # an output program keeps the line as RS274 words, the constructs as comments
        comments = [c.replace("(", "[").replace(")", "]") for c in comments]
        text = " ".join([f"{letter}{number}" for letter, _, number, _ in words]
                        + [f"({c})" for c in comments])
        try:
            done = self.execute(words, traori, trafoof, text, comments)
        finally:
            self.supa = False
        if exact_stop_once:
            self.path_tolerance = saved_tolerance
        if end and not done:
            self.stops.append(Stop(self.n_moves, self.row, "end"))
        return done or end

    def value_mode(self, letter, value, mode, construct, absolute):
        """A word's value given by ``AC()``, ``IC()``, ``DC()``, ``ACP()``, ``ACN()`` as the
        number the block's distance mode reads."""
        centre = "IJK".find(letter)
        axis = self.axis_index.get(letter, centre if centre >= 0 else None)
        if axis is None:
            self.fail(f"{mode}() is for an axis or an arc centre, not {letter}", construct)
        position = self.program_position()[axis]
        if centre >= 0:
            if mode == "AC":     # an absolute centre: I J K are incremental from the start
                return value - position if math.isfinite(position) else value
            if mode == "IC":
                return value
            self.fail(f"{mode}() is for a rotary axis", construct)
        if mode in ("DC", "ACP", "ACN"):
            if axis < 3:
                self.fail(f"{mode}() is for a rotary axis, not {letter}", construct)
            if not math.isfinite(position):
                target = value
            elif mode == "DC":
                target = position + ((value - position + 180.0) % 360.0) - 180.0
            elif mode == "ACP":
                target = position + (value - position) % 360.0
            else:
                target = position - (position - value) % 360.0
            if absolute:
                return target
            return target - position if math.isfinite(position) else value
        if mode == "IC":
            if not absolute:
                return value
            if not math.isfinite(position):
                self.fail(f"IC() on axis {letter} before its position is known", construct)
            return position + value
        # AC
        if absolute:
            return value
        if not math.isfinite(position):
            self.fail(f"AC() on axis {letter} in G91 before its position is known", construct)
        return value - position

    # ------------------------------------------------------------------ calls
    def sinumerik_call(self, item, comments):
        name = item.name
        if name == "MSG":
            self.skipped["MSG"] += 1
            comments.append("MSG, " + item.value.strip().strip('"'))
            return None
        if name == "WORKPIECE":
            self.skipped["WORKPIECE"] += 1
            return None
        if name == "TRAORI":
            return "TRAORI"
        if name == "CYCLE832":
            self.cycle832(item)
            return None
        if name == "CYCLE800":
            self.cycle800(item)
            return None
        self.refuse_foreign(item.text)
        self.refuse_sinumerik("a call", item.text)

    def arguments(self, item):
        """The arguments of a call: (text, number or None) per argument (strings and empty
        arguments are None)."""
        parts = split_arguments(item.value) if item.value.strip() else []
        values = []
        for part in parts:
            text = part.strip()
            if not text or text.startswith('"'):
                values.append((text.strip('"'), None))
            else:
                values.append((text, self.value_of(compile_expression(text, item.text),
                                                   item.text)))
        return values

    def cycle832(self, item):
        """CYCLE832(tolerance, mode, ...): the tolerance becomes the corner tolerance."""
        parts = split_arguments(item.value) if item.value.strip() else []
        first = parts[0].strip() if parts else ""
        tolerance = (self.value_of(compile_expression(first, item.text), item.text)
                     if first else 0.0)
        if tolerance > 0.0:
            tolerance *= 25.4 if self.inch else 1.0
            self.blend_tolerance = self.path_tolerance = tolerance
            if not self.said_cycle832:
                self.said_cycle832 = True
                self.notices.append(
                    f"{self.source}, line {self.row}: {item.text if len(item.text) <= 40 else 'CYCLE832(...)'}: "
                    f"its tolerance {tolerance:g} mm is taken as the corner tolerance (as "
                    "G64 P); the compressor and jerk settings it selects are not modelled")
        else:
            self.blend_tolerance = self.path_tolerance = math.nan
        self.skipped["CYCLE832"] += 1

    def cycle800(self, item):
        """CYCLE800: the swivelled plane (see the module docstring)."""
        short = "CYCLE800(...)" if len(item.text) > 40 else item.text
        args = self.arguments(item)
        if not args or (len(args) > 1 and args[1][0] == "0" and args[1][1] is None):
            self.leave_tilt()
            self.skipped["CYCLE800"] += 1
            return
        if len(args) < 14:
            self.fail(f"CYCLE800 needs at least 14 arguments (_FR, _TC, _ST, _MODE, _X0, _Y0, "
                      f"_Z0, _A, _B, _C, _X1, _Y1, _Z1, _DIR), got {len(args)}", short)

        def number(k, name):
            value = args[k][1]
            if value is None:
                if args[k][0] == "":
                    return 0.0
                self.fail(f"CYCLE800 argument {name} is not a number", short)
            return value

        fr, st, mode = number(0, "_FR"), number(2, "_ST"), number(3, "_MODE")
        if int(st) % 10 != 0:
            self.refuse_sinumerik(f"an additive swivel, _ST={st:g}: only a new plane (_ST "
                                  "units digit 0) is read", short)
        mode = int(mode)
        kind = (mode >> 6) & 3
        if kind != 0:
            what = {1: "solid angle", 2: "projection angle", 3: "rotary axes direct"}[kind]
            self.refuse_sinumerik(f"swivel mode {what}, _MODE={mode}: only axis by axis (_MODE "
                                  "bits 7-6 = 0, e.g. 57 for X Y Z) is read", short)
        axes = [_AXIS_ROTATION.get((mode >> shift) & 3) for shift in (0, 2, 4)]
        if None in axes:
            self.fail(f"CYCLE800 _MODE={mode}: an axis of the rotation sequence is 0", short)
        if self.pframe is not None:
            self.fail("CYCLE800 with a programmable frame (TRANS, ROT ...) active is not "
                      "supported: clear it (TRANS) first", short)
        if "TRAORI" in self.tcp_sources:
            self.fail("CYCLE800 under TRAORI is not supported: TRAFOOF first", short)
        scale = 25.4 if self.inch else 1.0
        x0 = np.array([number(k, n) for k, n in ((4, "_X0"), (5, "_Y0"), (6, "_Z0"))]) * scale
        angles = [number(k, n) for k, n in ((7, "_A"), (8, "_B"), (9, "_C"))]
        x1 = np.array([number(k, n) for k, n in ((10, "_X1"), (11, "_Y1"), (12, "_Z1"))]) * scale
        direction = int(number(13, "_DIR"))
        rotation = np.eye(3)
        for axis, angle in zip(axes, angles):
            rotation = rotation @ _rotation(axis, angle)
        if fr and not self.said_retract:
            self.said_retract = True
            self.notices.append(f"{self.source}, line {self.row}: {short}: the retract _FR="
                                f"{fr:g} is not made (the machine file gives no retract "
                                "position); the axes swivel where they stand")
        if self.tilt is not None:
            self.leave_tilt()           # a new plane replaces the one before
        self.enter_tilt(x0 + rotation @ x1, rotation, short, "CYCLE800", "CYCLE800()")
        if direction:
            self.align_tool(short, prefer=1 if direction > 0 else -1)
        self.skipped["CYCLE800"] += 1

    # ------------------------------------------------------------------ frames
    def frame_block(self, keyword, others):
        """TRANS / ATRANS / ROT / AROT with their axis words, in a block of their own."""
        name = keyword.name
        if self.tilt is not None:
            self.fail(f"{name} under a swivelled plane (CYCLE800, G68.2) is not supported",
                      keyword.text)
        values = {}
        scale = 25.4 if self.inch else 1.0
        for item in others:
            if item.kind == "word" and item.name == "N":
                continue
            if item.kind == "extended" and item.name == "RPL" and name in ("ROT", "AROT"):
                values["RPL"] = self.value_of(item.expr, item.text)
                continue
            if item.kind != "word" or item.name not in "XYZ" or item.mode is not None:
                self.fail(f"{name} takes a block of its own with X Y Z"
                          + (" or RPL=" if "ROT" in name else ""), item.text)
            value = item.value if item.expr is None else self.value_of(item.expr, item.text)
            values[item.name] = value
        origin, rotation = self.pframe if self.pframe is not None else (np.zeros(3), np.eye(3))
        if name in ("TRANS", "ATRANS"):
            shift = np.array([values.get(a, 0.0) for a in "XYZ"]) * scale
            if name == "TRANS":
                origin, rotation = shift, np.eye(3)
            else:
                origin = origin + rotation @ shift
        else:
            turn = np.eye(3)
            if "RPL" in values:
                if len(values) > 1:
                    self.fail(f"{name} RPL= turns in the plane: no X Y Z with it", keyword.text)
                normal = "XYZ"[self.plane[2]]
                turn = _rotation(normal, values["RPL"])
            else:
                for axis in "ZYX":          # RPY: Z, then the new Y, then the new X
                    if axis in values:
                        turn = turn @ _rotation(axis, values[axis])
            if name == "ROT":
                origin, rotation = np.zeros(3), turn
            else:
                rotation = rotation @ turn
        if name in ("TRANS", "ROT") and not values:
            origin, rotation = np.zeros(3), np.eye(3)
        # the position stays where it is: its coordinates change to the new frame's
        outer = list(self.to_workpiece(self.prog)) if self.pframe is not None else list(self.prog)
        identity = not origin.any() and np.array_equal(rotation, np.eye(3))
        self.pframe = None if identity else (origin, rotation)
        if all(math.isfinite(v) for v in outer[:3]):
            self.prog = self.from_workpiece(outer)
        elif self.pframe is not None and np.array_equal(rotation, np.eye(3)):
            self.prog = [p - o if i < 3 else p for i, (p, o) in
                         enumerate(zip(outer, [*origin, 0.0, 0.0]))]
        elif self.pframe is not None:
            self.fail(f"{name} turns the coordinates before the position of every axis is "
                      "known", keyword.text)
        else:
            self.prog = outer
        self.skipped[name] += 1
        self.passthrough.append((self.row, f"({keyword.text} ...)"))
