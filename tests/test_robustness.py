"""Hostile but realistic use of every command: each failure is one line with exit 2, before
any computing where it concerns an output, and leaves every input byte-identical and no
temporary file behind."""

from __future__ import annotations

import errno
import gzip
import hashlib
import os
import shutil
import stat
import warnings
from pathlib import Path

import numpy as np
import pytest

from precontour.cli import main
from precontour.machine.machine_file import builtin_machine_text
from precontour.tables import read_columns

FULL = ("t", "X", "Y", "Z", "A", "C", "Px", "Py", "Pz", "Oi", "Oj", "Ok")


@pytest.fixture(scope="module")
def paper_csv(tmp_path_factory):
    path = tmp_path_factory.mktemp("paper") / "paper.csv"
    assert main(["trajectory", "--builtin", "paper", "-o", str(path)]) == 0
    return path


@pytest.fixture(scope="module")
def paper(paper_csv):
    return read_columns(paper_csv, FULL)


@pytest.fixture
def work(tmp_path, paper_csv, monkeypatch):
    """A folder holding paper.csv and a machine file m.toml, as the working directory."""
    shutil.copy(paper_csv, tmp_path / "paper.csv")
    (tmp_path / "m.toml").write_text(builtin_machine_text())
    monkeypatch.chdir(tmp_path)
    return tmp_path


def digest(folder: Path) -> dict[str, str]:
    """Content hash of every regular file under ``folder`` (symlinks not followed)."""
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file() and not p.is_symlink()}


def fails_cleanly(argv, match, folder, capsys):
    """Run the command; it must fail with one line matching ``match`` and change nothing."""
    before = digest(folder)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        code = main([str(a) for a in argv])
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.startswith("precontour: error:")]
    assert code == 2, err
    assert len(lines) == 1 and "Traceback" not in err, err
    assert any(__import__("re").search(match, line) for line in lines), err
    assert digest(folder) == before
    assert not list(folder.rglob("*.tmp"))
    return lines[0]


# --------------------------------------------------------------------------------------------
# 1. inputs are never overwritten


def test_compare_out_never_overwrites_the_input_trajectory(work, capsys):
    (work / "X").mkdir()
    shutil.copy(work / "paper.csv", work / "X" / "contour_errors.csv")
    fails_cleanly(["compare", "X/contour_errors.csv", "--out", "X"],
                  r"X/contour_errors.csv: refusing to overwrite an input", work, capsys)


def test_compare_out_never_overwrites_the_machine_file(work, capsys):
    (work / "Y").mkdir()
    shutil.copy(work / "m.toml", work / "Y" / "compare.md")
    fails_cleanly(["compare", "--machine", "Y/compare.md", "--out", "Y"],
                  r"Y/compare.md: refusing to overwrite an input", work, capsys)


@pytest.mark.parametrize("command", ["predict", "compensate", "simulate"])
def test_output_naming_the_machine_file_is_refused(work, capsys, command):
    shutil.copy(work / "m.toml", work / "machine.csv")
    fails_cleanly([command, "paper.csv", "--machine", "machine.csv", "-o", "machine.csv"],
                  r"machine.csv: refusing to overwrite an input", work, capsys)


def test_trajectory_output_naming_the_program_or_machine_is_refused(work, capsys):
    (work / "path.csv").write_text("Px,Py,Pz,Oi,Oj,Ok\n0,0,0,0,0,1\n10,0,0,0,0,1\n")
    fails_cleanly(["trajectory", "path.csv", "-o", "path.csv"], "refusing to overwrite", work,
                  capsys)
    shutil.copy(work / "m.toml", work / "m.parquet")
    fails_cleanly(["trajectory", "--builtin", "paper", "--machine", "m.parquet", "-o",
                   "m.parquet"], "refusing to overwrite", work, capsys)


@pytest.mark.parametrize("alias", ["hard", "symlink"])
def test_simulate_reference_is_safe_through_links(work, capsys, alias):
    shutil.copy(work / "paper.csv", work / "ref.csv")
    if alias == "hard":
        os.link(work / "ref.csv", work / "out.csv")
    else:
        (work / "out.csv").symlink_to(work / "ref.csv")
    fails_cleanly(["simulate", "paper.csv", "--reference", "ref.csv", "-o", "out.csv"],
                  "refusing to overwrite an input", work, capsys)


# --------------------------------------------------------------------------------------------
# 3. write failures: one line, checked before computing


def test_output_is_an_existing_folder(work, capsys):
    (work / "X").mkdir()
    (work / "d.csv").mkdir()
    fails_cleanly(["predict", "paper.csv", "-o", "X"], "X: is an existing folder", work, capsys)
    fails_cleanly(["compensate", "paper.csv", "-o", "d.csv"], "d.csv: is an existing folder",
                  work, capsys)


@pytest.mark.parametrize("command", [["demo"], ["compare"], ["compare", "paper.csv"]])
def test_report_folder_below_a_file_fails_before_computing(work, capsys, command):
    line = fails_cleanly(command + ["--out", "paper.csv/report"], "is a file, not a folder",
                         work, capsys)
    assert "paper.csv" in line
    assert "%]" not in capsys.readouterr().err   # no progress: nothing was computed


def test_read_only_report_folder_fails_before_computing(work, capsys, monkeypatch):
    (work / "ro").mkdir()
    real_access = os.access
    monkeypatch.setattr(os, "access", lambda p, mode: False if Path(p).resolve() == work / "ro"
                        else real_access(p, mode))
    fails_cleanly(["demo", "--out", "ro"], "cannot write in folder .*ro.*permission denied",
                  work, capsys)


def test_disk_full_while_writing(work, capsys, monkeypatch):
    import pyarrow.csv

    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(pyarrow.csv, "write_csv", full)
    (work / "old.csv").write_bytes(b"previous result\n")
    fails_cleanly(["predict", "paper.csv", "-o", "old.csv"],
                  "old.csv: cannot write: no space left on device", work, capsys)


def test_outputs_follow_the_umask_and_keep_an_existing_mode(work, capsys):
    old = os.umask(0o022)
    try:
        assert main(["predict", "paper.csv", "-o", "new.csv"]) == 0
        assert stat.S_IMODE((work / "new.csv").stat().st_mode) == 0o644
        os.chmod(work / "new.csv", 0o640)
        assert main(["predict", "paper.csv", "-o", "new.csv"]) == 0
        assert stat.S_IMODE((work / "new.csv").stat().st_mode) == 0o640
    finally:
        os.umask(old)


@pytest.fixture
def short_traj(work, paper):
    """The first 400 samples of the paper trajectory (with its reference): cheap to compare."""
    _write_rows(work / "short.csv", {k: v[:400] for k, v in paper.items()})
    return work / "short.csv"


_CHEAP = [["trajectory", "--builtin", "circle", "-o", "out.csv"],
          ["predict", "short.csv", "-o", "out.npz"],
          ["compensate", "short.csv", "-o", "out.parquet"],
          ["simulate", "short.csv", "--reference", "short.csv", "-o", "out.csv"]]
_REPORTS = [["demo", "--paths", "circle", "--out", "report"],
            ["compare", "short.csv", "--out", "report"]]


@pytest.mark.parametrize("argv, failure", [(argv, failure) for argv in _CHEAP
                                           for failure in ("ENOSPC", "SIGTERM")]
                         + [(_REPORTS[0], "SIGTERM"), (_REPORTS[1], "ENOSPC")],
                         ids=lambda value: value[0] if isinstance(value, list) else value)
def test_every_command_failing_while_writing_leaves_inputs_and_no_temporary_file(
        work, short_traj, capsys, monkeypatch, argv, failure):
    import signal

    import precontour.files as files
    (work / "report").mkdir()
    (work / "report" / "index.html").write_text("previous report")   # must survive as is

    def fail(src, dst):
        assert Path(src).exists() and Path(src).name.endswith(".tmp")
        if failure == "SIGTERM":
            os.kill(os.getpid(), signal.SIGTERM)
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(files, "_rename", fail)
    if argv[0] == "compare":  # its figures take seconds to draw and are written like the rest
        import precontour.reports.compare_report as compare_report
        monkeypatch.setattr(compare_report, "_figures", lambda result: [])
    before = digest(work)
    code = main(argv)
    err = capsys.readouterr().err
    if failure == "SIGTERM":
        assert code == 128 + signal.SIGTERM and "precontour: terminated" in err, err
    else:
        assert code == 2 and "cannot write: no space left on device" in err, err
        assert len([line for line in err.splitlines() if "error" in line]) == 1, err
    assert "Traceback" not in err
    after = digest(work)
    assert {k: v for k, v in after.items() if k in before} == before
    assert not list(work.rglob("*.tmp")) and not list(work.rglob(".*.tmp"))
    assert not (work / "out.csv").exists()


# --------------------------------------------------------------------------------------------
# 2., 4., 5., 6., 8., 9., 11., 12. bad content


def _write_rows(path, columns, header=None):
    header = header or list(columns)
    rows = np.column_stack([columns[name] for name in columns])
    with open(path, "w") as handle:
        handle.write(",".join(header) + "\n")
        for row in rows:
            handle.write(",".join(repr(float(v)) for v in row) + "\n")


def test_c_wrapped_by_two_pi_is_unwrapped_with_one_notice(work, paper, capsys):
    wrapped = dict(paper)
    wrapped["C"] = paper["C"].copy()
    wrapped["C"][1500:] -= 2 * np.pi
    _write_rows(work / "wrap.csv", wrapped)
    assert main(["predict", "wrap.csv", "--controller", "pid-high", "-o", "w.csv"]) == 0
    assert main(["predict", "paper.csv", "--controller", "pid-high", "-o", "p.csv"]) == 0
    err = capsys.readouterr().err
    notes = [line for line in err.splitlines() if line.startswith("precontour: note:")]
    assert len(notes) == 1 and "wrap.csv, row 1501, field 'C'" in notes[0], err
    got, want = (read_columns(work / name, ["eps_tip"])["eps_tip"] for name in ("w.csv", "p.csv"))
    np.testing.assert_allclose(got, want, atol=1e-9)   # the same trajectory, the same errors


def test_reference_off_the_kinematics_is_rejected_with_row_and_size(work, paper, capsys):
    shifted = dict(paper)
    shifted["Py"] = paper["Py"].copy()
    shifted["Py"][700:] += 10.0
    _write_rows(work / "off.csv", shifted)
    for command, tolerance in (("predict", "2"), ("compensate", "0.01"), ("simulate", "2")):
        fails_cleanly([command, "off.csv", "-o", "o.csv"],
                      r"off.csv, row 701, field 'Px': reference tool tip is 10 mm from the "
                      rf"direct kinematics .*tolerance {tolerance} mm", work, capsys)
    fails_cleanly(["simulate", "paper.csv", "--reference", "off.csv", "-o", "o.csv"],
                  r"off.csv, row 701, .*tolerance 0.01 mm", work, capsys)


def test_pre_compensated_commands_simulate_against_their_own_reference(work, capsys):
    assert main(["compensate", "paper.csv", "-o", "comp.csv"]) == 0
    assert main(["predict", "comp.csv", "-o", "pred.csv"]) == 0
    assert main(["simulate", "comp.csv", "-o", "sim.csv"]) == 0
    assert "eps_tip" in (work / "sim.csv").read_text().splitlines()[0]


@pytest.mark.parametrize("options, match", [
    (["--ts", "1e-8"], r"at least 2.\d+e\+08 samples .* sampled every 1e-08 s"),
    (["--feed", "1e-9"], r"at most 1e-09 mm/s"),
    (["--dwell", "1e9"], r"a 1e\+09 s dwell"),
    (["--max-samples", "1000"], r"more than the limit of 1000 \(max_samples, option "
                                r"--max-samples"),
])
def test_size_traps_are_refused_before_sampling(work, capsys, options, match):
    fails_cleanly(["trajectory", "--builtin", "paper", *options, "-o", "t.csv"], match, work,
                  capsys)


def test_far_away_cl_point_and_huge_gcode_coordinate(work, capsys):
    (work / "far.csv").write_text("Px,Py,Pz,Oi,Oj,Ok\n0,0,0,0,0,1\n1e7,0,0,0,0,1\n")
    fails_cleanly(["trajectory", "far.csv", "-o", "t.csv"],
                  r"far.csv, row 3, field 'Px': value 1e\+07 is out of range", work, capsys)
    (work / "500m.csv").write_text("Px,Py,Pz,Oi,Oj,Ok\n0,0,0,0,0,1\n5e5,0,0,0,0,1\n")
    fails_cleanly(["trajectory", "500m.csv", "-o", "t.csv", "--max-samples", "1000000"],
                  r"500m.csv, field 'max_samples': the trajectory would have at least 5e\+06 "
                  r"samples \(500000 mm of path", work, capsys)
    (work / "big.nc").write_text("G1 X0 Y0 Z0 A0 C0 F1000\nG1 X1000000000000\n")
    fails_cleanly(["trajectory", "big.nc", "-o", "t.csv"],
                  r"big.nc, line 2, word 'X1000000000000': coordinate .* is out of range", work, capsys)
    (work / "a.nc").write_text("G1 X0 Y0 Z0 A0 C0 F1000\nG1 X10 A90\nG1 X20 A190\n")
    fails_cleanly(["trajectory", "a.nc", "-o", "t.csv"],
                  r"a.nc, line 3, word 'A': A = 190 deg is outside", work, capsys)


def test_bad_content_is_one_line(work, paper, capsys):
    text = (work / "paper.csv").read_bytes()
    (work / "gz.csv").write_bytes(gzip.compress(text))
    (work / "u16.csv").write_bytes(text[:3000].decode().encode("utf-16"))
    (work / "bin.csv").write_bytes(bytes(range(256)) * 20)
    (work / "semi.csv").write_bytes(text.replace(b",", b";"))
    (work / "long.csv").write_bytes(b"t,X" + b",abcd" * 600_000)
    np.savez(work / "t.npz", **paper)
    whole = (work / "t.npz").read_bytes()
    (work / "trunc.npz").write_bytes(whole[: len(whole) // 2])
    (work / "text.npz").write_text("t,X\n1,2\n")
    np.savez(work / "cplx.npz", **{**paper, "X": paper["X"] + 1j})
    np.savez(work / "huge.npz", **{**paper, "Y": paper["Y"] * 1e300})
    np.savez(work / "words.npz", **{**paper, "Z": np.array(["oops"] * paper["Z"].size)})
    lines = text.decode().splitlines()
    (work / "dup.csv").write_text("\n".join([lines[0] + ",X"] + [r + ",1" for r in lines[1:]]))
    (work / "d.csv").mkdir()
    os.mkfifo(work / "fifo.csv")
    cases = [
        ("gz.csv", "gz.csv: gzip-compressed"),
        ("u16.csv", "u16.csv: UTF-16 text"),
        ("bin.csv", "bin.csv: .*(binary|not UTF-8)"),
        ("semi.csv", "semi.csv: fields are separated by ';': use comma separators"),
        ("long.csv", "long.csv: no line break in the first 1048576 bytes"),
        ("trunc.npz", "trunc.npz: cannot read .npz file"),
        ("text.npz", r"text.npz: not a .npz file \(not a zip archive\)"),
        ("cplx.npz", "cplx.npz, field 'X': complex numbers"),
        ("huge.npz", "huge.npz, row 1, field 'Y': value .* is out of range"),
        ("words.npz", "words.npz, row 1, field 'Z': not a number: 'oops'$"),
        ("dup.csv", "dup.csv, field 'X': column name appears twice"),
        ("d.csv", "d.csv: is a folder, not a file"),
        ("fifo.csv", r"fifo.csv: is a FIFO \(named pipe\)"),
    ]
    for name, match in cases:
        line = fails_cleanly(["predict", name, "-o", "o.csv"], match, work, capsys)
        assert "np." not in line


def test_tiny_fit_tolerance_names_the_file(work, capsys):
    fails_cleanly(["predict", "paper.csv", "--tol-linear", "1e-30", "-o", "o.csv"],
                  r"paper.csv, field 'X': the spline fit cannot get within the tolerance 1e-30",
                  work, capsys)


def test_bom_trajectory_is_read(work, capsys):
    (work / "bom.csv").write_bytes(b"\xef\xbb\xbf" + (work / "paper.csv").read_bytes())
    assert main(["predict", "bom.csv", "-o", "a.csv"]) == 0
    assert main(["predict", "paper.csv", "-o", "b.csv"]) == 0
    assert (work / "a.csv").read_bytes() == (work / "b.csv").read_bytes()


def test_one_minimum_number_of_samples(work, paper, capsys):
    for n in (0, 2, 4, 5):
        _write_rows(work / "few.csv", {k: v[:n] for k, v in paper.items()})
        fails_cleanly(["predict", "few.csv", "-o", "o.csv"],
                      rf"few.csv, field 't': too few samples: {n}, need at least 6", work,
                      capsys)


def test_time_step_change_is_reported_at_its_row(work, paper, capsys):
    changed = dict(paper)
    t = paper["t"].copy()
    t[1000:] = t[999] + 0.002 * np.arange(1, t.size - 999)   # row 1001 comes 2 ms late
    changed["t"] = t
    _write_rows(work / "step.csv", changed)
    fails_cleanly(["predict", "step.csv", "-o", "o.csv"],
                  r"step.csv, row 1001, field 't': time is not uniformly sampled \(step 0.002 s",
                  work, capsys)


def test_simulate_at_another_period_names_the_file(work, paper, capsys):
    _write_rows(work / "ms2.csv", {k: v[::2] for k, v in paper.items()})
    fails_cleanly(["simulate", "ms2.csv", "-o", "o.csv"],
                  r"ms2.csv, field 't': sample period 0.002 s differs", work, capsys)


def test_unstable_gains_name_the_machine_file_and_controller(work, capsys):
    text = builtin_machine_text().replace("X = { kp = 30.000, ki = 650.00, kd = 0.4000 }",
                                          "X = { kp = 30.0, ki = 6500000.0, kd = 0.0 }")
    assert "ki = 6500000.0" in text
    (work / "unstable.toml").write_text(text)
    fails_cleanly(["predict", "paper.csv", "--machine", "unstable.toml", "--controller",
                   "pid-high", "-o", "o.csv"],
                  r"unstable.toml: \[controllers.pid-high\] axis X: closed loop is not stable",
                  work, capsys)


def test_cl_orientations_with_four_decimals_are_normalized_with_one_notice(work, capsys):
    (work / "cl.csv").write_text("Px,Py,Pz,Oi,Oj,Ok\n0,0,0,0.5774,0.5774,0.5773\n"
                                 "10,0,0,0.5774,0.5773,0.5774\n20,5,0,0.5773,0.5774,0.5774\n")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert main(["trajectory", "cl.csv", "-o", "t.csv"]) == 0
    err = capsys.readouterr().err
    notes = [line for line in err.splitlines() if line.startswith("precontour: note:")]
    assert len(notes) == 1 and "normalized 3 orientation vectors" in notes[0], err


def test_machine_file_that_is_not_text(work, capsys):
    (work / "bin.toml").write_bytes(b"\xff\xfe\x00garbage")
    fails_cleanly(["predict", "paper.csv", "--machine", "bin.toml", "-o", "o.csv"],
                  r"bin.toml: not UTF-8 text", work, capsys)


# --------------------------------------------------------------------------------------------
# Fuzzing every reader: arbitrary and mutated bytes raise nothing but precontour's own errors
# (and no Python warning).

from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from precontour.errors import PrecontourError  # noqa: E402
from precontour.machine.machine_file import load_machine  # noqa: E402
from precontour.tables import read_trajectory  # noqa: E402
from precontour.toolpath import read_toolpath  # noqa: E402

MACHINE = load_machine("zhang2013")
FUZZ = settings(max_examples=100, deadline=None,
                suppress_health_check=[HealthCheck.function_scoped_fixture,
                                       HealthCheck.too_slow])

_TRAJ_TEXT = ("t,X,Y,Z,A,C,Px,Py,Pz,Oi,Oj,Ok\n" + "".join(
    f"{k * 1e-3!r},{-x!r},0.0,300.0,0.0,0.0,{x!r},0.0,-100.0,0.0,0.0,1.0\n"
    for k, x in enumerate(np.linspace(0.0, 1.0, 8).tolist()))).encode()
_CL_TEXT = b"Px,Py,Pz,Oi,Oj,Ok,F\n0,0,0,0,0,1,600\n5,1,0,0.1,0,0.995,600\n10,3,1,0,0.1,0.995,\n"
_APT_TEXT = (b"PARTNO/TEST\nUNITS/MM\nFEDRAT/MMPM,600\nGOTO/0,0,10,0,0,1\n"
             b"GOTO/10,0,10,0.1,0,0.99498744\nRAPID\nGOTO/20,5,10,0,0,1\nFINI\n")
_GCODE_TEXT = (b"%\n(test)\nG21 G90 G94\nG0 X0 Y0 Z300 A0 C0\nG1 X10 Y5 F600\n"
               b"G1 X20 A10 C45\nG4 P0.5\nG1 Z290 C90\nM30\n%\n")
_TOML_TEXT = builtin_machine_text().encode()


def _npz_bytes() -> bytes:
    import io
    buffer = io.BytesIO()
    lines = _TRAJ_TEXT.decode().splitlines()
    names = lines[0].split(",")
    values = np.array([[float(v) for v in line.split(",")] for line in lines[1:]])
    np.savez(buffer, **{name: values[:, i] for i, name in enumerate(names)})
    return buffer.getvalue()


def _parquet_bytes() -> bytes:
    import io

    import pyarrow as pa
    import pyarrow.parquet as pq
    buffer = io.BytesIO()
    lines = _TRAJ_TEXT.decode().splitlines()
    names = lines[0].split(",")
    values = np.array([[float(v) for v in line.split(",")] for line in lines[1:]])
    pq.write_table(pa.table({name: values[:, i] for i, name in enumerate(names)}), buffer)
    return buffer.getvalue()


@st.composite
def mutated(draw, seed: bytes):
    """``seed`` with a few bytes replaced, inserted or deleted, or cut short."""
    data = bytearray(seed)
    for _ in range(draw(st.integers(1, 6))):
        kind = draw(st.sampled_from(["replace", "insert", "delete", "truncate"]))
        at = draw(st.integers(0, max(len(data) - 1, 0)))
        if kind == "replace" and data:
            data[at] = draw(st.integers(0, 255))
        elif kind == "insert":
            data[at:at] = draw(st.sampled_from(
                [b",", b"\n", b"-", b"e999", b"nan", b"1e308", b"\x00", b";", b"\"", b"=",
                 b"[", b"G2", b"A400", b"9" * 40, b"\xef\xbb\xbf", b"\xff"]))
        elif kind == "delete" and data:
            del data[at:at + draw(st.integers(1, 8))]
        else:
            del data[at:]
    return bytes(data)


def _reads_cleanly(read, path: Path, data: bytes) -> None:
    path.write_bytes(data)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        try:
            read(path)
        except PrecontourError:
            pass


READERS = {
    "trajectory.csv": (lambda p: read_trajectory(p, kinematics=MACHINE.kinematics), _TRAJ_TEXT),
    "trajectory.npz": (lambda p: read_trajectory(p, kinematics=MACHINE.kinematics),
                       _npz_bytes()),
    "trajectory.parquet": (lambda p: read_trajectory(p, kinematics=MACHINE.kinematics),
                           _parquet_bytes()),
    "machine.toml": (load_machine, _TOML_TEXT),
    "program.nc": (lambda p: read_toolpath(p, machine=MACHINE), _GCODE_TEXT),
    "program.apt": (read_toolpath, _APT_TEXT),
    "program.csv": (read_toolpath, _CL_TEXT),
}


@pytest.mark.parametrize("name", sorted(READERS))
def test_fuzz_arbitrary_bytes(tmp_path, name):
    read, _ = READERS[name]

    @FUZZ
    @given(data=st.binary(max_size=3000))
    def check(data):
        _reads_cleanly(read, tmp_path / name, data)

    check()


@pytest.mark.parametrize("name", sorted(READERS))
def test_fuzz_mutated_valid_files(tmp_path, name):
    read, seed = READERS[name]
    read(_write_seed(tmp_path / name, seed))   # the seed itself is valid

    @FUZZ
    @given(data=mutated(seed))
    def check(data):
        _reads_cleanly(read, tmp_path / name, data)

    check()


def _write_seed(path: Path, seed: bytes) -> Path:
    path.write_bytes(seed)
    return path


_NAMES = ("t", "X", "Y", "Z", "A", "C", "Px", "Py", "Pz", "Oi", "Oj", "Ok", "x", "")
_ARRAYS = st.one_of(
    st.lists(st.floats(allow_nan=True, allow_infinity=True), max_size=12).map(np.array),
    st.lists(st.integers(-2**62, 2**62), max_size=12).map(np.array),
    st.lists(st.complex_numbers(allow_nan=True), max_size=12).map(np.array),
    st.lists(st.booleans(), max_size=12).map(np.array),
    st.lists(st.text(max_size=5), max_size=12).map(lambda v: np.array(v, dtype=str)),
    st.lists(st.floats(-1e3, 1e3), min_size=1, max_size=12).map(
        lambda v: np.array(v).reshape(-1, 1)),
    st.integers(0, 12).map(lambda n: (np.arange(n) * 1e-3).astype("datetime64[ms]")),
)


@settings(FUZZ, max_examples=int(os.environ.get("FUZZ_COLUMNS_EXAMPLES", "60")))
@given(columns=st.dictionaries(st.sampled_from(_NAMES), _ARRAYS, max_size=14),
       suffix=st.sampled_from([".npz", ".parquet"]))
def test_fuzz_column_files_with_arbitrary_columns(tmp_path_factory, columns, suffix):
    path = tmp_path_factory.mktemp("columns") / f"c{suffix}"
    if suffix == ".npz":
        np.savez(path, **{name or "_": values for name, values in columns.items()})
    else:
        import pyarrow as pa
        import pyarrow.parquet as pq
        try:
            table = pa.table({name: pa.array(list(values) if values.ndim == 1 else
                                             values.tolist()) for name, values in columns.items()
                              if values.dtype.kind != "c"})
        except (pa.ArrowException, ValueError, TypeError):
            return  # not storable in parquet: nothing to read
        pq.write_table(table, path)
    _reads_cleanly(lambda p: read_trajectory(p, kinematics=MACHINE.kinematics), path,
                   path.read_bytes())
