"""Tests of the demo: it runs, writes every promised file, its table holds the numbers of its
result objects, compensation works on the virtual machine, and the ``demo`` command."""

from __future__ import annotations

import csv
import io
import math
import warnings

import numpy as np
import pytest
from scipy import signal

from precontour import cli
from precontour.machine.controllers import closed_loop_bandwidth
from precontour.reports import demo_report as report
from precontour.reports.demo import MACHINE_MODELS, TRAJECTORY_KINDS
from precontour.reports.demo_report import run_demo
from precontour.reports.progress import ProgressLine
from precontour.errors import InputError, MachineFileError

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def demo_and_warnings(tmp_path_factory):
    out = tmp_path_factory.mktemp("demo") / "report"
    calls = []
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = run_demo(out, paths=("paper",), controllers=("pid-high",),
                          progress=lambda done, total, msg: calls.append((done, total, msg)))
    return (result, calls), caught


@pytest.fixture(scope="module")
def demo(demo_and_warnings):
    return demo_and_warnings[0]


def test_demo_and_its_report_warn_nothing(demo_and_warnings):
    # every warning is recorded ("always"), so none can reach a user's terminal unseen
    caught = demo_and_warnings[1]
    assert not caught, [f"{w.filename}:{w.lineno}: {w.category.__name__}: {w.message}"
                        for w in caught]


def test_writes_every_promised_file(demo):
    result, _ = demo
    names = report.demo_file_names(("paper",), ("pid-high",))
    expected = sorted(names.values())
    assert sorted(p.name for p in result.out_dir.iterdir()) == expected
    assert sorted(p.name for p in result.files) == expected
    assert result.files[-1].name == "index.html"
    for name in expected:
        if name.endswith(".png"):
            data = (result.out_dir / name).read_bytes()
            assert data.startswith(PNG_SIGNATURE) and len(data) > 10_000, name


def test_csv_and_markdown_tables(demo):
    result, _ = demo
    with open(result.out_dir / "contour_errors.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert tuple(rows[0]) == report.TABLE_COLUMNS
    # paper's measurement, then realistic and exact machine, each without and with compensation
    assert [(r["machine"], r["trajectory"]) for r in rows] == [
        (m, k) for m in ("paper-measured", *MACHINE_MODELS) for k in TRAJECTORY_KINDS]
    md = (result.out_dir / "contour_errors.md").read_text().splitlines()
    header = next(line for line in md if line.startswith("| path"))
    for column in ("controller", "machine", "trajectory", "tip max (um)", "tip mean (um)",
                   "orientation max (mrad)", "orientation mean (mrad)",
                   "tip mean reduction (%)", "orientation mean reduction (%)"):
        assert f"| {column} |" in header
    assert sum(line.startswith("| paper | pid-high |") for line in md) == 6


def test_table_numbers_are_the_result_objects_numbers(demo):
    result, _ = demo
    case = result.case("paper", "pid-high")
    with open(result.out_dir / "contour_errors.csv", newline="") as handle:
        rows = {(r["machine"], r["trajectory"]): r for r in csv.DictReader(handle)}
    for model in MACHINE_MODELS:
        for kind in TRAJECTORY_KINDS:
            contour = case.run(model, kind).contour
            row = rows[(model, kind)]
            assert float(row["tip_max_um"]) == 1e3 * contour.tip.max()
            assert float(row["tip_mean_um"]) == pytest.approx(1e3 * np.mean(contour.tip),
                                                              rel=1e-12)
            assert float(row["ori_max_mrad"]) == 1e3 * contour.orientation.max()
            assert float(row["ori_mean_mrad"]) == pytest.approx(
                1e3 * np.mean(contour.orientation), rel=1e-12)
        before = case.run(model, "uncompensated").contour.tip.mean()
        after = case.run(model, "pre-compensated").contour.tip.mean()
        assert float(rows[(model, "pre-compensated")]["tip_mean_reduction_pct"]) == \
            pytest.approx(100 * (1 - after / before), rel=1e-12)
    assert rows[("paper-measured", "uncompensated")]["tip_max_um"] == "43.1"


def test_html_shows_the_folders_figures_and_holds_numbers(demo):
    result, _ = demo
    page = (result.out_dir / "index.html").read_text(encoding="utf-8")
    pngs = sorted(p for p in result.files if p.suffix == ".png")
    # each figure is the PNG file beside the page, by its name (not embedded, not remote)
    assert page.count("<img src=") == len(pngs) == 3
    for png in pngs:
        assert png.parent == result.out_dir
        assert page.count(f'<img src="{png.name}"') == 1
    assert "data:image" not in page and "<img src=\"http" not in page
    realistic = result.case("paper", "pid-high").run("realistic", "pre-compensated").contour
    assert f"<td class=\"num\">{1e3 * realistic.tip.max():#.4g}</td>" in page
    assert "<td class=\"num\">43.10</td>" in page
    assert "zhang2013" in page and "pid-high" in page and "friction" in page
    bw = result.bandwidths["pid-high"][0]
    assert f"X {bw:.1f} Hz" in page


def test_exact_machine_measures_what_the_closed_form_predicts(demo):
    # The continuous frictionless simulation is an independent integration of the linear
    # model the compensator predicts with; their contour errors must agree closely.
    result, _ = demo
    case = result.case("paper", "pid-high")
    exact_unc = case.run("exact", "uncompensated").contour
    exact_comp = case.run("exact", "pre-compensated").contour
    assert 1e3 * exact_unc.tip.max() == pytest.approx(
        case.compensation.before.summary()["tip_max_um"], rel=1e-3)
    assert 1e3 * exact_comp.tip.max() == pytest.approx(
        case.compensation.after.summary()["tip_max_um"], rel=2e-2)
    # predicted tracking errors vs the exact simulation, all five axes
    t = case.trajectory.t
    e_sim = case.run("exact", "uncompensated").simulation.e
    scale = np.abs(e_sim).max(axis=0)
    assert np.all(np.abs(case.prediction(t) - e_sim).max(axis=0) < 0.02 * scale)


def test_compensation_works_on_the_realistic_machine(demo):
    # The paper's claim (Table 3: -56 % tip, -51 % orientation mean with pid-high).
    result, _ = demo
    row = next(r for r in result.rows if r["machine"] == "realistic"
               and r["trajectory"] == "pre-compensated")
    assert row["tip_mean_reduction_pct"] > 56
    assert row["ori_mean_reduction_pct"] > 51


def test_progress_steps(demo):
    result, calls = demo
    total = calls[0][1]
    assert [c[0] for c in calls] == list(range(total + 1))
    assert all(c[1] == total for c in calls)
    assert calls[0][2] == "paper: trajectory"
    assert sum("on the realistic machine" in c[2] for c in calls) == 2
    assert calls[-1][2].startswith("done in")
    assert set(result.timings) == {"compute", "report", "total"}


def test_closed_loop_bandwidth_matches_the_paper():
    # The paper's Table 1: 55.8 Hz (high) and 38.6 Hz (low) bandwidth (X axis).
    from precontour import load_machine

    machine = load_machine("zhang2013")
    for name, paper_hz in (("pid-high", 55.8), ("pid-low", 38.6)):
        model = machine.error_models(name)[0]
        hz = closed_loop_bandwidth(model)
        assert hz == pytest.approx(paper_hz, abs=0.5)
        # independent check of the -3 dB definition with scipy.signal.freqresp
        system = signal.lti(np.trim_zeros(np.polysub(model.den, model.num), "f"), model.den)
        _, h = signal.freqresp(system, [2 * math.pi * hz])
        assert abs(h[0]) == pytest.approx(math.sqrt(0.5), rel=1e-9)


def test_report_overwrites_only_its_files(demo, tmp_path):
    result, _ = demo
    from dataclasses import replace

    (tmp_path / "notes.txt").write_text("mine")
    (tmp_path / "index.html").write_text("old")
    files = report.write_demo_report(replace(result, out_dir=tmp_path), result.rows)
    assert (tmp_path / "notes.txt").read_text() == "mine"
    assert (tmp_path / "index.html").read_text().startswith("<!DOCTYPE html>")
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        [p.name for p in files] + ["notes.txt"])


def test_progress_line_streams():
    plain = io.StringIO()
    line = ProgressLine(plain)
    line(0, 3, "first")
    line(1, 3, "second")
    line.close()
    lines = plain.getvalue().splitlines()
    assert len(lines) == 2 and lines[1].endswith("1/3 second") and lines[0].startswith("[")

    class Terminal(io.StringIO):
        def isatty(self):
            return True

    tty = Terminal()
    line = ProgressLine(tty)
    line(0, 2, "a long first message")
    line(1, 2, "short")
    line.close()
    text = tty.getvalue()
    assert text.count("\r") == 2 and text.endswith("\n") and text.count("\n") == 1
    # the shorter message blanks out the rest of the longer one
    first, second = text.split("\r")[1:]
    assert len(second.rstrip("\n")) == len(first)


def test_compile_note_gets_a_line_of_its_own_under_a_progress_line(capsys):
    from precontour import kernels

    class Terminal(io.StringIO):
        def isatty(self):
            return True

    tty = Terminal()
    line = ProgressLine(tty)
    line(0, 2, "trajectory")
    kernels.print_note()             # what the first compile prints, on stderr
    line(1, 2, "predict")
    line.close()
    assert tty.getvalue().count("\n") == 2  # the updating line was ended before the note
    assert tty.getvalue().split("\n")[1].startswith("\r[")
    assert capsys.readouterr().err.startswith("precontour: note: compiling numerical kernels")


@pytest.mark.parametrize("kwargs, error, match", [
    (dict(paths=("paper", "spiral")), InputError, "field 'paths': unknown built-in path 'spiral'"),
    (dict(paths=()), InputError, "no path to run"),
    (dict(paths=("fan", "fan")), InputError, "a path is named twice: fan, fan"),
    (dict(controllers=()), InputError, "no controller to run"),
    (dict(controllers=("pid-low", "pid-low")), InputError, "a controller is named twice"),
    (dict(controllers=("p-pi",)), MachineFileError, "unknown controller 'p-pi'"),
    (dict(iterations=0), InputError, "iterations must be a whole number >= 1, got 0"),
])
def test_run_demo_input_errors(tmp_path, kwargs, error, match):
    with pytest.raises(error, match=match):
        run_demo(tmp_path / "out", **kwargs)
    assert not (tmp_path / "out").exists()


def test_run_demo_refuses_a_file_as_output(tmp_path):
    target = tmp_path / "taken"
    target.write_text("x")
    with pytest.raises(InputError, match="taken: the demo output must be a directory"):
        run_demo(target, paths=("fan",))
    assert target.read_text() == "x"


def test_cli_demo(tmp_path, capsys):
    out = tmp_path / "cli-demo"
    assert cli.main(["demo", "--out", str(out), "--paths", "fan"]) == 0
    captured = capsys.readouterr()
    lines = captured.out.splitlines()
    header = next(line for line in lines if line.startswith("path"))
    assert header.split()[:6] == ["path", "controller", "machine", "trajectory", "tip", "max"]
    table_rows = [line.split() for line in lines if line.startswith("fan ")]
    assert [(r[1], r[2], r[3]) for r in table_rows] == [
        (c, m, k) for c in ("pid-high", "pid-low") for m in MACHINE_MODELS
        for k in TRAJECTORY_KINDS]
    with open(out / "contour_errors.csv", newline="") as handle:
        csv_rows = list(csv.DictReader(handle))
    for printed, row in zip(table_rows, csv_rows):
        assert float(printed[4]) == pytest.approx(float(row["tip_max_um"]), rel=1e-3)
    assert f"open {out / 'index.html'}" in captured.out
    assert "done in" in captured.err
    assert (out / "contour_fan_pid-low.png").read_bytes().startswith(PNG_SIGNATURE)


def test_cli_demo_errors(tmp_path, capsys):
    assert cli.main(["demo", "--out", str(tmp_path / "o"), "--paths", "paper,nope"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("precontour: error: field 'paths': unknown built-in path 'nope'")
    with pytest.raises(SystemExit) as exit_info:
        cli.main(["demo", "--iterations", "0"])
    assert exit_info.value.code == 2
    assert "must be >= 1, got '0'" in capsys.readouterr().err


def test_demo_on_a_head_head_machine_from_the_command_line(tmp_path, capsys):
    """``demo --machine``: the paper's evaluation on the head-head bridge mill, its figures
    labelled with the machine's letters (B in slot 3), compensation removing most of the
    error on the realistic machine (measured: 93.2 % of the max tip error with pid-high)."""
    from precontour.cli import main
    from precontour.reports.demo_report import plot_path

    out = tmp_path / "report"
    assert main(["demo", "--machine", "linuxcnc-bridgemill", "--report", str(out)]) == 0
    printed = capsys.readouterr().out
    assert printed.startswith("contour errors on linuxcnc-bridgemill:")
    row = next(line for line in printed.splitlines()
               if line.startswith("paper  pid-high    realistic  pre-compensated"))
    assert float(row.split()[-4]) >= 85.0            # reduction of the max tip error, %
    assert "B 5" in (out / "index.html").read_text()  # the bandwidths name B, not A
    from precontour import load_machine
    from precontour.trajectory import builtin_path
    from precontour.trajectory.generate import generate_trajectory
    machine = load_machine("linuxcnc-bridgemill")
    fig = plot_path(generate_trajectory(builtin_path("paper"), machine),
                    axis_names=machine.axis_names)
    labels = [ax.get_ylabel() for ax in fig.axes[1:]]
    assert labels == ["X (mm)", "Y (mm)", "Z (mm)", "B (rad)", "C (rad)"]


def test_demo_on_the_two_tilt_table_from_the_command_line(tmp_path, capsys):
    """``demo --machine`` on LinuxCNC's A-B table dual rotary: the figures and bandwidths name
    A and B (B in slot 4), compensation removing most of the error on the realistic machine
    (measured: 89.8 % of the max tip error with pid-high, 93.9 % with pid-low)."""
    from precontour import load_machine
    from precontour.cli import main
    from precontour.reports.demo_report import plot_path
    from precontour.trajectory import builtin_path
    from precontour.trajectory.generate import generate_trajectory

    out = tmp_path / "report"
    assert main(["demo", "--machine", "linuxcnc-xyzab-tdr", "--report", str(out)]) == 0
    printed = capsys.readouterr().out
    assert printed.startswith("contour errors on linuxcnc-xyzab-tdr:")
    row = next(line for line in printed.splitlines()
               if line.startswith("paper  pid-high    realistic  pre-compensated"))
    assert float(row.split()[-4]) >= 85.0            # reduction of the max tip error, %
    assert ", B 5" in (out / "index.html").read_text() and "C 5" not in (
        out / "index.html").read_text()
    machine = load_machine("linuxcnc-xyzab-tdr")
    fig = plot_path(generate_trajectory(builtin_path("paper"), machine),
                    axis_names=machine.axis_names)
    labels = [ax.get_ylabel() for ax in fig.axes[1:]]
    assert labels == ["X (mm)", "Y (mm)", "Z (mm)", "A (rad)", "B (rad)"]
