"""Output safety (precontour.files): locations checked before computing, atomic writes that
keep modes and clean up after every failure, inputs never overwritten."""

from __future__ import annotations

import errno
import os
import signal
import stat

import pytest

from precontour.errors import InputError, OutputError
from precontour.files import (Terminated, atomic_write, check_input_file, check_outputs,
                              check_report_folder, input_files, is_same_file, new_file_mode)

ROOT = hasattr(os, "geteuid") and os.geteuid() == 0


def leftovers(folder):
    return sorted(p.name for p in folder.iterdir() if p.name.endswith(".tmp"))


def test_same_file_through_symlink_and_hard_link(tmp_path):
    a = tmp_path / "a.csv"
    a.write_text("x")
    (tmp_path / "sym.csv").symlink_to(a)
    os.link(a, tmp_path / "hard.csv")
    (tmp_path / "other.csv").write_text("x")
    assert is_same_file(a, tmp_path / "sym.csv")
    assert is_same_file(tmp_path / "hard.csv", a)
    assert not is_same_file(a, tmp_path / "other.csv")
    assert not is_same_file(a, tmp_path / "missing.csv")


@pytest.mark.parametrize("name", ["a.csv", "sym.csv", "hard.csv"])
def test_check_outputs_refuses_every_alias_of_an_input(tmp_path, name):
    a = tmp_path / "a.csv"
    a.write_text("x")
    (tmp_path / "sym.csv").symlink_to(a)
    os.link(a, tmp_path / "hard.csv")
    with pytest.raises(OutputError, match="refusing to overwrite an input file"):
        check_outputs([tmp_path / name], [a])


def test_check_outputs_locations(tmp_path):
    (tmp_path / "dir.csv").mkdir()
    (tmp_path / "file").write_text("x")
    with pytest.raises(OutputError, match="dir.csv: is an existing folder"):
        check_outputs([tmp_path / "dir.csv"])
    with pytest.raises(OutputError, match="output directory does not exist"):
        check_outputs([tmp_path / "nodir" / "x.csv"])
    with pytest.raises(OutputError, match="'.*file' is a file, not a folder"):
        check_outputs([tmp_path / "file" / "x.csv"])
    with pytest.raises(OutputError, match="the same file is given for two outputs"):
        check_outputs([tmp_path / "o.csv", tmp_path / "o.csv"])
    assert check_outputs([tmp_path / "new.csv"]) == [tmp_path / "new.csv"]
    # an OutputError is an InputError: one line and exit 2 from the command line
    assert issubclass(OutputError, InputError)


def test_check_outputs_read_only_folder(tmp_path, monkeypatch):
    real_access = os.access
    monkeypatch.setattr(os, "access", lambda p, mode: False if str(p) == str(tmp_path)
                        else real_access(p, mode))
    with pytest.raises(OutputError, match="cannot write in folder .*permission denied"):
        check_outputs([tmp_path / "x.csv"])


def test_report_folder_checks(tmp_path):
    traj = tmp_path / "X" / "contour_errors.csv"
    traj.parent.mkdir()
    traj.write_text("input")
    with pytest.raises(OutputError, match="refusing to overwrite an input file"):
        check_report_folder(tmp_path / "X", ["contour_errors.csv", "index.html"], [traj])
    # the same folder reached through a symlink
    (tmp_path / "link").symlink_to(tmp_path / "X")
    with pytest.raises(OutputError, match="refusing to overwrite an input file"):
        check_report_folder(tmp_path / "link", ["contour_errors.csv"], [traj])
    (tmp_path / "f").write_text("x")
    with pytest.raises(OutputError, match="the report output must be a directory, not a file"):
        check_report_folder(tmp_path / "f", ["index.html"])
    with pytest.raises(OutputError, match="'.*f' is a file, not a folder"):
        check_report_folder(tmp_path / "f" / "sub" / "deeper", ["index.html"])
    (tmp_path / "R").mkdir()
    (tmp_path / "R" / "index.html").mkdir()
    with pytest.raises(OutputError, match="index.html: is an existing folder"):
        check_report_folder(tmp_path / "R", ["index.html"])
    # a folder that does not exist yet is fine (created when writing), and nothing is created
    assert check_report_folder(tmp_path / "new" / "report", ["index.html"]) == \
        tmp_path / "new" / "report"
    assert not (tmp_path / "new").exists()
    assert traj.read_text() == "input"


def test_check_input_file_names_what_it_is(tmp_path):
    (tmp_path / "d.csv").mkdir()
    os.mkfifo(tmp_path / "p.csv")
    with pytest.raises(InputError, match="d.csv: is a folder, not a file"):
        check_input_file(tmp_path / "d.csv")
    with pytest.raises(InputError, match=r"p.csv: is a FIFO \(named pipe\), not a regular file"):
        check_input_file(tmp_path / "p.csv")
    with pytest.raises(InputError, match="m.csv: no such file"):
        check_input_file(tmp_path / "m.csv")
    assert input_files(None, "zhang2013", tmp_path / "d.csv") == [tmp_path / "d.csv"]


def test_atomic_write_modes_follow_umask_and_existing_file(tmp_path):
    old = os.umask(0o027)
    try:
        new = atomic_write(tmp_path / "new.txt", b"abc")
        assert stat.S_IMODE(new.stat().st_mode) == 0o640
        existing = tmp_path / "old.txt"
        existing.write_text("x")
        os.chmod(existing, 0o604)
        atomic_write(existing, b"def")
        assert stat.S_IMODE(existing.stat().st_mode) == 0o604
        assert existing.read_bytes() == b"def"
    finally:
        os.umask(old)
    assert new_file_mode(tmp_path / "missing") == 0o666 & ~old


def test_atomic_write_disk_full_is_one_line_and_leaves_nothing(tmp_path):
    target = tmp_path / "out.csv"
    target.write_bytes(b"before")

    def full(handle):
        handle.write(b"partial")
        raise OSError(errno.ENOSPC, "No space left on device")

    with pytest.raises(OutputError, match=r"out.csv: cannot write: no space left on device"):
        atomic_write(target, full)
    assert target.read_bytes() == b"before" and leftovers(tmp_path) == []


@pytest.mark.parametrize("interrupt", [KeyboardInterrupt, "SIGTERM"])
def test_atomic_write_interrupted_removes_the_temporary_file(tmp_path, interrupt):
    target = tmp_path / "out.csv"
    target.write_bytes(b"before")

    def write(handle):
        handle.write(b"partial")
        if interrupt == "SIGTERM":
            os.kill(os.getpid(), signal.SIGTERM)
        else:
            raise interrupt()
        handle.write(b"never")

    expected = Terminated if interrupt == "SIGTERM" else KeyboardInterrupt
    with pytest.raises(expected):
        atomic_write(target, write)
    assert target.read_bytes() == b"before" and leftovers(tmp_path) == []
    # the handler is only installed while writing
    assert signal.getsignal(signal.SIGTERM) in (signal.SIG_DFL, None)


def test_atomic_write_refuses_an_input(tmp_path):
    a = tmp_path / "a.csv"
    a.write_bytes(b"input")
    os.link(a, tmp_path / "b.csv")
    with pytest.raises(OutputError, match="refusing to overwrite an input"):
        atomic_write(tmp_path / "b.csv", b"x", inputs=[a])
    assert a.read_bytes() == b"input" and leftovers(tmp_path) == []


@pytest.mark.skipif(ROOT, reason="root writes into read-only folders")
def test_atomic_write_read_only_folder(tmp_path):
    folder = tmp_path / "ro"
    folder.mkdir()
    folder.chmod(0o555)
    try:
        with pytest.raises(OutputError, match="permission denied"):
            atomic_write(folder / "x.csv", b"x")
    finally:
        folder.chmod(0o755)


def test_read_only_output_file_is_not_overwritten(tmp_path, monkeypatch):
    target = tmp_path / "locked.csv"
    target.write_text("keep")
    real_access = os.access
    monkeypatch.setattr(os, "access", lambda p, mode: False if str(p) == str(target)
                        else real_access(p, mode))
    with pytest.raises(OutputError, match="locked.csv: is read-only; not overwritten"):
        atomic_write(target, b"new")
    assert target.read_text() == "keep" and leftovers(tmp_path) == []


# --------------------------------------------------------------------------------------------
# Output sets: every output checked when declared, all written together or none


from precontour.files import OutputSet, check_signals, interruption, signals_deferred  # noqa: E402


def _old_set(tmp_path):
    """Three outputs with old contents, and a report folder with an old index.html."""
    files = {name: tmp_path / name for name in ("a.ngc", "s.txt", "c.csv")}
    for name, path in files.items():
        path.write_text(f"old {name}")
    (tmp_path / "R").mkdir()
    (tmp_path / "R" / "index.html").write_text("old report")
    return files


def _declared(tmp_path, files, inputs=()):
    out = OutputSet(inputs)
    for path in files.values():
        out.file(path)
    out.folder(tmp_path / "R", ["index.html", "summary.txt"])
    return out


def _contents(tmp_path):
    return {p.name: p.read_text() for p in sorted(tmp_path.rglob("*")) if p.is_file()}


def test_output_set_declarations_are_checked_at_once(tmp_path):
    machine = tmp_path / "R" / "summary.txt"
    machine.parent.mkdir()
    machine.write_text("machine file")
    out = OutputSet([machine, tmp_path / "prog.ngc"])
    out.file(tmp_path / "a.ngc")
    # a report file that is an input: refused when declared, naming the file
    with pytest.raises(OutputError, match=r"R/summary.txt: refusing to overwrite an input"):
        out.folder(tmp_path / "R", ["index.html", "summary.txt"])
    with pytest.raises(OutputError, match=r"a.ngc: the same file is given for two outputs"):
        out.file(tmp_path / "a.ngc")
    (tmp_path / "S" / "index.html").mkdir(parents=True)
    with pytest.raises(OutputError, match=r"S/index.html: is an existing folder"):
        OutputSet().folder(tmp_path / "S", ["index.html"])
    with pytest.raises(InputError, match=r"b.txt: unsupported output type '.txt'; use one of "
                                         r"\.ngc"):
        OutputSet().file(tmp_path / "b.txt", suffixes=(".ngc",))
    # a report file that is also an output file
    other = OutputSet()
    other.file(tmp_path / "index.html")
    with pytest.raises(OutputError, match="the same file is given for two outputs"):
        other.folder(tmp_path, ["index.html"])
    assert machine.read_text() == "machine file"


def test_output_set_writes_all_files_when_all_are_complete(tmp_path):
    files = _old_set(tmp_path)
    out = _declared(tmp_path, files)
    with out:
        for name, path in files.items():
            atomic_write(path, f"new {name}".encode())
            # nothing replaced while the set is being written: only temporary files beside
            assert path.read_text() == f"old {name}"
        atomic_write(tmp_path / "R" / "index.html", b"new report")
        assert len(leftovers(tmp_path)) == 3 and len(leftovers(tmp_path / "R")) == 1
    assert _contents(tmp_path) == {"a.ngc": "new a.ngc", "s.txt": "new s.txt",
                                   "c.csv": "new c.csv", "index.html": "new report"}
    assert leftovers(tmp_path) == [] and leftovers(tmp_path / "R") == []


def test_output_set_on_a_full_disk_replaces_nothing(tmp_path):
    files = _old_set(tmp_path)
    before = _contents(tmp_path)

    def full(handle):
        handle.write(b"partial")
        raise OSError(errno.ENOSPC, "No space left on device")

    with pytest.raises(OutputError, match=r"s.txt: cannot write: no space left on device"):
        with _declared(tmp_path, files):
            atomic_write(files["a.ngc"], b"new")
            atomic_write(files["s.txt"], full)
            atomic_write(files["c.csv"], b"never")
    assert _contents(tmp_path) == before
    assert leftovers(tmp_path) == [] and leftovers(tmp_path / "R") == []


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT])
def test_output_set_interrupted_while_writing_replaces_nothing(tmp_path, signum):
    files = _old_set(tmp_path)
    before = _contents(tmp_path)

    def interrupted(handle):
        handle.write(b"partial")
        os.kill(os.getpid(), signum)   # deferred: the write goes on, the set is not renamed
        handle.write(b" rest")

    expected = Terminated if signum == signal.SIGTERM else KeyboardInterrupt
    with pytest.raises(expected):
        with _declared(tmp_path, files):
            atomic_write(files["a.ngc"], b"new")
            atomic_write(files["s.txt"], interrupted)
            atomic_write(files["c.csv"], b"new")
    assert _contents(tmp_path) == before
    assert leftovers(tmp_path) == [] and leftovers(tmp_path / "R") == []
    assert signal.getsignal(signal.SIGTERM) in (signal.SIG_DFL, None)
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_output_set_rename_failing_midway_puts_the_renamed_files_back(tmp_path, monkeypatch):
    import precontour.files as files_module
    files = _old_set(tmp_path)
    before = _contents(tmp_path)
    real = files_module._rename
    calls = []

    def second_fails(src, dst):
        calls.append(dst)
        if len(calls) == 2:
            raise OSError(errno.EIO, "Input/output error")
        real(src, dst)

    monkeypatch.setattr(files_module, "_rename", second_fails)
    with pytest.raises(OutputError, match=r"s.txt: cannot write: Input/output error"):
        with _declared(tmp_path, files):
            for name, path in files.items():
                atomic_write(path, f"new {name}".encode())
    assert len(calls) == 2   # a.ngc had been renamed: it was put back
    assert _contents(tmp_path) == before
    assert not [p for p in tmp_path.rglob("*") if p.name.endswith(".tmp")]


def test_output_set_joins_an_outer_set_and_removes_a_folder_it_created(tmp_path):
    outer = OutputSet()
    outer.file(tmp_path / "a.csv")
    outer.folder(tmp_path / "new" / "report", ["index.html"])
    with pytest.raises(RuntimeError):
        with outer:
            inner = OutputSet()
            inner.file(tmp_path / "a.csv")
            with inner:   # joins: nothing renamed when the inner block ends
                atomic_write(tmp_path / "a.csv", b"new")
            assert not (tmp_path / "a.csv").exists()
            atomic_write(tmp_path / "new" / "report" / "index.html", b"report")
            raise RuntimeError("a failure after the writes")
    assert sorted(p.name for p in tmp_path.iterdir()) == []   # the created folders too
    with outer:
        atomic_write(tmp_path / "a.csv", b"new")
    assert (tmp_path / "a.csv").read_bytes() == b"new"


def test_output_set_refuses_an_undeclared_write_over_an_input(tmp_path):
    source = tmp_path / "m.toml"
    source.write_text("input")
    with pytest.raises(OutputError, match="refusing to overwrite an input"):
        with OutputSet([source]):
            atomic_write(source, b"report")
    assert source.read_text() == "input" and leftovers(tmp_path) == []


# --------------------------------------------------------------------------------------------
# Signals: a flag, acted upon between stages


@pytest.mark.parametrize("signum, expected", [(signal.SIGTERM, Terminated),
                                              (signal.SIGINT, KeyboardInterrupt)])
def test_a_signal_sets_a_flag_and_the_next_check_raises(signum, expected):
    done = []
    with pytest.raises(expected):
        with signals_deferred():
            os.kill(os.getpid(), signum)
            total = sum(range(100_000))   # Python code runs on: the handler did not raise
            done.append(total)
            check_signals()
            done.append("never")
    assert done == [sum(range(100_000))]
    check_signals()   # nothing left pending


def test_a_second_signal_raises_at_once():
    with pytest.raises(KeyboardInterrupt):
        with signals_deferred():
            os.kill(os.getpid(), signal.SIGINT)
            os.kill(os.getpid(), signal.SIGINT)
            sum(range(100_000))
            pytest.fail("the second Ctrl-C did not stop")


def test_a_signal_during_a_compiled_call_lets_it_finish():
    """A SIGTERM while a compiled (numba) kernel runs: the kernel returns its result, and
    the run stops at the next check (raising in the handler made numba's dispatcher fail
    with a SystemError instead)."""
    import threading

    import numpy as np

    from precontour.toolpath.writers import decimate

    t = np.arange(2_000_000) * 1e-3
    q = np.column_stack([np.sin(t * k) for k in range(1, 6)])
    decimate(t[:10], q[:10], 1e-3)   # compiled before the timing starts
    timer = threading.Timer(0.02, os.kill, (os.getpid(), signal.SIGTERM))
    result = []
    with pytest.raises(Terminated):
        with signals_deferred():
            timer.start()
            for _ in range(20):
                result.append(decimate(t, q, 1e-6).size)
            timer.join()
            check_signals()
    assert len(result) == 20 and len(set(result)) == 1


def test_interruption_finds_the_signal_behind_a_system_error():
    try:
        try:
            raise Terminated()
        except Terminated:
            raise SystemError("CPUDispatcher(<function f>) returned a result with an "
                              "exception set")
    except SystemError as exc:
        assert isinstance(interruption(exc), Terminated)
    assert interruption(ValueError("x")) is None


def test_a_signal_during_an_import_waits_for_the_import(tmp_path, monkeypatch):
    """A signal during an import (the numerical libraries loading at a command's start-up) is
    deferred like any other: raising inside an import lost the signal or killed the process,
    depending on where it landed (see :func:`signals_deferred`). The import completes, and
    the end of the block raises."""
    import sys
    (tmp_path / "slow_module_for_signals.py").write_text(
        "import os, signal\nos.kill(os.getpid(), signal.SIGINT)\nsum(range(100000))\n"
        "REACHED = True\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(KeyboardInterrupt):
        with signals_deferred():
            import slow_module_for_signals  # noqa: F401
    assert sys.modules.pop("slow_module_for_signals").REACHED


def test_output_set_without_hard_links_never_loses_a_file(tmp_path, monkeypatch):
    """Where no hard link can keep an old file, a rename failing later cannot put it back:
    the file renamed before stays the new one (removing it would lose both)."""
    import precontour.files as files_module
    files = _old_set(tmp_path)
    real = files_module._rename
    calls = []

    def second_fails(src, dst):
        calls.append(dst)
        if len(calls) == 2:
            raise OSError(errno.EIO, "Input/output error")
        real(src, dst)

    def no_links(src, dst):
        raise OSError(errno.EPERM, "Operation not permitted")

    monkeypatch.setattr(files_module, "_rename", second_fails)
    monkeypatch.setattr(os, "link", no_links)
    with pytest.raises(OutputError, match=r"s.txt: cannot write"):
        with _declared(tmp_path, files):
            for name, path in files.items():
                atomic_write(path, f"new {name}".encode())
    assert files["a.ngc"].read_text() == "new a.ngc"
    assert files["s.txt"].read_text() == "old s.txt" and files["c.csv"].read_text() == "old c.csv"
    assert not [p for p in tmp_path.rglob("*") if p.name.endswith(".tmp")]
