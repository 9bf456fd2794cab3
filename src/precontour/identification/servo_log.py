"""Servo logs in: commanded and actual axis positions (and motor currents) at the servo rate.

Formats (picked by ``fmt``, else by the file's suffix and first line):

* ``table``: CSV / ``.npz`` / ``.parquet`` with columns ``t``, ``X..C`` (commanded), ``X_act..C_act``
  (measured), optionally ``I_X..I_C`` (motor current, A) and ``line``; mm, rad, s.
* ``halsampler``: LinuxCNC halsampler(1) output, one line per sample, values in pin order
  separated by blanks; ``columns`` names them (``n`` for the sample number that ``-t`` prints,
  empty names skip a pin); ``overrun`` lines (lost samples) are errors. Without a ``t`` column
  the time is the sample number (or line) times ``period``.
* ``halscope``: a log saved by LinuxCNC halscope: the line ``Sampling period is N ns``
  (``# Sampling period is N ns`` since LinuxCNC 2.10), then either ``label;label;...`` and rows
  ``value;value;...`` (2.10), or rows of ``label value`` pairs (before 2.10; that writer emits
  one row past the capture, which is dropped). Channels are named by their labels, or by
  ``columns`` (a list in channel order, or a map {label: column}).
* ``sco`` (Heidenhain TNCscope, ``.sco``), ``twincat-csv`` (Beckhoff TwinCAT Scope View's CSV
  export, told from a table by its first line ``Name``), ``sinumerik-xml`` (a Siemens
  Sinumerik Operate trace, ``.xml``): the controllers' servo traces, in mm and degrees, their
  channels recognised by name (an axis letter and a setpoint or actual word, English or
  German) or named by ``columns``; ``csv``: any delimited text whose columns ``columns``
  names (a ``.csv`` given ``columns`` is read so). Their layouts:
  :mod:`precontour.identification._trace_formats`.

Columns (and ``columns`` names) are the machine's axis letters (``axis_names``): ``B``,
``B_act``, ``I_B`` on a B-C machine, ``A``..``B`` on an A-B machine. A B-C machine's log with
the former column ``A`` (``A_act``, ``I_A``) holding B is still read, with a one-line notice,
as the trajectory tables are (:func:`precontour.tables.read_trajectory`). Inside, the axes
are keyed by the library's q slots (``X Y Z A C``), as the drives and the error models are;
messages name the machine's letters. A column ``line`` in any format is the program line
executing at each sample (whole numbers).

An axis may be absent (neither its command nor its actual); one with only its actual is an
error, and so is one with only its command unless the log is read with ``require_actual=False``
(a trace used for its timing only). Every problem is an :class:`~precontour.errors.InputError`
naming the file, row and field: non-numeric, NaN or infinite values, gaps, non-uniform or
non-increasing time, currents that are zero throughout (not recorded) and saturated currents (a
current column held at its extreme value for :data:`SATURATION_RUN` or more samples, as an
amplifier at its current limit does). Text logs are read line by line, each line at most
:data:`MAX_LINE_BYTES` long: a file that is no log (binary data, a line that does not end, a
first line whose values do not match the column names) is refused at that line, before the
rest is read.
"""

from __future__ import annotations

import itertools
import re
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType
from typing import Mapping, Sequence

import numpy as np

from ..defaults import LOG_FORMATS as FORMATS
from ..errors import InputError
from ..machine.drives import AXES
from ..tables import SUPPORTED_SUFFIXES, read_columns
from ..trajectory.sampled import check_uniform_time
from . import _trace_formats as traces
from ._log_reading import (MAX_LINE_BYTES, Letters, Rows, axis_of,
                           check_sample_numbers, log_names, parse_number, text_lines)
from ._trace_formats import parse_column_map

__all__ = ["ACTUAL_COLUMNS", "COMMAND_COLUMNS", "CURRENT_COLUMNS", "FORMATS", "GAP_FACTOR",
           "MAX_LINE_BYTES", "MIN_SAMPLES", "SATURATION_RUN", "ServoLog", "parse_column_map",
           "read_servo_log"]

COMMAND_COLUMNS: tuple[str, ...] = AXES
ACTUAL_COLUMNS: tuple[str, ...] = tuple(f"{a}_act" for a in AXES)
CURRENT_COLUMNS: tuple[str, ...] = tuple(f"I_{a}" for a in AXES)
#: Consecutive samples at a current column's extreme value that count as saturation.
SATURATION_RUN = 3
#: A time step longer than this many typical steps is a gap (lost samples).
GAP_FACTOR = 1.5
#: Fewest samples a log needs.
MIN_SAMPLES = 20
#: Largest program line a log may give: an integer a float holds exactly.
MAX_LINE_NUMBER = 2 ** 53

_PERIOD = re.compile(r"^\s*#?\s*Sampling period is\s+(\S+)\s*ns", re.IGNORECASE)
#: Readers of the controllers' traces and of any CSV, by format name.
_TRACE_READERS = {"sco": traces.read_sco, "twincat-csv": traces.read_twincat,
                  "sinumerik-xml": traces.read_sinumerik, "csv": traces.read_csv}


@dataclass(frozen=True)
class ServoLog:
    """A checked servo log. Per-axis arrays are keyed by q slot (only the axes present):
    ``command`` holds every axis of the log, ``actual`` those whose position was measured
    (all of them, unless the log was read with ``require_actual=False``), ``current`` those
    with a motor current. ``line`` is the program line executing at each sample, if the log
    recorded it."""

    source: str
    t: np.ndarray
    command: Mapping[str, np.ndarray]
    actual: Mapping[str, np.ndarray]
    current: Mapping[str, np.ndarray]
    line: np.ndarray | None = None

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
                   columns: Sequence[str] | Mapping[str, str] | None = None,
                   period: float | None = None, default_period: float | None = None,
                   angle_scale: float = 1.0, axis_names: Sequence[str] = AXES,
                   require_actual: bool = True) -> ServoLog:
    """Read and check a servo log (see the module docstring for the formats).

    ``columns`` names the columns or channels: a list in file (channel) order, or for the
    formats whose channels have names a map {channel name: column}
    (:func:`parse_column_map` reads one from ``"s ist/X=X_act,s soll/X=X"``). ``period`` (s)
    is the time step of a log without time stamps (it overrides a halscope log's own);
    ``default_period`` is used when neither is given (e.g. the machine's servo period).
    ``angle_scale`` multiplies the rotary axes' values (``pi/180`` for logs in degrees).
    ``axis_names``: the machine's letters (``Machine.axis_names``), which name the log's
    columns. ``require_actual=False`` accepts axes with a command and no actual position (a
    trace read for its timing only): ``actual`` then lacks them.
    """
    path = Path(path)
    source = str(path)
    letters = Letters(tuple(axis_names))
    fmt = _format(path, fmt, columns)
    if fmt not in FORMATS:
        raise InputError(f"unknown log format {fmt!r}; choose one of {', '.join(FORMATS)}",
                         source=source)
    if isinstance(columns, Mapping) and fmt == "table":
        raise InputError("a table names its columns t, X, X_act, ... in its header; a column map "
                         "is for other CSV files (format csv)", source=source)
    if isinstance(columns, Mapping) and fmt == "halsampler":
        raise InputError("halsampler output names no channels: name its pins with a list in "
                         "their order (--columns)", source=source)
    if fmt == "table":
        data = read_columns(path, (), ("t", "line") + letters.columns())
        first_row = 1
        if "t" not in data:
            if period is None:
                raise InputError("missing column t (or give the sample period)", source=source,
                                 field="t")
    elif fmt == "halsampler":
        data, first_row = _read_halsampler(path, columns, letters)
    elif fmt == "halscope":
        data, first_row, scope_period = _read_halscope(path, columns, letters)
        period = scope_period if period is None else period
    else:
        data, first_row = _TRACE_READERS[fmt](path, columns, letters)
    if period is None:
        period = default_period
    return _assemble(source, letters.to_slots(data, source), first_row, period, angle_scale,
                     letters, require_actual)


def _format(path: Path, fmt: str | None, columns) -> str:
    """The format asked for, else the one the file's suffix and first line say."""
    if fmt is not None:
        return fmt
    suffix = path.suffix.lower()
    head = _first_line(path)
    if suffix == ".sco" or head.startswith("%TNCscope"):
        return "sco"
    if suffix == ".xml" or head.startswith(("<?xml", "<traceSession")):
        return "sinumerik-xml"
    if re.match(r"Name[\t;,]", head):
        return "twincat-csv"
    if suffix in SUPPORTED_SUFFIXES:
        # a CSV whose columns the caller names is no table of the library's own names
        return "csv" if suffix == ".csv" and columns is not None else "table"
    return "halscope" if _PERIOD.match(head) else "halsampler"


def _first_line(path: Path) -> str:
    """The start of the file's first line (nothing for a file that cannot be read: the
    reader says why)."""
    try:
        with open(path, "rb") as handle:
            head = handle.read(200).decode("utf-8", "replace")
    except OSError:
        return ""
    return head.removeprefix("\ufeff").splitlines()[0] if head.strip() else ""


def _read_halsampler(path: Path, columns, letters: Letters) -> tuple[dict, list[int]]:
    source = str(path)
    rows = Rows()
    names = None
    for number, line in text_lines(path):
        text = line.strip()
        if not text:
            continue
        if text == "overrun":
            raise InputError("halsampler overrun: samples were lost here (a gap); record again "
                             "with a larger sampler FIFO", source=source, row=number)
        fields = text.split()
        if names is None:
            names = log_names(columns, len(fields), source, letters)
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
    check_sample_numbers(data, line_numbers, source)
    return data, line_numbers


def _read_halscope(path: Path, columns, letters: Letters) -> tuple[dict, list[int], float]:
    source = str(path)
    lines = text_lines(path)
    first = next(lines, None)
    if first is None:
        raise InputError("empty file", source=source)
    match = _PERIOD.match(first[1])
    if not match:
        raise InputError("not a halscope log: the first line must be 'Sampling period is N ns'",
                         source=source, row=1)
    period_ns = parse_number(match.group(1), source, 1, "Sampling period")
    if not (np.isfinite(period_ns) and period_ns > 0):
        raise InputError(f"sampling period must be > 0 ns, got {match.group(1)}", source=source,
                         row=1, field="Sampling period")
    body = ((number, line.strip()) for number, line in lines if line.strip())
    head = next(body, None)
    if head is None:
        raise InputError("no samples", source=source)
    rows = Rows()
    if ";" in head[1] or not any(c.isspace() for c in head[1]):
        # LinuxCNC 2.10 and later: a label header, optional '# ...' lines, ';' rows.
        labels = [label.strip() for label in head[1].split(";")]
        names = _label_names(labels, columns, source, letters)
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
                names = _label_names(labels, columns, source, letters)
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


def _label_names(labels: list[str], columns, source: str, letters: Letters) -> list[str]:
    """The column of each halscope channel: its label, or as ``columns`` names it (a list in
    channel order, or a map {label: column})."""
    if columns is None:
        return labels
    if isinstance(columns, Mapping):
        return traces.map_labels(labels, columns, source, letters)
    return log_names(columns, len(labels), source, letters)


def _assemble(source: str, data: dict, first_row, period, angle_scale: float,
              letters: Letters, require_actual: bool = True) -> ServoLog:
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
    command, actual, current = _axes(source, data, angle_scale, letters, require_actual,
                                     row_of)
    return ServoLog(source=source, t=t, command=MappingProxyType(command),
                    actual=MappingProxyType(actual), current=MappingProxyType(current),
                    line=_program_line(data, source, row_of))


def _axes(source: str, data: dict, angle_scale: float, letters: Letters, require_actual: bool,
          row_of) -> tuple[dict, dict, dict]:
    """Command, actual position and current of each axis of the log, keyed by q slot."""
    command, actual, current = {}, {}, {}
    for axis in AXES:
        cmd, act = data.get(axis), data.get(f"{axis}_act")
        name = letters.letter[axis]
        if cmd is None and act is not None:
            raise InputError(f"axis {name} has only one of {name}, {name}_act", source=source,
                             field=name)
        if cmd is not None and act is None and require_actual:
            raise InputError(f"axis {name} has only one of {name}, {name}_act (a trace read for "
                             "its timing only: require_actual=False)", source=source,
                             field=f"{name}_act")
        if cmd is None:
            continue
        scale = angle_scale if axis in ("A", "C") else 1.0
        command[axis] = cmd * scale
        if act is not None:
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
        pair = "one pair of columns X, X_act" if require_actual else "one column X"
        raise InputError(f"no axis in the log: need at least {pair} (or "
                         f"{', '.join(letters.names[1:])}); found "
                         f"{', '.join(_named(data, letters)) or 'none'} (name them with "
                         "--columns)", source=source)
    return command, actual, current


def _program_line(data: dict, source: str, row_of) -> np.ndarray | None:
    """The program line of each sample (column ``line``) as integers, if the log has it."""
    if "line" not in data:
        return None
    values = data["line"]
    bad = (values != np.round(values)) | (np.abs(values) > MAX_LINE_NUMBER)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise InputError(f"a program line must be a whole number, got {values[k]:g}",
                         source=source, row=row_of(k), field="line")
    return values.astype(np.int64)


def _named(data: dict, letters: Letters) -> list[str]:
    """The columns of ``data`` (keyed by q slot) by the machine's letters."""
    out = []
    for name in data:
        axis = axis_of(name)
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
