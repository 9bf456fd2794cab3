"""The text level of Sinumerik 840D lines as five-axis posts write them: a line split into its
words, keywords, calls, assignments and declarations, and its expressions compiled.

The reader (:mod:`.gcode`) executes what this module parses. What is parsed (SINUMERIK 840D sl
Programming Manual, Fundamentals and Job Planning):

- words as RS274 writes them (``G1``, ``X10.5``, ``N20``) and addresses set by an expression
  after ``=`` (``Z=_Z_HOME``, ``X=R1*2``), with the value functions ``AC()``, ``IC()``
  (absolute, incremental for this word), ``DC()``, ``ACP()``, ``ACN()`` (a rotary axis by the
  shortest way, the positive, the negative direction);
- extended addresses ``CR=`` (arc radius), ``CTOL=``, ``OTOL=``, ``ADIS=``, ``ADISPOS=``,
  ``A3=`` ...;
- keywords (``TRAORI``, ``SUPA``, ``TRANS`` ...), calls ``NAME(arguments)`` (``CYCLE800(...)``,
  ``MSG("...")``), the tool by name ``T="name"``;
- declarations ``DEF REAL a, b=1`` and assignments ``R1=...``, ``_camtolerance=.02``,
  ``WearChanged = FALSE``;
- expressions: numbers, variables and R parameters, ``TRUE``/``FALSE``, ``+ - * /``, ``DIV``,
  ``MOD``, ``( )``, a leading sign, the functions ``SIN COS TAN ASIN ACOS ATAN2 SQRT ABS POT
  TRUNC ROUND MINVAL MAXVAL`` (angles in degrees).

Names are not case-sensitive; a ``;`` starts a comment (outside a string).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

__all__ = ["SinumerikError", "Item", "parse_line", "compile_expression", "split_arguments",
           "NUMERIC_TYPES"]

#: Variable types whose values are numbers (``DEF REAL``, ...); the others (``STRING``,
#: ``CHAR``, ``AXIS``, ``FRAME``) are declared and never read as a number.
NUMERIC_TYPES = frozenset(["REAL", "INT", "BOOL"])
_TYPES = NUMERIC_TYPES | {"STRING", "CHAR", "AXIS", "FRAME"}

_NUMBER = re.compile(r"(?:\d+\.?\d*|\.\d+)(?:EX[-+]?\d+)?", re.IGNORECASE)
_IDENT = re.compile(r"[A-Za-z_$][\w$]*")
_WORD = re.compile(r"([A-Za-z])\s*([-+]?(?:\d+\.?\d*|\.\d+))")
_EXTENDED = re.compile(r"([A-Za-z])(\d+)\s*=")
_FUNCTIONS = {"SIN": 1, "COS": 1, "TAN": 1, "ASIN": 1, "ACOS": 1, "ATAN2": 2, "SQRT": 1,
              "ABS": 1, "POT": 1, "TRUNC": 1, "ROUND": 1, "MINVAL": 2, "MAXVAL": 2}
#: Addresses of more than one letter set with ``=`` (the others are variables).
EXTENDED_NAMES = frozenset(["CR", "CTOL", "OTOL", "ADIS", "ADISPOS", "RPL"])
#: Value functions of an address (``X=IC(5)``).
VALUE_MODES = ("AC", "IC", "DC", "ACP", "ACN")


class SinumerikError(Exception):
    """A line that is not Sinumerik as read here: ``message`` and the ``construct``."""

    def __init__(self, message: str, construct: str | None = None):
        super().__init__(message)
        self.message, self.construct = message, construct


@dataclass(frozen=True)
class Item:
    """One element of a line, as written (``text``).

    ``kind`` is ``"word"`` (``name`` the letter; ``value`` a number, or ``expr`` a compiled
    expression and ``mode`` one of :data:`VALUE_MODES` or None), ``"extended"`` (``name``
    ``CR``, ``CTOL``, ``A3`` ...; ``expr``), ``"assign"`` (``name`` the variable, ``expr``),
    ``"def"`` (``name`` the type, ``value`` a tuple of (variable, expr or None)),
    ``"call"`` (``name``; ``value`` the argument text), ``"tool"`` (``value`` the tool's
    name), or ``"keyword"`` (``name``).
    """

    kind: str
    name: str
    text: str
    value: object = None
    expr: object = None
    mode: str | None = None


def strip_comment(line: str) -> str:
    """``line`` up to its ``;`` comment (a ``;`` in a string is none)."""
    in_string = False
    for i, c in enumerate(line):
        if c == '"':
            in_string = not in_string
        elif c == ";" and not in_string:
            return line[:i]
    return line


def parse_line(code: str) -> list[Item]:
    """The items of a line's code (its comment already cut off)."""
    items, i, n = [], 0, len(code)
    while i < n:
        c = code[i]
        if c.isspace():
            i += 1
            continue
        if c == "/" and not items:
            i += 1
            continue
        ident = _IDENT.match(code, i)
        if ident is None:      # not a name (a digit, an operator, a letter outside ASCII)
            raise SinumerikError(f"cannot read {_rest(code, i)!r}", _rest(code, i))
        name = ident.group().upper()
        extended = _EXTENDED.match(code, i)
        if extended and len(ident.group()) == len(extended.group(1) + extended.group(2)):
            letter = extended.group(1).upper() + extended.group(2)
            end, expr_text = _expression_text(code, extended.end())
            text = code[i:end].strip()
            kind = "assign" if letter[0] == "R" else "extended"
            items.append(Item(kind, letter, text, expr=compile_expression(expr_text, text)))
            i = end
            continue
        if len(name) >= 2 and not name[1].isdigit() and name[1] not in "+-.":
            i = ident.end()
            j = _skip_blanks(code, i)
            if name == "DEF":
                items.append(_declaration(code, i))
                return items
            if j < n and code[j] == "(":
                end = _closing(code, j)
                items.append(Item("call", name, code[ident.start():end].strip(),
                                  value=code[j + 1:end - 1]))
                i = end
                continue
            if j < n and code[j] == "=" and code[j + 1:j + 2] != "=":
                end, expr_text = _expression_text(code, j + 1)
                text = code[ident.start():end].strip()
                kind = "extended" if name in EXTENDED_NAMES \
                    else "assign"
                items.append(Item(kind, name, text, expr=compile_expression(expr_text, text)))
                i = end
                continue
            items.append(Item("keyword", name, ident.group()))
            continue
        letter = c.upper()
        j = _skip_blanks(code, i + 1)
        if j < n and code[j] == "=":
            k = _skip_blanks(code, j + 1)
            if letter == "T" and code[k:k + 1] == '"':
                end = code.find('"', k + 1)
                if end < 0:
                    raise SinumerikError("the tool's name has no closing '\"'", code[i:])
                items.append(Item("tool", "T", code[i:end + 1].strip(), value=code[k + 1:end]))
                i = end + 1
                continue
            end, expr_text = _expression_text(code, j + 1)
            text = code[i:end].strip()
            mode = None
            call = re.fullmatch(r"\s*([A-Za-z]+)\s*\((.*)\)\s*", expr_text)
            if call and call.group(1).upper() in VALUE_MODES:
                mode, expr_text = call.group(1).upper(), call.group(2)
            items.append(Item("word", letter, text, expr=compile_expression(expr_text, text),
                              mode=mode))
            i = end
            continue
        word = _WORD.match(code, i)
        if word is None:
            raise SinumerikError(f"cannot read {_rest(code, i)!r}", _rest(code, i))
        items.append(Item("word", letter, word.group(), value=float(word.group(2))))
        i = word.end()
    return items


def _rest(code: str, i: int) -> str:
    return code[i:].split()[0] if code[i:].split() else code[i:]


def _skip_blanks(code: str, i: int) -> int:
    while i < len(code) and code[i] in " \t":
        i += 1
    return i


def _closing(code: str, start: int) -> int:
    """The end (exclusive) of the ( ) group opening at ``start`` (strings inside skipped)."""
    depth, i, in_string = 0, start, False
    while i < len(code):
        c = code[i]
        if c == '"':
            in_string = not in_string
        elif not in_string:
            depth += (c == "(") - (c == ")")
            if depth == 0:
                return i + 1
        i += 1
    raise SinumerikError("a '(' is not closed on its line", code[start:].strip())


def _expression_text(code: str, start: int) -> tuple[int, str]:
    """(end, text) of the expression after an ``=`` at ``start``: up to a blank outside
    ( ) that neither follows nor precedes an operator."""
    i = _skip_blanks(code, start)
    begin, depth = i, 0
    while i < len(code):
        c = code[i]
        if c == "(":
            depth += 1
        elif c == ")":
            depth -= 1
        elif c == '"':
            i = code.find('"', i + 1)
            if i < 0:
                raise SinumerikError("a string has no closing '\"'", code[start:].strip())
        elif c in " \t" and depth == 0:
            before = code[begin:i].rstrip()
            after = code[_skip_blanks(code, i):]
            if not (before.endswith(("+", "-", "*", "/", "=")) or after[:1] in ("+", "-", "*", "/")
                    or re.match(r"(?:DIV|MOD)\b", after, re.IGNORECASE)
                    or re.search(r"\b(?:DIV|MOD)$", before, re.IGNORECASE)):
                break
        i += 1
    if depth:
        raise SinumerikError("a '(' is not closed on its line", code[start:].strip())
    return i, code[begin:i]


def _declaration(code: str, i: int) -> Item:
    """``DEF <type> a, b=1, c``: the declared names and their initial values."""
    text = "DEF" + code[i:]
    match = re.match(r"\s*([A-Za-z]+)\s*", code[i:])
    kind = match.group(1).upper() if match else ""
    if kind not in _TYPES:
        raise SinumerikError(f"DEF {kind or '?'}: not a variable type "
                             f"({', '.join(sorted(_TYPES))})", text.strip())
    names = []
    for part in split_arguments(code[i + match.end():]):
        name, _, value = part.partition("=")
        name = name.strip()
        name = re.sub(r"\[.*\]$", "", name)   # an array's size: its first element is read
        if not _IDENT.fullmatch(name):
            raise SinumerikError(f"DEF {kind}: {part.strip()!r} is not a variable name",
                                 text.strip())
        expr = None
        if value.strip() and kind in NUMERIC_TYPES:
            expr = compile_expression(value, text.strip())
        names.append((name.upper(), expr))
    return Item("def", kind, text.strip(), value=tuple(names))


def split_arguments(text: str) -> list[str]:
    """The comma-separated parts of ``text`` (commas in ( ) and strings do not split)."""
    parts, depth, start, in_string = [], 0, 0, False
    for i, c in enumerate(text):
        if c == '"':
            in_string = not in_string
        elif not in_string:
            if c == "(":
                depth += 1
            elif c == ")":
                depth -= 1
            elif c == "," and depth == 0:
                parts.append(text[start:i])
                start = i + 1
    parts.append(text[start:])
    return parts


# ---------------------------------------------------------------------- expressions

_TOKEN = re.compile(r"\s*(?:(?P<num>(?:\d+\.?\d*|\.\d+)(?:EX[-+]?\d+)?)|(?P<name>[A-Za-z_$][\w$]*)"
                    r"|(?P<op>[-+*/(),]))", re.IGNORECASE)


def compile_expression(text: str, construct: str):
    """A function ``f(lookup) -> float`` of the expression ``text``; ``lookup(name)`` gives a
    variable's (or R parameter's) value."""
    tokens, pos = [], 0
    text = text.strip()
    if not text:
        raise SinumerikError("a value is missing after '='", construct)
    while pos < len(text):
        match = _TOKEN.match(text, pos)
        if match is None or match.end() == pos:
            if text[pos:].strip() == "":
                break
            raise SinumerikError(f"cannot read {text[pos:].strip()!r} in an expression",
                                 construct)
        pos = match.end()
        if match.group("num"):
            tokens.append(("num", float(match.group("num").upper().replace("EX", "E"))))
        elif match.group("name"):
            tokens.append(("name", match.group("name").upper()))
        else:
            tokens.append(("op", match.group("op")))
    parser = _Parser(tokens, construct)
    fn = parser.sum()
    if parser.i != len(tokens):
        raise SinumerikError(f"cannot read the expression {text!r}", construct)
    return fn


class _Parser:
    """Recursive descent: sum of products of signed factors."""

    def __init__(self, tokens, construct):
        self.tokens, self.i, self.construct = tokens, 0, construct

    def peek(self):
        return self.tokens[self.i] if self.i < len(self.tokens) else (None, None)

    def take(self):
        token = self.peek()
        self.i += 1
        return token

    def expect(self, op):
        if self.take() != ("op", op):
            raise SinumerikError(f"'{op}' expected in an expression", self.construct)

    def sum(self):
        fn = self.product()
        while self.peek() in (("op", "+"), ("op", "-")):
            op = self.take()[1]
            left, right = fn, self.product()
            fn = (lambda l, r: lambda v: l(v) + r(v))(left, right) if op == "+" else \
                (lambda l, r: lambda v: l(v) - r(v))(left, right)
        return fn

    def product(self):
        fn = self.factor()
        while self.peek() in (("op", "*"), ("op", "/"), ("name", "DIV"), ("name", "MOD")):
            op = self.take()[1]
            left, right = fn, self.factor()
            fn = _binary(op, left, right, self.construct)
        return fn

    def factor(self):
        kind, value = self.take()
        if kind == "op" and value in "+-":
            inner = self.factor()
            return inner if value == "+" else (lambda f: lambda v: -f(v))(inner)
        if kind == "num":
            return lambda v, x=value: x
        if kind == "op" and value == "(":
            fn = self.sum()
            self.expect(")")
            return fn
        if kind == "name":
            if value in ("TRUE", "FALSE"):
                return lambda v, x=float(value == "TRUE"): x
            if value in _FUNCTIONS:
                self.expect("(")
                args = [self.sum()]
                while self.peek() == ("op", ","):
                    self.take()
                    args.append(self.sum())
                self.expect(")")
                if len(args) != _FUNCTIONS[value]:
                    raise SinumerikError(f"{value} takes {_FUNCTIONS[value]} argument(s)",
                                         self.construct)
                return _function(value, args, self.construct)
            return lambda v, name=value: v(name)
        raise SinumerikError("an expression is incomplete", self.construct)


def _binary(op, left, right, construct):
    def divide(v):
        denominator = right(v)
        if denominator == 0.0:
            raise SinumerikError("division by zero", construct)
        return left(v) / denominator

    if op == "*":
        return lambda v: left(v) * right(v)
    if op == "/":
        return divide
    if op == "DIV":
        return lambda v: float(math.trunc(divide(v)))
    return lambda v: math.fmod(left(v), right(v)) if right(v) != 0.0 else divide(v)


def _function(name, args, construct):
    def domain(fn):
        def checked(*x):
            try:
                return fn(*x)
            except ValueError:
                raise SinumerikError(f"{name} of {', '.join(f'{a:g}' for a in x)} is not "
                                     "defined", construct) from None
        return checked

    fns = {"SIN": lambda x: math.sin(math.radians(x)), "COS": lambda x: math.cos(math.radians(x)),
           "TAN": lambda x: math.tan(math.radians(x)),
           "ASIN": lambda x: math.degrees(math.asin(x)),
           "ACOS": lambda x: math.degrees(math.acos(x)),
           "ATAN2": lambda y, x: math.degrees(math.atan2(y, x)), "SQRT": math.sqrt,
           "ABS": abs, "POT": lambda x: x * x, "TRUNC": lambda x: float(math.trunc(x)),
           "ROUND": lambda x: float(math.floor(abs(x) + 0.5)) * (1.0 if x >= 0 else -1.0),
           "MINVAL": min, "MAXVAL": max}
    fn = domain(fns[name])
    return lambda v: fn(*(a(v) for a in args))
