"""Column files in and out: CSV (pyarrow's C++ reader and writer), ``.npz`` and ``.parquet``.

Readers check every value (finite, required columns present) and name the file, the 1-based
data row (the header is not counted) and the column of the first bad value. Writers write to a
temporary file beside the target and rename it, and refuse to overwrite an input.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import Iterable, Mapping, Sequence

import numpy as np

from .machine.drives import AXES
from .errors import InputError
from .machine.kinematics import normalize_orientations
from .trajectory.sampled import Trajectory, check_uniform_time

TRAJECTORY_COLUMNS: tuple[str, ...] = ("t",) + AXES
REFERENCE_COLUMNS: tuple[str, ...] = ("Px", "Py", "Pz", "Oi", "Oj", "Ok")
SUPPORTED_SUFFIXES: tuple[str, ...] = (".csv", ".npz", ".parquet")


def read_columns(path: str | Path, required: Sequence[str], optional: Sequence[str] = ()
                 ) -> dict[str, np.ndarray]:
    """Read the named float columns of a CSV, ``.npz`` or ``.parquet`` file.

    Other columns are ignored. Raises :class:`InputError` for a missing file or column, an
    unparseable or non-finite value (naming its row and column), or an unknown format.
    """
    path = Path(path)
    source = str(path)
    suffix = path.suffix.lower()
    if suffix not in SUPPORTED_SUFFIXES:
        raise InputError(f"unsupported file type {suffix or '(none)'!r}; use one of "
                         f"{', '.join(SUPPORTED_SUFFIXES)}", source=source)
    if not path.is_file():
        raise InputError("no such file", source=source)
    if suffix == ".csv":
        raw = _read_csv(path, list(required) + list(optional))
    elif suffix == ".npz":
        try:
            with np.load(path, allow_pickle=False) as data:
                raw = {name: data[name] for name in data.files}
        except (OSError, ValueError) as exc:
            raise InputError(f"cannot read .npz file: {exc}", source=source) from None
    else:
        import pyarrow.parquet as pq
        try:
            table = pq.read_table(path)
        except Exception as exc:  # pyarrow raises its own exception types
            raise InputError(f"cannot read parquet file: {exc}", source=source) from None
        raw = {name: table.column(name).to_numpy(zero_copy_only=False)
               for name in table.column_names}

    missing = [name for name in required if name not in raw]
    if missing:
        raise InputError(f"missing column(s) {', '.join(missing)}; the file has "
                         f"{', '.join(raw) or 'no columns'}", source=source, field=missing[0])
    columns: dict[str, np.ndarray] = {}
    for name in list(required) + [c for c in optional if c in raw]:
        try:
            values = np.asarray(raw[name], dtype=float)
        except (TypeError, ValueError):
            values = _coerce_with_row(raw[name], source, name)
        if values.ndim != 1:
            raise InputError(f"column must be 1-D, got shape {values.shape}", source=source,
                             field=name)
        bad = ~np.isfinite(values)
        if bad.any():
            row = int(np.flatnonzero(bad)[0])
            raise InputError(f"value is not finite ({values[row]})", source=source,
                             row=row + 1, field=name)
        columns[name] = values
    lengths = {len(v) for v in columns.values()}
    if len(lengths) > 1:
        raise InputError("columns have different lengths", source=source)
    return columns


def read_trajectory(path: str | Path, *, min_samples: int = 4) -> Trajectory:
    """Read a trajectory file with columns ``t,X,Y,Z,A,C`` (s, mm, rad) and, if all present,
    the reference ``Px,Py,Pz,Oi,Oj,Ok``. Time must be uniformly sampled."""
    source = str(path)
    columns = read_columns(path, TRAJECTORY_COLUMNS, REFERENCE_COLUMNS)
    check_uniform_time(columns["t"], source=source, min_samples=min_samples)
    q = np.stack([columns[axis] for axis in AXES], axis=1)
    P = O = None
    if all(name in columns for name in REFERENCE_COLUMNS):
        P = np.stack([columns[name] for name in REFERENCE_COLUMNS[:3]], axis=1)
        O = normalize_orientations(np.stack([columns[name] for name in REFERENCE_COLUMNS[3:]],
                                            axis=1), source=source)
    return Trajectory(t=columns["t"], q=q, P=P, O=O)


def trajectory_columns(traj: Trajectory) -> dict[str, np.ndarray]:
    """The columns of a trajectory file: ``t,X,Y,Z,A,C`` and, if present, ``Px..Ok``."""
    columns = {"t": traj.t}
    columns.update({axis: traj.q[:, i] for i, axis in enumerate(AXES)})
    if traj.has_reference:
        columns.update({name: traj.P[:, i] for i, name in enumerate(REFERENCE_COLUMNS[:3])})
        columns.update({name: traj.O[:, i] for i, name in enumerate(REFERENCE_COLUMNS[3:])})
    return columns


def write_columns(path: str | Path, columns: Mapping[str, np.ndarray], *,
                  inputs: Iterable[str | Path] = ()) -> Path:
    """Write float columns to CSV / ``.npz`` / ``.parquet`` (by suffix), atomically.

    CSV values are written with full (round-trip) precision. ``inputs`` are the files the
    result was computed from: writing over one of them is refused.
    """
    path = check_output_path(path, inputs=inputs, suffixes=SUPPORTED_SUFFIXES)
    suffix = path.suffix.lower()
    names = list(columns)
    arrays = [np.ascontiguousarray(columns[name], dtype=float) for name in names]

    def write(handle) -> None:
        if suffix == ".npz":
            np.savez(handle, **dict(zip(names, arrays)))
            return
        import pyarrow as pa
        table = pa.table(dict(zip(names, arrays)))
        if suffix == ".csv":
            import pyarrow.csv as pacsv
            handle.write((",".join(names) + "\n").encode())
            pacsv.write_csv(table, handle,
                            write_options=pacsv.WriteOptions(include_header=False))
        else:
            import pyarrow.parquet as pq
            pq.write_table(table, handle)

    return _write_atomically(path, write)


def write_text(path: str | Path, chunks: str | Iterable[str], *,
               inputs: Iterable[str | Path] = (), suffixes: Sequence[str] | None = None
               ) -> Path:
    """Write text (a string or an iterable of strings, UTF-8) atomically, like
    :func:`write_columns`: to a temporary file beside ``path``, then renamed; an input is never
    overwritten; ``suffixes``, when given, are the allowed file extensions."""
    path = check_output_path(path, inputs=inputs, suffixes=suffixes)
    if isinstance(chunks, str):
        chunks = (chunks,)

    def write(handle) -> None:
        for chunk in chunks:
            handle.write(chunk.encode())

    return _write_atomically(path, write)


def check_output_path(path: str | Path, *, inputs: Iterable[str | Path] = (),
                      suffixes: Sequence[str] | None = None) -> Path:
    """Check, before computing, that ``path`` can be an output: a known extension (when
    ``suffixes`` are given), an existing directory to put it in, not a directory itself, and
    not one of ``inputs``. Returns ``path`` as a :class:`Path`; raises :class:`InputError`."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffixes is not None and suffix not in suffixes:
        raise InputError(f"unsupported output type {suffix or '(none)'!r}; use one of "
                         f"{', '.join(suffixes)}", source=str(path))
    for source in inputs:
        if _same_file(path, Path(source)):
            raise InputError("refusing to overwrite an input file; choose another output",
                             source=str(path))
    directory = path.parent if str(path.parent) else Path(".")
    if not directory.is_dir():
        raise InputError("output directory does not exist", source=str(path))
    if path.is_dir():
        raise InputError("output is a directory; name a file", source=str(path))
    return path


def _write_atomically(path: Path, write) -> Path:
    """Call ``write(binary_handle)`` on a temporary file beside ``path``, then rename it."""
    directory = path.parent if str(path.parent) else Path(".")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=directory)
    try:
        with os.fdopen(fd, "wb") as handle:
            write(handle)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def _read_csv(path: Path, wanted: list[str]) -> dict[str, np.ndarray]:
    import pyarrow as pa
    import pyarrow.csv as pacsv

    source = str(path)
    try:
        with open(path, "rb") as handle:
            header = handle.readline().decode("utf-8", "replace")
    except OSError as exc:
        raise InputError(f"cannot read file: {exc}", source=source) from None
    if not header.strip():
        raise InputError("empty file (no header line)", source=source)
    names = [name.strip().strip('"') for name in header.strip().split(",")]
    present = [name for name in wanted if name in names]
    convert = pacsv.ConvertOptions(include_columns=present,
                                   column_types={name: pa.float64() for name in present})
    parse = pacsv.ParseOptions(ignore_empty_lines=True)
    read = pacsv.ReadOptions(column_names=names, skip_rows=1)
    try:
        table = pacsv.read_csv(path, read_options=read, parse_options=parse,
                               convert_options=convert)
    except pa.ArrowInvalid as exc:
        raise _csv_error(path, names, present, str(exc)) from None
    return {name: table.column(name).to_numpy() for name in present}


def _csv_error(path: Path, names: list[str], present: list[str], message: str) -> InputError:
    """Locate the first bad CSV row with a slow, exact scan (only on the error path)."""
    import csv

    source = str(path)
    with open(path, newline="") as handle:
        reader = csv.reader(handle)
        next(reader, None)
        row = 0
        for fields in reader:
            if not fields or all(not f.strip() for f in fields):
                continue
            row += 1
            if len(fields) != len(names):
                return InputError(f"expected {len(names)} fields, found {len(fields)}",
                                  source=source, row=row)
            for name in present:
                text = fields[names.index(name)].strip()
                try:
                    float(text)
                except ValueError:
                    return InputError(f"not a number: {text!r}", source=source, row=row,
                                      field=name)
    return InputError(f"cannot parse CSV: {message.splitlines()[0]}", source=source)


def _coerce_with_row(values, source: str, name: str) -> np.ndarray:
    out = np.empty(len(values))
    for row, value in enumerate(values):
        try:
            out[row] = float(value)
        except (TypeError, ValueError):
            raise InputError(f"not a number: {value!r}", source=source, row=row + 1,
                             field=name) from None
    return out


def _same_file(a: Path, b: Path) -> bool:
    try:
        return a.exists() and b.exists() and os.path.samefile(a, b)
    except OSError:
        return False
