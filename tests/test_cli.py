"""The command line: happy paths end to end, and every user error as one line with exit 2."""

import re

import numpy as np
import pytest

from precontour.cli import main
from precontour.tables import read_columns, write_columns

HEADER = ("t", "X", "Y", "Z", "A", "C")


def _traj_columns(n=300, ts=1e-3):
    t = np.arange(n) * ts
    s = t / t[-1]
    ramp = 35 * s**4 - 84 * s**5 + 70 * s**6 - 20 * s**7
    return {"t": t, "X": 10 * ramp, "Y": -5 * ramp, "Z": 300 + 2 * ramp, "A": 0.3 + 0.2 * ramp,
            "C": 0.5 * ramp}


@pytest.fixture
def traj_csv(tmp_path):
    path = tmp_path / "traj.csv"
    write_columns(path, _traj_columns())
    return path


@pytest.fixture(scope="module")
def paper_csv(tmp_path_factory):
    path = tmp_path_factory.mktemp("paper") / "paper.csv"
    assert main(["trajectory", "--builtin", "paper", "-o", str(path)]) == 0
    return path


def test_predict_writes_errors_at_full_precision(traj_csv, tmp_path, capsys):
    out = tmp_path / "pred.csv"
    assert main(["predict", str(traj_csv), "--machine", "zhang2013", "--controller", "pid-low",
                 "-o", str(out)]) == 0
    text = out.read_text().splitlines()
    assert text[0] == "t,eX,eY,eZ,eA,eC"
    cols = read_columns(out, ["t", "eX", "eY", "eZ", "eA", "eC"])
    assert cols["t"].size == 300 and np.abs(cols["eX"]).max() > 0
    printed = capsys.readouterr().out
    assert "knots" in printed and "max|e|" in printed and "wrote" in printed


@pytest.mark.parametrize("suffix", [".npz", ".parquet"])
def test_predict_reads_npz_and_parquet(tmp_path, suffix):
    src = tmp_path / f"traj{suffix}"
    write_columns(src, _traj_columns())
    out = tmp_path / f"pred{suffix}"
    assert main(["predict", str(src), "-o", str(out)]) == 0
    assert read_columns(out, ["eY"])["eY"].size == 300


def test_pipeline_end_to_end(paper_csv, tmp_path, capsys):
    header = paper_csv.read_text().splitlines()[0]
    assert header == "t,X,Y,Z,A,C,Px,Py,Pz,Oi,Oj,Ok"
    pred = tmp_path / "pred.csv"
    assert main(["predict", str(paper_csv), "--controller", "pid-high", "-o", str(pred)]) == 0
    assert pred.read_text().splitlines()[0] == "t,eX,eY,eZ,eA,eC,eps_tip,eps_ori"
    comp = tmp_path / "comp.csv"
    assert main(["compensate", str(paper_csv), "--controller", "pid-high", "--iterations", "2",
                 "--learn", "1", "-o", str(comp)]) == 0
    assert comp.read_text().splitlines()[0] == header
    printed = capsys.readouterr().out
    assert "predicted before" in printed and "predicted after" in printed
    # 1 reference + 12 linear and its 11 settled tails + 13 plain pass (1 inside the contour
    # step, 1 + 11 tails) + 14 line-searched pass (1 inside, 2 steps, 11 tails of the better),
    # each on 5 draws of the machine, and the judgements of any local fallback
    learned = re.search(r"learned against the virtual machine with friction \(1 pass\(es\), "
                        r"5 draw\(s\), (\d+) runs\)", printed)
    assert learned and int(learned.group(1)) >= 40 * 5
    assert "within the machine's limits" in printed
    sim = tmp_path / "sim.csv"
    assert main(["simulate", str(comp), "--controller", "pid-high", "--reference",
                 str(paper_csv), "--friction", "on", "--ff-friction", "on", "-o", str(sim)]) == 0
    cols = read_columns(sim, ["t", "X", "eps_tip", "eps_ori"])
    sim0 = tmp_path / "sim0.csv"
    assert main(["simulate", str(paper_csv), "--controller", "pid-high", "-o", str(sim0)]) == 0
    cols0 = read_columns(sim0, ["eps_tip"])
    assert cols["eps_tip"].mean() < 0.1 * cols0["eps_tip"].mean()


def _write_csv(path, header, rows):
    path.write_text(",".join(header) + "\n" + "\n".join(",".join(r) for r in rows) + "\n")
    return path


def _rows(n=10):
    return [[f"{k * 1e-3:.3f}", "1", "2", "3", "0.5", "0.1"] for k in range(n)]


@pytest.mark.parametrize("make, pattern", [
    (lambda p: _write_csv(p, ("t", "X", "Y", "Z", "A"), [r[:5] for r in _rows()]),
     r"traj\.csv, field 'C': missing column\(s\) C; the file has t, X, Y, Z, A"),
    (lambda p: _write_csv(p, HEADER, _rows()[:4] + [["0.004", "nan", "2", "3", "0.5", "0.1"]] + _rows()[5:]),
     r"traj\.csv, row 5, field 'X': value is not finite"),
    (lambda p: _write_csv(p, HEADER, _rows()[:4] + [["0.004", "abc", "2", "3", "0.5", "0.1"]] + _rows()[5:]),
     r"traj\.csv, row 5, field 'X': not a number: 'abc'"),
    (lambda p: _write_csv(p, HEADER, _rows()[:3] + [["0.001", "1", "2", "3", "0.5", "0.1"]] + _rows()[4:]),
     r"traj\.csv, row 4, field 't': time is not increasing"),
    (lambda p: _write_csv(p, HEADER, _rows()[:6] + [["0.0065", "1", "2", "3", "0.5", "0.1"]] + _rows()[7:]),
     r"traj\.csv, row 7, field 't': time is not uniformly sampled"),
    (lambda p: _write_csv(p, HEADER, _rows(3)),
     r"traj\.csv, field 't': too few samples: 3, need at least 6"),
    (lambda p: p.write_text("") and p or p, r"traj\.csv: empty file"),
])
def test_predict_bad_trajectory_files(tmp_path, capsys, make, pattern):
    src = make(tmp_path / "traj.csv")
    assert main(["predict", str(src), "-o", str(tmp_path / "out.csv")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("precontour: error: ")
    import re
    assert re.search(pattern, err), err


def test_predict_bad_machine_and_controller(traj_csv, tmp_path, capsys):
    out = str(tmp_path / "out.csv")
    assert main(["predict", str(traj_csv), "--machine", "nope", "-o", out]) == 2
    assert "not a built-in machine" in capsys.readouterr().err
    assert main(["predict", str(traj_csv), "--controller", "pid-medium", "-o", out]) == 2
    assert "unknown controller 'pid-medium'" in capsys.readouterr().err
    bad = tmp_path / "bad.toml"
    bad.write_text("name = \n")
    assert main(["predict", str(traj_csv), "--machine", str(bad), "-o", out]) == 2
    assert "bad.toml: malformed TOML" in capsys.readouterr().err


def test_outputs_never_overwrite_inputs(traj_csv, capsys):
    before = traj_csv.read_bytes()
    assert main(["predict", str(traj_csv), "-o", str(traj_csv)]) == 2
    assert "refusing to overwrite an input" in capsys.readouterr().err
    assert traj_csv.read_bytes() == before


def test_new_commands_bad_inputs(traj_csv, paper_csv, tmp_path, capsys):
    out = str(tmp_path / "out.csv")
    assert main(["compensate", str(traj_csv), "-o", out]) == 2
    assert "needs the reference tool path columns" in capsys.readouterr().err
    short = tmp_path / "short.csv"
    write_columns(short, _traj_columns(200))
    assert main(["simulate", str(short), "--reference", str(paper_csv), "-o", out]) == 2
    assert "same time stamps" in capsys.readouterr().err
    assert main(["trajectory", str(tmp_path / "missing.csv"), "-o", out]) == 2
    assert "missing.csv" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["compensate", str(paper_csv), "--iterations", "0", "-o", out])
    assert "must be >= 1" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["compensate", str(paper_csv), "--learn", "-1", "-o", out])
    assert "must be >= 0" in capsys.readouterr().err


def test_compensate_without_learning_is_the_linear_pass(paper_csv, tmp_path, capsys):
    """With --ignore-limits, the linear pass of the library's compensate; by default the
    compensation within the limits (as run's), which on `paper` / pid-low needs no slowing
    and is then the same linear pass."""
    from precontour import load_machine
    from precontour.compensation.precompensate import compensate
    from precontour.tables import read_trajectory

    machine = load_machine("zhang2013")
    traj = read_trajectory(paper_csv)
    linear = compensate(traj, machine.kinematics,
                        machine.controller("pid-low").error_models(machine.drives))
    for options in (["--ignore-limits"], []):
        out = tmp_path / f"comp{len(options)}.csv"
        assert main(["compensate", str(paper_csv), "--controller", "pid-low", "--learn", "0",
                     "-o", str(out)] + options) == 0
        printed = capsys.readouterr().out
        assert "learned against" not in printed
        assert ("within the machine's limits: not slowed" in printed) == (not options)
        assert np.array_equal(read_trajectory(out).q, linear.trajectory.q)


def test_compensate_keeps_the_limits_so_export_takes_its_output(tmp_path, capsys):
    """Issue 21 section 5: `compensate` writes commands within every limit, which `export`
    writes as G-code; with --ignore-limits, on `circle` / pid-high (whose compensated A and C
    break a jerk limit near the end), it does not, and `export` refuses them."""
    from precontour import load_machine
    from precontour.tables import read_trajectory

    circle = tmp_path / "circle.csv"
    assert main(["trajectory", "--builtin", "circle", "-o", str(circle)]) == 0
    machine = load_machine("zhang2013")
    limits = {key: np.array([getattr(d, key) for d in machine.drives])
              for key in ("v_max", "a_max", "j_max")}
    for options, keeps in (([], True), (["--ignore-limits"], False)):
        out = tmp_path / f"comp{len(options)}.csv"
        assert main(["compensate", str(circle), "--controller", "pid-high", "--learn", "0",
                     "-o", str(out)] + options) == 0
        commands = read_trajectory(out)
        jerk = np.abs(np.diff(commands.q, 3, axis=0)).max(axis=0) / commands.ts ** 3
        assert np.all(jerk <= limits["j_max"] * (1 + 1e-9)) == keeps
        code = main(["export", str(out), "-o", str(tmp_path / f"out{len(options)}.ngc")])
        assert code == (0 if keeps else 2)
        printed = capsys.readouterr()
        assert ("slowed in" in printed.out) == keeps
        assert ("exceed the machine's limits" in printed.err) == (not keeps)


def test_module_entry_point(traj_csv, tmp_path):
    import subprocess
    import sys
    result = subprocess.run([sys.executable, "-m", "precontour", "predict", str(traj_csv), "-o",
                             str(tmp_path / "p.csv")], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
