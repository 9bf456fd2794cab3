"""The RS274/NGC language as LinuxCNC reads it: parameters, expressions and O-word control.

This module owns the text level of a G-code line that is not a machining word: it compiles a
line's words and parameter settings whose values are expressions (``X[#1 * 2]``,
``#<depth> = -2``) into small functions of the parameters, and finds the structure of a
program's O-words (``sub``/``endsub``, ``if``/``elseif``/``else``/``endif``, ``while``/
``endwhile``, ``do``/``while``, ``repeat``/``endrepeat``, ``break``/``continue``,
``call``/``return``) and its Fanuc subprogram labels (``O1000`` ... ``M99``) before it runs.
The reader (:mod:`.gcode`) executes them.

The rules are LinuxCNC's (RS274/NGC manual, "O Codes" and "Numbered Parameters", and its
``rs274`` interpreter where the manual is silent):

- values: a number, ``[expression]``, ``#n``, ``#<name>``, ``#[expression]``, ``##n``, a
  function, each with optional leading ``+``/``-`` (``X-#1``, ``-[1]``);
- binary operators, in falling precedence, each level left to right: ``**``; ``*``, ``/``,
  ``MOD`` (the result takes the sign of the divisor's magnitude: ``-7 MOD 3`` is 2); ``+``,
  ``-``; ``EQ``, ``NE`` (equal within 0.0001), ``GT``, ``GE``, ``LT``, ``LE`` (1 or 0);
  ``AND``, ``OR``, ``XOR`` (non-zero is true). A leading sign binds tighter than ``**``:
  ``[-2 ** 2]`` is 4;
- functions (angles in degrees): ``ABS ACOS ASIN COS EXP FIX`` (floor) ``FUP`` (ceiling)
  ``LN ROUND`` (half away from zero) ``SIN SQRT TAN``, ``ATAN[y]/[x]`` and
  ``EXISTS[#<name>]``;
- parameters: numbered ``#1`` ... ``#5602`` (0 until set; ``#1``-``#30`` are a subroutine's
  arguments, saved and restored around a call); named ``#<name>`` local to the subroutine
  that sets it, ``#<_name>`` global; reading a named parameter never set is an error. Every
  value a line reads is read before any of the line's settings take effect (``#1 = 1 #2 =
  #1`` gives #2 the old #1).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

__all__ = ["NgcError", "compile_line", "needs_macro_reader", "OWord", "parse_oword",
           "Structure", "scan_structure", "MAX_PARAMETER", "format_number"]

#: Highest numbered parameter (LinuxCNC's RS274NGC_MAX_PARAMETERS - 1).
MAX_PARAMETER = 5602
#: EQ / NE compare within this (LinuxCNC's TOLERANCE_EQUAL).
EQUAL_TOLERANCE = 1e-4
#: A parameter number or repeat count must be this close to a whole number.
INTEGER_TOLERANCE = 1e-4

_NUMBER = re.compile(r"\d+\.?\d*|\.\d+")
_NAME = re.compile(r"<([^>]*)>")
_FUNCTIONS = ("ABS", "ACOS", "ASIN", "ATAN", "COS", "EXISTS", "EXP", "FIX", "FUP", "LN",
              "ROUND", "SIN", "SQRT", "TAN")
# binary operators by precedence level (0 lowest); longer spellings first within a level
_LEVELS = (("AND", "XOR", "OR"), ("EQ", "NE", "GT", "GE", "LT", "LE"), ("+", "-"),
           ("*", "/", "MOD"), ("**",))
_OWORD = re.compile(r"O(\d+|<[^>]*>)(SUB|ENDSUB|CALL|RETURN|IF|ELSEIF|ELSE|ENDIF|DO|WHILE|"
                    r"ENDWHILE|REPEAT|ENDREPEAT|BREAK|CONTINUE)(.*)")
_LABEL = re.compile(r"O(\d+)")


class NgcError(Exception):
    """A problem in a line's language: ``message`` and the ``word`` it concerns."""

    def __init__(self, message: str, word: str | None = None):
        super().__init__(message)
        self.message, self.word = message, word


def format_number(value: float) -> str:
    """A value as a G-code number (for the words an output program keeps)."""
    text = f"{value:.10f}".rstrip("0").rstrip(".")
    return "0" if text in ("", "-", "-0") else text


def needs_macro_reader(code: str) -> bool:
    """Whether a line (upper case, blanks removed) has parameters, expressions or polar
    words, which the plain word reader does not read."""
    return "#" in code or "[" in code or "@" in code or "^" in code


# ---------------------------------------------------------------------- expressions


def _const(value):
    return lambda ctx: value


def _check_integer(value: float, what: str, word: str) -> int:
    number = round(value)
    if abs(value - number) > INTEGER_TOLERANCE:
        raise NgcError(f"{what} {value:g} is not a whole number", word)
    return int(number)


def _math(name, fn, word):
    def apply(x):
        try:
            return fn(x)
        except (ValueError, OverflowError):
            raise NgcError(f"{name}[{x:g}] is not defined (argument out of its domain)",
                           word) from None
    return apply


def _round(x):
    return math.floor(x + 0.5) if x >= 0 else -math.floor(-x + 0.5)


def _unary(name, word):
    table = {
        "ABS": abs,
        "ACOS": lambda x: math.degrees(math.acos(x)),
        "ASIN": lambda x: math.degrees(math.asin(x)),
        "COS": lambda x: math.cos(math.radians(x)),
        "EXP": math.exp,
        "FIX": lambda x: float(math.floor(x)),
        "FUP": lambda x: float(math.ceil(x)),
        "LN": lambda x: math.log(x) if x > 0 else math.log(-1.0),
        "ROUND": lambda x: float(_round(x)),
        "SIN": lambda x: math.sin(math.radians(x)),
        "SQRT": math.sqrt,
        "TAN": lambda x: math.tan(math.radians(x)),
    }
    return _math(name, table[name], word)


def _binary(op, word):
    if op == "**":
        def power(a, b):
            if a < 0 and b != int(b):
                raise NgcError(f"[{a:g} ** {b:g}]: a negative number to a fractional power",
                               word)
            try:
                return float(a ** b)
            except (OverflowError, ZeroDivisionError):
                raise NgcError(f"[{a:g} ** {b:g}] is out of range", word) from None
        return power
    if op == "/":
        def divide(a, b):
            if b == 0.0:
                raise NgcError("division by zero", word)
            return a / b
        return divide
    if op == "MOD":
        def modulo(a, b):
            if b == 0.0:
                raise NgcError("MOD by zero", word)
            r = math.fmod(a, b)
            return r + abs(b) if r < 0.0 else r
        return modulo
    return {
        "*": lambda a, b: a * b,
        "+": lambda a, b: a + b,
        "-": lambda a, b: a - b,
        "EQ": lambda a, b: 1.0 if abs(a - b) < EQUAL_TOLERANCE else 0.0,
        "NE": lambda a, b: 0.0 if abs(a - b) < EQUAL_TOLERANCE else 1.0,
        "GT": lambda a, b: 1.0 if a > b else 0.0,
        "GE": lambda a, b: 1.0 if a >= b else 0.0,
        "LT": lambda a, b: 1.0 if a < b else 0.0,
        "LE": lambda a, b: 1.0 if a <= b else 0.0,
        "AND": lambda a, b: 1.0 if (a != 0.0 and b != 0.0) else 0.0,
        "OR": lambda a, b: 1.0 if (a != 0.0 or b != 0.0) else 0.0,
        "XOR": lambda a, b: 1.0 if ((a != 0.0) != (b != 0.0)) else 0.0,
    }[op]


class _Parser:
    """Recursive descent over one line's code (upper case, no blanks)."""

    def __init__(self, code: str, word: str):
        self.s, self.word = code, word

    def fail(self, message, at=None):
        raise NgcError(message, self.word)

    def value(self, i):
        """A real value at ``i``: (function of the parameters, is-a-constant, end)."""
        s = self.s
        if i >= len(s):
            self.fail("a number or expression is missing")
        c = s[i]
        if c == "[":
            fn, const, i = self.expression(i + 1)
            if i >= len(s) or s[i] != "]":
                self.fail("unclosed '[' in an expression")
            return fn, const, i + 1
        if c == "#":
            return self.parameter(i + 1)
        if c in "+-":
            fn, const, j = self.value(i + 1)
            if c == "+":
                return fn, const, j
            if const:
                v = -fn(None)
                return _const(v), True, j
            return (lambda ctx: -fn(ctx)), False, j
        if c.isalpha():
            return self.function(i)
        match = _NUMBER.match(s, i)
        if match is None:
            self.fail(f"cannot parse a number at {s[i:i + 12]!r}")
        return _const(float(match.group())), True, match.end()

    def parameter(self, i):
        """After ``#``: the parameter's value."""
        s = self.s
        if i < len(s) and s[i] == "<":
            match = _NAME.match(s, i)
            if match is None:
                self.fail("unclosed '<' in a parameter name")
            name = match.group(1)
            if not name:
                self.fail("empty parameter name #<>")
            return (lambda ctx: ctx.named(name)), False, match.end()
        index, const, j = self.value(i)
        word = self.word

        if const:
            n = _check_integer(index(None), "parameter number", word)
            _check_range(n, word)
            return (lambda ctx: ctx.number(n)), False, j

        def read(ctx):
            n = _check_integer(index(ctx), "parameter number", word)
            _check_range(n, word)
            return ctx.number(n)
        return read, False, j

    def function(self, i):
        s = self.s
        name = next((f for f in sorted(_FUNCTIONS, key=len, reverse=True)
                     if s.startswith(f, i)), None)
        if name is None:
            j = i
            while j < len(s) and s[j].isalpha():
                j += 1
            self.fail(f"unknown function or operator {s[i:j]!r}")
        j = i + len(name)
        if j >= len(s) or s[j] != "[":
            self.fail(f"{name} needs its argument in [ ]")
        if name == "EXISTS":
            k = j + 1
            if not s.startswith("#<", k):
                self.fail("EXISTS needs a named parameter, EXISTS[#<name>]")
            match = _NAME.match(s, k + 1)
            if match is None or s[match.end():match.end() + 1] != "]":
                self.fail("EXISTS needs a named parameter, EXISTS[#<name>]")
            pname = match.group(1)
            return (lambda ctx: 1.0 if ctx.exists(pname) else 0.0), False, match.end() + 1
        arg, const, k = self.value(j)
        if name == "ATAN":
            if k >= len(s) or s[k] != "/" or s[k + 1:k + 2] != "[":
                self.fail("ATAN needs two arguments, ATAN[y]/[x]")
            arg2, const2, k = self.value(k + 1)

            def atan(ctx):
                return math.degrees(math.atan2(arg(ctx), arg2(ctx)))
            if const and const2:
                return _const(atan(None)), True, k
            return atan, False, k
        op = _unary(name, self.word)
        if const:
            return _const(op(arg(None))), True, k
        return (lambda ctx: op(arg(ctx))), False, k

    def operator(self, i, level):
        s = self.s
        for op in _LEVELS[level]:
            if s.startswith(op, i):
                if op == "*" and s.startswith("**", i):
                    continue
                return op
        return None

    def expression(self, i, level=0):
        if level == len(_LEVELS):
            return self.value(i)
        left, const, i = self.expression(i, level + 1)
        while i < len(self.s):
            op = self.operator(i, level)
            if op is None:
                break
            right, rconst, i = self.expression(i + len(op), level + 1)
            fn = _binary(op, self.word)
            if const and rconst:
                left = _const(fn(left(None), right(None)))
            else:
                left = (lambda f, a, b: lambda ctx: f(a(ctx), b(ctx)))(fn, left, right)
                const = False
        return left, const, i


def _check_range(n, word):
    if not 1 <= n <= MAX_PARAMETER:
        raise NgcError(f"parameter #{n} is out of range (#1 ... #{MAX_PARAMETER})", word)


@dataclass(frozen=True)
class CompiledLine:
    """A line's parameter settings and words, their values functions of the parameters.

    ``settings``: (target, value) with target an int (numbered), a str (named) or a function
    giving the number; ``words``: (letter, value, spelled) in line order, ``spelled`` the
    word as written (for messages)."""

    settings: tuple
    words: tuple


def compile_line(code: str) -> CompiledLine:
    """Compile a line's code (upper case, blanks and comments removed) that
    :func:`needs_macro_reader`; raise :class:`NgcError` for what does not parse."""
    settings, words = [], []
    i, n = 0, len(code)
    while i < n:
        start = i
        c = code[i]
        if c == "#":
            # a parameter setting: #n = value, #<name> = value, #[expr] = value
            parser = _Parser(code, _word_text(code, start))
            if code.startswith("<", i + 1):
                match = _NAME.match(code, i + 1)
                if match is None:
                    raise NgcError("unclosed '<' in a parameter name", _word_text(code, start))
                target, j = match.group(1), match.end()
                if not target:
                    raise NgcError("empty parameter name #<>", _word_text(code, start))
            else:
                index, const, j = parser.value(i + 1)
                word = code[start:j]
                if const:
                    target = _check_integer(index(None), "parameter number", word)
                    _check_range(target, word)
                else:
                    target = (lambda f, w: lambda ctx: _check_integer(
                        f(ctx), "parameter number", w))(index, word)
            if j >= n or code[j] != "=":
                raise NgcError("a parameter outside an expression must be set: #n = value",
                               code[start:j])
            parser.word = _word_text(code, start)
            value, _, i = parser.value(j + 1)
            parser.word = code[start:i]
            settings.append((target, value, code[start:i]))
            continue
        if c.isalpha() or c in "@^":
            parser = _Parser(code, None)
            if i + 1 >= n:
                raise NgcError(f"cannot parse number {c!r}", c)
            parser.word = _word_text(code, start)
            value, const, i = parser.value(i + 1)
            spelled = code[start:i]
            parser.word = spelled
            words.append((c, value, spelled, code[start + 1:i] if const and _NUMBER.fullmatch(
                code[start + 1:i].lstrip("+-")) else None))
            continue
        raise NgcError(f"cannot parse {_word_text(code, start)!r}", None)
    return CompiledLine(tuple(settings), tuple(words))


def _word_text(code: str, pos: int) -> str:
    """The text from ``pos`` to the next word letter outside brackets (a word as written)."""
    depth, i = 0, pos + 1
    while i < len(code):
        c = code[i]
        if c == "[":
            depth += 1
        elif c == "]":
            depth -= 1
        elif depth <= 0 and (c.isalpha() or c in "#@^") and not code[i - 1] in "#<":
            # letters of a function or operator belong to the value
            if not any(code.startswith(f, i) for f in _FUNCTIONS + ("MOD", "EQ", "NE", "GT",
                                                                      "GE", "LT", "LE", "AND",
                                                                      "OR", "XOR")):
                break
        i += 1
    return code[pos:i]


# ---------------------------------------------------------------------- O-words


@dataclass(frozen=True)
class OWord:
    """An O-word control line: its label (``"100"`` or ``"<NAME>"``), keyword (upper case),
    and the values in brackets after it (call arguments, a condition, a count)."""

    label: str
    keyword: str
    args: tuple
    text: str


def parse_oword(code: str) -> OWord | None:
    """The O-word statement of a line's code, or None if it is none. A plain ``O1000`` (a
    program number, a Fanuc subprogram label) is not a statement."""
    match = _OWORD.fullmatch(code)
    if match is None:
        return None
    label, keyword, rest = match.groups()
    if label.startswith("<"):
        label = "<" + label[1:-1] + ">"
    else:
        label = str(int(label))
    text = f"O{label}{keyword}"
    args, i = [], 0
    parser = _Parser(rest, text)
    while i < len(rest):
        if rest[i] != "[":
            raise NgcError(f"after O{label} {keyword.lower()} only values in [ ] may follow, "
                           f"got {rest[i:i + 12]!r}", text)
        fn, _, i = parser.value(i)
        args.append(fn)
    return OWord(label, keyword, tuple(args), text)


@dataclass
class Structure:
    """Where a program's O-word structures begin and end (0-based line indices).

    ``subs``: label -> (sub line, endsub line); ``block``: for each if/elseif/else line the
    next branch line and the endif line, for each loop line (while, endwhile, do, the do's
    while, repeat, endrepeat, break, continue) its loop's (kind, first line, last line);
    ``labels``: Fanuc program numbers (``O1000``) -> line; ``owords``: line -> OWord."""

    subs: dict = field(default_factory=dict)
    branches: dict = field(default_factory=dict)
    loops: dict = field(default_factory=dict)
    labels: dict = field(default_factory=dict)
    owords: dict = field(default_factory=dict)
    sub_of: dict = field(default_factory=dict)


class StructureError(Exception):
    def __init__(self, message, index, word):
        super().__init__(message)
        self.message, self.index, self.word = message, index, word


def scan_structure(codes) -> Structure:
    """Match a program's O-words, given each line's code (None for lines without one)."""
    st = Structure()
    stack = []   # (keyword, label, index, extra)
    for index, code in enumerate(codes):
        if not code or code[0] != "O":
            continue
        try:
            oword = parse_oword(code)
        except NgcError as exc:
            raise StructureError(exc.message, index, exc.word) from None
        if oword is None:
            label = _LABEL.match(code)
            if label is not None and label.end() == len(code):
                st.labels.setdefault(int(label.group(1)), index)
            continue
        st.owords[index] = oword
        key, label = oword.keyword, oword.label
        name = f"o{label.lower()} {key.lower()}"

        def opener(*kinds, inner=False):
            for k in range(len(stack) - 1, -1, -1):
                kind, lab, _, _ = stack[k]
                if lab == label and kind in kinds:
                    return k
                if not inner:
                    return None
            return None

        if key in ("SUB", "IF", "REPEAT", "DO"):
            if key == "SUB" and any(kind == "SUB" for kind, *_ in stack):
                raise StructureError(f"{name}: a subroutine inside subroutine "
                                     f"o{stack[-1][1].lower()}", index, oword.text)
            if key == "SUB" and label in st.subs:
                raise StructureError(f"{name}: subroutine o{label.lower()} is defined twice "
                                     f"(first on line {st.subs[label][0] + 1})", index,
                                     oword.text)
            stack.append((key, label, index, []))
        elif key == "WHILE":
            k = opener("DO")
            if k is not None and k == len(stack) - 1:
                _, _, start, members = stack.pop()
                for m in [start, index] + members:
                    st.loops[m] = ("DO", start, index)
            else:
                stack.append(("WHILE", label, index, []))
        elif key in ("ELSEIF", "ELSE", "ENDIF"):
            if not stack or stack[-1][:2] != ("IF", label):
                raise StructureError(f"{name} without an open o{label.lower()} if", index,
                                     oword.text)
            stack[-1][3].append(index)
            if key == "ENDIF":
                _, _, start, members = stack.pop()
                chain = [start] + members
                for a, b in zip(chain[:-1], chain[1:]):
                    st.branches[a] = (b, chain[-1])
        elif key in ("ENDWHILE", "ENDREPEAT", "ENDSUB"):
            kind = {"ENDWHILE": "WHILE", "ENDREPEAT": "REPEAT", "ENDSUB": "SUB"}[key]
            if not stack or stack[-1][:2] != (kind, label):
                raise StructureError(f"{name} without an open o{label.lower()} "
                                     f"{kind.lower()}", index, oword.text)
            _, _, start, members = stack.pop()
            if kind == "SUB":
                st.subs[label] = (start, index)
                for m in range(start, index + 1):
                    st.sub_of[m] = label
            else:
                for m in [start, index] + members:
                    st.loops[m] = (kind, start, index)
        elif key in ("BREAK", "CONTINUE"):
            # LinuxCNC's break and continue are for while and do loops (not repeat)
            k = opener("WHILE", "DO", inner=True)
            if k is None:
                raise StructureError(f"{name} outside an o{label.lower()} while or do loop",
                                     index, oword.text)
            stack[k][3].append(index)
        elif key == "RETURN":
            # the label may be the subroutine's or an enclosing block's (LinuxCNC)
            if not any(kind == "SUB" for kind, *_ in stack):
                raise StructureError(f"{name} outside a subroutine", index, oword.text)
        # CALL: resolved when it runs
    if stack:
        kind, label, index, _ = stack[-1]
        raise StructureError(f"o{label.lower()} {kind.lower()} is never closed", index,
                             f"O{label}{kind}")
    return st
