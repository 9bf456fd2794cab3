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
    # one notice of the normalization; the other says which feed a path without one gets
    normalized = [note for note in notes if "orientation vectors" in note]
    assert len(normalized) == 1 and "normalized 3 orientation vectors" in normalized[0], err
    assert len(notes) == 2 and "no feed is programmed" in notes[1], err


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


# --------------------------------------------------------------------------------------------
# run, export, excite and identify: outputs as one set, inputs safe from reports, sizes and
# limits checked first, signals between stages


import re  # noqa: E402
import signal  # noqa: E402

#: A short G-code program: run takes a second or two on it.
_SMALL_NC = "G21 G90 G94\nG0 X0 Y0 Z300 A0 C0\nG1 X10 Y5 F1200\nG1 X20 A2 C5\nM2\n"


#: run and export name the machine (and run the controller).
_MC = ["--machine", "zhang2013", "--controller", "pid-low"]


@pytest.fixture
def small(work):
    (work / "small.ngc").write_text(_SMALL_NC)
    return work / "small.ngc"


def _first_err_line(capsys):
    err = capsys.readouterr().err
    return err.splitlines()[0] if err else "", err


def test_run_report_never_overwrites_the_machine_file(work, small, capsys):
    (work / "R").mkdir()
    shutil.copy(work / "m.toml", work / "R" / "summary.txt")
    line = fails_cleanly(["run", "small.ngc", "--machine", "R/summary.txt", "--controller", "pid-low",
                          "--report", "R", "-o", "out.ngc"],
                         r"R/summary.txt: refusing to overwrite an input file", work, capsys)
    assert "%]" not in line


def test_identify_report_never_overwrites_the_machine_file(work, capsys):
    t = np.arange(200) * 1e-3
    _write_rows(work / "log.csv", {"t": t, "X": np.sin(t), "X_act": np.sin(t) - 1e-4})
    (work / "R").mkdir()
    shutil.copy(work / "m.toml", work / "R" / "index.html")
    fails_cleanly(["identify", "log.csv", "--machine", "R/index.html", "--report", "R",
                   "-o", "out.toml"],
                  r"R/index.html: refusing to overwrite an input file", work, capsys)


def test_run_report_index_that_is_a_folder_fails_before_computing(work, small, capsys):
    (work / "R" / "index.html").mkdir(parents=True)
    fails_cleanly(["run", "small.ngc", *_MC, "--report", "R", "-o", "out.ngc"],
                  r"R/index.html: is an existing folder", work, capsys)
    assert list((work / "R").iterdir()) == [work / "R" / "index.html"]


def _old_outputs(work):
    for name in ("A.ngc", "s.txt", "c.csv"):
        (work / name).write_text(f"old {name}\n")
    return ["-o", "A.ngc", "--stream", "s.txt", "--commands", "c.csv"]


def test_run_on_a_full_disk_keeps_every_old_output(work, small, capsys, monkeypatch):
    """The halstreamer file cannot be written: the program (written before it) must not
    replace the old one either."""
    import precontour.files as files
    real = files._write_temporary

    def full(path, content):
        if path.name == "s.txt":
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(path, content)

    monkeypatch.setattr(files, "_write_temporary", full)
    fails_cleanly(["run", "small.ngc", *_MC, *_old_outputs(work)],
                  r"s.txt: cannot write: no space left on device", work, capsys)


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT])
def test_run_interrupted_while_writing_keeps_every_old_output(work, small, capsys, monkeypatch,
                                                              signum):
    import precontour.files as files
    real = files._write_temporary

    def interrupted(path, content):
        if path.name == "c.csv":   # the last of the three: two are written already
            os.kill(os.getpid(), signum)
        return real(path, content)

    monkeypatch.setattr(files, "_write_temporary", interrupted)
    argv = ["run", "small.ngc", *_MC, *_old_outputs(work)]
    before = digest(work)
    code = main(argv)
    err = capsys.readouterr().err
    assert code == (128 + signal.SIGTERM if signum == signal.SIGTERM else 130), err
    assert err.splitlines()[-1] == ("precontour: terminated" if signum == signal.SIGTERM
                                    else "precontour: interrupted"), err
    assert "Traceback" not in err
    assert digest(work) == before and not list(work.rglob("*.tmp"))


def test_run_rename_failing_midway_keeps_every_old_output(work, small, capsys, monkeypatch):
    import precontour.files as files
    real = files._rename
    calls = []

    def second_fails(src, dst):
        calls.append(dst)
        if len(calls) == 2:
            raise OSError(errno.EIO, "Input/output error")
        real(src, dst)

    monkeypatch.setattr(files, "_rename", second_fails)
    fails_cleanly(["run", "small.ngc", *_MC, *_old_outputs(work), "--report", "R"],
                  r"cannot write: Input/output error", work, capsys)
    assert len(calls) == 2 and not (work / "R").exists()


def test_run_refuses_a_huge_program_early_as_trajectory_does(work, capsys):
    (work / "huge.ngc").write_text("G21 G90\nG1 X0 Y0 Z0 A0 C0 F1000\nG1 X999999\n")
    messages = []
    for command in (["trajectory", "huge.ngc", "-o", "t.csv"],
                    ["run", "huge.ngc", *_MC, "-o", "o.ngc"]):
        assert main(command) == 2
        err = capsys.readouterr().err.splitlines()
        assert len(err) == 1, err   # the error alone: no progress line before it
        messages.append(err[0])
    assert messages[0] == messages[1]
    assert re.search(r"^precontour: error: huge.ngc: the program's trajectory would have about "
                     r"6e\+07 samples at ts = 0.001 s, more than \d+; raise ts", messages[0]), \
        messages[0]


def test_a_failing_run_says_the_error_first(work, capsys):
    (work / "home.ngc").write_text("G90 G21\nG1 X0 Y0 Z300 A0 C0 F600\nG1 X1..5\n")
    (work / "bad.toml").write_text("[machine]\nname = 1\n")
    for argv, match in (
            (["run", "home.ngc", *_MC, "-o", "o.ngc"], r"^precontour: error: home.ngc, line 3, word 'X1..5'"),
            (["run", "home.ngc", "--machine", "zhang2013", "--controller", "nope", "-o",
              "o.ngc"], "unknown controller"),
            (["run", "home.ngc", "--machine", "bad.toml", "--controller", "pid-low", "-o",
              "o.ngc"], "bad.toml")):
        assert main(argv) == 2
        first, err = _first_err_line(capsys)
        assert re.search(match, first), err


def test_excite_travel_beyond_the_axis_is_refused(work, capsys):
    fails_cleanly(["excite", "--axes", "X", "--travel-linear", "1e9", "-o", "e.csv"],
                  r"field '--travel-linear': X: a half travel of 1e\+09 mm does not fit in the "
                  r"X axis's travel \[-1e\+06, 1e\+06\] mm", work, capsys)
    fails_cleanly(["excite", "--axes", "A", "--travel-rotary", "4", "-o", "e.ngc"],
                  r"A: a half travel of 4 rad does not fit in the A axis's travel "
                  r"\[-3.14159, 3.14159\] rad", work, capsys)
    fails_cleanly(["excite", "--machine", "linuxcnc-xyzac-trt", "--axes", "Y",
                   "--travel-linear", "150", "-o", "e.csv"],
                  r"Y: a half travel of 150 mm does not fit in the Y axis's travel \[-100, "
                  r"100\] mm", work, capsys)
    fails_cleanly(["excite", "--axes", "C", "-o", "e.xyz"], r"e.xyz: unsupported output type",
                  work, capsys)


@pytest.mark.parametrize("axes", ["", "  "])
def test_excite_without_axes_is_refused(work, capsys, axes):
    """``--axes ""`` (from a fuzz suite: it excited all five axes, exit 0)."""
    fails_cleanly(["excite", "--axes", axes, "-o", "e.csv"],
                  r"^precontour: error: field '--axes': no axis given; use letters of XYZAC "
                  r"\(or leave --axes out for all five\)$", work, capsys)
    fails_cleanly(["excite", "--axes", "XQ", "-o", "e.csv"],
                  r"^precontour: error: field '--axes': unknown axis 'Q'; use letters of "
                  r"XYZAC$", work, capsys)


def test_excite_on_a_short_axis_stays_within_its_travel(work, capsys):
    text = builtin_machine_text().replace("[drives.X]\n", "[drives.X]\np_min = -10\np_max = 10\n")
    assert "p_min = -10" in text
    (work / "short.toml").write_text(text)
    assert main(["excite", "--machine", "short.toml", "--axes", "X", "-o", "e.csv"]) == 0
    err = capsys.readouterr().err
    assert "precontour: note: excitation of X: half travel 9 mm instead of 25 mm" in err, err
    q = read_columns(work / "e.csv", ["X"])["X"]
    assert -10 <= q.min() and q.max() <= 10 and q.max() - q.min() > 17
    assert main(["export", "e.csv", "--machine", "short.toml", "-o", "e.ngc"]) == 0


def test_export_refuses_a_tilt_beyond_its_travel_suggesting_degrees(work, capsys):
    t = np.arange(100) * 1e-3
    _write_rows(work / "deg.csv", {"t": t, "X": 0 * t, "Y": 0 * t, "Z": 300 + 0 * t,
                                   "A": 90 + 0 * t, "C": 0 * t})
    for fmt in ("ngc", "txt"):
        fails_cleanly(["export", "deg.csv", "--format", "gcode" if fmt == "ngc" else
                       "halstreamer", "--machine", "zhang2013", "-o", f"o.{fmt}"],
                      r"deg.csv, row 1, field 'A': A = 90 rad is outside the A axis's travel "
                      r"\[-3.14159, 3.14159\] rad .*were degrees given\? \(90 deg would be "
                      r"1.5708 rad\)", work, capsys)


def test_run_learning_that_diverges_is_not_kept(work, small, capsys, monkeypatch):
    """A learning update that blows up (here: multiplied a thousandfold each pass, inf and
    NaN after a few) is not kept; run writes the linear compensation, exit 0."""
    import precontour.compensation.within_limits as within_limits
    real = within_limits.learning_step

    def diverging(*args, **kwargs):
        step = real(*args, **kwargs)
        return lambda q_cmd, q_act, actual: q_cmd + 1e150 * (step(q_cmd, q_act, actual) - q_cmd)

    monkeypatch.setattr(within_limits, "learning_step", diverging)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert main(["run", "small.ngc", *_MC, "--learn", "3", "-o", "o.ngc"]) == 0
    out = capsys.readouterr().out
    assert "kept linear" in out or "kept uncompensated" in out, out
    assert "nan" not in (work / "o.ngc").read_text().lower()


def test_identify_with_zero_currents_names_the_log_and_the_column(work, capsys):
    t = np.arange(400) * 1e-3
    _write_rows(work / "zero.csv", {"t": t, "X": np.sin(5 * t), "X_act": np.sin(5 * t) - 1e-4,
                                    "I_X": 0 * t})
    fails_cleanly(["identify", "zero.csv", "-o", "o.toml"],
                  r"zero.csv, field 'I_X': the motor current of X is zero on every row",
                  work, capsys)


def test_identify_of_a_huge_sparse_halsampler_file_refuses_at_its_first_line(
        work, capsys, tmp_path_factory):
    import tracemalloc
    path = tmp_path_factory.mktemp("sparse") / "sparse.txt"   # not hashed by fails_cleanly
    with open(path, "wb") as handle:
        handle.write(b"0.0\n")
        handle.truncate(1 << 30)   # 1 GiB, a hole after the first line
    tracemalloc.start()
    try:
        fails_cleanly(["identify", path, "--format", "halsampler", "--columns",
                       "t,X,X_act", "-o", "o.toml"],
                      r"sparse.txt: 3 column names for 1 values per line", work, capsys)
        # the rest of the file is never read
        assert tracemalloc.get_traced_memory()[1] < 50e6
        with open(path, "r+b") as handle:
            handle.seek(0)
            handle.write(b"".join(b"%d 0.5 0.5\n" % k for k in range(30)))
        fails_cleanly(["identify", path, "--format", "halsampler", "--columns",
                       "t,X,X_act", "-o", "o.toml"],
                      r"sparse.txt, row 31: binary data", work, capsys)
        assert tracemalloc.get_traced_memory()[1] < 50e6
    finally:
        tracemalloc.stop()


@pytest.mark.parametrize("signum, code, line", [(signal.SIGTERM, 143, "precontour: terminated"),
                                                (signal.SIGINT, 130, "precontour: interrupted")])
def test_a_signal_stops_run_between_stages_not_inside_one(work, small, capsys, monkeypatch,
                                                         signum, code, line):
    """The signal comes while the virtual machine runs (compiled code): that stage ends
    normally, the run stops before the next one, with one line and nothing written."""
    import precontour.workflow.run as workflow   # where run looks the stage up
    real = workflow.check_on_virtual_machine
    finished = []

    def stage(*args, **kwargs):
        os.kill(os.getpid(), signum)
        sum(range(200_000))   # Python code: a handler that raises would stop here
        result = real(*args, **kwargs)
        finished.append(True)
        return result

    monkeypatch.setattr(workflow, "check_on_virtual_machine", stage)
    before = digest(work)
    assert main(["run", "small.ngc", *_MC, "-o", "o.ngc"]) == code
    err = capsys.readouterr().err
    assert finished == [True]
    assert err.splitlines()[-1] == line and "Traceback" not in err, err
    assert digest(work) == before


@pytest.mark.parametrize("delay", [0.3, 1.0])
def test_ctrl_c_during_start_up_is_one_line(work, delay):
    import subprocess
    import sys
    import time
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).parents[1] / "src"))
    proc = subprocess.Popen([sys.executable, "-m", "precontour", "compensate", "paper.csv",
                             "-o", "c.csv"], cwd=work, env=env, stderr=subprocess.PIPE,
                            stdout=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    time.sleep(delay)
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=300)
    assert proc.returncode == 130, (out, err)
    assert "Traceback" not in err, err
    assert [x for x in err.splitlines() if x.startswith("precontour:")
            and not x.startswith("precontour: note:")] == ["precontour: interrupted"], err
    assert not (work / "c.csv").exists()


def test_a_c_wrap_is_unwrapped_alike_by_every_command(work, paper, capsys):
    """A 2 pi step of C between two samples (a post-processor's wrap): predict, compensate,
    simulate and export each unwrap it with one notice naming the row and the step, and
    work on the same continuous C as without the wrap."""
    wrapped = dict(paper)
    wrapped["C"] = paper["C"].copy()
    wrapped["C"][1500:] += 2 * np.pi
    _write_rows(work / "wrap.csv", wrapped)
    machine = load_machine("zhang2013")
    for argv in (["predict", "wrap.csv", "-o", "p.csv"],
                 ["compensate", "wrap.csv", "--learn", "0", "-o", "c.csv"],
                 ["simulate", "wrap.csv", "-o", "s.csv"],
                 ["export", "wrap.csv", "--machine", "zhang2013", "-o", "e.ngc"]):
        assert main(argv) == 0, argv
        notes = [x for x in capsys.readouterr().err.splitlines()
                 if x.startswith("precontour: note:")]
        assert len(notes) == 1 and "wrap.csv, row 1501, field 'C': C steps by 6.28" in \
            notes[0], (argv, notes)
    c = read_columns(work / "c.csv", ["t", "C"])
    assert np.abs(np.diff(c["C"])).max() / 1e-3 <= machine.drive("C").v_max
    assert main(["compensate", "paper.csv", "--learn", "0", "-o", "c0.csv"]) == 0
    np.testing.assert_allclose(c["C"], read_columns(work / "c0.csv", ["C"])["C"], atol=1e-9)


# --------------------------------------------------------------------------------------------
# Fuzzing the servo-log readers, the excitation's options and export: only precontour's own
# errors, and what is made keeps the machine's limits and is accepted by the next command

from precontour.identification.servo_log import read_servo_log  # noqa: E402

_HALSAMPLER_TEXT = "".join(f"{k} {0.01 * k!r} {0.01 * k - 1e-4!r} {0.1 * (k % 7)!r}\n"
                           for k in range(40)).encode()
_HALSCOPE_TEXT = ("Sampling period is 1000000 ns\nX;X_act\n" + "".join(
    f"{0.01 * k!r};{0.01 * k - 1e-4!r}\n" for k in range(40))).encode()
_LOG_CSV = ("t,X,X_act,I_X\n" + "".join(f"{k * 1e-3!r},{0.01 * k!r},{0.01 * k - 1e-4!r},"
                                        f"{0.1 + 0.01 * (k % 5)!r}\n"
                                        for k in range(40))).encode()

LOG_READERS = {
    "halsampler.txt": (lambda p: read_servo_log(p, fmt="halsampler",
                                                columns=["n", "X", "X_act", "I_X"],
                                                default_period=1e-3), _HALSAMPLER_TEXT),
    "halscope.txt": (lambda p: read_servo_log(p, fmt="halscope"), _HALSCOPE_TEXT),
    "log.csv": (read_servo_log, _LOG_CSV),
}


@pytest.mark.parametrize("name", sorted(LOG_READERS))
def test_fuzz_servo_logs_arbitrary_and_mutated(tmp_path, name):
    read, seed = LOG_READERS[name]
    read(_write_seed(tmp_path / name, seed))   # the seed itself is valid

    @FUZZ
    @given(data=st.one_of(st.binary(max_size=2000), mutated(seed)))
    def check(data):
        _reads_cleanly(read, tmp_path / name, data)

    check()


_MACHINES = {name: load_machine(name) for name in ("zhang2013", "linuxcnc-xyzac-trt",
                                                    "linuxcnc-xyzbc-trt")}


@settings(FUZZ, max_examples=int(os.environ.get("FUZZ_EXCITE_EXAMPLES", "25")))
@given(name=st.sampled_from(sorted(_MACHINES)),
       axes=st.lists(st.sampled_from("XYZAC"), min_size=1, max_size=3, unique=True),
       linear=st.one_of(st.none(), st.floats(1e-3, 1e9), st.sampled_from([0.0, -1.0, np.inf,
                                                                         np.nan])),
       rotary=st.one_of(st.none(), st.floats(1e-4, 10.0)),
       safety=st.sampled_from([0.05, 0.5, 1.0]))
def test_fuzz_excitation_options(name, axes, linear, rotary, safety):
    """Any travel and safety: refused with precontour's error, or a motion within
    ``safety`` of every velocity, acceleration and jerk limit and within every axis's travel
    -- what export checks before it writes a program."""
    from precontour.identification import excitation_trajectory
    from precontour.trajectory.limits import AxisLimits, check_limits, check_travel

    machine = _MACHINES[name]
    travel = {a: (rotary if a in "AC" else linear) for a in axes}
    travel = {a: v for a, v in travel.items() if v is not None}
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        try:
            traj = excitation_trajectory(machine, axes=tuple(axes), travel=travel,
                                         safety=safety, max_samples=300_000)
        except PrecontourError:
            return
    limits = AxisLimits.from_machine(machine)
    check_travel(traj.q, limits)
    scaled = AxisLimits(limits.position_min, limits.position_max, safety * limits.velocity,
                        safety * limits.acceleration, safety * limits.jerk)
    assert check_limits(traj.q, traj.ts, scaled).ok


@settings(FUZZ, max_examples=int(os.environ.get("FUZZ_EXPORT_EXAMPLES", "25")))
@given(scale=st.sampled_from([1e-3, 1.0, 90.0, 1e3, 1e7]),
       axis=st.integers(0, 4), n=st.integers(0, 60),
       name=st.sampled_from(sorted(_MACHINES)))
def test_fuzz_export_writes_only_what_the_gcode_reader_reads(tmp_path_factory, scale, axis, n,
                                                             name):
    """A command file with one axis scaled (degrees for radians, metres, nonsense): export
    refuses it with one of precontour's errors, or writes a program that the G-code reader
    reads back on the same machine."""
    from precontour.toolpath import read_program
    from precontour.workflow import export_commands

    folder = tmp_path_factory.mktemp("export")
    t = np.arange(n) * 1e-3
    q = np.zeros((n, 5))
    q[:, 2] = 100.0
    q[:, axis] += scale * np.sin(np.pi * t) ** 2
    path = folder / "cmd.csv"
    _write_rows(path, {"t": t, **{a: q[:, i] for i, a in enumerate("XYZAC")}})
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        try:
            export_commands(path, folder / "o.ngc", machine=name)
        except PrecontourError:
            return
        read_program(folder / "o.ngc", _MACHINES[name])


def test_what_excite_writes_export_accepts(work, capsys):
    """On the LinuxCNC machine the excitation of X went to 173 % of v_max, which export then
    refused; now export takes it, and the G-code excite writes reads back."""
    from precontour.toolpath import read_program
    machine = "linuxcnc-xyzac-trt"
    assert main(["excite", "--machine", machine, "--axes", "XA", "-o", "e.csv"]) == 0
    assert main(["excite", "--machine", machine, "--axes", "XA", "-o", "e.ngc"]) == 0
    assert main(["export", "e.csv", "--machine", machine, "-o", "x.ngc"]) == 0
    assert main(["export", "e.csv", "--machine", machine, "--format", "halstreamer",
                 "-o", "x.txt"]) == 0
    read_program(work / "e.ngc", load_machine(machine))
    capsys.readouterr()
