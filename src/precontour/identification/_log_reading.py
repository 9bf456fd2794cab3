"""What every servo-log reader shares: text read line by line, numbers gathered in flat arrays,
and the names of the log's columns against the library's q slots.

:mod:`.servo_log` (tables, halsampler, halscope) and :mod:`._trace_formats` (the controllers'
trace exports, any CSV) both read through :func:`text_lines`, one line at a time, so that a file
that is no log is refused at its first bad line without reading on; they gather the values in
:class:`Rows` (``array`` buffers, not lists of Python floats) and check the names a caller gives
the columns with :func:`log_names`. Kept apart from both so that neither imports the other.
"""

from __future__ import annotations

from array import array
from collections.abc import Iterator, Sequence
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..files import check_input_file, refuse_non_text
from ..machine.drives import AXES
from ..tables import notice_former_tilt_column, reads_former_tilt_column

#: Longest line of a text log, bytes (a halsampler line of 15 pins is about 300 bytes).
MAX_LINE_BYTES = 1 << 16
#: Column names that are no axis: time (s), sample number, program line.
PLAIN_NAMES: tuple[str, ...] = ("t", "n", "line")


def text_lines(path: Path, fallback_encoding: str | None = None) -> Iterator[tuple[int, str]]:
    """(line number, text) of each line of a text log, read one at a time: refused at the
    first line that is binary data, not UTF-8 or longer than :data:`MAX_LINE_BYTES`.

    ``fallback_encoding`` (e.g. ``"cp1252"``) decodes a line that is not UTF-8: the Windows
    tools of the controllers write their exports in the system's code page, where a unit
    ``µm`` or a German channel name is one byte that UTF-8 refuses.
    """
    source = str(path)
    check_input_file(path)
    try:
        handle = open(path, "rb")
    except OSError as exc:
        raise InputError(f"cannot read file: {exc.strerror or exc}", source=source) from None
    with handle:
        for number in range(1, 1 << 62):
            try:
                raw = handle.readline(MAX_LINE_BYTES + 1)
            except OSError as exc:
                raise InputError(f"cannot read file: {exc.strerror or exc}", source=source,
                                 row=number) from None
            if not raw:
                return
            if number == 1:
                refuse_non_text(raw, source)
            if b"\x00" in raw:
                raise InputError("binary data, not a text log", source=source, row=number)
            if len(raw) > MAX_LINE_BYTES:
                raise InputError(f"line longer than {MAX_LINE_BYTES} bytes: not a servo log",
                                 source=source, row=number)
            yield number, _decode(raw, source, number, fallback_encoding)


def _decode(raw: bytes, source: str, number: int, fallback: str | None) -> str:
    for encoding in ("utf-8",) + ((fallback,) if fallback else ()):
        try:
            text = raw.decode(encoding)
            break
        except UnicodeDecodeError:
            continue
    else:
        what = "invalid UTF-8" if fallback is None else f"neither UTF-8 nor {fallback}"
        raise InputError(f"not a text file ({what})", source=source, row=number)
    return text.removeprefix("\ufeff") if number == 1 else text


def parse_number(text: str, source: str, line: int, field: str) -> float:
    """``text`` as a float, or an error naming the file, its line and the field."""
    try:
        return float(text)
    except ValueError:
        raise InputError(f"not a number: {text!r}", source=source, row=line,
                         field=field) from None


class Rows:
    """Parsed values of a text log, row by row, in one flat float array (not Python lists)."""

    def __init__(self, width: int | None = None):
        self.values = array("d")
        self.lines = array("q")
        self.width = width

    def add(self, number: int, fields, names, source: str) -> None:
        for i, text in enumerate(fields):
            self.values.append(parse_number(text.strip(), source, number,
                                            names[i] or f"column {i + 1}"))
        self.lines.append(number)

    def __len__(self) -> int:
        return len(self.lines)

    def drop_last(self) -> None:
        if len(self.lines):
            del self.lines[-1]
            del self.values[len(self.values) - self.width:]

    def table(self) -> np.ndarray:
        return np.frombuffer(self.values, dtype=float).reshape(-1, self.width).copy()


class Letters:
    """The machine's axis letters against the library's q slots (``X Y Z A C``), for the
    log's column names: ``B`` / ``B_act`` / ``I_B`` of a B-C machine is slot ``A``."""

    def __init__(self, axis_names: tuple[str, ...]):
        if len(axis_names) != len(AXES):
            raise ValueError(f"axis_names must name {len(AXES)} axes, got {axis_names!r}")
        self.names = axis_names
        self.slot = dict(zip(axis_names, AXES))
        self.letter = dict(zip(AXES, axis_names))
        # a B-C machine: the former spelling A of its B column is read too
        self.former = {"A": "B"} if reads_former_tilt_column(axis_names) else {}

    def columns(self) -> tuple[str, ...]:
        """Every column name a log may have: the machine's, then the former spellings."""
        names = self.names + tuple(self.former)
        return (tuple(names) + tuple(f"{a}_act" for a in names)
                + tuple(f"I_{a}" for a in names))

    def to_slots(self, data: dict, source: str) -> dict:
        """The log's columns keyed by q slot (a former spelling with a notice)."""
        present = {axis_of(name) for name in data}
        out = {}
        for name, values in data.items():
            axis = axis_of(name)
            if axis not in self.slot and axis not in self.former:
                out[name] = values    # t, n, line, or a halscope channel of another name
                continue
            letter = axis
            if axis in self.former:
                letter = self.former[axis]
                if letter in present:
                    raise InputError(f"both column {name} and the machine's "
                                     f"{name.replace(axis, letter)}: keep one",
                                     source=source, field=name)
            out[name.replace(axis, self.slot[letter])] = values
        former = sorted(a for a in present if a in self.former)
        if former:
            notice_former_tilt_column(source, former[0])
        return out


def axis_of(name: str) -> str | None:
    """The axis letter of a column name (``B``, ``B_act``, ``I_B``), None for t, n and line."""
    if name in PLAIN_NAMES:
        return None
    if name.startswith("I_"):
        return name[2:]
    return name[:-4] if name.endswith("_act") else name


def check_log_name(name: str, source: str, letters: Letters) -> str:
    """``name`` (stripped) if it is a column name the log may have, or empty (skip)."""
    name = name.strip()
    if name and name not in PLAIN_NAMES + letters.columns():
        raise InputError(f"unknown column name {name!r}; use t, n, line, "
                         f"{', '.join(letters.names)}, X_act.., I_X.. or an empty name to "
                         "skip", source=source, field=name)
    return name


def check_unique(names: Sequence[str], source: str) -> None:
    """Refuse a log name given to two columns."""
    duplicates = {n for n in names if n and names.count(n) > 1}
    if duplicates:
        raise InputError(f"column {sorted(duplicates)[0]!r} named twice", source=source)


def log_names(columns: Sequence[str] | None, count: int, source: str,
              letters: Letters) -> list[str]:
    """The names ``columns`` gives, in order, to the ``count`` values of each line."""
    if columns is None:
        raise InputError("name the columns (--columns X,X_act,...)", source=source)
    names = [check_log_name(c, source, letters) for c in columns]
    check_unique(names, source)
    if len(names) != count:
        raise InputError(f"{len(names)} column names for {count} values per line", source=source)
    return names


def check_sample_numbers(data: dict, line_numbers: Sequence[int], source: str) -> None:
    """A sample-number column ``n`` that does not count up by one lost samples: refuse it at
    the first jump."""
    if "n" not in data:
        return
    step = np.diff(data["n"])
    bad = np.flatnonzero(step != 1)
    if bad.size:
        k = int(bad[0]) + 1
        raise InputError(f"sample number jumps from {data['n'][k - 1]:g} to {data['n'][k]:g} "
                         "(a gap: samples were lost)", source=source, row=line_numbers[k],
                         field="n")
