"""Reader for cutter-location (CL) data in CSV form.

The header names the columns ``Px, Py, Pz`` (tool tip, mm) and ``Oi, Oj, Ok`` (tool
orientation), in any order and case, with an optional feed column ``F``; other columns are
ignored. Feeds are in ``feed_units`` (mm/min by default, as CAM writes them); an empty ``F``
cell means "not programmed". Empty lines are ignored. Parsing is done by ``pyarrow.csv``.
"""

from __future__ import annotations

import csv
import io
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv

from ..errors import ToolPathError
from ._common import ReadReport, feed_factor, finish, read_bytes

REQUIRED_COLUMNS = ("Px", "Py", "Pz", "Oi", "Oj", "Ok")
#: Longest stretch searched for the header row, in bytes.
MAX_HEADER_BYTES = 1 << 20
FEED_COLUMN = "F"

__all__ = ["read_clcsv", "read_clcsv_report", "REQUIRED_COLUMNS", "FEED_COLUMN"]


def read_clcsv(path: str | Path, *, feed_units: str = "mm/min"):
    """Read a CL-data CSV file into a :class:`~precontour.toolpath.ToolPath`.

    Parameters
    ----------
    path : str or Path
        CSV file with a header row; see the module docstring for the columns.
    feed_units : {"mm/min", "mm/s"}
        Unit of the ``F`` column. Feeds are returned in mm/s.

    Returns
    -------
    ToolPath
        P (M, 3) mm, unit O (M, 3), feed (M,) mm/s (NaN where empty or no ``F`` column).

    Raises
    ------
    ToolPathError
        Missing file or column, unparseable or non-finite number, bad orientation, fewer
        than two distinct points, orientation reversal (see :func:`read_clcsv_report`).
    """
    return read_clcsv_report(path, feed_units=feed_units).toolpath


def read_clcsv_report(path: str | Path, *, feed_units: str = "mm/min") -> ReadReport:
    """Like :func:`read_clcsv`, returning the :class:`ReadReport` (source line of each
    point, duplicates dropped).

    Consecutive duplicate rows (same P and O) are dropped and counted in
    ``report.n_duplicates``. Orientations within
    :data:`~precontour.machine.kinematics.UNIT_TOLERANCE` of unit length are normalized with
    one notice; others, zero-length ones and a turn of more than 90 degrees between consecutive
    rows are errors naming the file line (header = line 1).
    """
    source = str(path)
    factor = feed_factor(feed_units)
    data = read_bytes(path)
    try:
        data.decode("utf-8")
    except UnicodeDecodeError:  # pyarrow would fail decoding a bad row's text for messages
        data = data.decode("utf-8", errors="replace").encode("utf-8")
    if not data.endswith(b"\n"):
        # a last row without its line break is a row (pyarrow refused a header-only file
        # without one as malformed)
        data += b"\n"
    header_line, header = _header(data, source)
    columns = _map_columns(header, source, header_line)
    wanted = [columns[c] for c in REQUIRED_COLUMNS]
    feed_col = columns.get(FEED_COLUMN)
    if feed_col is not None:
        wanted.append(feed_col)

    invalid: list[str] = []

    def on_invalid(row):
        invalid.append(row.number)  # not row.text: it may not be UTF-8
        return "skip"

    try:
        # an arrow buffer, not a Python file: pyarrow 14's threaded reader, failing on a file
        # without a newline after its header, joined its reading thread while holding the
        # GIL that thread needed to read a Python file (a hang, or an abort at exit)
        table = pacsv.read_csv(
            pa.py_buffer(data),
            parse_options=pacsv.ParseOptions(invalid_row_handler=on_invalid),
            convert_options=pacsv.ConvertOptions(
                include_columns=wanted, column_types={c: pa.float64() for c in wanted},
                # only an empty cell is "missing"; 'nan' must reach the finite check
                null_values=[""], strings_can_be_null=False,
                quoted_strings_can_be_null=True))
    except pa.ArrowInvalid:
        _raise_bad_number(data, header, wanted, source)
        raise  # _raise_bad_number always raises; keeps type checkers quiet
    lines = _data_lines(data, header_line)
    if lines.size != table.num_rows:  # quoted line breaks: number rows after the header
        lines = header_line + 1 + np.arange(table.num_rows)
    if invalid:
        _raise_bad_row(data, header, source)

    values = np.column_stack([table.column(c).to_numpy(zero_copy_only=False)
                              for c in wanted]) if table.num_rows else np.empty((0, len(wanted)))
    for j, name in enumerate(wanted[:6]):
        missing = np.isnan(values[:, j]) & _is_null(table.column(name))
        if missing.any():
            r = int(np.flatnonzero(missing)[0])
            raise ToolPathError("missing value", source=source, row=int(lines[r]),
                                field=name.strip())
    if feed_col is not None:
        feed = values[:, 6] * factor
    else:
        feed = np.full(values.shape[0], np.nan)
    return finish(values[:, 0:3], values[:, 3:6], feed, lines=lines, source=source,
                  format="clcsv", empty="no data rows after the header")


def _header(data: bytes, source: str) -> tuple[int, list[str]]:
    """1-based line number and fields of the header (the first non-empty line)."""
    # a header is short: look no further than MAX_HEADER_BYTES for it
    text = data[:MAX_HEADER_BYTES].decode("utf-8-sig", errors="replace")
    for number, line in enumerate(io.StringIO(text), start=1):
        if line.strip("\r\n"):
            if len(line) >= MAX_HEADER_BYTES // 4 and not line.endswith("\n"):
                raise ToolPathError(f"no line break in the first {MAX_HEADER_BYTES} bytes: "
                                    "not a CSV table with a header row", source=source)
            return number, _fields(line, source, number)
    raise ToolPathError("empty file (no header row)", source=source)


def _fields(line: str, source: str, number: int) -> list[str]:
    try:
        return next(csv.reader([line]))
    except csv.Error as exc:
        raise ToolPathError(f"malformed CSV line: {exc}", source=source, row=number) from None


def _map_columns(header: list[str], source: str, header_line: int) -> dict[str, str]:
    """Map canonical column names to the header's spelling (case and spaces are free)."""
    canonical = {name.lower(): name for name in (*REQUIRED_COLUMNS, FEED_COLUMN)}
    found: dict[str, str] = {}
    for raw in header:
        key = canonical.get(raw.strip().lower())
        if key is None:
            continue
        if key in found:
            raise ToolPathError(f"column {key!r} appears twice in the header", source=source,
                                row=header_line, field=key)
        found[key] = raw
    missing = [c for c in REQUIRED_COLUMNS if c not in found]
    if missing:
        raise ToolPathError(
            f"header lacks column(s) {', '.join(missing)}; a CL CSV needs "
            f"{', '.join(REQUIRED_COLUMNS)} (optional {FEED_COLUMN}), found "
            f"{', '.join(h.strip() for h in header)}", source=source, row=header_line)
    return found


def _line_starts(data: bytes) -> tuple[np.ndarray, np.ndarray]:
    """Start offsets and lengths (without the line break) of the lines of ``data``."""
    buf = np.frombuffer(data, dtype=np.uint8)
    ends = np.flatnonzero(buf == ord("\n"))
    if buf.size and buf[-1] != ord("\n"):
        ends = np.append(ends, buf.size)
    starts = np.concatenate([[0], ends[:-1] + 1])
    lengths = ends - starts
    # a CR before the LF is part of the line break
    has_cr = (lengths > 0) & (buf[np.maximum(ends - 1, 0)] == ord("\r"))
    return starts, lengths - has_cr


def _data_lines(data: bytes, header_line: int) -> np.ndarray:
    """1-based file line of each data row: the non-empty lines after the header, as
    pyarrow counts them (it skips empty lines)."""
    _, lengths = _line_starts(data)
    number = np.arange(1, lengths.size + 1)
    return number[(lengths > 0) & (number > header_line)]


def _is_null(column) -> np.ndarray:
    return np.asarray(column.is_null().to_numpy(zero_copy_only=False), dtype=bool)


def _rows(data: bytes, header: list[str], source: str):
    """(line number, fields) of every non-empty data line: slow path, for messages only."""
    text = data.decode("utf-8-sig", errors="replace")
    seen_header = False
    for number, line in enumerate(io.StringIO(text), start=1):
        if not line.strip("\r\n"):
            continue
        if not seen_header:
            seen_header = True
            continue
        yield number, _fields(line, source, number)


def _raise_bad_row(data: bytes, header: list[str], source: str):
    for number, fields in _rows(data, header, source):
        if len(fields) != len(header):
            raise ToolPathError(f"expected {len(header)} columns as in the header, got "
                                f"{len(fields)}", source=source, row=number)
    raise ToolPathError("malformed CSV row", source=source)


def _raise_bad_number(data: bytes, header: list[str], wanted: list[str], source: str):
    index = {name: header.index(name) for name in wanted}
    for number, fields in _rows(data, header, source):
        if len(fields) != len(header):
            raise ToolPathError(f"expected {len(header)} columns as in the header, got "
                                f"{len(fields)}", source=source, row=number)
        for name, j in index.items():
            text = fields[j].strip()
            if text == "":
                continue
            try:
                float(text)
            except ValueError:
                raise ToolPathError(f"cannot parse number {text!r}", source=source,
                                    row=number, field=name.strip()) from None
    raise ToolPathError("malformed CSV file", source=source)
