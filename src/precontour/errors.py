"""Exception tree of precontour.

Every error a user can cause derives from :class:`PrecontourError`, and each is also the
matching builtin (``ValueError``), so callers may catch either. Messages are one line and name
the file, the row and the field where the problem is. Options given in a former spelling are
accepted with a DeprecationWarning naming the release that removes them
(:func:`with_former_spellings`).
"""

from __future__ import annotations

import logging
import numbers
import warnings
from dataclasses import replace

from .defaults import FORMER_SPELLINGS_REMOVED_IN

#: Where one-line notices go (a normalization, an unwrap): the command line prints them as
#: ``precontour: note: ...``; a library user gets them through :mod:`logging`.
NOTICES = logging.getLogger("precontour")


def is_whole_number(value) -> bool:
    """Whether ``value`` is an integer, Python's or numpy's (``numbers.Integral``), and not a
    bool: the check of every count a caller gives (draws, passes, iterations, a seed)."""
    return not isinstance(value, bool) and isinstance(value, numbers.Integral)


def plain(value):
    """``value`` as a plain Python object, so that messages show ``0.5``, not
    ``np.float64(0.5)`` (numpy scalars and 0-d arrays become Python numbers and strings)."""
    item = getattr(value, "item", None)
    if item is not None and getattr(value, "ndim", None) == 0:
        return item()
    return value


def notice(message: str) -> None:
    """Tell the user, in one line, about something that was fixed up on the way in."""
    NOTICES.warning(message)


#: The label of a notice: ``note`` (something fixed up on the way in) or ``warning`` (a result
#: the user must look at before using it); the record's ``label`` attribute.
NOTE, WARNING = "note", "warning"


def warning(message: str) -> None:
    """Warn the user, in one line, about a result to look at before using it (the command
    line prints ``precontour: warning: ...``; a library user gets a logging record whose
    ``label`` is :data:`WARNING`)."""
    NOTICES.warning(message, extra={"label": WARNING})


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

    #: How the location's row and field are called in messages.
    ROW_NAME = "row"
    FIELD_NAME = "field"

    def __init__(self, message: str, *, source: str | None = None,
                 row: int | None = None, field: str | None = None):
        self.message = message
        self.source = source
        self.row = row
        self.field = field
        super().__init__(_located(message, source, row, field, self.ROW_NAME,
                                  self.FIELD_NAME))

    def located(self, source: str) -> "InputError":
        """The same error naming ``source`` if it names no file yet (for callers that know
        which file the values came from)."""
        if self.source is not None or type(self) is not InputError:
            return self
        return InputError(self.message, source=source, row=self.row, field=self.field)


def _located(message: str, source, row, field, row_name: str = "row",
             field_name: str | None = "field") -> str:
    # field_name None: the message itself begins with the field (ForeignSyntaxError)
    where = []
    if source is not None:
        where.append(str(source))
    if row is not None:
        where.append(f"{row_name} {row}")
    if field is not None and field_name is not None:
        where.append(f"{field_name} {field!r}")
    return (", ".join(where) + ": " if where else "") + message


class OutputError(InputError):
    """An output cannot go where it was asked to: an input would be overwritten, the folder is
    missing, read-only or a file, the disk is full. The message names the output. (An output
    location is user input too, so this is an :class:`InputError`.)"""

    def __init__(self, message: str, *, source: str | None = None):
        super().__init__(message, source=source)


class MachineFileError(InputError):
    """A machine description (TOML) is malformed or incomplete."""


class ToolPathError(InputError):
    """A tool path file cannot be read or describes an impossible path."""


class ProgramError(ToolPathError):
    """An NC program (G-code) cannot be read: the message names the file, the line and the
    word (``prog.ngc, line 12, word 'G28': ...``)."""

    ROW_NAME = "line"
    FIELD_NAME = "word"


class ForeignSyntaxError(ProgramError):
    """A line of an NC program is another controller's language (Sinumerik 840D, Heidenhain
    conversational, Haas): the message begins with the construct as written
    (``part.mpf, line 3: 'DEF REAL _X' is Sinumerik 840D syntax ...``), so ``field``, the
    construct, is not repeated before it."""

    FIELD_NAME = None


class UnsupportedControllerError(PrecontourError, ValueError):
    """The requested operation does not support this controller (e.g. a nonlinear one)."""


class MachineLimitError(PrecontourError, ValueError):
    """Commands would ask more of the machine than its axis limits allow."""


class ToleranceError(PrecontourError, ValueError):
    """A contour-error tolerance cannot be met, even at the slowest motion allowed: the
    message names where (source line, time) and by how much."""


def with_former_spellings(value, kind: type, make, name: str, **former):
    """``value`` as options of ``kind`` (itself, or ``make(value)`` of a plain value) with the
    fields given in their former spellings (``former``: field -> value, None where not given),
    each with a DeprecationWarning naming the release that removes it (pointed at the caller
    of the function that takes them). Beside an options object they are refused: the object
    holds them."""
    given = {key: v for key, v in former.items() if v is not None}
    if isinstance(value, kind):
        if given:
            raise InputError(f"give {', '.join(given)} in {name} ({kind.__name__}), not "
                             "beside it", field=next(iter(given)))
        return value
    if given:
        fields = ", ".join(f"{key}=..." for key in given)
        warn_former(", ".join(f"{key}=" for key in given),
                    f"give {name}={kind.__name__}({fields})", stacklevel=3)
    options = make(value)
    return replace(options, **given) if given else options


def renamed_keyword(value, former_value, name: str, former: str):
    """The value of keyword ``name``, or ``former_value`` where the caller gave it in the
    keyword's former spelling ``former`` (with a DeprecationWarning naming the release that
    removes it, pointed at the caller of the function that takes them); both: refused."""
    if former_value is None:
        return value
    if value is not None:
        raise InputError(f"give {name}, not {former} (its former spelling) beside it",
                         field=former)
    warn_former(f"{former}=", f"give {name}=", stacklevel=3)
    return former_value


def warn_former(former: str, instead: str, *, kind: str = "spelling",
                stacklevel: int = 2) -> None:
    """The DeprecationWarning of every former spelling (a keyword, an attribute, an entry):
    ``"{former}: former {kind}, removed in precontour {release}; {instead}"``.
    ``stacklevel`` counts as :func:`warnings.warn`'s would from the caller of this function
    (2: that caller's caller)."""
    warnings.warn(f"{former}: former {kind}, removed in precontour "
                  f"{FORMER_SPELLINGS_REMOVED_IN}; {instead}", DeprecationWarning,
                  stacklevel=stacklevel + 1)
