"""Command-line interface: ``precontour <command> ...``.

Each command reads files, calls the pipeline stages and writes files; no numerics live here.
User errors (bad files, values, names) print one line ``precontour: error: ...`` and exit 2.
Every command checks its output locations (:mod:`precontour.files`) before computing, and
passes its input files (trajectory, reference, machine file, program) as ``inputs`` so that no
output can overwrite one. Notices print as ``precontour: note: ...``.

The parts: :mod:`.parser` (the commands, their options and the checks of their values) and
:mod:`.commands` (what each command calls and prints); :func:`main` runs one and turns what
goes wrong into its one line and exit code."""

from __future__ import annotations

import logging
import sys

from ..errors import NOTICES, PrecontourError
from ..files import Terminated, interruption, sigterm_as_exception
from ..parallel import using_jobs
from .parser import build_parser

#: Exit code of a user error (bad files, values, names) and of a bad command line.
EXIT_USAGE = 2


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "command", None):
        parser.print_help()
        return EXIT_USAGE
    notices = logging.StreamHandler(sys.stderr)
    notices.setFormatter(_NoticeFormat())
    NOTICES.addHandler(notices)
    propagate, NOTICES.propagate = NOTICES.propagate, False
    try:
        with sigterm_as_exception(), using_jobs(getattr(args, "jobs", None)):
            return args.run(args)
    except PrecontourError as exc:
        print(f"precontour: error: {_one_line(exc)}", file=sys.stderr)
        return EXIT_USAGE
    except MemoryError:
        print("precontour: error: out of memory (the input is too large for this machine)",
              file=sys.stderr)
        return EXIT_USAGE
    except OSError as exc:  # e.g. an input that vanished or turned unreadable while read
        where = f"{exc.filename}: " if getattr(exc, "filename", None) else ""
        print(f"precontour: error: {where}{exc.strerror or exc}", file=sys.stderr)
        return EXIT_USAGE
    except (Terminated, KeyboardInterrupt, SystemError) as exc:
        # SystemError: a compiled call that a second signal interrupted
        stop = interruption(exc)
        if stop is None:
            raise
        return _stopped(stop)
    finally:
        NOTICES.removeHandler(notices)
        NOTICES.propagate = propagate


class _NoticeFormat(logging.Formatter):
    """``precontour: note: ...``, or ``precontour: warning: ...`` for a warning
    (:func:`precontour.errors.warning`)."""

    def format(self, record: logging.LogRecord) -> str:
        return f"precontour: {getattr(record, 'label', 'note')}: {record.getMessage()}"


def _stopped(exc: BaseException) -> int:
    """The one line and the exit code of a command stopped by SIGTERM or Ctrl-C."""
    if isinstance(exc, Terminated):
        print("precontour: terminated", file=sys.stderr)
        return int(exc.code)
    print("precontour: interrupted", file=sys.stderr)
    return 130


def _one_line(exc: Exception) -> str:
    return " ".join(str(exc).split("\n"))


__all__ = ["main", "build_parser", "EXIT_USAGE"]
