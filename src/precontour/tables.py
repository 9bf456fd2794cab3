"""Column files in and out: CSV (pyarrow's C++ reader and writer), ``.npz`` and ``.parquet``.

Readers check every value (finite, required columns present, numeric, names unique) and name
the file, the 1-based data row (the header is not counted) and the column of the first bad
value; a file that is not what its suffix says (binary, gzip or UTF-16 text named ``.csv``, a
text file named ``.npz``) is called that. Writers go through :func:`precontour.files.atomic_write`
(temporary file, rename, never an input).

Trajectory files are checked further (:func:`read_trajectory`): at least
:data:`~precontour.trajectory.sampled.MIN_SAMPLES` uniformly spaced samples, coordinates within
:data:`MAX_LINEAR` / :data:`MAX_ROTARY`, C free of 2 pi wraps (unwrapped, with a notice) and, when
a machine's kinematics is given, the reference ``Px..Ok`` within a tolerance of the axes'
direct kinematics (:data:`REFERENCE_TOLERANCE`).
"""

from __future__ import annotations

import zipfile
from pathlib import Path
from typing import Iterable, Mapping, Sequence

import numpy as np

from .machine.drives import AXES
from .errors import InputError, OutputError, notice
from .files import atomic_write, check_input_file, check_outputs, refuse_non_text
from .machine.kinematics import angle_between, normalize_orientations
from .trajectory.sampled import MIN_SAMPLES, Trajectory, check_uniform_time

#: Axis columns are named after the machine's axes: t,X,Y,Z,A,C on an A-C machine, t,X,Y,Z,B,C
#: on a B-C machine (``Machine.axis_names``; the q slot 3 holds the tilt axis either way).
#: A B-C machine still reads the old spelling, column A holding B, with a one-line notice; an
#: A-B machine (two tilts) has t,X,Y,Z,A,B.
TRAJECTORY_COLUMNS: tuple[str, ...] = ("t",) + AXES
#: Letters of rotary axis columns.
ROTARY_COLUMNS: tuple[str, ...] = ("A", "B", "C")
REFERENCE_COLUMNS: tuple[str, ...] = ("Px", "Py", "Pz", "Oi", "Oj", "Ok")
#: Optional column: source line of the NC-program block executing at each sample.
LINE_COLUMN = "line"
SUPPORTED_SUFFIXES: tuple[str, ...] = (".csv", ".npz", ".parquet")

#: Longest CSV header line read, in bytes: a file without a line break within it is refused
#: before it is loaded whole (a 50 MB one-line file would otherwise take gigabytes).
MAX_HEADER_BYTES = 1 << 20

#: Largest |X|, |Y|, |Z|, |Px|, |Py|, |Pz| accepted in a trajectory file, mm (1 km: larger
#: numbers are no machine coordinates, and would overflow the spline fit's arithmetic).
MAX_LINEAR = 1e6
#: Largest |A|, |C| accepted in a trajectory file, rad (about 160,000 turns).
MAX_ROTARY = 1e6
#: Largest |t| accepted in a trajectory file, s (about four months).
MAX_TIME = 1e7

#: Largest distance (mm) between the reference tool tip ``Px,Py,Pz`` and the direct kinematics
#: of the axes ``X..C`` of the same row, and largest angle (rad) between ``Oi,Oj,Ok`` and the
#: axes' orientation, for a trajectory that is a reference (``compensate``, ``compare``,
#: ``simulate --reference``): files written by ``precontour trajectory`` agree to round-off; a
#: CAM post-processor's rounding to 1e-4 mm and 1e-4 rad stays far below.
REFERENCE_TOLERANCE = (0.01, 1e-3)
#: The same for a command file measured against its own reference columns (``predict``,
#: ``simulate`` without ``--reference``): pre-compensated commands differ from their reference by the
#: correction, which is of the size of the predicted errors (measured on the built-in paths,
#: both methods, PID and P-PI: at most 0.33 mm and 6.9 mrad, with ``pid-low`` on ``fan``).
COMMAND_TOLERANCE = (2.0, 0.05)


def read_columns(path: str | Path, required: Sequence[str], optional: Sequence[str] = ()
                 ) -> dict[str, np.ndarray]:
    """Read the named float columns of a CSV, ``.npz`` or ``.parquet`` file.

    Other columns are ignored. Raises :class:`InputError` for a missing file or column, an
    unparseable or non-finite value (naming its row and column), or an unknown format.
    """
    path = Path(path)
    source = str(path)
    suffix = path.suffix.lower()
    if path.is_dir():
        raise InputError("is a folder, not a file", source=source)
    if suffix not in SUPPORTED_SUFFIXES:
        raise InputError(f"unsupported file type {suffix or '(none)'!r}; use one of "
                         f"{', '.join(SUPPORTED_SUFFIXES)}", source=source)
    check_input_file(path)
    if suffix == ".csv":
        raw = _read_csv(path, list(required) + list(optional))
    elif suffix == ".npz":
        raw = _read_npz(path)
    else:
        raw = _read_parquet(path)

    missing = [name for name in required if name not in raw]
    if missing:
        raise InputError(f"missing column(s) {', '.join(missing)}; the file has "
                         f"{', '.join(raw) or 'no columns'}", source=source, field=missing[0])
    columns: dict[str, np.ndarray] = {}
    for name in list(required) + [c for c in optional if c in raw]:
        values = _as_floats(raw[name], source, name)
        if values.ndim != 1:
            raise InputError(f"column must be 1-D, got shape {values.shape}", source=source,
                             field=name)
        bad = ~np.isfinite(values)
        if bad.any():
            row = int(np.flatnonzero(bad)[0])
            raise InputError(f"value is not finite ({float(values[row])})", source=source,
                             row=row + 1, field=name)
        columns[name] = values
    lengths = {len(v) for v in columns.values()}
    if len(lengths) > 1:
        raise InputError("columns have different lengths", source=source)
    return columns


def read_trajectory(path: str | Path, *, min_samples: int = MIN_SAMPLES, kinematics=None,
                    tolerance: tuple[float, float] = REFERENCE_TOLERANCE,
                    axis_names: Sequence[str] | None = None) -> Trajectory:
    """Read a trajectory file: the axis commands, and their reference where given.

    The columns are ``t,X,Y,Z,A,C`` (s, mm, rad; ``B`` in place of ``A`` on a B-C machine)
    and, if all present, the reference ``Px,Py,Pz,Oi,Oj,Ok``, and the optional program
    ``line`` (whole numbers). A B-C machine's file with the old column ``A`` is read as B,
    with one notice. Time must be uniformly sampled; values within :data:`MAX_TIME`,
    :data:`MAX_LINEAR`, :data:`MAX_ROTARY`. A step of C by a multiple of 2 pi between two
    samples (a post-processor's wrap into one turn) is unwrapped, with one notice.

    Parameters
    ----------
    path : str or Path
        A CSV, ``.npz`` or ``.parquet`` file.
    min_samples : int
        Fewest samples accepted.
    kinematics : optional
        The machine's kinematics: the reference must then agree with the axes' direct
        kinematics within ``tolerance`` on every row (see :data:`REFERENCE_TOLERANCE`); its
        axis letters are the file's.
    tolerance : tuple of (float, float)
        That agreement, mm and rad.
    axis_names : sequence of str, optional
        The machine's axis letters (default the ``kinematics``' own, else either letter).

    Returns
    -------
    Trajectory
        The checked samples; a bad value is an error naming the file, the row and the
        column.
    """
    source = str(path)
    if axis_names is None and kinematics is not None:
        axis_names = getattr(kinematics, "axis_names", None)
    columns = read_columns(path, ("t", "X", "Y", "Z"),
                           ROTARY_COLUMNS + REFERENCE_COLUMNS + (LINE_COLUMN,))
    names = _axis_columns(columns, axis_names, source)
    _check_magnitudes(columns, source)
    check_uniform_time(columns["t"], source=source, min_samples=min_samples)
    if "C" in columns:
        columns["C"] = _unwrap_c(columns["C"], source)
    q = np.stack([columns[axis] for axis in names], axis=1)
    P = O = None
    if all(name in columns for name in REFERENCE_COLUMNS):
        P = np.stack([columns[name] for name in REFERENCE_COLUMNS[:3]], axis=1)
        O = normalize_orientations(np.stack([columns[name] for name in REFERENCE_COLUMNS[3:]],
                                            axis=1), source=source)
    line = None
    if LINE_COLUMN in columns:
        values = columns[LINE_COLUMN]
        whole = (values == np.round(values)) & (np.abs(values) < 2.0**53)
        if not whole.all():
            row = int(np.flatnonzero(~whole)[0])
            raise InputError(f"line number is not a whole number ({float(values[row])!r})",
                             source=source, row=row + 1, field=LINE_COLUMN)
        line = values.astype(np.int64)
    traj = Trajectory(t=columns["t"], q=q, P=P, O=O, line=line)
    if kinematics is not None and traj.has_reference:
        check_reference(traj, kinematics, source=source, tolerance=tolerance)
    return traj


def reads_former_tilt_column(axis_names: Sequence[str]) -> bool:
    """Whether a machine of these axis letters still reads the old spelling, column A
    holding its B: a B-C machine (B in the tilt slot, no A axis)."""
    return axis_names[3] == "B" and "A" not in axis_names


def notice_former_tilt_column(source: str, column: str = "A") -> None:
    """The one-line notice that a B-C machine's file gave its B as the old ``column``."""
    notice(f"{source}: column {column} read as the B axis of this B-C machine (the old "
           "spelling; write B)")


def _axis_columns(columns: dict, axis_names: Sequence[str] | None, source: str
                  ) -> tuple[str, ...]:
    """The five column names that hold q, in q order: the machine's ``axis_names`` (its old
    spelling ``A`` for a B-C machine's B, with a notice); without names, X Y Z, A or B, C, or
    X Y Z A B where there are A and B and no C (an A-B machine's)."""
    expected = tuple(axis_names) if axis_names is not None else None
    if expected is None and all(name in columns for name in ("A", "B")) and "C" not in columns:
        expected = ("X", "Y", "Z", "A", "B")     # an A-B machine's file
    if expected is None:
        tilt = [name for name in ("A", "B") if name in columns]
        if len(tilt) == 2:
            raise InputError("both columns A and B: which one is the tilt axis? Give the "
                             "machine (--machine) or keep one", source=source, field="B")
        expected = ("X", "Y", "Z", tilt[0] if tilt else "A", "C")
    names = list(expected)
    if reads_former_tilt_column(names) and "B" not in columns and "A" in columns:
        notice_former_tilt_column(source)
        names[3] = "A"
    missing = [name for name in names if name not in columns]
    if missing:
        raise InputError(f"missing column(s) {', '.join(missing)}; the file has "
                         f"{', '.join(columns)} (the axes: {','.join(expected)})",
                         source=source, field=missing[0])
    return tuple(names)


def check_same_times(commands: Trajectory, reference: Trajectory, *,
                     source: str | None = None) -> None:
    """Refuse a ``reference`` (from the file ``source``) whose time stamps are not those of
    ``commands``: contour errors compare the two sample by sample."""
    if not np.array_equal(reference.t, commands.t):
        raise InputError("reference and command files must have the same time stamps",
                         source=source, field="t")


def check_reference(traj: Trajectory, kinematics, *, source: str | None = None,
                    tolerance: tuple[float, float] = REFERENCE_TOLERANCE) -> None:
    """Raise :class:`InputError` naming the first row where the reference tool tip or
    orientation is farther than ``tolerance`` = (mm, rad) from the direct kinematics of the
    axes on that row, with the size of the difference."""
    P, O = kinematics.forward(traj.q)
    tip = np.linalg.norm(P - traj.P, axis=1)
    angle = angle_between(O, traj.O)
    for values, limit, field, unit, what in ((tip, tolerance[0], "Px", "mm", "tool tip"),
                                             (angle, tolerance[1], "Oi", "rad", "orientation")):
        off = ~(values <= limit)
        if off.any():
            row = int(np.flatnonzero(off)[0])
            raise InputError(
                f"reference {what} is {float(values[row]):.6g} {unit} from the direct "
                f"kinematics of X..C on this row (largest {float(values.max()):.6g} {unit}; "
                f"tolerance {limit:g} {unit}): the reference columns do not belong to these "
                "axes", source=source, row=row + 1, field=field)


def _check_magnitudes(columns: Mapping[str, np.ndarray], source: str) -> None:
    for name, values in columns.items():
        if name == LINE_COLUMN:
            continue  # source line numbers: checked as whole numbers below
        limit = (MAX_TIME if name == "t" else MAX_ROTARY if name in ROTARY_COLUMNS
                 else MAX_LINEAR)
        big = np.abs(values) > limit
        if big.any():
            row = int(np.flatnonzero(big)[0])
            raise InputError(f"value {float(values[row]):g} is out of range (|value| <= "
                             f"{limit:g})", source=source, row=row + 1, field=name)


def _unwrap_c(c: np.ndarray, source: str) -> np.ndarray:
    """C with steps of more than pi between samples removed by whole turns (np.unwrap), and
    one notice naming the first such row; no real motion turns C by pi in one servo period."""
    jumps = np.abs(np.diff(c)) > np.pi
    if not jumps.any():
        return c
    rows = np.flatnonzero(jumps)
    step = float(c[rows[0] + 1] - c[rows[0]])
    more = f" and {rows.size - 1} more" if rows.size > 1 else ""
    notice(f"{source}, row {rows[0] + 2}, field 'C': C steps by {step:.6g} rad from the row "
           f"before{more}; unwrapped by whole turns (2 pi) to keep C continuous")
    return np.unwrap(c)


def trajectory_columns(traj: Trajectory, axis_names: Sequence[str] = AXES
                       ) -> dict[str, np.ndarray]:
    """The columns of a trajectory file: ``t`` and the machine's ``axis_names`` (``X,Y,Z,A,C``
    by default, ``X,Y,Z,B,C`` on a B-C machine) and, if present, ``Px..Ok`` and ``line``
    (written as a float column, like the others)."""
    columns = {"t": traj.t}
    columns.update({axis: traj.q[:, i] for i, axis in enumerate(axis_names)})
    if traj.has_reference:
        columns.update({name: traj.P[:, i] for i, name in enumerate(REFERENCE_COLUMNS[:3])})
        columns.update({name: traj.O[:, i] for i, name in enumerate(REFERENCE_COLUMNS[3:])})
    if traj.line is not None:
        columns[LINE_COLUMN] = traj.line
    return columns


def write_columns(path: str | Path, columns: Mapping[str, np.ndarray], *,
                  inputs: Iterable[str | Path] = ()) -> Path:
    """Write float columns to CSV, ``.npz`` or ``.parquet`` (by suffix), atomically
    (:func:`precontour.files.atomic_write`); CSV values with full (round-trip) precision.

    Parameters
    ----------
    path : str or Path
        The output file.
    columns : Mapping[str, ndarray]
        Column name -> values, all of one length.
    inputs : iterable of str or Path
        The files the result was computed from: writing over one of them is refused.

    Returns
    -------
    Path
        The file written.
    """
    path = check_output_table(path, inputs)
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

    return atomic_write(path, write, inputs=inputs)


def write_text(path: str | Path, chunks: str | Iterable[str], *,
               inputs: Iterable[str | Path] = (), suffixes: Sequence[str] | None = None
               ) -> Path:
    """Write text (a string or an iterable of strings, UTF-8) atomically, like
    :func:`write_columns`; ``suffixes``, when given, are the allowed file extensions."""
    path = check_output_path(path, inputs=inputs, suffixes=suffixes)
    if isinstance(chunks, str):
        chunks = (chunks,)

    def write(handle) -> None:
        for chunk in chunks:
            handle.write(chunk.encode("utf-8"))

    return atomic_write(path, write, inputs=inputs)


def check_output_path(path: str | Path, *, inputs: Iterable[str | Path] = (),
                      suffixes: Sequence[str] | None = None) -> Path:
    """Check, before computing, that ``path`` can be an output: a known extension (when
    ``suffixes`` are given), not a folder, at a place :func:`precontour.files.check_outputs`
    allows (an existing writable folder, never one of ``inputs``). Returns it as a Path."""
    path = Path(path)
    suffix = path.suffix.lower()
    if path.is_dir():
        raise OutputError("is an existing folder; give a file name", source=str(path))
    if suffixes is not None and suffix not in suffixes:
        raise InputError(f"unsupported output type {suffix or '(none)'!r}; use one of "
                         f"{', '.join(suffixes)}", source=str(path))
    check_outputs([path], inputs)
    return path


def check_output_table(path: str | Path, inputs: Iterable[str | Path] = ()) -> Path:
    """:func:`check_output_path` for a table file :func:`write_columns` can write."""
    return check_output_path(path, inputs=inputs, suffixes=SUPPORTED_SUFFIXES)


def _read_csv(path: Path, wanted: list[str]) -> dict[str, np.ndarray]:
    import pyarrow as pa
    import pyarrow.csv as pacsv

    source = str(path)
    try:
        with open(path, "rb") as handle:
            header_bytes = handle.readline(MAX_HEADER_BYTES + 1)
    except OSError as exc:
        raise InputError(f"cannot read file: {exc.strerror or exc}", source=source) from None
    refuse_non_text(header_bytes, source)
    if len(header_bytes) > MAX_HEADER_BYTES and not header_bytes.endswith(b"\n"):
        raise InputError(f"no line break in the first {MAX_HEADER_BYTES} bytes: not a CSV "
                         "table with a header line", source=source)
    try:
        header = header_bytes.decode("utf-8").removeprefix("\ufeff")
    except UnicodeDecodeError:
        raise InputError("the header line is not UTF-8 text (binary data?)",
                         source=source) from None
    if not header.strip():
        raise InputError("empty file (no header line)", source=source)
    names = [name.strip().strip('"').strip() for name in header.strip().split(",")]
    if len(names) == 1:
        for separator, label in ((";", "';'"), ("\t", "tabs")):
            if separator in names[0]:
                raise InputError(f"fields are separated by {label}: use comma separators",
                                 source=source)
    seen = set()
    for name in names:
        if name in seen and name:
            raise InputError("column name appears twice in the header", source=source,
                             field=name)
        seen.add(name)
    present = [name for name in wanted if name in names]
    convert = pacsv.ConvertOptions(include_columns=present,
                                   column_types={name: pa.float64() for name in present})
    parse = pacsv.ParseOptions(ignore_empty_lines=True)
    read = pacsv.ReadOptions(column_names=names, skip_rows=1)
    try:
        table = pacsv.read_csv(path, read_options=read, parse_options=parse,
                               convert_options=convert)
    except (pa.ArrowException, ValueError) as exc:
        raise _csv_error(path, names, present, str(exc)) from None
    return {name: table.column(name).to_numpy() for name in present}


def _csv_error(path: Path, names: list[str], present: list[str], message: str) -> InputError:
    """Locate the first bad CSV row with a slow, exact scan (only on the error path)."""
    import csv

    source = str(path)
    row = 0
    try:
        with open(path, newline="", encoding="utf-8", errors="replace") as handle:
            reader = csv.reader(handle)
            next(reader, None)
            for fields in reader:
                if not fields or all(not f.strip() for f in fields):
                    continue
                row += 1
                if "\x00" in "".join(fields):
                    return InputError("binary data, not a CSV text file", source=source,
                                      row=row)
                if len(fields) != len(names):
                    return InputError(f"expected {len(names)} fields, found {len(fields)}",
                                      source=source, row=row)
                for name in present:
                    text = fields[names.index(name)].strip()
                    try:
                        float(text)
                    except ValueError:
                        return InputError(f"not a number: {text[:40]!r}", source=source,
                                          row=row, field=name)
    except (csv.Error, OSError) as exc:
        return InputError(f"cannot parse CSV: {exc}", source=source, row=row + 1)
    return InputError(f"cannot parse CSV: {message.splitlines()[0] if message else 'unknown'}",
                      source=source)


def _read_npz(path: Path) -> dict[str, np.ndarray]:
    source = str(path)
    with open(path, "rb") as handle:
        magic = handle.read(4)
    if magic not in (b"PK\x03\x04", b"PK\x05\x06"):
        raise InputError("not a .npz file (not a zip archive)", source=source)
    try:
        # our own handle: np.load leaks its file when the archive is damaged
        with open(path, "rb") as handle, np.load(handle, allow_pickle=False) as data:
            raw = {name: data[name] for name in data.files}
    except ValueError as exc:
        reason = ("it holds an object array (Python pickle), which is never loaded"
                  if "pickle" in str(exc) else str(exc).splitlines()[0] if str(exc) else
                  "bad array data")
        raise InputError(f"cannot read .npz file: {reason}", source=source) from None
    except (OSError, EOFError, zipfile.BadZipFile, zipfile.LargeZipFile, KeyError,
            NotImplementedError, RuntimeError, TypeError, IndexError, OverflowError,
            MemoryError) as exc:
        # a truncated or damaged archive: zipfile, zlib and numpy's header parser each
        # raise their own types
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise InputError(f"cannot read .npz file (truncated or damaged?): {reason}",
                         source=source) from None
    except Exception as exc:  # zlib.error and other codec errors of damaged members
        raise InputError(f"cannot read .npz file (truncated or damaged?): "
                         f"{type(exc).__name__}", source=source) from None
    return raw


def _read_parquet(path: Path) -> dict[str, np.ndarray]:
    import pyarrow.parquet as pq

    source = str(path)
    try:
        names = pq.read_schema(path).names
        for k, name in enumerate(names):
            if name in names[:k]:
                raise InputError("column name appears twice", source=source, field=name)
        table = pq.read_table(path)
    except InputError:
        raise
    except Exception as exc:  # pyarrow raises its own exception types
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise InputError(f"cannot read parquet file: {reason}", source=source) from None
    raw = {}
    for name in names:
        try:
            raw[name] = table.column(name).to_numpy(zero_copy_only=False)
        except Exception:  # nested or other types numpy cannot hold
            raw[name] = np.asarray(table.column(name).to_pylist(), dtype=object)
    return raw


def _as_floats(values, source: str, name: str) -> np.ndarray:
    """``values`` as a float array, or an error naming the first value that is no number."""
    dtype = getattr(values, "dtype", None)
    if dtype is not None and dtype.kind == "c":
        raise InputError("complex numbers; a column must hold real numbers", source=source,
                         field=name)
    if dtype is not None and dtype.kind in "fiub":
        return np.asarray(values, dtype=float)
    if dtype is not None and dtype.kind in "mMV":
        raise InputError(f"column holds {dtype} values, not numbers", source=source,
                         field=name)
    try:
        with np.errstate(all="ignore"):
            return np.asarray(values, dtype=float)
    except (TypeError, ValueError, OverflowError):
        return _coerce_with_row(values, source, name)


def _coerce_with_row(values, source: str, name: str) -> np.ndarray:
    values = np.asarray(values, dtype=object).reshape(-1)
    out = np.empty(len(values))
    for row, value in enumerate(values):
        try:
            out[row] = float(value)
        except (TypeError, ValueError, OverflowError):
            if isinstance(value, np.generic):
                value = value.item()
            text = repr(value)
            text = text if len(text) <= 40 else text[:37] + "..."
            raise InputError(f"not a number: {text}", source=source, row=row + 1,
                             field=name) from None
    return out
