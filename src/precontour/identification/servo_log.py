"""Servo logs in: commanded and actual axis positions (and motor currents) at the servo rate.

Formats (picked by ``fmt`` or the file's suffix):

* ``table``: CSV / ``.npz`` / ``.parquet`` with columns ``t``, ``X..C`` (commanded), ``X_act..C_act``
  (measured) and optionally ``I_X..I_C`` (motor current, A); mm, rad, s.

Columns (and ``columns`` names) are the machine's axis letters (``axis_names``): ``B``,
``B_act``, ``I_B`` on a B-C machine, ``A``..``B`` on an A-B machine. A B-C machine's log with
the former column ``A`` (``A_act``, ``I_A``) holding B is still read, with a one-line notice,
as the trajectory tables are (:func:`precontour.tables.read_trajectory`). Inside, the axes
are keyed by the library's q slots (``X Y Z A C``), as the drives and the error models are;
messages name the machine's letters.
* ``halsampler``: LinuxCNC halsampler(1) output, one line per sample, values in pin order
  separated by blanks; ``columns`` names them (``n`` for the sample number that ``-t`` prints,
  empty names skip a pin); ``overrun`` lines (lost samples) are errors. Without a ``t`` column
  the time is the sample number (or line) times ``period``.
* ``halscope``: a log saved by LinuxCNC halscope: the line ``Sampling period is N ns``
  (``# Sampling period is N ns`` since LinuxCNC 2.10), then either ``label;label;...`` and rows
  ``value;value;...`` (2.10), or rows of ``label value`` pairs (before 2.10; that writer emits
  one row past the capture, which is dropped). Channels are named by their labels, or by
  ``columns`` in channel order.

An axis may be absent (neither its command nor its actual); one with only one of the two is an
error. Every problem is an :class:`~precontour.errors.InputError` naming the file, row and
field: non-numeric, NaN or infinite values, gaps, non-uniform or non-increasing time, currents
that are zero throughout (not recorded) and saturated currents (a current column held at its
extreme value for :data:`SATURATION_RUN` or more samples, as an amplifier at its current limit
does). Text logs are read line by line, each line at most :data:`MAX_LINE_BYTES` long: a file
that is no log (binary data, a line that does not end, a first line whose values do not match
the column names) is refused at that line, before the rest is read.
"""

from __future__ import annotations

import itertools
import re
from array import array
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType
from typing import Mapping, Sequence

import numpy as np

from ..defaults import LOG_FORMATS as FORMATS
from ..errors import InputError
from ..files import check_input_file, refuse_non_text
from ..machine.drives import AXES
from ..tables import (SUPPORTED_SUFFIXES, notice_former_tilt_column, read_columns,
                      reads_former_tilt_column)
from ..trajectory.sampled import check_uniform_time

COMMAND_COLUMNS: tuple[str, ...] = AXES
ACTUAL_COLUMNS: tuple[str, ...] = tuple(f"{a}_act" for a in AXES)
CURRENT_COLUMNS: tuple[str, ...] = tuple(f"I_{a}" for a in AXES)
#: Consecutive samples at a current column's extreme value that count as saturation.
SATURATION_RUN = 3
#: A time step longer than this many typical steps is a gap (lost samples).
GAP_FACTOR = 1.5
#: Fewest samples a log needs.
MIN_SAMPLES = 20
#: Longest line of a text log, bytes (a halsampler line of 15 pins is about 300 bytes).
MAX_LINE_BYTES = 1 << 16

_PERIOD = re.compile(r"^\s*#?\s*Sampling period is\s+(\S+)\s*ns", re.IGNORECASE)


@dataclass(frozen=True)
class ServoLog:
    """A checked servo log. Per-axis arrays are keyed by axis name (only the axes present)."""

    source: str
    t: np.ndarray
    command: Mapping[str, np.ndarray]
    actual: Mapping[str, np.ndarray]
    current: Mapping[str, np.ndarray]

    @property
    def period(self) -> float:
        return float((self.t[-1] - self.t[0]) / (self.t.size - 1))

    @property
    def n_samples(self) -> int:
        return int(self.t.size)

    @property
    def axes(self) -> tuple[str, ...]:
        return tuple(a for a in AXES if a in self.command)


def read_servo_log(path: str | Path, *, fmt: str | None = None,
                   columns: Sequence[str] | None = None, period: float | None = None,
                   default_period: float | None = None, angle_scale: float = 1.0,
                   axis_names: Sequence[str] = AXES) -> ServoLog:
    """Read and check a servo log (see the module docstring for the formats).

    ``period`` (s) is the time step of a log without a ``t`` column (it overrides a halscope
    log's own); ``default_period`` is used when neither is given (e.g. the machine's servo
    period). ``angle_scale`` multiplies the rotary axes' values (``pi/180`` for logs in
    degrees). ``axis_names``: the machine's letters (``Machine.axis_names``), which name the
    log's columns.
    """
    path = Path(path)
    source = str(path)
    letters = _Letters(tuple(axis_names))
    if fmt is None:
        fmt = "table" if path.suffix.lower() in SUPPORTED_SUFFIXES else None
        if fmt is None:
            fmt = "halscope" if _looks_like_halscope(path) else "halsampler"
    if fmt not in FORMATS:
        raise InputError(f"unknown log format {fmt!r}; choose one of {', '.join(FORMATS)}",
                         source=source)
    if fmt == "table":
        data = read_columns(path, (), ("t",) + letters.columns())
        first_row = 1
        if "t" not in data:
            if period is None:
                raise InputError("missing column t (or give the sample period)", source=source,
                                 field="t")
    elif fmt == "halsampler":
        data, first_row = _read_halsampler(path, columns, letters)
    else:
        data, first_row, scope_period = _read_halscope(path, columns, letters)
        period = scope_period if period is None else period
    if period is None:
        period = default_period
    return _assemble(source, letters.to_slots(data, source), first_row, period, angle_scale,
                     letters)


class _Letters:
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
        present = {_axis_of(name) for name in data}
        out = {}
        for name, values in data.items():
            axis = _axis_of(name)
            if axis not in self.slot and axis not in self.former:
                out[name] = values    # t, n, or a halscope channel of another name
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


def _axis_of(name: str) -> str | None:
    """The axis letter of a column name (``B``, ``B_act``, ``I_B``), None for t and n."""
    if name in ("t", "n"):
        return None
    if name.startswith("I_"):
        return name[2:]
    return name[:-4] if name.endswith("_act") else name


def _looks_like_halscope(path: Path) -> bool:
    try:
        with open(path, "rb") as handle:
            head = handle.read(200).decode("utf-8", "replace")
    except OSError:
        return False
    return bool(_PERIOD.match(head.splitlines()[0] if head.splitlines() else ""))


def _text_lines(path: Path):
    """(line number, text) of each line of a text log, read one at a time: refused at the
    first line that is binary data, not UTF-8 or longer than :data:`MAX_LINE_BYTES`."""
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
            try:
                text = raw.decode("utf-8")
            except UnicodeDecodeError:
                raise InputError("not a text file (invalid UTF-8)", source=source,
                                 row=number) from None
            yield number, text.removeprefix("\ufeff") if number == 1 else text


def _parse_number(text: str, source: str, line: int, field: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise InputError(f"not a number: {text!r}", source=source, row=line,
                         field=field) from None


def _names(columns: Sequence[str] | None, count: int, source: str,
           letters: _Letters) -> list[str]:
    if columns is None:
        raise InputError("name the columns (--columns X,X_act,...)", source=source)
    names = [c.strip() for c in columns]
    known = set(("t", "n") + letters.columns())
    for name in names:
        if name and name not in known:
            raise InputError(f"unknown column name {name!r}; use t, n, "
                             f"{', '.join(letters.names)}, X_act.., I_X.. or an empty name to "
                             "skip", source=source, field=name)
    duplicates = {n for n in names if n and names.count(n) > 1}
    if duplicates:
        raise InputError(f"column {sorted(duplicates)[0]!r} named twice", source=source)
    if len(names) != count:
        raise InputError(f"{len(names)} column names for {count} values per line", source=source)
    return names


class _Rows:
    """Parsed values of a text log, row by row, in one flat float array (not Python lists)."""

    def __init__(self):
        self.values = array("d")
        self.lines = array("q")
        self.width = None

    def add(self, number: int, fields, names, source: str) -> None:
        for i, text in enumerate(fields):
            self.values.append(_parse_number(text.strip(), source, number,
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


def _read_halsampler(path: Path, columns, letters: _Letters) -> tuple[dict, list[int]]:
    source = str(path)
    rows = _Rows()
    names = None
    for number, line in _text_lines(path):
        text = line.strip()
        if not text:
            continue
        if text == "overrun":
            raise InputError("halsampler overrun: samples were lost here (a gap); record again "
                             "with a larger sampler FIFO", source=source, row=number)
        fields = text.split()
        if names is None:
            names = _names(columns, len(fields), source, letters)
            rows.width = len(names)
        if len(fields) != len(names):
            raise InputError(f"expected {len(names)} values, found {len(fields)}", source=source,
                             row=number)
        rows.add(number, fields, names, source)
    if not len(rows):
        raise InputError("no samples", source=source)
    table = rows.table()
    line_numbers = rows.lines.tolist()
    data = {name: table[:, i] for i, name in enumerate(names) if name}
    if "n" in data:
        step = np.diff(data["n"])
        bad = np.flatnonzero(step != 1)
        if bad.size:
            k = int(bad[0]) + 1
            raise InputError(f"sample number jumps from {data['n'][k - 1]:g} to {data['n'][k]:g} "
                             "(a gap: samples were lost)", source=source, row=line_numbers[k],
                             field="n")
    return data, line_numbers


def _read_halscope(path: Path, columns, letters: _Letters) -> tuple[dict, list[int], float]:
    source = str(path)
    lines = _text_lines(path)
    first = next(lines, None)
    if first is None:
        raise InputError("empty file", source=source)
    match = _PERIOD.match(first[1])
    if not match:
        raise InputError("not a halscope log: the first line must be 'Sampling period is N ns'",
                         source=source, row=1)
    period_ns = _parse_number(match.group(1), source, 1, "Sampling period")
    if not (np.isfinite(period_ns) and period_ns > 0):
        raise InputError(f"sampling period must be > 0 ns, got {match.group(1)}", source=source,
                         row=1, field="Sampling period")
    body = ((number, line.strip()) for number, line in lines if line.strip())
    head = next(body, None)
    if head is None:
        raise InputError("no samples", source=source)
    rows = _Rows()
    if ";" in head[1] or not any(c.isspace() for c in head[1]):
        # LinuxCNC 2.10 and later: a label header, optional '# ...' lines, ';' rows.
        labels = [label.strip() for label in head[1].split(";")]
        names = labels if columns is None else _names(columns, len(labels), source, letters)
        rows.width = len(labels)
        for number, text in body:
            if text.startswith("#"):
                continue
            fields = text.split(";")
            if len(fields) != len(labels):
                raise InputError(f"expected {len(labels)} values, found {len(fields)}",
                                 source=source, row=number)
            rows.add(number, fields, labels, source)
    else:
        labels = None
        for number, text in itertools.chain([head], body):
            fields = text.split()
            if len(fields) % 2:
                raise InputError("expected 'label value' pairs", source=source, row=number)
            these = fields[0::2]
            if labels is None:
                labels = these
                names = labels if columns is None else _names(columns, len(labels), source, letters)
                rows.width = len(labels)
            elif these != labels:
                raise InputError(f"labels {' '.join(these)} differ from the first row's "
                                 f"{' '.join(labels)}", source=source, row=number)
            rows.add(number, fields[1::2], labels, source)
        # That writer's loop runs one row past the captured samples.
        rows.drop_last()
    if not len(rows):
        raise InputError("no samples", source=source)
    table = rows.table()
    data = {name: table[:, i] for i, name in enumerate(names) if name}
    return data, rows.lines.tolist(), period_ns * 1e-9


def _assemble(source: str, data: dict, first_row, period, angle_scale: float,
              letters: _Letters) -> ServoLog:
    row_of = (lambda k: k + first_row) if isinstance(first_row, int) else (lambda k: first_row[k])
    n = len(next(iter(data.values()))) if data else 0
    if n < MIN_SAMPLES:
        raise InputError(f"too few samples: {n}, need at least {MIN_SAMPLES}", source=source)
    for name, values in data.items():
        bad = ~np.isfinite(values)
        if bad.any():
            k = int(np.flatnonzero(bad)[0])
            raise InputError(f"value is not finite ({values[k]})", source=source, row=row_of(k),
                             field=_named({name: None}, letters)[0])
    if "t" in data:
        t = data["t"]
    else:
        if period is None or not (np.isfinite(period) and period > 0):
            raise InputError("the log has no time column t: give the sample period", source=source,
                             field="t")
        base = data["n"] if "n" in data else np.arange(n, dtype=float)
        t = (base - base[0]) * period
    dt = np.diff(t)
    typical = np.median(dt)
    gaps = np.flatnonzero(dt > GAP_FACTOR * typical) if typical > 0 else np.zeros(0, int)
    if gaps.size:
        k = int(gaps[0]) + 1
        raise InputError(f"gap: {dt[k - 1]:.6g} s between samples, the log's period is "
                         f"{typical:.6g} s (samples lost?)", source=source, row=row_of(k), field="t")
    try:
        check_uniform_time(t, min_samples=MIN_SAMPLES)
    except InputError as exc:
        # Re-point the row at the file's own numbering (data rows, or text lines).
        message = str(exc)
        prefix = f"row {exc.row}, field 't': " if exc.row is not None else "field 't': "
        message = message[len(prefix):] if message.startswith(prefix) else message
        row = None if exc.row is None else row_of(exc.row - 1)
        raise InputError(message, source=source, row=row, field="t") from None
    command, actual, current = {}, {}, {}
    for axis in AXES:
        cmd, act = data.get(axis), data.get(f"{axis}_act")
        name = letters.letter[axis]
        if (cmd is None) != (act is None):
            missing = name if cmd is None else f"{name}_act"
            raise InputError(f"axis {name} has only one of {name}, {name}_act", source=source,
                             field=missing)
        if cmd is None:
            continue
        scale = angle_scale if axis in ("A", "C") else 1.0
        command[axis] = cmd * scale
        actual[axis] = act * scale
        if f"I_{axis}" in data:
            current[axis] = data[f"I_{axis}"]
            if not np.any(current[axis]):
                raise InputError(f"the motor current of {name} is zero on every row (not "
                                 "recorded?): J, B and friction cannot be identified from it; "
                                 "record the current, or leave the column out to identify the "
                                 "closed loop alone", source=source, field=f"I_{name}")
            _check_saturation(current[axis], source, f"I_{name}", row_of)
    if not command:
        raise InputError(f"no axis in the log: need at least one pair of columns X, X_act (or "
                         f"{', '.join(letters.names[1:])}); found "
                         f"{', '.join(_named(data, letters)) or 'none'} (name them with "
                         "--columns)", source=source)
    return ServoLog(source=source, t=t, command=MappingProxyType(command),
                    actual=MappingProxyType(actual), current=MappingProxyType(current))


def _named(data: dict, letters: _Letters) -> list[str]:
    """The columns of ``data`` (keyed by q slot) by the machine's letters."""
    out = []
    for name in data:
        axis = _axis_of(name)
        out.append(name.replace(axis, letters.letter[axis]) if axis in letters.letter
                   else name)
    return out


def _check_saturation(values: np.ndarray, source: str, name: str, row_of) -> None:
    peak = np.max(np.abs(values))
    if peak == 0:
        return
    at_peak = np.abs(values) == peak
    # Longest run of consecutive samples at the extreme.
    edges = np.flatnonzero(np.diff(np.concatenate([[0], at_peak.astype(int), [0]])))
    starts, ends = edges[0::2], edges[1::2]
    runs = ends - starts
    if runs.max() >= SATURATION_RUN:
        k = int(starts[np.argmax(runs)])
        raise InputError(f"saturated: held at {values[k]:g} for {int(runs.max())} samples (the "
                         "amplifier's current limit?); the drive is not linear there, record "
                         "with a gentler motion", source=source, row=row_of(k), field=name)
