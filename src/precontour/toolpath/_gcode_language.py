"""LinuxCNC's language in the G-code reader (the reader's :class:`~.gcode._Reader` mixes
this in): numbered, named, global, predefined and stored parameters, expressions (compiled by
:mod:`._ngc`), O-word flow control and subroutines, Fanuc's M98/M99 subprograms in the same
file, and the modal state of M70-M73. Loops and calls are bounded
(:data:`MAX_LOOP_ITERATIONS`, :data:`MAX_CALL_DEPTH`): a runaway ends with an error on its
line."""

from __future__ import annotations

import math

from ..machine.gcode import WORK_OFFSETS
from ._common import INCH
from ._gcode_codes import _ZERO, _Frame
from ._ngc import MAX_PARAMETER, NgcError, OWord, compile_line, format_number

#: Most times one loop may run, and deepest calls may nest (runaway guards).
MAX_LOOP_ITERATIONS = 1_000_000
MAX_CALL_DEPTH = 100
#: LinuxCNC's parameter slots of the axes (5161 + slot: X Y Z A B C U V W).
_SLOTS = {0: "X", 1: "Y", 2: "Z", 3: "A", 4: "B", 5: "C"}


class LanguageBlocks:
    """The reader's parameters, expressions, flow control and subprograms."""

    # ------------------------------------------------------------------ parameters
    def evaluate(self, code: str, line: str | None = None) -> list[tuple[str, float, str, str]]:
        """The words of a line with parameters and expressions, evaluated; its parameter
        settings take effect after every value of the line is read (LinuxCNC)."""
        compiled = self.compile(code, line)
        try:
            words = []
            for letter, value, spelled, literal in compiled.words:
                number = value(self)
                if not math.isfinite(number):
                    self.fail(f"value is not finite in {spelled!r}", spelled)
                words.append((letter, number, literal or format_number(number), spelled))
            settings = [(target if not callable(target) else target(self), value(self), text)
                        for target, value, text in compiled.settings]
        except NgcError as exc:
            self.fail(exc.message, exc.word)
        for target, number, text in settings:
            self.set_parameter(target, number, text)
        return words

    def compile(self, code: str, line: str | None = None):
        """The compiled code of a line (once per distinct code); a line that does not compile
        and is another controller's syntax (``line`` as written) is refused as such."""
        compiled = self.compiled.get(code)
        if compiled is None:
            try:
                compiled = compile_line(code)
            except NgcError as exc:
                self.refuse_foreign(line)
                self.fail(exc.message, exc.word)
            self.compiled[code] = compiled
        return compiled

    # the parameter context of compiled expressions (see _ngc)
    def number(self, n: int) -> float:
        system = self.system_parameter(n)
        return self.params[n] if system is None else system

    def named(self, name: str) -> float:
        value = self.named_value(name)
        if value is None:
            if name.startswith(("_HAL[", "_INI[")):
                source = "a HAL pin" if name[1] == "H" else "the INI file"
                raise NgcError(f"#<{name.lower()}> reads {source} "
                               "of a running LinuxCNC, which precontour does not have",
                               f"#<{name}>")
            raise NgcError(f"named parameter #<{name.lower()}> is not defined", f"#<{name}>")
        return value

    def exists(self, name: str) -> bool:
        return self.named_value(name) is not None

    def named_value(self, name: str):
        if name.startswith("_"):
            value = self.predefined(name)
            return self.globals.get(name) if value is None else value
        return self.frames[-1].locals.get(name)

    def set_parameter(self, target, value, text):
        if isinstance(target, str):
            if target.startswith("_"):
                if self.predefined(target) is not None:
                    self.fail(f"#<{target.lower()}> is read-only", text)
                self.globals[target] = value
            else:
                self.frames[-1].locals[target] = value
            return
        if not 1 <= target <= MAX_PARAMETER:
            self.fail(f"parameter #{target} is out of range (#1 ... #{MAX_PARAMETER})", text)
        if self.system_parameter(target) is not None:
            self.fail(f"parameter #{target} is the controller's stored position or offset "
                      "data: set it with G10, G28.1/G30.1 or G92", text)
        self.params[target] = value

    def program_position(self) -> list[float]:
        """The current position in program coordinates and units (work and G92 offsets
        taken off), NaN where not known."""
        scale = INCH if self.inch else 1.0
        return [(p - o - g) / (scale if i < 3 else 1.0)
                for i, (p, o, g) in enumerate(zip(self.prog, self.g5x, self.g92))]

    def system_parameter(self, n: int):
        """LinuxCNC's stored parameters that precontour keeps itself (None for the others):
        5161-5169 G28 and 5181-5189 G30 positions, 5211-5219 the G92 offset, 5220 the work
        offset number, 5221-5409 the work offsets, 5420-5428 the current position."""
        if not 5161 <= n <= 5428:
            return None

        def axis_value(vector, slot):
            # the machine's axis in LinuxCNC's slot (0 for the axes it does not have)
            i = self.axis_index.get(_SLOTS.get(slot))
            return 0.0 if i is None else float(vector[i])

        if 5161 <= n <= 5169 or 5181 <= n <= 5189:
            reference = self.reference.get(280 if n < 5180 else 300) or _ZERO
            return axis_value(reference, (n - 5161) % 20)
        if 5211 <= n <= 5219:
            return axis_value(self.g92, n - 5211)
        if n == 5220:
            return float(WORK_OFFSETS.index(self.work_offset) + 1
                         if self.work_offset in WORK_OFFSETS else 1)
        if 5221 <= n <= 5409:
            k, slot = divmod(n - 5221, 20)
            if slot > 9:
                return None
            if slot == 9:
                return 0.0   # the rotation R (G10 L2 R is refused)
            return axis_value(self.offsets.get(WORK_OFFSETS[k], _ZERO), slot)
        if 5420 <= n <= 5428:
            value = axis_value(self.program_position(), n - 5420)
            return value if math.isfinite(value) else 0.0
        return None

    def predefined(self, name: str):
        """LinuxCNC's predefined named parameters (#<_x>, #<_metric>, ...), None if not one."""
        if len(name) == 2 and name[1] in "XYZABCUVW":
            letter = name[1]
            if letter not in self.axis_index:
                return 0.0
            value = self.program_position()[self.axis_index[letter]]
            return value if math.isfinite(value) else 0.0
        if name == "_VALUE":
            return self.value
        if name == "_VALUE_RETURNED":
            return self.value_returned
        if name == "_LINE":
            return float(self.row)
        if name == "_CALL_LEVEL":
            return float(len(self.frames) - 1)
        flag = {"_METRIC": not self.inch, "_IMPERIAL": self.inch,
                "_ABSOLUTE": not self.incremental, "_INCREMENTAL": self.incremental,
                "_INVERSE_TIME": self.inverse_time, "_UNITS_PER_MINUTE": not self.inverse_time,
                "_TASK": False}.get(name)
        if flag is not None:
            return 1.0 if flag else 0.0
        if name == "_FEED":
            feed = self.feed / (INCH if self.inch else 1.0)
            return feed if math.isfinite(feed) else 0.0
        if name == "_MOTION_MODE":
            return float(-1 if self.motion is None else self.motion * 10)
        if name == "_PLANE":
            return float({(0, 1, 2): 170, (2, 0, 1): 180, (1, 2, 0): 190}[self.plane])
        if name == "_COORD_SYSTEM":
            if self.work_offset not in WORK_OFFSETS:
                return 541.0
            return float(int(round(float(self.work_offset[1:]) * 10)))
        return None

    # ------------------------------------------------------------------ control flow
    def control(self, pc: int, oword: OWord):
        """Execute an O-word line; the index of the next line to run (None: program end)."""
        st = self.structure
        key = oword.keyword
        frame = self.frames[-1]
        if key == "SUB":
            return st.subs[oword.label][1] + 1         # a definition: skip it
        if key in ("ENDSUB", "RETURN"):
            if frame.kind != "sub" or key == "ENDSUB" and frame.name != oword.label:
                self.fail(f"o{oword.label.lower()} {key.lower()} outside a call of "
                          f"o{st.sub_of.get(pc, oword.label).lower()}", oword.text)
            if oword.args:
                self.value, self.value_returned = self.condition(oword, 0), 1.0
            else:
                self.value_returned = 0.0
            return self.leave()
        if key == "CALL":
            return self.call(pc, oword)
        if key in ("IF", "ELSEIF"):
            if key == "ELSEIF":                          # reached from a branch that ran
                return st.branches[pc][1] + 1
            at = pc
            while True:
                line = st.owords[at]
                if line.keyword == "ENDIF":
                    return at + 1
                if line.keyword == "ELSE":
                    return at + 1
                if self.condition(line, 0, at) != 0.0:
                    return at + 1
                at = st.branches[at][0]
        if key == "ELSE":
            return st.branches[pc][1] + 1
        if key == "ENDIF":
            return pc + 1
        kind, first, last = st.loops[pc]
        if key == "WHILE" and kind == "WHILE" or key == "ENDWHILE":
            if self.condition(st.owords[first], 0, first) != 0.0:
                self.iterate(frame, first)
                return first + 1
            frame.iterations.pop(first, None)
            return last + 1
        if key == "DO":
            return pc + 1
        if key == "WHILE":                               # the end of a do-while
            if self.condition(oword, 0) != 0.0:
                self.iterate(frame, first)
                return first + 1
            frame.iterations.pop(first, None)
            return last + 1
        if key == "REPEAT":
            count = self.condition(oword, 0)
            count = round(count) if abs(count - round(count)) <= 1e-4 else math.floor(count)
            if count <= 0:
                return last + 1
            frame.repeats[first] = count
            return pc + 1
        if key == "ENDREPEAT":
            left = frame.repeats.get(first, 1) - 1
            if left > 0:
                frame.repeats[first] = left
                self.iterate(frame, first)
                return first + 1
            frame.repeats.pop(first, None)
            frame.iterations.pop(first, None)
            return last + 1
        if key == "BREAK":
            frame.repeats.pop(first, None)
            frame.iterations.pop(first, None)
            return last + 1
        if key == "CONTINUE":
            # the next iteration: a while or a do-while tests its condition, a repeat counts
            return last if kind != "WHILE" else first
        raise AssertionError(key)  # pragma: no cover - every keyword is handled above

    def condition(self, oword: OWord, k: int, at=None) -> float:
        """The value of the ``k``-th bracket of an O-word line (its condition or count)."""
        if at is not None:
            self.row = at + 1
        if len(oword.args) <= k:
            self.fail(f"o{oword.label.lower()} {oword.keyword.lower()} needs its value in "
                      "[ ]", oword.text)
        try:
            return oword.args[k](self)
        except NgcError as exc:
            self.fail(exc.message, exc.word or oword.text)

    def iterate(self, frame, first):
        count = frame.iterations.get(first, 0) + 1
        if count > MAX_LOOP_ITERATIONS:
            self.row = first + 1
            oword = self.structure.owords[first]
            self.fail(f"o{oword.label.lower()} {oword.keyword.lower()} ran {MAX_LOOP_ITERATIONS} "
                      "times: a runaway loop?", oword.text)
        frame.iterations[first] = count

    def call(self, pc: int, oword: OWord):
        """``oN call [a] [b] ...``: #1, #2, ... are the arguments in the subroutine (the
        caller's #1-#30 come back after it), its named parameters are its own."""
        sub = self.structure.subs.get(oword.label)
        if sub is None:
            name = oword.label.lower()
            where = (f" (LinuxCNC looks for {name[1:-1]}.ngc in its SUBROUTINE_PATH; precontour "
                     "reads one file)" if name.startswith("<") else "")
            self.fail(f"subroutine o{name} is not defined in this file{where}", oword.text)
        if len(oword.args) > 30:
            self.fail("a call passes at most 30 arguments (#1 ... #30)", oword.text)
        try:
            args = [fn(self) for fn in oword.args]
        except NgcError as exc:
            self.fail(exc.message, exc.word or oword.text)
        self.enter(_Frame("sub", oword.label, pc + 1, saved=self.params[1:31]))
        self.params[1:31] = args + [0.0] * (30 - len(args))
        return sub[0] + 1

    def enter(self, frame):
        if len(self.frames) > MAX_CALL_DEPTH:
            self.fail(f"calls nested more than {MAX_CALL_DEPTH} deep: a runaway recursion?")
        self.frames.append(frame)

    def leave(self):
        frame = self.frames.pop()
        if frame.saved is not None:
            self.params[1:31] = frame.saved
        if frame.auto_restore is not None:      # M73 in the subroutine
            self.restore_state(frame.auto_restore)
        return frame.return_pc

    def modal_state(self, m_numbers, m_codes):
        """M70 save the modal state, M71 forget it, M72 restore it, M73 save it and restore
        it when the subroutine returns (LinuxCNC): units, distance modes, feed mode and rate,
        plane, path tolerance."""
        word = next(w for c, w in m_codes if c // 10 in (70, 71, 72, 73))
        if len(m_numbers & {70, 71, 72, 73}) > 1:
            self.fail("two of M70-M73 in one block", word)
        state = (self.inch, self.incremental, self.arc_absolute, self.inverse_time, self.feed,
                 self.plane, self.path_tolerance)
        if 70 in m_numbers:
            self.saved_state = state
        elif 71 in m_numbers:
            self.saved_state = None
        elif 72 in m_numbers:
            if self.saved_state is None:
                self.fail("M72 without a state saved by M70", word)
            self.restore_state(self.saved_state)
        else:
            if self.frames[-1].kind != "sub":
                self.fail("M73 is for a subroutine (it restores the state when it returns)",
                          word)
            self.frames[-1].auto_restore = state

    def restore_state(self, state):
        (self.inch, self.incremental, self.arc_absolute, self.inverse_time, self.feed,
         self.plane, self.path_tolerance) = state

    def subprogram(self, values, spelled, m_word):
        """Fanuc's M98 P<program> L<count> (also P<count><4-digit program>): jump to the
        line ``O<program>``; M99 comes back. Parameters are shared with the caller."""
        if "P" not in values:
            self.fail("M98 needs the subprogram number P", m_word)
        number = values["P"]
        count = values.get("L", 1.0)
        if number != int(number) or number < 0:
            self.fail(f"M98 {spelled['P']}: not a program number", spelled["P"])
        if count != int(count) or count < 0:
            self.fail(f"M98 {spelled['L']}: not a repeat count", spelled["L"])
        number, count = int(number), int(count)
        labels = self.structure.labels
        if number not in labels and number >= 10000 and number % 10000 in labels:
            count, number = number // 10000, number % 10000   # Fanuc: P<count><program>
        if number not in labels:
            self.fail(f"M98: there is no O{number} (its subprogram) in this file",
                      spelled["P"])
        if count == 0:
            return
        self.enter(_Frame("m98", f"O{number}", self.row, locals=self.frames[-1].locals,
                          start=labels[number], left=count))
        self.jump = labels[number] + 1

    def subprogram_return(self, m_word):
        frame = self.frames[-1]
        if frame.kind != "m98":
            self.fail("M99 outside a subprogram: in the main program it would restart it "
                      "without end (Fanuc); end the program with M30", m_word)
        frame.left -= 1
        if frame.left > 0:
            self.jump = frame.start + 1
            return
        self.frames.pop()
        self.jump = frame.return_pc
