"""Tests of the comparison (``precontour compare``): its numbers are those of its result
objects and of independent recomputations, every promised file exists and is valid, the
printed claims carry the measured numbers, and bad inputs stop with one line and exit 2."""

from __future__ import annotations

import base64
import contextlib
import csv
import io
import math
import re
import struct

import numpy as np
import pytest
from scipy import signal

from conftest import servo_of
from precontour import cli
from precontour.reports import compare, compare_report
from precontour.compensation.precompensate import (COMPENSATION_TOL_LINEAR, COMPENSATION_TOL_ROTARY,
                                     compensate)
from precontour.compensation.programmed_end import end_at_programmed_end
from precontour.prediction.contour import ReferencePath, contour_errors
from precontour.machine.drives import AXES
from precontour.errors import InputError, MachineFileError
from precontour.machine.machine_file import load_machine
from precontour.simulation.virtual_machine import simulate
from precontour.tables import trajectory_columns, write_columns
from precontour.prediction.tracking import predict_tracking
from precontour.trajectory.sampled import Trajectory

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
NUMBER = r"([-+]?[0-9.]+(?:e[-+]?[0-9]+)?)"


@pytest.fixture(scope="module")
def machine():
    return load_machine("zhang2013")


@pytest.fixture(scope="module")
def paper_csv(tmp_path_factory, machine):
    from precontour.trajectory.builtin_paths import builtin_path
    from precontour.trajectory.generate import generate_trajectory

    traj = generate_trajectory(builtin_path("paper"), machine, ts=machine.servo_period)
    return write_columns(tmp_path_factory.mktemp("in") / "paper.csv", trajectory_columns(traj))


@pytest.fixture(scope="module")
def cli_run(tmp_path_factory, paper_csv):
    """``precontour compare paper.csv --out DIR`` (all default controllers), its printed output
    and the CompareResult the command computed (caught on its way to the printing)."""
    out = tmp_path_factory.mktemp("compare") / "report"
    caught = []
    original = compare_report.run_compare

    def catching(*args, **kwargs):
        caught.append(original(*args, **kwargs))
        return caught[-1]

    stdout, stderr = io.StringIO(), io.StringIO()
    with pytest.MonkeyPatch.context() as patch, contextlib.redirect_stdout(stdout), \
            contextlib.redirect_stderr(stderr):
        patch.setattr(compare_report, "run_compare", catching)
        code = cli.main(["compare", str(paper_csv), "--out", str(out)])
    assert code == 0, stderr.getvalue()
    return caught[0], stdout.getvalue(), stderr.getvalue()


def _csv(path):
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


# --------------------------------------------------------------------------------------------
# Files
# --------------------------------------------------------------------------------------------

def test_writes_every_promised_file(cli_run):
    result, _, _ = cli_run
    names = compare_report.compare_file_names(result)
    expected = sorted(names.values())
    assert sorted(p.name for p in result.out_dir.iterdir()) == expected
    assert sorted(p.name for p in result.files) == expected
    assert result.files[-1].name == "index.html"
    assert {"fig11", "fig11:model-error", "fig12:pid-high", "fig12:pid-low", "fig13:pid-high",
            "fig13:pid-low", "fig14", "fig15", "fig16", "model-error.csv"} <= set(names)
    for path in result.files:
        if path.suffix == ".png":
            data = path.read_bytes()
            assert data.startswith(PNG_SIGNATURE), path.name
            width, height = struct.unpack(">II", data[16:24])  # IHDR
            assert width >= 800 and height >= 600 and len(data) > 20_000, path.name


def test_csv_files_have_their_headers_and_rows(cli_run):
    result, _, _ = cli_run
    out = result.out_dir
    contour = _csv(out / "contour_errors.csv")
    assert tuple(contour[0]) == compare_report.CONTOUR_COLUMNS
    assert [(r["controller"], r["compensation"]) for r in contour] == [
        ("smc", "none")] + [(c, k) for c in ("p-pi-high", "pid-high", "pid-low")
                            for k in compare.COMPENSATIONS]
    spectra = _csv(out / "compensation_spectra.csv")
    assert tuple(spectra[0]) == compare_report.SPECTRUM_COLUMNS
    assert len(spectra) == 3 * len(compare.SPECTRUM_SIGNALS) * len(compare.SPECTRUM_CUTOFFS_HZ)
    peaks = _csv(out / "command_peaks.csv")
    assert tuple(peaks[0]) == compare_report.PEAK_COLUMNS
    assert len(peaks) == 3 * 2 * 3 * 5
    model_error = _csv(out / "model_error.csv")
    assert tuple(model_error[0]) == compare_report.MODEL_ERROR_COLUMNS
    assert [(r["model_error_pct"], r["controller"], r["compensation"]) for r in model_error] == [
        (pct, c, k) for pct in ("0.0", "20.0", "-20.0")
        for c, k in (("smc", "none"), ("p-pi-high", "none"), ("p-pi-high", "contour"))]
    claims = _csv(out / "claims.csv")
    assert [r["key"] for r in claims] == [c.key for c in result.claims]
    assert [r["verdict"] for r in claims] == [c.verdict for c in result.claims]


def test_markdown_and_html(cli_run):
    result, _, _ = cli_run
    md = (result.out_dir / "compare.md").read_text()
    for claim in result.claims:
        assert f"**({claim.key})** {claim.question} **{claim.verdict.upper()}**" in md
        for line in claim.lines:
            assert f"- {line}" in md
    assert md.count("| controller | compensation | passes |") == 1
    page = (result.out_dir / "index.html").read_text(encoding="utf-8")
    pngs = [p for p in result.files if p.suffix == ".png"]
    assert page.count('src="data:image/png;base64,') == len(pngs) == 9
    for png in pngs:
        assert base64.b64encode(png.read_bytes()).decode() in page
    assert "<img src=\"http" not in page and ".png\"" not in page
    tip = 1e3 * result.run("p-pi-high", "contour").contour.tip.max()
    assert f'<td class="num">{tip:#.4g}</td>' in page
    assert "friction" in page and "10 Hz" in page


# --------------------------------------------------------------------------------------------
# Numbers
# --------------------------------------------------------------------------------------------

def test_contour_table_is_the_runs_numbers(cli_run):
    result, _, _ = cli_run
    rows = {(r["controller"], r["compensation"]): r
            for r in _csv(result.out_dir / "contour_errors.csv")}
    assert len(rows) == len(result.runs) == 10
    for key, run in result.runs.items():
        row = rows[key]
        assert float(row["tip_max_um"]) == 1e3 * np.max(run.contour.tip)
        assert float(row["tip_mean_um"]) == pytest.approx(1e3 * np.mean(run.contour.tip),
                                                          rel=1e-12)
        assert float(row["ori_max_mrad"]) == 1e3 * np.max(run.contour.orientation)
        assert float(row["ori_mean_mrad"]) == pytest.approx(
            1e3 * np.mean(run.contour.orientation), rel=1e-12)
        comp = run.compensation_result
        if key[0] == "smc":
            assert row["predicted_tip_max_um"] == "" and row["passes"] == ""
        elif comp is not None:
            assert int(row["passes"]) == comp.iterations == 1
            assert float(row["predicted_tip_max_um"]) == 1e3 * comp.after.tip.max()


def test_runs_are_what_an_independent_run_measures(cli_run, machine):
    # Re-run one comparison cell by hand: simulate the commands on the realistic machine and
    # measure against the reference read from the same file.
    result, _, _ = cli_run
    run = result.run("pid-high", "contour")
    traj = result.trajectory
    np.testing.assert_array_equal(run.simulation.q_cmd, run.commands.q)
    sim = simulate(traj.t, run.commands.q, machine, "pid-high", mode="discrete",
                   friction=True, ff_friction=True)
    np.testing.assert_array_equal(sim.q_act, run.simulation.q_act)
    errors = contour_errors(ReferencePath.from_trajectory(traj), sim.q_act, machine.kinematics)
    assert errors.summary() == run.contour.summary()
    np.testing.assert_array_equal(run.axis_errors, traj.q - sim.q_act)
    # the uncompensated run drives the reference commands themselves
    np.testing.assert_array_equal(result.run("smc").commands.q, traj.q)
    assert result.run("smc").simulation.controller == "smc"


def test_model_error_runs_are_what_an_independent_run_measures(cli_run, machine):
    # Claim a2: the same commands as on the exact plant, on a plant whose J and B are scaled;
    # re-run each cell by hand and compare with the table written.
    result, _, _ = cli_run
    traj = result.trajectory
    reference = ReferencePath.from_trajectory(traj)
    rows = {(float(r["model_error_pct"]), r["controller"], r["compensation"]): r
            for r in _csv(result.out_dir / "model_error.csv")}
    assert result.model_errors == compare.DEFAULT_MODEL_ERRORS
    for (name, kind, error), run in result.model_error_runs.items():
        np.testing.assert_array_equal(run.commands.q, result.run(name, kind).commands.q)
        sim = simulate(traj.t, run.commands.q, machine, name, mode="discrete", friction=True,
                       ff_friction=True, inertia_scale=1 + error, damping_scale=1 + error)
        np.testing.assert_array_equal(sim.q_act, run.simulation.q_act)
        summary = contour_errors(reference, sim.q_act, machine.kinematics).summary()
        row = rows[(100 * error, name, kind)]
        assert float(row["inertia_scale"]) == float(row["damping_scale"]) == 1 + error
        for key in ("tip_max_um", "tip_mean_um", "ori_max_mrad", "ori_mean_mrad"):
            assert float(row[key]) == pytest.approx(summary[key], rel=1e-12)
    # a model error changes what the plant does: sliding mode's feed-forward no longer matches
    exact = result.run("smc").contour.summary()["tip_mean_um"]
    for error in result.model_errors:
        off = result.model_error_runs[("smc", "none", error)].contour.summary()["tip_mean_um"]
        assert off > 2 * exact


def test_printed_claim_a2_matches_the_model_error_runs(cli_run):
    result, out, _ = cli_run
    block = _claim_block(out, "a2:p-pi-high")
    pattern = re.compile(rf"^J, B x([0-9.]+): (tip max|tip mean|orientation max|orientation "
                         rf"mean): sliding mode {NUMBER} (um|mrad), P-PI\+contour {NUMBER} "
                         rf"(um|mrad): P-PI\+contour {NUMBER} % (lower|higher)$")
    metrics = {"tip max": "tip_max_um", "tip mean": "tip_mean_um",
               "orientation max": "ori_max_mrad", "orientation mean": "ori_mean_mrad"}
    wins = []
    for line in block[2:]:
        m = pattern.match(line)
        assert m, line
        scale, label, a, _, b, _, pct, word = m.groups()
        error = next(e for e in result.model_errors if f"{1 + e:g}" == scale)
        sliding = result.model_error_runs[("smc", "none", error)].contour.summary()
        ppi = result.model_error_runs[("p-pi-high", "contour", error)].contour.summary()
        key = metrics[label]
        assert float(a) == pytest.approx(sliding[key], rel=6e-4)
        assert float(b) == pytest.approx(ppi[key], rel=6e-4)
        assert word == ("lower" if ppi[key] < sliding[key] else "higher")
        wins.append(ppi[key] < sliding[key])
    assert len(wins) == 4 * len(result.model_errors)
    expected = "holds" if all(wins) else "does not hold" if not any(wins) else "partly holds"
    assert block[1] == f"-> {expected.upper()}"


def test_model_errors_can_be_left_out():
    names = compare.report_file_names("smc", "p-pi-high", ("pid-high",), ())
    assert "model-error.csv" not in names and "fig11:model-error" not in names
    assert "model-error.csv" in compare.report_file_names("smc", "p-pi-high", ())
    # without sliding mode there is nothing to rank under model error
    assert "model-error.csv" not in compare.report_file_names(None, "p-pi-high", ())


def test_tracking_baseline_adds_the_predicted_tracking_errors(cli_run, machine):
    # Spec section 7: q + e(q), e from the closed form -- one pass, applied unconditionally.
    result, _, _ = cli_run
    traj = result.trajectory
    for name in ("p-pi-high", "pid-low"):
        models = machine.error_models(name)
        e = predict_tracking(traj.t, traj.q, models, tol_linear=COMPENSATION_TOL_LINEAR,
                             tol_rotary=COMPENSATION_TOL_ROTARY)(traj.t)
        # its corrections tapered to zero over the final rest, ending at the programmed end
        # (issue 42 item 5)
        np.testing.assert_allclose(result.run(name, "tracking").commands.q,
                                   end_at_programmed_end(traj.q, traj.q + e, traj.ts),
                                   rtol=0, atol=1e-12)


def test_min_passes_keeps_a_pass_that_does_not_improve(cli_run, machine):
    # Under P-PI the tracking baseline makes the predicted contour errors worse on this path:
    # compensate() alone would keep the uncompensated commands; min_passes=1 keeps the pass.
    result, _, _ = cli_run
    traj = result.trajectory
    servo = servo_of(machine, "p-pi-high")
    default = compensate(servo, traj, method="tracking")
    assert default.iterations == 0
    np.testing.assert_array_equal(default.trajectory.q, traj.q)
    kept = result.run("p-pi-high", "tracking").compensation_result
    assert kept.iterations == 1
    assert kept.after.orientation.mean() > kept.before.orientation.mean()
    assert kept.history[1] == kept.after.summary()
    for bad in (-1, 2):
        with pytest.raises(ValueError, match=rf"min_passes must be within 0..1, got {bad}"):
            compensate(servo, traj, min_passes=bad)


def test_band_power_of_two_sinusoids():
    # Sines of amplitudes a and b have mean squares a^2/2 and b^2/2, below and above 10 Hz.
    # At whole numbers of cycles per Welch segment (5.9 and 39 Hz) the Hann-windowed estimate
    # is exact: no leakage across the cut-off, and no mean to remove.
    t = np.arange(4096) * 1e-3
    bin_hz = 1000.0 / compare.WELCH_SEGMENT
    low, high = 3 * bin_hz, 20 * bin_hz
    a, b = 2e-3, 1e-4  # mm
    q = np.zeros((t.size, 5))
    q[:, 0] = a * np.sin(2 * np.pi * low * t) + b * np.sin(2 * np.pi * high * t + 0.3)
    q[:, 3] = b * np.sin(2 * np.pi * high * t)
    ref = Trajectory(t=t, q=np.zeros_like(q))
    spectrum = compare.compensation_spectrum("x", ref, ref.with_axes(q), ref.with_axes(2 * q))
    assert spectrum.band_power("tracking", "X", 10.0) == pytest.approx(1e6 * b**2 / 2, rel=1e-9)
    assert spectrum.total_power("tracking", "X") == pytest.approx(1e6 * (a**2 + b**2) / 2,
                                                                  rel=1e-9)
    assert spectrum.band_power("contour", "X", 10.0) == pytest.approx(4e6 * b**2 / 2, rel=1e-9)
    assert spectrum.band_power("tracking", "A", 10.0) == pytest.approx(1e6 * b**2 / 2, rel=1e-9)
    assert spectrum.band_power("tracking", "XYZ", 10.0) == spectrum.band_power(
        "tracking", "X", 10.0)
    assert spectrum.band_power("tracking", "Y", 10.0) == 0.0


def test_spectra_are_welch_of_the_compensation_signals(cli_run):
    result, _, _ = cli_run
    traj = result.trajectory
    for name, spectrum in result.spectra.items():
        f, psd = signal.welch(result.run(name, "contour").commands.q - traj.q, fs=1000.0,
                              nperseg=compare.WELCH_SEGMENT, window="hann", axis=0)
        np.testing.assert_allclose(spectrum.f, f, rtol=1e-15)
        np.testing.assert_allclose(spectrum.contour, psd, rtol=1e-12, atol=0)
    rows = _csv(result.out_dir / "compensation_spectra.csv")
    for row in rows:
        spectrum = result.spectra[row["controller"]]
        cutoff = float(row["cutoff_hz"])
        keep = spectrum.f >= cutoff
        df = spectrum.f[1] - spectrum.f[0]
        if row["signal"] == "XYZ":
            expected = 1e6 * spectrum.tracking[keep, :3].sum() * df
        else:
            expected = 1e6 * spectrum.tracking[keep, AXES.index(row["signal"])].sum() * df
        assert float(row["tracking_power"]) == pytest.approx(expected, rel=1e-12)
        assert float(row["ratio"]) == pytest.approx(
            float(row["contour_power"]) / float(row["tracking_power"]), rel=1e-12)


def test_command_derivatives_of_a_cubic():
    # Backward differences of c t^3 are exact in the third difference: jerk = 6 c.
    ts = 1e-3
    t = np.arange(50) * ts
    q = np.outer(t**3, [1.0, -2.0, 3.0, 0.5, 0.0])
    v, a, j = compare.command_derivatives(q, ts)
    assert v.shape == (49, 5) and a.shape == (48, 5) and j.shape == (47, 5)
    np.testing.assert_allclose(j, np.tile(6 * np.array([1.0, -2.0, 3.0, 0.5, 0.0]), (47, 1)),
                               rtol=1e-6, atol=1e-6)
    # the second difference at t_k is 6 c (t_k - ts) exactly
    np.testing.assert_allclose(a[:, 0], 6 * (t[2:] - ts), rtol=1e-6, atol=1e-9)


def test_peak_rows_are_the_commands_differences(cli_run):
    result, _, _ = cli_run
    ts = result.trajectory.ts
    rows = _csv(result.out_dir / "command_peaks.csv")
    order = {"velocity": 1, "acceleration": 2, "jerk": 3}
    for row in rows:
        i, n = AXES.index(row["axis"]), order[row["quantity"]]
        before = np.abs(np.diff(result.trajectory.q[:, i], n=n)).max() / ts**n
        after = np.abs(np.diff(result.run(row["controller"], row["compensation"]).commands.q[:, i],
                               n=n)).max() / ts**n
        assert float(row["reference"]) == pytest.approx(before, rel=1e-6)
        assert float(row["compensated"]) == pytest.approx(after, rel=1e-6)
        assert float(row["change_pct"]) == pytest.approx(100 * (after / before - 1), rel=1e-6,
                                                         abs=1e-9)


# --------------------------------------------------------------------------------------------
# Printed answers
# --------------------------------------------------------------------------------------------

def test_printed_contour_table_is_the_measurement(cli_run):
    result, out, err = cli_run
    lines = out.splitlines()
    printed = {(p[0], p[1]): p for p in (line.split() for line in lines)
               if len(p) >= 6 and (p[0], p[1]) in result.runs}
    assert len(printed) == len(result.runs)
    for key, run in result.runs.items():
        values = [float(x) for x in printed[key][-4:]]
        s = run.contour.summary()
        assert values == pytest.approx([s["tip_max_um"], s["tip_mean_um"], s["ori_max_mrad"],
                                        s["ori_mean_mrad"]], rel=6e-4)
    assert f"open {result.out_dir / 'index.html'}" in out
    assert "done in" in err and "writing the report" in err


def _claim_block(out: str, key: str) -> list[str]:
    lines = out.splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith(f"({key}) "))
    block = [lines[start]]
    for line in lines[start + 1:]:
        if not line.startswith("    "):
            break
        block.append(line.strip())
    return block


def test_printed_claims_a_match_the_contour_errors(cli_run):
    result, out, _ = cli_run
    metrics = {"tip max": "tip_max_um", "tip mean": "tip_mean_um",
               "orientation max": "ori_max_mrad", "orientation mean": "ori_mean_mrad"}
    pattern = re.compile(rf"^(tip max|tip mean|orientation max|orientation mean): (\w+) "
                         rf"{NUMBER} (um|mrad), (\w+) {NUMBER} (um|mrad): \w+ {NUMBER} % "
                         rf"(lower|higher)$")
    for name in ("p-pi-high", "pid-high", "pid-low"):
        block = _claim_block(out, f"a:{name}")
        verdict = block[1].removeprefix("-> ").lower()
        wins = []
        tracking = result.run(name, "tracking").contour.summary()
        contour = result.run(name, "contour").contour.summary()
        for line in block[2:]:
            m = pattern.match(line)
            assert m, line
            label, a_name, a, _, b_name, b, _, pct, word = m.groups()
            key = metrics[label]
            assert (a_name, b_name) == ("tracking", "contour")
            assert float(a) == pytest.approx(tracking[key], rel=6e-4)
            assert float(b) == pytest.approx(contour[key], rel=6e-4)
            change = 100 * (contour[key] / tracking[key] - 1)
            assert float(pct) == pytest.approx(abs(change), abs=0.051)
            assert word == ("lower" if change < 0 else "higher")
            wins.append(change < 0)
        assert len(wins) == 4
        assert verdict == ("holds" if all(wins) else "does not hold" if not any(wins)
                           else "partly holds")
        assert result.claim(f"a:{name}").verdict == verdict
    # P-PI: tracking vs none, where the claim is that tracking is worse
    block = _claim_block(out, "a0:p-pi-high")
    worse = [result.run("p-pi-high", "tracking").contour.summary()[k]
             > result.run("p-pi-high").contour.summary()[k] for k in metrics.values()]
    expected = "holds" if all(worse) else "does not hold" if not any(worse) else "partly holds"
    assert block[1] == f"-> {expected.upper()}"


def test_printed_claims_b_match_the_spectra(cli_run):
    result, out, _ = cli_run
    pattern = re.compile(rf"^(X|Y|Z|A|C|XYZ): power above 10 Hz: tracking {NUMBER} "
                         rf"(um\^2|mrad\^2) \({NUMBER} % of its total\), contour {NUMBER} "
                         rf"(um\^2|mrad\^2) \({NUMBER} %\): ratio contour/tracking {NUMBER}$")
    assert compare.SPECTRUM_CUTOFF_HZ == 10.0
    for name in ("p-pi-high", "pid-high", "pid-low"):
        block = _claim_block(out, f"b:{name}")
        spectrum = result.spectra[name]
        wins = []
        matched = 0
        for line in block[2:]:
            m = pattern.match(line)
            if not m:
                continue
            matched += 1
            sig, track, unit, _, cont, _, _, ratio = m.groups()
            expected = {k: spectrum.band_power(k, sig, 10.0) for k in ("tracking", "contour")}
            assert float(track) == pytest.approx(expected["tracking"], rel=6e-4)
            assert float(cont) == pytest.approx(expected["contour"], rel=6e-4)
            assert float(ratio) == pytest.approx(expected["contour"] / expected["tracking"],
                                                 rel=6e-3)
            assert unit == ("mrad^2" if sig in ("A", "C") else "um^2")
            wins.append(expected["contour"] < expected["tracking"])
        assert matched == 6
        verdict = "holds" if all(wins) else "does not hold" if not any(wins) else "partly holds"
        assert block[1] == f"-> {verdict.upper()}"


def test_printed_claims_c_match_the_peaks(cli_run):
    result, out, _ = cli_run
    ts = result.trajectory.ts
    for name in ("p-pi-high", "pid-high", "pid-low"):
        block = _claim_block(out, f"c:{name}")
        q_ref = result.trajectory.q
        q_comp = result.run(name, "contour").commands.q
        changes = []
        for n, quantity in enumerate(("velocity", "acceleration", "jerk"), start=1):
            line = next(x for x in block if x.startswith(f"peak {quantity} change: "))
            printed = dict(re.findall(rf"([XYZAC]) {NUMBER} %", line))
            before = np.abs(np.diff(q_ref, n=n, axis=0)).max(axis=0) / ts**n
            after = np.abs(np.diff(q_comp, n=n, axis=0)).max(axis=0) / ts**n
            for i, axis in enumerate(AXES):
                change = 100 * (after[i] / before[i] - 1)
                assert float(printed[axis]) == pytest.approx(change, abs=0.051)
                changes.append(change)
        within = [abs(c) <= compare.NEARLY_UNCHANGED_PCT for c in changes]
        verdict = "holds" if all(within) else "does not hold" if not any(within) \
            else "partly holds"
        assert block[1] == f"-> {verdict.upper()}"
        largest = max(changes, key=abs)
        assert f"({largest:+.1f} %)" in block[-1]


# --------------------------------------------------------------------------------------------
# Bad input
# --------------------------------------------------------------------------------------------

def _run_cli(args, capsys):
    code = cli.main(["compare", *args])
    err = capsys.readouterr().err.strip().splitlines()
    return code, err


@pytest.mark.parametrize("make_args, match", [
    (lambda d: ["--builtin", "spiral"],
     "field 'builtin': unknown built-in path 'spiral'; choose one of paper, circle, cone, fan"),
    (lambda d: [str(d / "missing.csv")], r"missing\.csv: no such file"),
    (lambda d: [str(d / "noref.csv")], r"noref\.csv, field 'Px': the comparison needs the "
                                       r"reference tool path columns Px,Py,Pz,Oi,Oj,Ok"),
    (lambda d: [str(d / "slow.csv")], r"slow\.csv, field 't': sample period 0\.002 s differs "
                                      r"from the machine's servo period 0\.001 s"),
    (lambda d: ["--machine", "nowhere"], "nowhere"),
])
def test_cli_bad_inputs_exit_2_with_one_line(tmp_path, capsys, make_args, match):
    t = np.arange(50) * 1e-3
    base = {"t": t, "X": t, "Y": 0 * t, "Z": 0 * t, "A": 0 * t, "C": 0 * t}
    write_columns(tmp_path / "noref.csv", base)
    slow = dict(base, t=2 * t, Px=t, Py=0 * t, Pz=0 * t, Oi=0 * t, Oj=0 * t, Ok=1 + 0 * t)
    write_columns(tmp_path / "slow.csv", slow)
    code, err = _run_cli(make_args(tmp_path) + ["--out", str(tmp_path / "out")], capsys)
    assert code == 2
    assert len(err) == 1 and err[0].startswith("precontour: error: ")
    assert re.search(match, err[0]), err[0]
    assert not (tmp_path / "out").exists()


def test_cli_usage_errors_exit_2(tmp_path, paper_csv):
    for args in (["--builtin", "paper", str(paper_csv)], ["--iterations", "0"],
                 ["--model-error", "-5"]):
        with pytest.raises(SystemExit) as exit_info:
            cli.main(["compare", *args, "--out", str(tmp_path / "o")])
        assert exit_info.value.code == 2


@pytest.mark.parametrize("kwargs, error, match", [
    (dict(iterations=0), InputError, "iterations must be a whole number >= 1, got 0"),
    (dict(pids=("pid-high", "pid-high")), InputError, "a controller is named twice"),
    (dict(sliding=None, ppi=None, pids=()), InputError, "no controller to compare"),
    (dict(ppi="smc", sliding=None), InputError,
     "controller 'smc' is not linear: it cannot be pre-compensated"),
    (dict(pids=("pid-medium",)), MachineFileError, "unknown controller 'pid-medium'"),
    (dict(builtin="fan", trajectory="x.csv"), InputError,
     "give a built-in path or a trajectory, not both"),
    (dict(model_errors=(0.2, -1.0)), InputError,
     r"field 'model_errors': model error must be a nonzero fraction above -1"),
    (dict(model_errors=(0.0,)), InputError, "model error must be a nonzero fraction"),
    (dict(model_errors=(0.1, 0.1)), InputError, "a model error is given twice"),
])
def test_run_compare_input_errors(tmp_path, kwargs, error, match):
    with pytest.raises(error, match=match):
        compare_report.run_compare(tmp_path / "out", **kwargs)
    assert not (tmp_path / "out").exists()


def test_run_compare_refuses_a_file_as_output(tmp_path):
    target = tmp_path / "taken"
    target.write_text("x")
    with pytest.raises(InputError, match="taken: the comparison output must be a directory"):
        compare_report.run_compare(target, builtin="fan", sliding=None, ppi=None, pids=("pid-high",))
    assert target.read_text() == "x"


def test_claim_verdicts():
    assert compare._verdict([True, True]) == "holds"
    assert compare._verdict([False, True]) == "partly holds"
    assert compare._verdict([False]) == "does not hold"
    assert compare._verdict([]) == "not measurable"
    assert math.isnan(compare._ratio(0.0, 0.0)) and compare._ratio(1.0, 0.0) == math.inf
