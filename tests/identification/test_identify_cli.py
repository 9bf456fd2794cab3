"""``precontour excite`` and ``precontour identify`` end to end, report included."""

from __future__ import annotations

import re

import numpy as np
import pytest

from precontour import load_machine
from precontour.simulation import simulate
from precontour.cli import main
from precontour.machine.drives import AXES
from precontour.tables import read_trajectory, write_columns

from vm_logs import B_FACTORS, J_FACTORS, hidden_plant, write_log_file


def test_excite_record_identify_use(tmp_path, capsys):
    exc = tmp_path / "exc.csv"
    assert main(["excite", "--axes", "Y", "--travel-linear", "5", "-o", str(exc)]) == 0
    assert "axes Y one at a time" in capsys.readouterr().out
    traj = read_trajectory(exc)
    machine = load_machine("zhang2013")
    log, sim = write_log_file(tmp_path / "log.parquet", traj, machine, AXES)
    out, report = tmp_path / "ident.toml", tmp_path / "report"
    assert main(["identify", str(log), "--machine", "zhang2013", "--base-controller", "pid-low",
                 "-o", str(out), "--name", "mine", "--report", str(report)]) == 0
    printed = capsys.readouterr().out
    assert "axis X: the command never moves in the log" in printed
    assert (report / "index.html").exists() and (report / "bode.png").exists()
    assert (report / "residuals_Y.png").exists()
    # No currents: the drives are the base machine's, so the tf loop names no controller for
    # learning against them (compensate --learn then runs the tf loops), and says so.
    assert load_machine(out).controller("mine").base is None
    assert "no base controller named for learning" in printed
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


def _identified_file(tmp_path, base="pid-high"):
    """A machine file as identify writes it from a log with motor currents: drives with other
    J and B than zhang2013's (the "identified" ones), and a tf controller, here the exact
    continuous pid-high loop of those drives, whose ``base`` names pid-high."""
    import copy

    from precontour.machine.machine_file import machine_data, machine_file_text, parse_machine

    data = copy.deepcopy(machine_data("zhang2013")[0])
    for axis, fj, fb in zip(AXES, J_FACTORS, B_FACTORS):
        data["drives"][axis]["J"] *= fj
        data["drives"][axis]["B"] *= fb
    drives = parse_machine(machine_file_text(data), source="<drives>").drives
    table = {"type": "tf", "base": base}
    for axis, model in zip(AXES, load_machine("zhang2013").controller("pid-high")
                           .error_models(drives)):
        num = np.trim_zeros(np.polysub(model.den, model.num), "f")
        table[axis] = {"num": [float(v) for v in num], "den": [float(v) for v in model.den]}
    data["controllers"]["identified"] = table
    path = tmp_path / "ident.toml"
    path.write_text(machine_file_text(data))
    return path


def test_compensate_learns_against_the_identified_drives(tmp_path, capsys):
    """--controller identified (type tf) predicts with the transfer function and learns
    against the realistic virtual machine of its base controller on the file's drives: the
    learning's uncompensated errors (the worst of the ensemble's draws) are those of
    simulate(..., "pid-high", REALISTIC) on that machine's draws, computed here
    independently, not those of the frictionless tf loop. (--ignore-limits: on the
    trajectory's own timing, which the errors here are computed on.)"""
    from precontour.prediction import ReferencePath, contour_errors
    from precontour.simulation.ensemble import MachineEnsemble
    from precontour.simulation.virtual_machine import REALISTIC

    ident = _identified_file(tmp_path)
    traj_path = tmp_path / "circle.csv"
    assert main(["trajectory", "--builtin", "circle", "-o", str(traj_path)]) == 0
    capsys.readouterr()
    machine = load_machine(ident)
    traj = read_trajectory(traj_path)
    reference = ReferencePath.from_trajectory(traj)

    draws = MachineEnsemble().options(traj.n_samples, [d.is_rotary for d in machine.drives])

    def uncompensated(controller):
        worst = max(contour_errors(reference, simulate(traj.t, traj.q, machine, controller,
                                                       **REALISTIC, **draw).q_act,
                                   machine.kinematics).summary()["tip_max_um"]
                    for draw in draws)
        return f"uncompensated:       tip max {worst:.3f} um"

    comp = tmp_path / "comp.csv"
    assert main(["compensate", str(traj_path), "--machine", str(ident), "--controller",
                 "identified", "--learn", "1", "--ignore-limits", "-o", str(comp)]) == 0
    out, err = capsys.readouterr()
    assert "virtual machine: controller pid-high (pid)" in out
    assert uncompensated("pid-high") in out and uncompensated("identified") not in out
    assert "transfer function without drives" not in err
    # Learning against the tf loop itself, asked for: it runs, with a note that it has no friction.
    assert main(["compensate", str(traj_path), "--machine", str(ident), "--controller",
                 "identified", "--learn", "1", "--learn-controller", "identified",
                 "--ignore-limits", "-o", str(tmp_path / "comp2.csv")]) == 0
    out, err = capsys.readouterr()
    assert uncompensated("identified") in out and "transfer function without drives" in err


def test_tf_base_must_name_a_controller_with_drives(tmp_path, capsys):
    traj_path = tmp_path / "circle.csv"
    assert main(["trajectory", "--builtin", "circle", "-o", str(traj_path)]) == 0
    for base, message in (("nope", "no controller 'nope'"),
                          ("identified", "is itself of type 'tf'")):
        ident = _identified_file(tmp_path, base=base)
        capsys.readouterr()
        assert main(["compensate", str(traj_path), "--machine", str(ident), "--controller",
                     "identified", "-o", str(tmp_path / "c.csv")]) == 2
        err = capsys.readouterr().err.strip()
        assert err.count("\n") == 0 and "[controllers.identified] base" in err and message in err


@pytest.mark.parametrize("name, rotary, other", [("linuxcnc-xyzbc-trt", "B", "A"),
                                                 ("linuxcnc-xyzab-tdr", "B", "C")])
def test_identify_names_the_machines_letters(tmp_path, capsys, monkeypatch, name, rotary, other):
    """excite, a log recorded on a virtual machine whose J and B differ from the file's, and
    identify --report on a B-C (slot A is B) and an A-B machine (slot C is B): the printed
    table, the notes, the J/B lines, the identified file, the report's files, table, figure
    titles and legends name the machine's letters, never the slot letter ``other``; the
    identified J of the rotary drive is the virtual machine's."""
    import tomllib

    import precontour.reports.identify_report as identify_report
    from precontour.machine.drives import AXES

    machine = load_machine(name)
    letters = machine.axis_names
    assert AXES[letters.index(rotary)] == other   # the slot the machine's rotary letter fills
    exc = tmp_path / "exc.csv"
    assert main(["excite", "--machine", name, "--axes", f"Y{rotary}", "--travel-linear", "5",
                 "--travel-rotary", "0.1", "-o", str(exc)]) == 0
    assert f"axes Y{rotary} one at a time" in capsys.readouterr().out
    traj = read_trajectory(exc, axis_names=letters)
    plant = hidden_plant(machine)
    log, _ = write_log_file(tmp_path / "log.parquet", traj, plant, letters,
                            currents=("Y", rotary))

    figure_texts, legends = [], []
    real_png = identify_report.figure_png

    def recording_png(fig):
        figure_texts.append([t.get_text() for t in fig.findobj(lambda a: hasattr(a, "get_text"))])
        legends.append([t.get_text() for ax in fig.axes if ax.get_legend() is not None
                        for t in ax.get_legend().get_texts()])
        return real_png(fig)

    monkeypatch.setattr(identify_report, "figure_png", recording_png)
    out, report = tmp_path / "ident.toml", tmp_path / "report"
    assert main(["identify", str(log), "--machine", name, "--base-controller", "pid-low",
                 "-o", str(out), "--report", str(report)]) == 0
    printed = capsys.readouterr().out
    lines = printed.splitlines()
    header = lines.index(next(line for line in lines if line.startswith("axis  order")))
    assert [line.split()[0] for line in lines[header + 1:header + 6]] == list(letters)
    assert [line.split()[1] for line in lines[header + 1:header + 6]] != ["base"] * 5
    assert set(re.findall(r"\baxis ([A-Z])\b", printed)) == set(letters) - {"Y", rotary}
    j_line = next(line for line in lines if line.startswith(f"{rotary}: J "))
    assert not any(line.startswith(f"{other}: J ") for line in lines)
    # the identified inertia is the virtual machine's (the file's J times J_FACTORS), to 1 %
    i = letters.index(rotary)
    assert float(j_line.split()[2]) == pytest.approx(plant.drives[i].J, rel=0.01)
    assert J_FACTORS[i] != 1 and abs(float(j_line.split()[2]) / machine.drives[i].J - 1) > 0.1

    text = out.read_text()
    data = tomllib.loads(text)
    assert set(data["controllers"]["identified"]) == {"type", "base", *letters}
    assert data["drives"][rotary]["J"] == pytest.approx(plant.drives[i].J, rel=0.01)
    assert f"# Drives Y, {rotary}: J, B and friction" in text
    identified = load_machine(out)
    assert identified.axis_names == letters
    assert identified.controller("identified").base == "pid-low"

    assert sorted(p.name for p in report.iterdir()) == sorted(
        ["bode.png", "index.html", "residuals_Y.png", f"residuals_{rotary}.png"])
    page = (report / "index.html").read_text()
    assert re.findall(r"<tr><td>([A-Z])</td>", page) == list(letters)
    assert f"Axis {rotary}: tracking error" in page and f"<li>{rotary}: J " in page
    assert f"Axis {other}" not in page and f"<li>{other}: J" not in page
    residuals = figure_texts[1:]
    assert legends[0] == [f"{a} {kind}" for a in letters for kind in ("identified", "base")]
    titles = sorted(next(t for t in texts if t.startswith("axis ")) for texts in residuals)
    assert [t.split(":")[0] for t in titles] == sorted(["axis Y", f"axis {rotary}"])
    assert any(t == f"e {rotary} (mrad)" for texts in residuals for t in texts)
    assert not any(re.search(rf"\b{other}\b", t) for texts in figure_texts for t in texts)
