"""Files in and out, safely: where inputs may come from, where outputs may go, how they are
written.

Every command follows the same three rules, and they live here only:

1. **Check before computing.** :func:`check_outputs` (single files) and
   :func:`check_report_folder` (a folder of named files) run before any work: each output's
   folder exists or can be created, is a folder and is writable; an output is not an existing
   folder; and no output is one of the inputs -- compared by real path (symlinks) and by
   device and inode (hard links).
2. **Write atomically.** :func:`atomic_write` writes to a temporary file beside the target,
   gives it the mode the target already has (a new file: ``0o666`` less the umask, as ``open``
   would), and renames it over the target. On any failure -- a full disk, Ctrl-C, SIGTERM --
   the temporary file is removed and the target is left as it was.
3. **One-line errors.** A path that cannot be read or written raises
   :class:`~precontour.errors.InputError` (inputs) or :class:`~precontour.errors.OutputError`
   (outputs) naming the file; a folder or a FIFO given as an input file is called that.

A command wires them up as::

    inputs = input_files(args.trajectory, args.machine)     # the files it reads
    check_outputs([args.output], inputs)                    # before computing
    ...
    atomic_write(args.output, lambda handle: handle.write(data), inputs=inputs)
"""

from __future__ import annotations

import errno
import os
import signal
import stat
import tempfile
import threading
from contextlib import contextmanager
from pathlib import Path
from typing import BinaryIO, Callable, Iterable, Iterator

from .errors import InputError, OutputError

PathLike = str | os.PathLike

__all__ = ["atomic_write", "check_input_file", "check_outputs", "check_report_folder",
           "input_files", "is_same_file", "make_folder", "new_file_mode", "refuse_non_text",
           "sigterm_as_exception", "Terminated"]


class Terminated(SystemExit):
    """Raised in the main thread on SIGTERM (see :func:`sigterm_as_exception`), so that
    ``finally`` blocks and :func:`atomic_write` clean up as they do on Ctrl-C."""

    def __init__(self):
        super().__init__(128 + signal.SIGTERM)


# --------------------------------------------------------------------------------------------
# Inputs
# --------------------------------------------------------------------------------------------

def check_input_file(path: PathLike, what: str = "file", error=InputError) -> Path:
    """Return ``path`` as a Path if it is an existing, readable regular file; otherwise raise
    ``error`` saying what it is instead (missing, a folder, a FIFO or other special file).

    Checking before opening matters for FIFOs: opening one would wait for a writer forever.
    """
    path = Path(path)
    try:
        mode = path.stat().st_mode
    except FileNotFoundError:
        raise error(f"no such {what}", source=str(path)) from None
    except OSError as exc:
        raise error(f"cannot read {what}: {_reason(exc)}", source=str(path)) from None
    if stat.S_ISDIR(mode):
        raise error(f"is a folder, not a {what}", source=str(path))
    if not stat.S_ISREG(mode):
        kind = "a FIFO (named pipe)" if stat.S_ISFIFO(mode) else "a special file"
        raise error(f"is {kind}, not a regular {what}", source=str(path))
    if not os.access(path, os.R_OK):
        raise error(f"cannot read {what}: permission denied", source=str(path))
    return path


def refuse_non_text(data: bytes, source: str, error=InputError) -> None:
    """Raise ``error`` when ``data`` (a file's bytes, or its first line) is no plain text:
    gzip, zip (e.g. a spreadsheet), UTF-16, or other binary data (NUL bytes)."""
    if data.startswith(b"\x1f\x8b"):
        raise error("gzip-compressed, not a text file: decompress it first", source=source)
    if data.startswith((b"\xff\xfe", b"\xfe\xff")):
        raise error("UTF-16 text: save it as UTF-8 (or ASCII)", source=source)
    if data.startswith(b"PK\x03\x04"):
        raise error("a zip archive (e.g. a spreadsheet), not a text file", source=source)
    if b"\x00" in data:
        raise error("binary data, not a text file", source=source)


def input_files(*paths: PathLike | None) -> list[Path]:
    """The paths among ``paths`` that name existing files (``None`` and built-in names such as
    ``zhang2013`` that are not files are dropped): the list to pass as ``inputs``."""
    return [Path(p) for p in paths if p is not None and Path(p).exists()]


def is_same_file(a: PathLike, b: PathLike) -> bool:
    """True when ``a`` and ``b`` are the same file: same real path (through symlinks), or
    same device and inode (hard links). A path that does not exist is no other file."""
    try:
        if os.path.realpath(a) == os.path.realpath(b):
            return True
        sa, sb = os.stat(a), os.stat(b)
    except (OSError, ValueError):
        return False
    return (sa.st_dev, sa.st_ino) == (sb.st_dev, sb.st_ino)


# --------------------------------------------------------------------------------------------
# Output locations, checked before computing
# --------------------------------------------------------------------------------------------

def check_outputs(outputs: Iterable[PathLike], inputs: Iterable[PathLike | None] = ()
                  ) -> list[Path]:
    """Check output files before computing; return them as Paths.

    Raises :class:`OutputError` when an output is an existing folder, other non-regular file
    or read-only file, its folder is missing, is not a folder or is not writable, or when it
    is one of ``inputs`` (real path, device and inode) or another output.
    """
    inputs = [Path(p) for p in inputs if p is not None]
    checked: list[Path] = []
    for output in outputs:
        path = Path(output)
        if path.exists() or path.is_symlink():
            try:
                mode = path.stat().st_mode
            except OSError:
                mode = stat.S_IFREG
            if stat.S_ISDIR(mode):
                raise OutputError("is an existing folder; give a file name", source=str(path))
            if not stat.S_ISREG(mode):
                raise OutputError("is not a regular file; give a file name", source=str(path))
            if not os.access(path, os.W_OK):
                raise OutputError("is read-only; not overwritten", source=str(path))
        _check_writable_folder(path.parent if str(path.parent) else Path("."), str(path),
                               create=False)
        _refuse_inputs(path, inputs)
        for other in checked:
            if other == path or is_same_file(other, path):
                raise OutputError("the same file is given for two outputs", source=str(path))
        checked.append(path)
    return checked


def check_report_folder(folder: PathLike, names: Iterable[str],
                        inputs: Iterable[PathLike | None] = (), *, what: str = "report"
                        ) -> Path:
    """Check a report folder before computing: it is a folder or can be created (no part of
    its path is a file), it is writable, and none of ``folder/name`` for ``names`` is an input
    or an existing folder. ``what`` names the report in messages. Returns the folder."""
    folder = Path(folder)
    inputs = [Path(p) for p in inputs if p is not None]
    if folder.exists() and not folder.is_dir():
        raise OutputError(f"the {what} output must be a directory, not a file",
                          source=str(folder))
    _check_writable_folder(folder, str(folder), create=True)
    for name in names:
        path = folder / name
        if path.is_dir():
            raise OutputError("is an existing folder, where the report writes a file",
                              source=str(path))
        _refuse_inputs(path, inputs)
    return folder


def _refuse_inputs(path: Path, inputs: list[Path]) -> None:
    for source in inputs:
        if is_same_file(path, source):
            what = "" if path == source else f" ({source})"
            raise OutputError(f"refusing to overwrite an input file{what}; choose another "
                              "output", source=str(path))


def _check_writable_folder(folder: Path, name: str, *, create: bool) -> None:
    """``folder`` exists (or, with ``create``, its nearest existing ancestor does), is a folder
    and is writable and searchable by this process."""
    probe = folder
    while not probe.exists():
        if not create:
            raise OutputError(f"output directory does not exist ({folder})", source=name)
        if probe.is_symlink():  # a dangling symlink
            raise OutputError(f"{str(probe)!r} is a broken symbolic link", source=name)
        parent = probe.parent
        if parent == probe:
            break
        probe = parent
    if not probe.is_dir():
        raise OutputError(f"{str(probe)!r} is a file, not a folder", source=name)
    if not os.access(probe, os.W_OK | os.X_OK):
        raise OutputError(f"cannot write in folder {str(probe)!r}: permission denied",
                          source=name)


def make_folder(folder: PathLike) -> Path:
    """Create a report folder (and its parents), turning OS errors into one line."""
    folder = Path(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except FileExistsError:
        raise OutputError("the report output must be a directory, not a file",
                          source=str(folder)) from None
    except OSError as exc:
        raise OutputError(f"cannot create folder: {_reason(exc)}", source=str(folder)) from None
    return folder


# --------------------------------------------------------------------------------------------
# Writing
# --------------------------------------------------------------------------------------------

def new_file_mode(path: PathLike) -> int:
    """Permission bits for writing ``path``: those of the existing file, or ``0o666`` less
    the process umask for a new one (what ``open(path, "w")`` would create)."""
    try:
        return stat.S_IMODE(os.stat(path).st_mode)
    except OSError:
        return 0o666 & ~_umask()


def _rename(source: PathLike, target: PathLike) -> None:
    """The atomic step of :func:`atomic_write` (its own name so that tests can make just this
    rename fail, not every ``os.replace`` in the process)."""
    os.replace(source, target)


def atomic_write(path: PathLike, content: bytes | Callable[[BinaryIO], object], *,
                 inputs: Iterable[PathLike | None] = ()) -> Path:
    """Write ``content`` (bytes, or a function that writes to a binary handle) to ``path``
    through a temporary file beside it and a rename.

    The file gets :func:`new_file_mode`. ``inputs`` are checked once more (see
    :func:`check_outputs`). An OS error (read-only folder, full disk, ...) raises
    :class:`OutputError` in one line; on that or any interruption (Ctrl-C, SIGTERM in the
    main thread) the temporary file is removed and an existing ``path`` is unchanged.
    """
    path = Path(path)
    check_outputs([path], inputs)
    directory = path.parent if str(path.parent) else Path(".")
    mode = new_file_mode(path)
    tmp = None
    with sigterm_as_exception():
        try:
            fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=directory)
            with os.fdopen(fd, "wb") as handle:
                if callable(content):
                    content(handle)
                else:
                    handle.write(content)
                handle.flush()
                os.fchmod(handle.fileno(), mode)
            _rename(tmp, path)
            tmp = None
        except OSError as exc:
            raise OutputError(f"cannot write: {_reason(exc)}", source=str(path)) from None
        finally:
            if tmp is not None:
                try:
                    os.unlink(tmp)
                except OSError:
                    pass
    return path


@contextmanager
def sigterm_as_exception() -> Iterator[None]:
    """Within the block, SIGTERM raises :class:`Terminated` (a ``SystemExit``) in the main
    thread instead of killing the process at once, so cleanup code runs. Does nothing outside
    the main thread or when someone else already handles SIGTERM."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    try:
        previous = signal.getsignal(signal.SIGTERM)
    except (ValueError, OSError):  # pragma: no cover - embedded interpreters
        yield
        return
    if previous not in (signal.SIG_DFL, None):
        yield
        return

    def handler(signum, frame):
        raise Terminated()

    signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


_UMASK_LOCK = threading.Lock()


def _umask() -> int:
    with _UMASK_LOCK:  # os.umask can only be read by setting it
        mask = os.umask(0o022)
        os.umask(mask)
    return mask


def _reason(exc: OSError) -> str:
    if exc.errno == errno.ENOSPC:
        return "no space left on device"
    if exc.errno in (errno.EACCES, errno.EPERM):
        return "permission denied"
    if exc.errno == errno.EROFS:
        return "read-only file system"
    return exc.strerror or str(exc)
