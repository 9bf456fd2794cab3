"""Tool lengths by tool number: the machine file's ``[tools]`` table and LinuxCNC tool table
files (``.tbl``), for the G-code reader's tool length offsets (``G43 H``, ``G43.4 H``,
``G234 H``).

A machine file's table gives each tool's length in mm, spindle nose (gauge line) to tip, the
length the kinematics' ``tool_offset`` is for the machine file's own tool::

    [tools]
    1 = 62.5
    2 = 80.0

A LinuxCNC tool table has one tool a line, ``T<n> P<pocket> Z<length> D<diameter> ;remark``
(LinuxCNC's ``tool.tbl`` format, words in any order, any of X Y Z A B C U V W D I J Q); its
Z is the tool length, read here in mm (a metric configuration's units).
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from types import MappingProxyType
from typing import Mapping

from ._config import ConfigTable
from ..errors import InputError

__all__ = ["parse_tools_table", "read_tool_table", "checked_tool_lengths", "MAX_TOOL_LENGTH"]

#: Longest tool accepted, mm (a number beyond it is a typo or another unit).
MAX_TOOL_LENGTH = 10_000.0

_TBL_WORD = re.compile(r"([A-Za-z])\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)")
_TBL_LETTERS = frozenset("TPXYZABCUVWDIJQ")


def parse_tools_table(table: ConfigTable | None) -> Mapping[int, float]:
    """The ``[tools]`` table of a machine file: tool number -> length (mm)."""
    if table is None:
        return MappingProxyType({})
    lengths = {}
    for key in table.keys():
        text = key.strip().upper().removeprefix("T")
        if not text.isdigit() or int(text) < 1:
            raise table.error(key, "not a tool number; write tools as 1 = 62.5 (mm)")
        number = int(text)
        if number in lengths:
            raise table.error(key, f"tool {number} is given twice")
        lengths[number] = table.get_float(key, minval=-MAX_TOOL_LENGTH, maxval=MAX_TOOL_LENGTH)
    table.finish()
    return MappingProxyType(lengths)


def read_tool_table(path: str | Path) -> Mapping[int, float]:
    """A LinuxCNC tool table file: tool number -> length (its Z, mm). Errors name the file,
    the line and the word."""
    source = str(path)
    try:
        text = Path(path).read_text(encoding="utf-8-sig")
    except FileNotFoundError:
        raise InputError("no such tool table file", source=source, field="--tool-table") \
            from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read the tool table: {exc}", source=source,
                         field="--tool-table") from None
    lengths = {}
    for row, line in enumerate(text.splitlines(), start=1):
        code = line.split(";", 1)[0].strip()
        if not code:
            continue
        words, pos = {}, 0
        for match in _TBL_WORD.finditer(code):
            if code[pos:match.start()].strip():
                break
            letter = match.group(1).upper()
            if letter not in _TBL_LETTERS or letter in words:
                raise InputError(f"word {match.group()!r} is no tool table word (T P X Y Z A B "
                                 "C U V W D I J Q, each once)", source=source, row=row,
                                 field=match.group())
            words[letter] = float(match.group(2))
            pos = match.end()
        if code[pos:].strip():
            raise InputError(f"cannot read {code[pos:].strip()!r}: a tool table line is "
                             "T<n> P<pocket> Z<length> ... ;remark", source=source, row=row,
                             field=code[pos:].strip())
        number = words.get("T")
        if number is None or number != int(number) or number < 1:
            raise InputError("a tool table line needs its tool number T (1 or more)",
                             source=source, row=row, field="T")
        length = words.get("Z", 0.0)
        if not (math.isfinite(length) and abs(length) <= MAX_TOOL_LENGTH):
            raise InputError(f"tool length Z{length:g} is out of range", source=source,
                             row=row, field="Z")
        if int(number) in lengths:
            raise InputError(f"tool {int(number)} is given twice", source=source, row=row,
                             field="T")
        lengths[int(number)] = length
    return MappingProxyType(lengths)


def checked_tool_lengths(lengths, *, field: str = "tool_table") -> Mapping[int, float]:
    """A mapping tool number -> length (mm) given in code, checked."""
    if not isinstance(lengths, Mapping):
        raise InputError(f"{field} must be a tool table file or a mapping tool number -> "
                         f"length (mm), got {type(lengths).__name__}", field=field)
    out = {}
    for number, length in lengths.items():
        if isinstance(number, bool) or not isinstance(number, int) or number < 1:
            raise InputError(f"{field}: tool numbers are whole numbers >= 1, got {number!r}",
                             field=field)
        if (isinstance(length, bool) or not isinstance(length, (int, float))
                or not math.isfinite(length) or abs(length) > MAX_TOOL_LENGTH):
            raise InputError(f"{field}: the length of tool {number} must be a finite number "
                             f"of mm, got {length!r}", field=field)
        out[number] = float(length)
    return MappingProxyType(out)

