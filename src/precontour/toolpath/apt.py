"""Reader for APT cutter-location data, as CAM post-processors write it.

Statements are ``NAME/arguments`` (spaces around ``/`` and ``,`` and any case allowed) or a
bare ``NAME``. Understood: ``GOTO/x,y,z,i,j,k`` and ``GOTO/x,y,z`` (keeps the previous
orientation, (0, 0, 1) before any), ``FROM/`` (same forms, the start point), ``FEDRAT/``
(``500``, ``MMPM,500``, ``500,MMPM``, ``IPM,20``; a bare number is in ``feed_units``),
``RAPID`` (the next move only is a rapid: flagged, feed NaN), ``UNITS/MM`` and
``UNITS/INCHES`` (coordinates and bare feeds in inches from then on). ``$$`` starts a
comment; a line ending in ``$`` continues on the next. Moves the reader cannot represent
(arcs, incremental and direction moves, canned cycles, per-revolution feeds) are errors;
every other statement (``PARTNO``, ``MULTAX``, ``LOADTL``, ``SPINDL``, ``COOLNT``,
``END``, ``FINI``, ``PAINT``, ...) is skipped and counted in ``ReadReport.skipped``.
"""

from __future__ import annotations

from collections import Counter
from itertools import repeat
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv

from ..errors import ToolPathError
from ._common import INCH, ReadReport, feed_factor, finish, read_text

#: Statements that put points on the path.
MOTION_STATEMENTS = ("GOTO", "FROM")

#: Statements that move the tool in a way a list of points cannot carry: an error.
UNSUPPORTED_STATEMENTS = {
    "CIRCLE": "circular moves (CIRCLE) are not supported; output linear GOTO points",
    "MOVARC": "circular moves (MOVARC) are not supported; output linear GOTO points",
    "GODLTA": "incremental moves (GODLTA) are not supported; output absolute GOTO points",
    "GOFWD": "direction moves (GOFWD) are not supported; output GOTO points",
    "GOLFT": "direction moves (GOLFT) are not supported; output GOTO points",
    "GORGT": "direction moves (GORGT) are not supported; output GOTO points",
    "GOBACK": "direction moves (GOBACK) are not supported; output GOTO points",
    "GOUP": "direction moves (GOUP) are not supported; output GOTO points",
    "GODOWN": "direction moves (GODOWN) are not supported; output GOTO points",
    "INDIRV": "direction moves (INDIRV) are not supported; output GOTO points",
}

#: Statements whose argument is free text: a '$' at its end is text, not a continuation.
_TEXT_STATEMENTS = ("PPRINT", "PARTNO", "INSERT", "REMARK")

_FEED_WORDS = {"MMPM": 1.0 / 60.0, "IPM": INCH / 60.0}
_PER_REV_WORDS = ("MMPR", "IPR")

__all__ = ["read_apt", "read_apt_report", "MOTION_STATEMENTS", "UNSUPPORTED_STATEMENTS"]


def read_apt(path: str | Path, *, feed_units: str = "mm/min"):
    """Read an APT CL file into a :class:`~precontour.toolpath.ToolPath`.

    Parameters
    ----------
    path : str or Path
        APT CL file (see the module docstring for the statements understood).
    feed_units : {"mm/min", "mm/s"}
        Unit of a ``FEDRAT`` that names none (``FEDRAT/ 500``) under ``UNITS/MM``.

    Returns
    -------
    ToolPath
        P (M, 3) mm, unit O (M, 3), feed (M,) mm/s, NaN before the first ``FEDRAT`` and
        after ``RAPID``.

    Raises
    ------
    ToolPathError
        See :func:`read_apt_report`.
    """
    return read_apt_report(path, feed_units=feed_units).toolpath


def read_apt_report(path: str | Path, *, feed_units: str = "mm/min") -> ReadReport:
    """Like :func:`read_apt`, returning the :class:`ReadReport`: the line of each point,
    rapid flags, duplicates dropped and the count of each skipped statement.

    Raises
    ------
    ToolPathError
        One line naming the file, line and field: an unparseable number, a ``GOTO`` with
        other than 3 or 6 values, a bad ``FEDRAT`` or ``UNITS``, an unsupported motion
        statement, a continuation at the end of the file, no ``GOTO`` at all, and the checks
        common to all readers (non-finite values, zero or non-unit orientation, fewer than
        two distinct points, orientation turning more than 90 degrees in one move).
    """
    source = str(path)
    bare_feed = feed_factor(feed_units)
    text = read_text(path)

    args: list[str] = []          # argument text of each motion statement
    arg_lines: list[int] = []
    arg_state: list[int] = []     # index into `states` of each motion
    states = [(np.nan, 1.0)]      # (feed mm/s, mm per length unit) after each change
    rapid_at: list[int] = []      # motions that follow a RAPID
    skipped: Counter[str] = Counter()
    rapid_next = False
    pending = ""
    pending_line = 0

    for number, raw in enumerate(text.splitlines(), start=1):
        # fast path: the plain 'GOTO/...' lines that make up nearly all of a CL file
        if raw[:5] == "GOTO/" and "$" not in raw and not (pending or rapid_next):
            args.append(raw[5:])
            arg_lines.append(number)
            arg_state.append(len(states) - 1)
            continue
        cut = raw.find("$$")
        if cut >= 0:
            raw = raw[:cut]
        stmt = raw.strip()
        if pending:
            stmt = pending + stmt
            line = pending_line
        else:
            line = number
        if stmt.endswith("$") and not stmt[:6].upper().startswith(_TEXT_STATEMENTS):
            if not pending:
                pending_line = number
            pending = stmt[:-1]
            continue
        pending = ""
        if not stmt:
            continue
        slash = stmt.find("/")
        if slash < 0:
            name, rest = stmt.upper(), ""
        else:
            name, rest = stmt[:slash].strip().upper(), stmt[slash + 1:]

        if name in MOTION_STATEMENTS:
            if rapid_next:
                rapid_at.append(len(args))
                rapid_next = False
            args.append(rest)
            arg_lines.append(line)
            arg_state.append(len(states) - 1)
        elif name == "FEDRAT":
            scale = states[-1][1]
            states.append((_fedrat(rest, bare_feed * scale, source, line), scale))
        elif name == "RAPID":
            rapid_next = True
        elif name == "UNITS":
            states.append((states[-1][0], _units(rest, source, line)))
        elif name in UNSUPPORTED_STATEMENTS:
            raise ToolPathError(UNSUPPORTED_STATEMENTS[name], source=source, row=line,
                                field=name)
        elif name == "CYCLE" and rest.strip().upper() != "OFF":
            raise ToolPathError("canned cycles (CYCLE) are not supported; their GOTO points "
                                "are hole positions, not a contour", source=source, row=line,
                                field="CYCLE")
        else:
            skipped[name.split()[0] if name else "?"] += 1
    if pending:
        raise ToolPathError("continuation '$' at the end of the file", source=source,
                            row=pending_line)

    P, O = _motion_values(args, arg_lines, source)
    state = np.asarray(states)[np.asarray(arg_state, dtype=np.int64)].reshape(-1, 2)
    feed, scale = state[:, 0].copy(), state[:, 1]
    P *= scale[:, None]
    rapid = np.zeros(len(args), dtype=bool)
    rapid[rapid_at] = True
    feed[rapid] = np.nan
    return finish(P, O, feed, lines=arg_lines, source=source, format="apt",
                  empty="no motion (no GOTO statement)", rapid=rapid, skipped=skipped)


def _motion_values(args: list[str], lines: list[int], source: str):
    """Parse the GOTO arguments (3 or 6 numbers each) into P and O, orientation carried
    forward where only a point is given."""
    n = len(args)
    if n == 0:
        return np.empty((0, 3)), np.empty((0, 3))
    counts = np.fromiter(map(str.count, args, repeat(",", n)), dtype=np.int64, count=n) + 1
    wrong = (counts != 3) & (counts != 6)
    if wrong.any():
        r = int(np.flatnonzero(wrong)[0])
        raise ToolPathError(f"GOTO needs 3 (x,y,z) or 6 (x,y,z,i,j,k) values, got "
                            f"{counts[r]}: {args[r].strip()!r}", source=source, row=lines[r],
                            field="GOTO")
    # pyarrow parses numbers far faster than Python or numpy; rows of 3 values are padded to
    # 6 fields (null orientation). Anything it cannot read is located (slowly) for the message.
    has_o = counts == 6
    rows = args if has_o.all() else [a if o else a + ",,," for a, o in zip(args, has_o)]
    names = ["x", "y", "z", "i", "j", "k"]
    try:
        table = pacsv.read_csv(
            pa.py_buffer("\n".join(rows).encode()),   # not a Python file (see clcsv.py)
            read_options=pacsv.ReadOptions(column_names=names),
            parse_options=pacsv.ParseOptions(quote_char=False),
            convert_options=pacsv.ConvertOptions(column_types={c: pa.float64() for c in names},
                                                 null_values=[""]))
        values = np.column_stack([table.column(c).to_numpy(zero_copy_only=False)
                                  for c in names])
        if values.shape[0] != n:
            raise ValueError("row count")
        missing = np.isnan(values) & np.column_stack([
            table.column(c).is_null().to_numpy(zero_copy_only=False) for c in names])
        missing[~has_o, 3:] = False
        if missing.any():
            raise ValueError("empty field")
    except (pa.ArrowInvalid, ValueError):
        _raise_bad_number([a.split(",") for a in args], lines, source)
        raise ToolPathError("cannot parse the GOTO values", source=source) from None
    P = values[:, :3]
    O = values[:, 3:].copy()
    # GOTO/x,y,z keeps the last orientation given (forward fill), (0, 0, 1) before any
    last = np.maximum.accumulate(np.where(has_o, np.arange(n), -1))
    O = np.where((last >= 0)[:, None], O[np.maximum(last, 0)], [0.0, 0.0, 1.0])
    return P, O


def _raise_bad_number(fields: list[list[str]], lines: list[int], source: str):
    names = ("x", "y", "z", "i", "j", "k")
    for f, line in zip(fields, lines):
        for name, value in zip(names, f):
            try:
                float(value)
            except ValueError:
                raise ToolPathError(f"cannot parse number {value.strip()!r}", source=source,
                                    row=line, field=name) from None


def _number(token: str) -> float | None:
    try:
        return float(token)
    except ValueError:
        return None


def _fedrat(rest: str, bare: float, source: str, line: int) -> float:
    """Feed in mm/s of a FEDRAT statement; ``bare`` converts a number without unit."""
    tokens = [t.strip() for t in rest.split(",") if t.strip()]
    numbers = [v for v in map(_number, tokens) if v is not None]
    words = [t.upper() for t in tokens if _number(t) is None]
    if len(numbers) != 1 or len(words) > 1:
        raise ToolPathError(f"cannot read FEDRAT/{rest.strip()}: expected one number and at "
                            "most one unit (MMPM or IPM)", source=source, row=line,
                            field="FEDRAT")
    if words and words[0] in _PER_REV_WORDS:
        raise ToolPathError(f"feed per revolution ({words[0]}) is not supported; use MMPM or "
                            "IPM", source=source, row=line, field="FEDRAT")
    if words and words[0] not in _FEED_WORDS:
        raise ToolPathError(f"unknown feed unit {words[0]!r}; expected MMPM or IPM",
                            source=source, row=line, field="FEDRAT")
    value = numbers[0]
    if not (np.isfinite(value) and value > 0):
        raise ToolPathError(f"feed must be positive and finite, got {value:g}",
                            source=source, row=line, field="FEDRAT")
    return value * (_FEED_WORDS[words[0]] if words else bare)


def _units(rest: str, source: str, line: int) -> float:
    unit = rest.strip().upper()
    if unit in ("MM", "MILLIMETERS", "MILLIMETRES"):
        return 1.0
    if unit in ("INCHES", "INCH", "IN"):
        return INCH
    raise ToolPathError(f"unknown UNITS/{rest.strip()}; expected MM or INCHES",
                        source=source, row=line, field="UNITS")
