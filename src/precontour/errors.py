"""Exception tree of precontour.

Every error a user can cause derives from :class:`PrecontourError`, and each is also the
matching builtin (``ValueError``), so callers may catch either. Messages are one line and name
the file, the row and the field where the problem is.
"""

from __future__ import annotations


class PrecontourError(Exception):
    """Root of all precontour errors."""


class InputError(PrecontourError, ValueError):
    """Bad user input: a file, a column, a value.

    Parameters
    ----------
    message
        What is wrong, in one line.
    source
        The file (or other named source) that holds the bad value.
    row
        1-based data row (or line number) where the problem is, when there is one.
    field
        Column, key or field name.
    """

    def __init__(self, message: str, *, source: str | None = None,
                 row: int | None = None, field: str | None = None):
        self.source = source
        self.row = row
        self.field = field
        where = []
        if source is not None:
            where.append(str(source))
        if row is not None:
            where.append(f"row {row}")
        if field is not None:
            where.append(f"field {field!r}")
        prefix = ": ".join([", ".join(where)]) + ": " if where else ""
        super().__init__(prefix + message)


class MachineFileError(InputError):
    """A machine description (TOML) is malformed or incomplete."""


class ToolPathError(InputError):
    """A tool path file cannot be read or describes an impossible path."""


class UnsupportedControllerError(PrecontourError, ValueError):
    """The requested operation does not support this controller (e.g. a nonlinear one)."""


class MachineLimitError(PrecontourError, ValueError):
    """Commands would ask more of the machine than its axis limits allow."""
