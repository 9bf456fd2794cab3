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
