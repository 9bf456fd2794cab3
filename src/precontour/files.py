"""Files in and out, safely: where inputs may come from, where outputs may go, how they are
written, and what a signal does meanwhile.

Every command follows the same rules, and they live here only:

1. **Check before computing.** :func:`check_outputs` (single files) and
   :func:`check_report_folder` (a folder of named files) run before any work: each output's
   folder exists or can be created, is a folder and is writable; an output is not an existing
   folder; and no output is one of the inputs -- compared by real path (symlinks) and by
   device and inode (hard links). :class:`OutputSet` gathers a command's outputs (files and
   report folders with their file names) and checks each against the inputs and the others.
2. **Write atomically, as one set.** :func:`atomic_write` writes to a temporary file beside the
   target, gives it the mode the target already has (a new file: ``0o666`` less the umask, as
   ``open`` would), and renames it over the target. Inside ``with outputs:`` (an
   :class:`OutputSet`) every :func:`atomic_write` only writes its temporary file; the renames
   happen when the block ends without an error, all of them. On any failure -- a full disk,
   Ctrl-C, SIGTERM -- the temporary files are removed and every target is left as it was.
3. **Signals between stages.** Within :func:`signals_deferred` (the command line runs every
   command in it) SIGTERM and SIGINT only set a flag: raising from a signal handler can land
   inside a compiled (numba) call, which then fails with a ``SystemError`` instead of
   stopping. :func:`check_signals`, called between stages (progress callbacks, before writing),
   raises :class:`Terminated` or ``KeyboardInterrupt`` there. A second signal raises at once.
4. **One-line errors.** A path that cannot be read or written raises
   :class:`~precontour.errors.InputError` (inputs) or :class:`~precontour.errors.OutputError`
   (outputs) naming the file; a folder or a FIFO given as an input file is called that.

A command wires them up as::

    inputs = input_files(args.trajectory, args.machine)     # the files it reads
    outputs = OutputSet(inputs)
    outputs.file(args.output)                                # checked before computing
    outputs.folder(args.report, REPORT_FILES)
    ...
    with outputs:                                            # renamed together at the end
        write_columns(args.output, columns)
        write_report(result, args.report)
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

__all__ = ["OutputSet", "atomic_write", "check_input_file", "check_outputs",
           "check_report_folder", "check_signals", "input_files", "interruption",
           "is_same_file", "make_folder", "new_file_mode", "refuse_non_text",
           "sigterm_as_exception", "signals_deferred", "Terminated"]


class Terminated(SystemExit):
    """Raised in the main thread for a SIGTERM (by :func:`check_signals`, see
    :func:`signals_deferred`), so that ``finally`` blocks and :func:`atomic_write` clean up as
    they do on Ctrl-C."""

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
                        inputs: Iterable[PathLike | None] = (), *, what: str = "report",
                        parent_must_exist: bool = False) -> Path:
    """Check a report folder before computing: it is a folder or can be created (no part of
    its path is a file; with ``parent_must_exist``, only the folder itself may be new), it is
    writable, and none of ``folder/name`` for ``names`` is an input or an existing folder.
    ``what`` names the report in messages. Returns the folder."""
    folder = Path(folder)
    inputs = [Path(p) for p in inputs if p is not None]
    if folder.exists() and not folder.is_dir():
        raise OutputError(f"the {what} output must be a directory, not a file",
                          source=str(folder))
    parent = folder.parent if str(folder.parent) else Path(".")
    if parent_must_exist and not folder.exists() and not parent.is_dir():
        raise OutputError(f"the {what} folder's parent does not exist", source=str(folder))
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
    """The atomic step of :func:`atomic_write` and :class:`OutputSet` (its own name so that
    tests can make just this rename fail, not every ``os.replace`` in the process)."""
    os.replace(source, target)


def _write_temporary(path: Path, content: bytes | Callable[[BinaryIO], object]) -> Path:
    """Write ``content`` to a new temporary file beside ``path`` with :func:`new_file_mode`
    and return its path; on any failure remove it and re-raise."""
    directory = path.parent if str(path.parent) else Path(".")
    mode = new_file_mode(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=directory)
    try:
        with os.fdopen(fd, "wb") as handle:
            if callable(content):
                content(handle)
            else:
                handle.write(content)
            handle.flush()
            os.fchmod(handle.fileno(), mode)
    except BaseException:
        _unlink(tmp)
        raise
    return Path(tmp)


def _unlink(path: PathLike | None) -> None:
    if path is not None:
        try:
            os.unlink(path)
        except OSError:
            pass


def atomic_write(path: PathLike, content: bytes | Callable[[BinaryIO], object], *,
                 inputs: Iterable[PathLike | None] = ()) -> Path:
    """Write ``content`` (bytes, or a function that writes to a binary handle) to ``path``
    through a temporary file beside it and a rename.

    The file gets :func:`new_file_mode`. ``inputs`` are checked once more (see
    :func:`check_outputs`). An OS error (read-only folder, full disk, ...) raises
    :class:`OutputError` in one line; on that or any interruption (Ctrl-C, SIGTERM in the
    main thread) the temporary file is removed and an existing ``path`` is unchanged.
    Inside ``with`` an :class:`OutputSet` the file is only staged: it replaces ``path`` when
    the whole set is complete.
    """
    path = Path(path)
    active = _active_set()
    if active is not None:
        return active._stage(path, content, inputs)
    check_outputs([path], inputs)
    tmp = None
    with signals_deferred():
        try:
            tmp = _write_temporary(path, content)
            check_signals()
            _rename(tmp, path)
            tmp = None
        except OSError as exc:
            check_signals()  # a signal that came meanwhile is what to report
            raise OutputError(f"cannot write: {_reason(exc)}", source=str(path)) from None
        finally:
            _unlink(tmp)
    return path


# --------------------------------------------------------------------------------------------
# Output sets: checked before computing, written together
# --------------------------------------------------------------------------------------------

_LOCAL = threading.local()


def _active_set() -> "OutputSet | None":
    """The outermost :class:`OutputSet` being written in this thread, if any."""
    sets = getattr(_LOCAL, "sets", None)
    return sets[0] if sets else None


class OutputSet:
    """The outputs of one command: each checked when it is declared (before computing), all
    written as one set.

    ``file(path)`` declares an output file, ``folder(folder, names)`` a report folder and the
    files it gets; each is checked at once (:func:`check_outputs`, :func:`check_report_folder`:
    never an input, never an existing folder, a writable place) and against the outputs
    declared before (never the same file twice). Inside ``with outputs:`` every
    :func:`atomic_write` (and so every ``write_text``, ``write_columns``, report figure ...)
    only writes its temporary file beside its target; when the block ends without an error
    and without a pending signal, the temporary files are renamed over their targets, all of
    them. On an error -- a full disk while any file is written, a signal, a failure in between
    -- the temporary files are removed and no target changes: the old files stay together.
    Should a rename itself fail midway, the files renamed before it are put back (from hard
    links kept until the set is complete). A report folder the set had to create is removed
    again if it stays empty.

    A set entered while another is being written joins it: its files are renamed with the
    outer set's. A write to an undeclared file inside the block is staged too, and checked
    against the inputs then.
    """

    def __init__(self, inputs: Iterable[PathLike | None] = ()):
        self.inputs = [Path(p) for p in inputs if p is not None]
        self._declared: list[Path] = []
        self._new_folders: list[Path] = []
        self._staged: dict[str, tuple[Path, Path]] = {}   # key -> (target, temporary file)
        self._signals = None

    # -- declaring ---------------------------------------------------------------------------
    def file(self, path: PathLike, *, suffixes: Iterable[str] | None = None) -> Path:
        """Declare and check an output file; ``suffixes``: the extensions it may have."""
        path = Path(path)
        if suffixes is not None:
            suffixes = tuple(suffixes)
            if path.suffix.lower() not in suffixes:
                raise InputError(f"unsupported output type {path.suffix.lower() or '(none)'!r}; "
                                 f"use one of {', '.join(suffixes)}", source=str(path))
        check_outputs([path], self.inputs)
        self._add(path)
        return path

    def folder(self, folder: PathLike, names: Iterable[str], *, what: str = "report",
               parent_must_exist: bool = False) -> Path:
        """Declare and check a report folder and the names of the files written into it
        (:func:`check_report_folder`)."""
        names = tuple(names)
        folder = check_report_folder(folder, names, self.inputs, what=what,
                                     parent_must_exist=parent_must_exist)
        self._new_folders += [p for p in (folder, *folder.parents) if not p.exists()]
        for name in names:
            self._add(folder / name)
        return folder

    @property
    def files(self) -> list[Path]:
        """The declared output files, in order."""
        return list(self._declared)

    def _add(self, path: Path) -> None:
        for other in self._declared:
            if other == path or is_same_file(other, path):
                raise OutputError("the same file is given for two outputs", source=str(path))
        self._declared.append(path)

    # -- writing -----------------------------------------------------------------------------
    def __enter__(self) -> "OutputSet":
        self._signals = signals_deferred()
        self._signals.__enter__()
        sets = getattr(_LOCAL, "sets", None)
        if sets is None:
            sets = _LOCAL.sets = []
        sets.append(self)
        return self

    def __exit__(self, exc_type, exc, tb) -> bool:
        sets = _LOCAL.sets
        outermost = sets[0] is self
        sets.remove(self)
        signals, self._signals = self._signals, None
        try:
            if outermost:
                if exc_type is None:
                    self._commit()
                else:
                    self._discard()
        except BaseException as error:
            self._discard()
            if signals.__exit__(type(error), error, error.__traceback__):
                return True  # pragma: no cover - signals_deferred never swallows
            raise
        return bool(signals.__exit__(exc_type, exc, tb))

    def _stage(self, path: Path, content, inputs: Iterable[PathLike | None] = ()) -> Path:
        check_signals()
        folder = path.parent if str(path.parent) else Path(".")
        if not folder.exists() and any(folder == f or f in folder.parents
                                       for f in self._new_folders):
            make_folder(folder)
        check_outputs([path], [*self.inputs, *(Path(p) for p in inputs if p is not None)])
        key = os.path.abspath(path)
        try:
            tmp = _write_temporary(path, content)
        except OSError as exc:
            check_signals()
            raise OutputError(f"cannot write: {_reason(exc)}", source=str(path)) from None
        previous = self._staged.pop(key, None)
        if previous is not None:  # written twice: the last one counts
            _unlink(previous[1])
        self._staged[key] = (path, tmp)
        return path

    def _commit(self) -> None:
        check_signals()
        staged = list(self._staged.values())
        # renamed targets: their old files (a hard link), or None for a new one, or False
        # for an old one that could not be kept (no hard links there: it stays replaced)
        done: list[tuple[Path, Path | None | bool]] = []
        target = None
        try:
            for target, tmp in staged:
                existed = target.exists()
                backup = _keep_old(target) if len(staged) > 1 and existed else None
                try:
                    _rename(tmp, target)
                except BaseException:
                    _unlink(backup)
                    raise
                done.append((target, backup if backup is not None or not existed else False))
        except OSError as exc:
            _put_back(done)
            done = []
            check_signals()
            raise OutputError(f"cannot write: {_reason(exc)}", source=str(target)) from None
        except BaseException:
            _put_back(done)
            done = []
            raise
        finally:
            for _, backup in done:
                if backup:
                    _unlink(backup)
            for _, tmp in staged:
                _unlink(tmp)
            self._staged.clear()

    def _discard(self) -> None:
        for _, tmp in self._staged.values():
            _unlink(tmp)
        self._staged.clear()
        # folders this set would have created, deepest first; rmdir removes empty ones only
        for folder in sorted(set(self._new_folders), key=lambda f: len(f.parts), reverse=True):
            try:
                folder.rmdir()
            except OSError:
                pass


def _keep_old(target: Path) -> Path | None:
    """A hard link to the file ``target`` names now (to put it back should a later rename of
    the set fail), or None when there is none or the file system has no hard links."""
    if not target.is_file():
        return None
    backup = target.parent / f".{target.name}.{os.getpid()}.old.tmp"
    try:
        _unlink(backup)
        os.link(target, backup)
    except OSError:
        return None
    return backup


def _put_back(done) -> None:
    """Undo renames already done: the old file back, or a new one removed (an old file that
    could not be kept stays replaced: removing its successor would lose both)."""
    for target, backup in reversed(done):
        try:
            if backup:
                os.replace(backup, target)
            elif backup is None:
                os.unlink(target)
        except OSError:  # pragma: no cover - nothing more can be done
            pass


# --------------------------------------------------------------------------------------------
# Signals
# --------------------------------------------------------------------------------------------

#: Signals received within :func:`signals_deferred` and not yet acted upon (main thread).
_PENDING: list[int] = []


def _exception_for(signum: int) -> BaseException:
    return KeyboardInterrupt() if signum == signal.SIGINT else Terminated()


def check_signals() -> None:
    """Act on a SIGTERM or SIGINT that came within :func:`signals_deferred`: raise
    :class:`Terminated` or ``KeyboardInterrupt`` now. Call it between stages, where raising
    is safe; it does nothing when no signal is pending."""
    if _PENDING:
        signum = _PENDING[0]
        _PENDING.clear()
        raise _exception_for(signum)


def interruption(exc: BaseException) -> BaseException | None:
    """The :class:`Terminated` or ``KeyboardInterrupt`` ``exc`` is or was caused by (a
    ``SystemError`` of a compiled call that a second signal interrupted), else None."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, (Terminated, KeyboardInterrupt)):
            return exc
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return None


@contextmanager
def signals_deferred() -> Iterator[None]:
    """Within the block, SIGTERM and SIGINT set a flag instead of raising at once; the next
    :func:`check_signals` raises :class:`Terminated` (exit code 143) or ``KeyboardInterrupt``,
    and so does the end of the block. Why: a handler that raises runs wherever the
    interpreter is, also inside a compiled (numba) call, which then fails with a
    ``SystemError`` instead of stopping, or inside an import of the numerical libraries at a
    command's start-up: raising there, Ctrl-C 0.2-0.3 s into ``compensate`` was lost (the
    command ran to its end, exit 0) or killed the process (exit -2) depending on where it
    landed; deferred, it stops at the first stage boundary (within about 2.5 s measured, exit
    130, one line). A second signal before the first was acted upon raises at once (the user
    insists). Does nothing outside the main thread, or for a signal someone else handles
    (nested blocks: the outermost one handles them)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    installed = []

    def handler(signum, frame):
        # a second signal stops at once
        if _PENDING:
            _PENDING.clear()
            raise _exception_for(signum)
        _PENDING.append(signum)

    for signum, defaults in ((signal.SIGTERM, (signal.SIG_DFL, None)),
                             (signal.SIGINT, (signal.default_int_handler,))):
        try:
            previous = signal.getsignal(signum)
        except (ValueError, OSError):  # pragma: no cover - embedded interpreters
            continue
        if any(previous is d for d in defaults):
            signal.signal(signum, handler)
            installed.append((signum, previous))
    if installed:
        _PENDING.clear()
    try:
        yield
    except BaseException:
        _restore(installed)
        if installed and _PENDING:
            check_signals()  # the signal, rather than what it may have caused
        raise
    _restore(installed)
    if installed:
        check_signals()


def _restore(installed) -> None:
    for signum, previous in reversed(installed):
        signal.signal(signum, previous if previous is not None else signal.SIG_DFL)


#: The former name of :func:`signals_deferred` (it deferred SIGTERM only, and raised at once).
sigterm_as_exception = signals_deferred


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
