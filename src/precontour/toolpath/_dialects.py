"""Other controllers' languages, recognized in the lines the G-code reader refuses.

The reader (:mod:`.gcode`) reads RS274/NGC as LinuxCNC and Fanuc-style controls write it,
Haas's own codes (``G234``, ``G254``/``G255``) and Sinumerik's ``TRAORI``. A program posted for
another control stops on its first line of that control's own syntax; without this module the
refusal names a letter (``DEF REAL _X`` as word ``'D'``). Here such a line is matched against
the constructs of two families, so that the refusal names the construct as written, the
language, and what to do:

- Sinumerik 840D: what the reader does not read in a Sinumerik program (it reads ``DEF``,
  ``MSG``, ``CYCLE800``, ``CYCLE832``, frames, variables ...: :mod:`._sinumerik_blocks`):
  other cycle calls (``CYCLE81(...)``), ``SCALE``/``MIRROR`` frames, orientation vectors
  (``A3=``), keywords that change the orientation's interpolation (``ORIVECT`` ...) or jump;
- Heidenhain TNC conversational (Klartext): ``BEGIN PGM`` / ``END PGM``, ``BLK FORM``,
  ``TOOL CALL``, ``CYCL DEF``, ``PLANE ...``, ``FUNCTION ...``, labels, Q parameters, and the
  numbered contour blocks ``L``, ``C``, ``CC``, ``CR``, ``CT``, ``RND``, ``CHF`` with signed
  coordinates or ``FMAX`` (``5 L X+10 Y-5 R0 FMAX``; a G-code line never begins with a
  number).

Only lines the reader has refused are matched (:func:`foreign_construct`), so nothing here
changes what is read. :func:`program_language` looks over a whole program for the same
constructs and for the Sinumerik words the reader does read (``TRAORI``, ``DEF``,
``CYCLE800(...)``, a ``%_N_..._MPF`` header ...: the reader reads a program that shows them as
Sinumerik's), to say which language a program looks like when its refused line is
no construct of its own (a ``G60`` in a Sinumerik program). Clues common to every family are
no evidence: ``;`` comments and ``N`` numbers (LinuxCNC), ``%`` and ``O`` numbers (Fanuc), and
``G43.4`` is read.

In a line, comments (``;`` to the end, and ``( )`` groups that are not a call's arguments)
and LinuxCNC's ``<name>`` spellings are left out before matching: a comment that says
``TRANS`` is no frame.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

__all__ = ["Foreign", "SINUMERIK", "HEIDENHAIN", "HAAS", "REPOST", "foreign_construct",
           "program_language", "SCANNED_LINES"]

SINUMERIK = "Sinumerik 840D"
HEIDENHAIN = "Heidenhain TNC conversational"
HAAS = "Haas"
#: What to do with a program in another language.
REPOST = "post-process for LinuxCNC/Fanuc-style G-code"
#: :func:`program_language` looks at this many lines at most (post-processors write the
#: constructs of their language in the header and at the first tool change; a refusal in a
#: long program should not cost a pass over all of it).
SCANNED_LINES = 2000
#: Constructs longer than this are shortened (a cycle call to ``CYCLE800(...)``), to keep
#: the message on one readable line.
MAX_CONSTRUCT = 40


@dataclass(frozen=True)
class Foreign:
    """A construct of another controller's language, as written in a line."""

    construct: str
    language: str
    what: str
    advice: str = REPOST

    def message(self) -> str:
        return (f"{self.construct!r} is {self.language} syntax ({self.what}), which this reader "
                f"does not read; {self.advice}")


@dataclass(frozen=True)
class _Rule:
    pattern: re.Pattern
    language: str
    what: str
    advice: str = REPOST
    #: The construct is a call: its ( ) arguments belong to it.
    call: bool = False


def _rule(regex: str, language: str, what: str, advice: str = REPOST, *, call=False,
          flags=re.IGNORECASE) -> _Rule:
    """A construct to recognize; the named group ``c``, where there is one, is the construct
    (a Heidenhain block without its block number)."""
    return _Rule(re.compile(regex, flags), language, what, advice, call)


# A name or number does not run on into the match (so that SOFTX is no SOFT, G2340 no G234);
# a G code may follow a number (G0G234).
_START = r"(?<![\w$.])"
_END = r"(?![\w$])"
_G_START = r"(?<![A-Za-z_$.])"
_G_END = r"(?![\w$.])"
#: Names whose ( ) are arguments, not a comment.
_CALL_NAMES = r"(?:MSG|CYCLE\d+|WORKPIECE|POCKET\d+|SLOT\d+|HOLES\d+|IC|AC|DC|ACP|ACN)"

#: Constructs the reader does not read; of two that begin at one place, the first listed.
_RULES = (
    # Sinumerik 840D: what the reader does not read in a Sinumerik program (the constructs it
    # reads are clues of the language, below)
    _rule(_START + r"(?:CYCLE|POCKET|SLOT|HOLES)\d+\s*\(", SINUMERIK, "a cycle call",
          call=True),
    _rule(_START + r"A?(?:SCALE|MIRROR)" + _END, SINUMERIK, "a programmable frame"),
    # Heidenhain's Q parameters, before Sinumerik's addresses with a number (A3=, S1=)
    _rule(_START + r"Q\d+\s*=\s*[^\s;]*", HEIDENHAIN, "a Q parameter"),
    _rule(_START + r"(?:A|B|C)[3-6]\s*=\s*[^\s;]+", SINUMERIK,
          "the tool orientation as a vector or its normal (A3= B3= C3=, A4= ...)",
          "post-process with the rotary axes' positions (A, C) under TRAORI"),
    _rule(_START + r"(?:ORIVECT|ORIRESET|ORICONO|ORICONCW|ORICONCCW|ORICONIO|ORICONTO|ORICURVE|"
          r"ORIPLANE|ORIEULER|ORIRPY|GOTOF|GOTOB|GOTOC|DIAMON)" + _END, SINUMERIK, "a keyword"),
    # Heidenhain conversational: key words, and contour blocks with signed coordinates or FMAX
    _rule(_START + r"(?:BEGIN\s+PGM|END\s+PGM|BLK\s+FORM|TOOL\s+(?:CALL|DEF)|"
          r"CYCL\s+(?:DEF|CALL)|CALL\s+(?:LBL|PGM)|LBL\s+\S+|FN\s*\d+\s*:|FUNCTION\s+\w+|"
          r"PLANE\s+(?:SPATIAL|PROJECTED|EULER|VECTOR|POINTS|RELATIV|AXIAL|RESET))" + _END,
          HEIDENHAIN, "a conversational block"),
    _rule(r"^\s*\d+\s+(?P<c>(?:L|LP|C|CC|CR|CT|CP|RND|CHF)\s+"
          r"(?=.*(?:[XYZABCIJK][+-]\d|FMAX|DR[+-]|R[LR0]\b)).*)", HEIDENHAIN,
          "a contour block", flags=0),
    _rule(r"^\s*\d+\s+(?P<c>\*\s.*)", HEIDENHAIN, "a section heading", flags=0),
)

#: Words the reader reads that only Sinumerik writes: evidence of the language of a program,
#: not of a line.
_CLUES = (
    _rule(_START + r"(?:TRAORI|TRAFOOF)" + _END, SINUMERIK, "its tool centre point mode"),
    _rule(r"%_N_\w+_[MS]PF", SINUMERIK, "a program header"),
    _rule(_START + r"DEF\s+(?:REAL|INT|BOOL|CHAR|STRING|AXIS|FRAME)\b[^;]*", SINUMERIK,
          "a variable definition"),
    _rule(_START + r"(?:MSG|CYCLE800|CYCLE832|WORKPIECE)\s*\(", SINUMERIK, "a call",
          call=True),
    _rule(_START + r"A?(?:TRANS|ROT)" + _END, SINUMERIK, "a programmable frame"),
    _rule(_START + r"T\s*=\s*\"[^\"]*\"", SINUMERIK, "a tool called by name"),
    _rule(_START + r"R\d+\s*=\s*[^\s;]*", SINUMERIK, "an R parameter"),
    _rule(_START + r"[_$A-Z][\w$]+(?:\[[^\]]*\])?\s*=\s*[^\s;]*", SINUMERIK,
          "a variable assignment"),
    _rule(_START + r"[A-Z]\s*=\s*(?:[_$A-Z(])[^\s;]*", SINUMERIK,
          "an address set by an expression"),
    _rule(_START + r"(?:SUPA|COMPCAD|COMPCURV|COMPSURF|COMPOF|ORIWKS|ORIMKS|ORIAXES|FFWON|"
          r"FFWOF|UPATH|SPATH|CFTCP|STOPRE|FNORM)" + _END, SINUMERIK, "a keyword"),
    _rule(_G_START + r"G0*(?:500|64[1-5]|700|710)" + _G_END, SINUMERIK, "a G code of its own"),
)

# what hides a construct: a ; comment, a ( ) comment, a LinuxCNC name (#<name>, o<name>);
# a string is passed over (a ; or ( in it starts nothing)
_HIDING = re.compile(r"[;(\"]|(?<=[#oO])\s*<")
_CALL_BEFORE = re.compile(_CALL_NAMES + r"\s*$", re.IGNORECASE)


def foreign_construct(line: str) -> Foreign | None:
    """The first construct of another controller's language in ``line`` (as written), or None.

    For lines the reader refused: nothing in an RS274/NGC line the reader reads is such a
    construct."""
    return _first(_RULES, line)


def program_language(lines) -> tuple[int, Foreign] | None:
    """(0-based index of the line, its construct) of the first line among the first
    :data:`SCANNED_LINES` of ``lines`` that shows another controller's language; None when
    none does."""
    for index, line in enumerate(lines):
        if index >= SCANNED_LINES:
            break
        found = _first(_RULES + _CLUES, line)
        if found is not None:
            return index, found
    return None


def _first(rules, line: str) -> Foreign | None:
    if not line or line.isspace():
        return None
    code = _code(line)
    best = None
    for rule in rules:
        match = rule.pattern.search(code)
        if match is None:
            continue
        group = "c" if "c" in rule.pattern.groupindex else 0
        if best is None or match.start(group) < best[0].start(best[2]):
            best = match, rule, group
    if best is None:
        return None
    match, rule, group = best
    if rule.call:
        text = code[match.start():_closing(code, match.end() - 1)]
    else:
        text = match.group(group)
    return Foreign(_shortened(text.strip()), rule.language, rule.what, rule.advice)


def _code(line: str) -> str:
    """``line`` without what hides a construct (see :data:`_HIDING`): cut at its ``;``
    comment, its ( ) comments and LinuxCNC names blanked out (the text keeps its places). The
    ( ) after a call's name (``CYCLE800(...)``, ``MSG("...")``) stay: they are arguments."""
    text = list(line)
    i = 0
    while True:
        match = _HIDING.search(line, i)
        if match is None:
            break
        i = match.start()
        c = line[i]
        if c == ";":
            del text[i:]
            break
        end = _closing(line, i)
        if c == "(" and _CALL_BEFORE.search(line, 0, i):
            i += 1       # a call's arguments: look into them (a string in them is passed over)
            continue
        if c != '"':
            text[i:end] = " " * (end - i)
        i = end
    return "".join(text)


def _closing(line: str, start: int) -> int:
    """The end (exclusive) of the group opening at ``start``: ``( )`` (nested, with strings),
    ``"..."`` or ``<...>`` (after blanks); the end of the line when it is never closed."""
    opener = line[start]
    if opener in "\"<" or opener.isspace():
        close = '"' if opener == '"' else ">"
        end = line.find(close, start + 1)
        return len(line) if end < 0 else end + 1
    depth, i = 0, start
    while i < len(line):
        c = line[i]
        if c == '"':
            i = _closing(line, i)
            continue
        depth += (c == "(") - (c == ")")
        i += 1
        if depth == 0:
            return i
    return len(line)


def _shortened(text: str) -> str:
    if len(text) <= MAX_CONSTRUCT:
        return text
    if "(" in text:
        return text[:text.index("(")].rstrip() + "(...)"
    return text[:MAX_CONSTRUCT - 3].rstrip() + "..."
