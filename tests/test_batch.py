"""``precontour batch``: many programs, one output set each, the same bytes as single runs,
on this machine's processes and on a Dask cluster; failures reported per program."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from precontour.batch import batch_jobs, run_batch
from precontour.errors import InputError
from precontour.workflow import RunOutputs, run_program, write_run_outputs

PROGRAM = Path(__file__).parent / "linuxcnc" / "data" / "3plus2.ngc"


def _programs(folder: Path, count: int) -> list[Path]:
    """``count`` variants of the 3+2 program (contour feed 1,600, 1,700 ... mm/min; the second
    index turned by the program's number), and one that cannot be read (line 2)."""
    folder.mkdir()
    text = PROGRAM.read_text()
    paths = []
    for k in range(count):
        path = folder / f"part{k:02d}.ngc"
        path.write_text(text.replace("F2400", f"F{1600 + 100 * k}")
                        .replace("C-60", f"C{-60 + k}"))
        paths.append(path)
    (folder / "broken.ngc").write_text("G21 G90\nG1 X10 Q?? F100\nM2\n")
    return paths


def _single_runs(paths, folder: Path, **options) -> dict[str, bytes]:
    """Each program through ``run_program`` and ``write_run_outputs`` in this process."""
    folder.mkdir()
    out = {}
    for path in paths:
        outputs = RunOutputs(program=folder / path.name)
        result = run_program(path, outputs, machine="zhang2013", controller="pid-high",
                             **options)
        write_run_outputs(result, outputs, [path])
        out[path.name] = outputs.program.read_bytes()
    return out


def test_batch_on_a_local_dask_cluster_writes_what_single_runs_write(tmp_path):
    """Twenty programs over a two-worker ``LocalCluster``: every output, bit for bit, what the
    single runs in this process write; the broken program is reported with its line and
    word, and the others are written all the same."""
    distributed = pytest.importorskip("distributed",
                                      reason="Dask's distributed is not installed "
                                             "(pip install 'precontour[dask]')")
    paths = _programs(tmp_path / "programs", 20)
    single = _single_runs(paths, tmp_path / "single")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster:
        address = cluster.scheduler_address.removeprefix("tcp://")
        result = run_batch([tmp_path / "programs"], tmp_path / "batch",
                           machines=["zhang2013"], controller="pid-high",
                           executor=f"dask://{address}")
    assert len(result.entries) == 21
    [broken] = result.failed
    assert broken.job.program.name == "broken.ngc"
    assert "line 2" in broken.error and "Q??" in broken.error
    assert not (tmp_path / "batch" / "broken.ngc").exists()
    for entry in result.entries:
        if entry.ok:
            assert entry.files == (tmp_path / "batch" / entry.job.program.name,)
            assert entry.files[0].read_bytes() == single[entry.job.program.name], entry.line()
    assert "20 of 21 program(s) compensated" in result.summary()


def test_batch_on_processes_writes_each_set_and_a_folder_per_machine(tmp_path):
    """The default executor (processes here), two machines, stream and command files: one
    folder per machine, the same program bytes as a single run on that machine."""
    paths = _programs(tmp_path / "programs", 2)
    result = run_batch(paths, tmp_path / "out", machines=["zhang2013", "linuxcnc-xyzac-trt"],
                       controller="pid-high", stream=True, commands=True, jobs=2, draws=2)
    assert not result.failed and len(result.entries) == 4
    for entry in result.entries:
        stem = tmp_path / "out" / Path(entry.job.machine).stem / entry.job.program.stem
        assert entry.files == (stem.with_suffix(".ngc"), stem.with_suffix(".txt"),
                               stem.with_suffix(".csv"))
        assert all(f.stat().st_size > 0 for f in entry.files)
    outputs = RunOutputs(program=tmp_path / "single.ngc")
    single = run_program(paths[1], outputs, machine="linuxcnc-xyzac-trt",
                         controller="pid-high", draws=2)
    write_run_outputs(single, outputs, [paths[1]])
    assert (outputs.program.read_bytes()
            == (tmp_path / "out" / "linuxcnc-xyzac-trt" / "part01.ngc").read_bytes())


def test_batch_refuses_outputs_over_inputs_and_twice_the_same_name(tmp_path):
    paths = _programs(tmp_path / "programs", 1)
    with pytest.raises(InputError, match="would overwrite an input"):
        batch_jobs([tmp_path / "programs"], tmp_path / "programs", machines=["zhang2013"])
    (tmp_path / "other").mkdir()
    twin = tmp_path / "other" / paths[0].name
    twin.write_text(paths[0].read_text())
    with pytest.raises(InputError, match="programs of the same name"):
        batch_jobs([paths[0], twin], tmp_path / "out", machines=["zhang2013"])
    with pytest.raises(InputError, match="no such file or folder"):
        batch_jobs([tmp_path / "missing.ngc"], tmp_path / "out", machines=["zhang2013"])
    (tmp_path / "empty").mkdir()
    (tmp_path / "empty" / "notes.txt").write_text("not a program\n")
    with pytest.raises(InputError, match=r"empty: no programs in this folder \(files ending "
                                         r"\.apt, .*\.ngc, \.tap\)"):
        batch_jobs([tmp_path / "empty"], tmp_path / "out", machines=["zhang2013"])
    machine_file = tmp_path / "zhang2013.toml"
    machine_file.write_text("[machine]\n")
    with pytest.raises(InputError, match=r"field '--machine': two machines share a name "
                                         r"\(zhang2013, zhang2013\): their outputs would go to "
                                         r"the same folder"):
        batch_jobs(paths, tmp_path / "out", machines=["zhang2013", machine_file])
    with pytest.raises(InputError, match="give at least one machine"):
        batch_jobs(paths, tmp_path / "out", machines=[])
    with pytest.raises(InputError, match="not an option of run: speed"):
        run_batch(paths, tmp_path / "out", machines=["zhang2013"], controller="pid-high",
                  speed=2)
    assert not (tmp_path / "out").exists()


def test_batch_command_reports_each_program_and_exits_1_where_one_failed(tmp_path):
    _programs(tmp_path / "programs", 1)
    done = subprocess.run([sys.executable, "-m", "precontour", "batch", str(tmp_path / "programs"),
                           "--machine", "zhang2013", "--controller", "pid-high", "--out-dir",
                           str(tmp_path / "out"), "--jobs", "2", "--draws", "1"],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 1, done.stderr
    assert "1 of 2 program(s) compensated" in done.stdout
    assert "part00.ngc on zhang2013: tip max" in done.stdout
    assert "broken.ngc, line 2, word 'Q??'" in done.stderr
    assert (tmp_path / "out" / "part00.ngc").is_file()
    refused = subprocess.run([sys.executable, "-m", "precontour", "batch",
                              str(tmp_path / "programs"), "--machine", "zhang2013",
                              "--controller", "pid-high", "--out-dir", str(tmp_path / "o2"),
                              "--executor", "localhost:8786"],
                             capture_output=True, text=True, timeout=60)
    assert refused.returncode == 2
    assert "dask://HOST:PORT" in refused.stderr and refused.stderr.count("\n") == 1
    assert not (tmp_path / "o2").exists()
