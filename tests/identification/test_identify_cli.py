"""``precontour excite`` and ``precontour identify`` end to end, report included."""

from __future__ import annotations

import numpy as np

from precontour import load_machine, simulate
from precontour.cli import main
from precontour.machine.drives import AXES
from precontour.tables import read_trajectory, write_columns


def test_excite_record_identify_use(tmp_path, capsys):
    exc = tmp_path / "exc.csv"
    assert main(["excite", "--axes", "Y", "--travel-linear", "5", "-o", str(exc)]) == 0
    assert "axes Y one at a time" in capsys.readouterr().out
    traj = read_trajectory(exc)
    machine = load_machine("zhang2013")
    sim = simulate(traj.t, traj.q, machine, "pid-low", mode="discrete", friction=False,
                   ff_friction=False)
    columns = {"t": traj.t}
    for i, axis in enumerate(AXES):
        columns[axis] = traj.q[:, i]
        columns[f"{axis}_act"] = sim.q_act[:, i]
    log = write_columns(tmp_path / "log.parquet", columns)
    out, report = tmp_path / "ident.toml", tmp_path / "report"
    assert main(["identify", str(log), "--machine", "zhang2013", "--base-controller", "pid-low",
                 "-o", str(out), "--name", "mine", "--report", str(report)]) == 0
    printed = capsys.readouterr().out
    assert "axis X: the command never moves in the log" in printed
    assert (report / "index.html").exists() and (report / "bode.png").exists()
    assert (report / "residuals_Y.png").exists()
    # The identified machine works with the other commands.
    pred = tmp_path / "pred.csv"
    assert main(["predict", str(exc), "--machine", str(out), "--controller", "mine",
                 "-o", str(pred)]) == 0
    sim_out = tmp_path / "sim.csv"
    assert main(["simulate", str(exc), "--machine", str(out), "--controller", "mine",
                 "-o", str(sim_out)]) == 0
    actual = read_trajectory(sim_out)
    peak = np.abs(sim.e[:, 1]).max()
    assert np.abs(actual.q[:, 1] - sim.q_act[:, 1]).max() < 0.01 * peak


def test_identify_errors_are_one_line_exit_2(tmp_path, capsys):
    bad = tmp_path / "bad.csv"
    t = np.arange(100) * 1e-3
    x = np.sin(t)
    x[40] = np.nan
    write_columns(bad, {"t": t, "X": np.sin(t), "X_act": x})
    assert main(["identify", str(bad), "-o", str(tmp_path / "o.toml")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "row 41, field 'X_act'" in err
    good = tmp_path / "good.csv"
    write_columns(good, {"t": t, "X": np.sin(t), "X_act": np.sin(t) - 1e-4})
    assert main(["identify", str(good), "--order", "zero", "-o", str(tmp_path / "o.toml")]) == 2
    assert "field 'order'" in capsys.readouterr().err
    assert main(["identify", str(good), "-o", str(good)]) == 2
    assert "refusing to overwrite" in capsys.readouterr().err
    assert main(["excite", "--axes", "Q", "-o", str(tmp_path / "e.csv")]) == 2
