"""Report of the comparison (:mod:`precontour.reports.compare`): figures like the paper's Figs. 11-16,
its tables as CSV and Markdown, the claims' measured answers, and a self-contained HTML page.

Like :mod:`precontour.reports.demo_report`, whose helpers it uses, it draws on
:class:`matplotlib.figure.Figure` objects (Agg, no pyplot); only these two modules import
matplotlib.
"""

from __future__ import annotations

import csv
import html
import io
import time
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Mapping, Sequence

import numpy as np
from matplotlib.figure import Figure

from .compare import (report_file_names, COMPENSATIONS, DEFAULT_MODEL_ERRORS, _g, DERIVATIVES, MACHINE_OPTIONS, METRICS, NEARLY_UNCHANGED_PCT,
                      SPECTRUM_CUTOFF_HZ, SPECTRUM_SIGNALS, WELCH_SEGMENT, Spectrum,
                      CompareResult, command_derivatives, compute_compare)
from ..prediction.contour import ContourErrors
from ..machine.drives import AXES, ROTARY_AXES
from .demo_report import _axis_scale, _data_uri, _figure, _write, figure_png

from .progress import Progress, ReportSteps
from ..files import OutputSet, make_folder

if TYPE_CHECKING:  # pragma: no cover
    from ..machine.machine_file import Machine
    from ..trajectory.sampled import Trajectory

#: Line colours of the compensation kinds and of the sliding-mode controller.
COLORS: dict[str, str] = {"none": "tab:red", "tracking": "tab:orange", "contour": "tab:blue",
                          "sliding": "tab:green"}
LABELS: dict[str, str] = {"none": "uncompensated", "tracking": "tracking-error pre-comp.",
                          "contour": "contour-error pre-comp."}

CONTOUR_COLUMNS: tuple[str, ...] = (
    ("controller", "compensation", "passes") + tuple(m for m, _, _ in METRICS)
    + tuple(f"predicted_{m}" for m, _, _ in METRICS))
SPECTRUM_COLUMNS: tuple[str, ...] = ("controller", "signal", "unit", "cutoff_hz",
                                     "tracking_power", "contour_power", "ratio",
                                     "tracking_share_pct", "contour_share_pct")
PEAK_COLUMNS: tuple[str, ...] = ("controller", "compensation", "axis", "quantity", "unit",
                                 "reference", "compensated", "change_pct")
CLAIM_COLUMNS: tuple[str, ...] = ("key", "verdict", "question", "numbers")
MODEL_ERROR_COLUMNS: tuple[str, ...] = (
    ("model_error_pct", "inertia_scale", "damping_scale", "controller", "compensation")
    + tuple(m for m, _, _ in METRICS))


# --------------------------------------------------------------------------------------------
# Figures
# --------------------------------------------------------------------------------------------

def plot_contour_comparison(t: np.ndarray, curves: Sequence[tuple[str, ContourErrors, str]], *,
                            linear_skip: Sequence[str] = (), title: str = "") -> Figure:
    """Figs. 11, 12, 15 of the paper: tool tip (um) and orientation (mrad) contour errors over
    time of several runs, on a linear scale (left) and a log scale (right, four decades below
    the largest peak), the legend giving each run's max and mean.

    Parameters
    ----------
    t : ndarray, shape (N,)
        Time, s.
    curves : sequence of (label, ContourErrors, colour)
    linear_skip : sequence of str
        Labels of curves drawn on the log scale only (ones that would squash the others).
    """
    fig = _figure(12.5, 7.6)
    grid = fig.subplots(2, 2, sharex=True)
    rows = (("tip", "tool tip", "um"), ("orientation", "orientation", "mrad"))
    for (attr, name, unit), (left, right) in zip(rows, grid):
        top = np.finfo(float).tiny
        for label, errors, color in curves:
            values = 1e3 * getattr(errors, attr)
            top = max(top, values.max())
            if label not in linear_skip:
                left.plot(t, values, color=color, lw=1.0)
            right.plot(t, values, color=color, lw=1.0,
                       label=f"{label}: max {values.max():.3g}, mean {values.mean():.3g} {unit}")
        for ax in (left, right):
            ax.set_ylabel(f"{name} contour error ({unit})")
            ax.grid(alpha=0.3)
        left.set_ylim(bottom=0.0)
        left.set_title(f"{name}, linear scale"
                       + (f" (without {', '.join(linear_skip)})" if linear_skip else ""),
                       fontsize=9)
        right.set_yscale("log")
        # two decades of headroom keep the legend off the curves
        right.set_ylim(1e-4 * top, 100.0 * top)
        right.set_title(f"{name}, log scale", fontsize=9)
        right.legend(loc="upper right", fontsize=7.5, framealpha=0.85)
    for ax in grid[1]:
        ax.set_xlabel("time (s)")
    if title:
        fig.suptitle(title, fontsize=11)
    fig.subplots_adjust(left=0.07, right=0.98, top=0.9, bottom=0.07, hspace=0.18, wspace=0.2)
    return fig


def plot_axis_errors(t: np.ndarray, curves: Sequence[tuple[str, np.ndarray, str]], *,
                     title: str = "") -> Figure:
    """Fig. 14 of the paper: each axis's error (reference command minus actual) over time for
    several runs, in um (X, Y, Z) and mrad (A, C), each panel listing the runs' max |e|.

    Parameters
    ----------
    t : ndarray, shape (N,)
    curves : sequence of (label, errors of shape (N, 5) in mm and rad, colour)
    """
    fig = _figure(11.5, 9.5)
    axes = fig.subplots(len(AXES), 1, sharex=True)
    for i, (axis, ax) in enumerate(zip(AXES, axes)):
        scale, unit = _axis_scale(axis)
        peaks = []
        for k, (label, errors, color) in enumerate(curves):
            values = scale * np.asarray(errors)[:, i]
            # the first run wide and pale, so that runs lying on it stay visible
            ax.plot(t, values, color=color, lw=3.0 if k == 0 else 1.0,
                    alpha=0.45 if k == 0 else 1.0, label=label)
            peaks.append(f"{label.split(' ')[0]} {np.abs(values).max():.3g}")
        lo, hi = ax.get_ylim()
        ax.set_ylim(lo, hi + 0.3 * (hi - lo))  # room for the text above the curves
        ax.text(0.995, 0.95, f"max |e| ({unit}): " + ", ".join(peaks), transform=ax.transAxes,
                ha="right", va="top", fontsize=8,
                bbox=dict(facecolor="white", alpha=0.85, edgecolor="none", pad=1.5))
        ax.set_ylabel(f"e{axis} ({unit})")
        ax.grid(alpha=0.3)
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, 0.955),
               ncol=len(curves), fontsize=9, frameon=False)
    axes[-1].set_xlabel("time (s)")
    if title:
        fig.suptitle(title, fontsize=11)
    fig.subplots_adjust(left=0.09, right=0.98, top=0.91, bottom=0.06, hspace=0.12)
    return fig


def plot_spectra(spectrum: Spectrum, *, cutoff_hz: float = SPECTRUM_CUTOFF_HZ,
                 f_max: float = 150.0, title: str = "") -> Figure:
    """Fig. 13 of the paper: power spectral densities of the two compensation signals
    (q_comp - q_ref) of each axis and of the linear axes together, log scale, the band above
    ``cutoff_hz`` shaded and its power written in each panel."""
    fig = _figure(13.0, 7.4)
    grid = fig.subplots(2, 3, sharex=True)
    shown = spectrum.f <= f_max
    f = spectrum.f[shown]
    for sig, ax in zip(SPECTRUM_SIGNALS, grid.ravel()):
        unit = "mrad" if sig in ROTARY_AXES else "um"
        top = np.finfo(float).tiny
        for kind in ("tracking", "contour"):
            psd = spectrum.psd(kind, sig)
            top = max(top, psd.max())
            ax.plot(f, psd[shown], color=COLORS[kind], lw=1.2, label=LABELS[kind])
        ax.axvspan(cutoff_hz, f_max, color="0.9", zorder=0)
        power = {k: spectrum.band_power(k, sig, cutoff_hz) for k in ("tracking", "contour")}
        if top > np.finfo(float).tiny:
            ax.set_yscale("log")
            # nine decades: below that the PSDs are rounding noise
            ax.set_ylim(1e-9 * top, 5.0 * top)
            ratio = _g(power["contour"] / power["tracking"]) if power["tracking"] > 0 else "-"
            text = (f"power above {cutoff_hz:g} Hz ({unit}$^2$):\ntracking "
                    f"{_g(power['tracking'])}\ncontour {_g(power['contour'])}\nratio {ratio}")
        else:
            text = "both compensation signals are zero"
        ax.text(0.98, 0.97, text, transform=ax.transAxes, ha="right", va="top",
                fontsize=8, bbox=dict(facecolor="white", alpha=0.85, edgecolor="none", pad=1.5))
        name = "X, Y, Z together" if sig == "XYZ" else sig
        ax.set_title(name, fontsize=9)
        ax.set_ylabel(f"PSD ({unit}$^2$/Hz)")
        ax.grid(alpha=0.3)
        ax.set_xlim(0.0, f_max)
    for ax in grid[1]:
        ax.set_xlabel("frequency (Hz)")
    handles, labels = grid[0, 0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, 0.95), ncol=2,
               fontsize=9, frameon=False)
    if title:
        fig.suptitle(title, fontsize=11)
    fig.subplots_adjust(left=0.07, right=0.98, top=0.87, bottom=0.08, hspace=0.2, wspace=0.28)
    return fig


def plot_command_derivatives(t: np.ndarray, reference: np.ndarray,
                             compensated: Sequence[tuple[str, np.ndarray]], *,
                             axis: str = "X", title: str = "") -> Figure:
    """Fig. 16 of the paper: velocity, acceleration and jerk (backward differences at the
    sample period) of one axis command before and after contour pre-compensation, one column
    per controller, each panel titled with the peak before -> after.

    Parameters
    ----------
    t : ndarray, shape (N,)
    reference : ndarray, shape (N, 5)
        Reference axis commands.
    compensated : sequence of (controller, commands of shape (N, 5))
    """
    i = AXES.index(axis)
    ts = float(t[1] - t[0])
    ref = command_derivatives(reference, ts)
    fig = _figure(4.6 * max(1, len(compensated)) + 1.0, 8.0)
    grid = np.asarray(fig.subplots(3, max(1, len(compensated)), sharex=True, squeeze=False))
    for col, (name, q) in enumerate(compensated):
        comp = command_derivatives(q, ts)
        for row, ((quantity, lin, rot), d_ref, d_comp) in enumerate(zip(DERIVATIVES, ref, comp)):
            ax = grid[row, col]
            unit = rot if axis in ROTARY_AXES else lin
            tt = t[row + 1:]
            ax.plot(tt, d_ref[:, i], color="k", lw=2.2, alpha=0.35, label="reference command")
            ax.plot(tt, d_comp[:, i], color=COLORS["contour"], lw=0.8,
                    label="contour pre-compensated")
            before, after = np.abs(d_ref[:, i]).max(), np.abs(d_comp[:, i]).max()
            ax.set_title(f"{name}: peak {before:.4g} \u2192 {after:.4g} "
                         f"({100 * (after / before - 1):+.1f} %)", fontsize=9)
            ax.grid(alpha=0.3)
            if col == 0:
                ax.set_ylabel(f"{axis} {quantity} ({unit})")
            if row == 2:
                ax.set_xlabel("time (s)")
    handles, labels = grid[0, 0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, 0.95), ncol=2,
               fontsize=9, frameon=False)
    if title:
        fig.suptitle(title, fontsize=11)
    fig.subplots_adjust(left=0.08, right=0.98, top=0.87, bottom=0.07, hspace=0.25, wspace=0.25)
    return fig


# --------------------------------------------------------------------------------------------
# Tables
# --------------------------------------------------------------------------------------------

def claim_rows(result: "CompareResult") -> list[dict]:
    """The claims as rows: ``key, verdict, question, numbers`` (lines joined by "; ")."""
    return [dict(key=c.key, verdict=c.verdict, question=c.question, numbers="; ".join(c.lines))
            for c in result.claims]


def write_rows_csv(rows: Sequence[Mapping], columns: Sequence[str], file: str | Path) -> Path:
    """Write rows as CSV with the header ``columns`` (floats at full precision, None empty)."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(columns)
    for row in rows:
        writer.writerow(["" if row[key] is None else repr(row[key])
                         if isinstance(row[key], float) else row[key] for key in columns])
    return _write(file, buffer.getvalue().encode())


def _cell(value) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        return f"{value:#.4g}"
    return str(value)


def markdown_rows(rows: Sequence[Mapping], columns: Sequence[str]) -> str:
    """A GitHub-flavoured Markdown table of ``rows`` (numbers to four significant digits)."""
    lines = ["| " + " | ".join(columns) + " |",
             "|" + "|".join("---:" if rows and isinstance(rows[0][c], (int, float))
                            and not isinstance(rows[0][c], bool) else "---"
                            for c in columns) + "|"]
    lines += ["| " + " | ".join(_cell(row[c]) for c in columns) + " |" for row in rows]
    return "\n".join(lines)


def format_contour_table(rows: Sequence[Mapping]) -> str:
    """Fixed-width text table of the measured contour errors (um, mrad), for a terminal."""
    head = ["controller", "compensation", "passes", "tip max", "tip mean", "ori max",
            "ori mean"]
    units = ["", "", "", "um", "um", "mrad", "mrad"]
    body = [[r["controller"], r["compensation"], "" if r["passes"] is None else str(r["passes"])]
            + [f"{r[m]:#.4g}" for m, _, _ in METRICS] for r in rows]
    widths = [max(len(x[i]) for x in [head, units] + body) for i in range(len(head))]

    def line(cells):
        return "  ".join(c.ljust(w) if i < 2 else c.rjust(w)
                         for i, (c, w) in enumerate(zip(cells, widths))).rstrip()
    return "\n".join([line(head), line(units), line(["-" * w for w in widths])]
                     + [line(b) for b in body])


# --------------------------------------------------------------------------------------------
# The report folder
# --------------------------------------------------------------------------------------------

def compare_file_names(result: "CompareResult") -> dict[str, str]:
    """Names of the files the report writes, keyed by role (figures ``fig11`` ... ``fig16``,
    possibly one per controller as ``fig12:<name>``; tables; ``compare.md``; ``index.html``
    last)."""
    return report_file_names(result.sliding, result.ppi, result.pids, result.model_errors)


def _figures(result: "CompareResult") -> list[tuple[str, str, bytes]]:
    """(role, caption, PNG bytes) of every figure."""
    t = result.trajectory.t
    where = f"{result.source}, realistic machine"
    out = []

    def contour_curves(name, kinds, prefix=""):
        return [(prefix + LABELS[k], result.run(name, k).contour, COLORS[k]) for k in kinds]

    if result.sliding and result.ppi:
        curves = ([(f"sliding mode ({result.sliding})", result.run(result.sliding).contour,
                    COLORS["sliding"]),
                   (f"P-PI ({result.ppi})", result.run(result.ppi).contour, COLORS["none"]),
                   ("P-PI + contour pre-comp.", result.run(result.ppi, "contour").contour,
                    COLORS["contour"])])
        out.append(("fig11", "Contour errors: sliding mode vs P-PI vs P-PI with contour "
                    "pre-compensation (like the paper's Fig. 11).",
                    figure_png(plot_contour_comparison(
                        t, curves, title=f"contour errors, {where}: sliding mode vs P-PI"))))
        if result.model_errors:
            error = result.model_errors[0]

            def off_model(name, kind):
                return result.model_error_runs[(name, kind, error)].contour
            curves = ([(f"sliding mode ({result.sliding})", off_model(result.sliding, "none"),
                        COLORS["sliding"]),
                       (f"P-PI ({result.ppi})", off_model(result.ppi, "none"), COLORS["none"]),
                       ("P-PI + contour pre-comp.", off_model(result.ppi, "contour"),
                        COLORS["contour"])])
            out.append(("fig11:model-error", "Fig. 11 again on a plant whose J and B are "
                        f"{100 * error:+g} % off the model both controllers use (claim a2; "
                        "every model error's numbers are in the model-error table).",
                        figure_png(plot_contour_comparison(
                            t, curves, title=f"contour errors, {where}, plant J, B "
                                             f"x{1 + error:g}: sliding mode vs P-PI"))))
    for name in result.pids:
        out.append((f"fig12:{name}", f"{name}: contour errors with tracking-error vs "
                    "contour-error pre-compensation (like the paper's Fig. 12).",
                    figure_png(plot_contour_comparison(
                        t, contour_curves(name, COMPENSATIONS), linear_skip=(LABELS["none"],),
                        title=f"contour errors, {where}, {name}"))))
        out.append((f"fig13:{name}", f"{name}: spectra of the two compensation signals "
                    f"q_comp - q_ref (Welch, Hann, {WELCH_SEGMENT}-sample segments); shaded: "
                    f"above {SPECTRUM_CUTOFF_HZ:g} Hz (like the paper's Fig. 13).",
                    figure_png(plot_spectra(
                        result.spectra[name],
                        title=f"compensation signals q_comp - q_ref, {result.source}, {name}"))))
    if result.ppi:
        name = result.ppi
        curves = [(LABELS[k], result.run(name, k).axis_errors, COLORS[k]) for k in COMPENSATIONS]
        out.append(("fig14", f"{name}: axis errors (reference command - actual) without, with "
                    "tracking-error and with contour-error pre-compensation (like the paper's "
                    "Fig. 14).", figure_png(plot_axis_errors(
                        t, curves, title=f"axis errors q_ref - q_act, {where}, {name}"))))
        out.append(("fig15", f"{name}: contour errors without, with tracking-error and with "
                    "contour-error pre-compensation (like the paper's Fig. 15).",
                    figure_png(plot_contour_comparison(
                        t, contour_curves(name, COMPENSATIONS),
                        title=f"contour errors, {where}, {name}"))))
    if result.linear:
        commands = [(name, result.run(name, "contour").commands.q) for name in result.linear]
        out.append(("fig16", "Velocity, acceleration and jerk of the X command before and "
                    "after contour pre-compensation, one column per controller (like the "
                    "paper's Fig. 16).", figure_png(plot_command_derivatives(
                        t, result.trajectory.q, commands,
                        title=f"X command before and after contour pre-compensation, "
                              f"{result.source}"))))
    return out


def _setup_lines(result: "CompareResult") -> list[str]:
    s = result.summary
    return [
        f"Machine {result.machine.name}, realistic virtual machine: each control law runs "
        "discretely at the servo period with zero-order hold, Stribeck friction in the "
        f"drives, feed-forward friction compensation (simulate options {MACHINE_OPTIONS}).",
        "Controllers: sliding mode " + (result.sliding or "(not run)") + "; P-PI "
        + (result.ppi or "(not run)") + "; PID " + (", ".join(result.pids) or "(not run)")
        + ".",
        f"Trajectory: {result.source}, {s.duration:.3f} s, {s.n_samples} samples at "
        f"{s.ts * 1e3:g} ms, peak feed {s.peak_feed:.1f} mm/s.",
        "Compensations: none; axis tracking-error pre-compensation (the paper's single pass: "
        "each command plus its predicted tracking error); contour-error pre-compensation (up "
        f"to {result.iterations} pass(es)). Each method's first pass is applied even when it "
        "does not improve the prediction.",
        f"Spectra: Welch PSD (Hann window, {WELCH_SEGMENT}-sample segments, half overlap) of "
        f"q_comp - q_ref; power above a cut-off = PSD integrated from the cut-off to fs/2 "
        f"(mean square); claim (b) uses {SPECTRUM_CUTOFF_HZ:g} Hz, chosen before measuring.",
        "Derivatives: backward differences of the sampled commands at the sample period; "
        f"'nearly unchanged' = peak within {NEARLY_UNCHANGED_PCT:g} %.",
    ]


def compare_markdown(result: "CompareResult") -> str:
    """The comparison's Markdown page (``compare.md``): set-up, the paper's claims as
    measured, and the tables."""
    parts = ["# Comparison of compensation methods and controllers", ""]
    parts += [f"- {line}" for line in _setup_lines(result)]
    parts += ["", "## The paper's claims, measured", ""]
    for c in result.claims:
        parts += [f"**({c.key})** {c.question} **{c.verdict.upper()}**", ""]
        parts += [f"- {line}" for line in c.lines] + [""]
    parts += ["## Contour errors (um, mrad); measured on the virtual machine, and predicted",
              "", markdown_rows(result.contour_rows, CONTOUR_COLUMNS), "",
              "## Power of the compensation signals above each cut-off", "",
              markdown_rows(result.spectrum_rows, SPECTRUM_COLUMNS), "",
              "## Peak velocity, acceleration and jerk of the axis commands", "",
              markdown_rows(result.peak_rows, PEAK_COLUMNS), ""]
    if result.model_error_rows:
        parts += ["## Sliding mode and P-PI when the plant's J and B are off the model "
                  "(claim a2; um, mrad)", "",
                  markdown_rows(result.model_error_rows, MODEL_ERROR_COLUMNS), ""]
    return "\n".join(parts)


def _html_rows(rows: Sequence[Mapping], columns: Sequence[str]) -> str:
    out = ["<table>", "<tr>" + "".join(f"<th>{html.escape(c)}</th>" for c in columns) + "</tr>"]
    for row in rows:
        out.append("<tr>" + "".join(
            f'<td class="{"num" if isinstance(row[c], (int, float)) else "txt"}">'
            f"{html.escape(_cell(row[c]))}</td>" for c in columns) + "</tr>")
    out.append("</table>")
    return "\n".join(out)


def _html(result: "CompareResult", figures) -> str:
    body = ["<h1>precontour: compensation methods and controllers compared</h1>",
            "<h2>Setup</h2>",
            "<ul>" + "".join(f"<li>{html.escape(line)}</li>" for line in _setup_lines(result))
            + "</ul>",
            "<h2>The paper's claims, measured</h2>"]
    for c in result.claims:
        cls = c.verdict.replace(" ", "-")
        body.append(f'<div class="claim"><p><b>({html.escape(c.key)})</b> '
                    f"{html.escape(c.question)} <span class=\"{cls}\">"
                    f"{html.escape(c.verdict.upper())}</span></p><ul>"
                    + "".join(f"<li>{html.escape(line)}</li>" for line in c.lines)
                    + "</ul></div>")
    body += ["<h2>Contour errors</h2>",
             "<p>Tool tip in um, orientation in mrad; measured on the realistic virtual "
             "machine, and predicted by the closed-form model (linear controllers).</p>",
             _html_rows(result.contour_rows, CONTOUR_COLUMNS), "<h2>Figures</h2>"]
    for _, caption, png in figures:
        body.append(f'<figure><img src="{_data_uri(png)}" alt="{html.escape(caption)}">'
                    f"<figcaption>{html.escape(caption)}</figcaption></figure>")
    body += ["<h2>Power of the compensation signals above each cut-off</h2>",
             _html_rows(result.spectrum_rows, SPECTRUM_COLUMNS),
             "<h2>Peak velocity, acceleration and jerk of the axis commands</h2>",
             _html_rows(result.peak_rows, PEAK_COLUMNS)]
    if result.model_error_rows:
        body += ["<h2>Sliding mode and P-PI when the plant's J and B are off the model</h2>",
                 "<p>Claim a2: both controllers use the nominal model (sliding mode feeds it "
                 "forward, the pre-compensation predicts with it); the plant's J and B are "
                 "scaled. Tool tip in um, orientation in mrad.</p>",
                 _html_rows(result.model_error_rows, MODEL_ERROR_COLUMNS)]
    timing = result.timings or {}
    if "compute" in timing:
        body.append(f"<p>Computed in {timing['compute']:.1f} s.</p>")
    style = ("body{font-family:sans-serif;max-width:1320px;margin:1em auto;padding:0 1em;"
             "color:#222}table{border-collapse:collapse;font-size:13px}"
             "th,td{border:1px solid #ccc;padding:2px 6px}td.num{text-align:right;"
             "font-variant-numeric:tabular-nums}img{max-width:100%}figure{margin:1.5em 0}"
             "figcaption{font-size:13px;color:#555}.claim ul{font-size:13px}"
             ".holds{color:#17642a;font-weight:bold}.partly-holds{color:#8a5a00;"
             "font-weight:bold}.does-not-hold{color:#a11;font-weight:bold}")
    return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            "<title>precontour comparison</title>"
            f"<style>{style}</style></head><body>\n" + "\n".join(body) + "\n</body></html>\n")


def write_compare_report(result: "CompareResult") -> list[Path]:
    """Write the comparison's folder: one PNG per figure, the tables as CSV, ``compare.md``
    (claims and tables) and ``index.html`` with everything embedded. Overwrites only these
    files, all together when all are written (:class:`~precontour.files.OutputSet`); returns
    their paths, ``index.html`` last."""
    with OutputSet():
        return _write_compare_files(result)


def _write_compare_files(result: "CompareResult") -> list[Path]:
    out = make_folder(result.out_dir)
    names = compare_file_names(result)
    figures = _figures(result)
    written = [_write(out / names[role], png) for role, _, png in figures]
    written += [
        write_rows_csv(result.contour_rows, CONTOUR_COLUMNS, out / names["contour.csv"]),
        write_rows_csv(result.spectrum_rows, SPECTRUM_COLUMNS, out / names["spectra.csv"]),
        write_rows_csv(result.peak_rows, PEAK_COLUMNS, out / names["peaks.csv"]),
        write_rows_csv(claim_rows(result), CLAIM_COLUMNS, out / names["claims.csv"]),
        *([write_rows_csv(result.model_error_rows, MODEL_ERROR_COLUMNS,
                          out / names["model-error.csv"])] if "model-error.csv" in names else []),
        _write(out / names["compare.md"], compare_markdown(result).encode("utf-8")),
        _write(out / names["index.html"], _html(result, figures).encode("utf-8")),
    ]
    return written


def run_compare(out_dir: str | Path, *, builtin: str | None = None,
                trajectory: "str | Path | Trajectory | None" = None,
                machine: "str | Path | Machine" = "zhang2013", iterations: int = 1,
                sliding: str | None = "smc", ppi: str | None = "p-pi-high",
                pids: Sequence[str] = ("pid-high", "pid-low"),
                model_errors: Sequence[float] = DEFAULT_MODEL_ERRORS,
                progress: "Progress | None" = None) -> "CompareResult":
    """Compare controllers and compensation methods on the realistic virtual machine and write
    the report folder. Parameters are those of
    :func:`precontour.reports.compare.compute_compare`; returns the :class:`CompareResult`
    with the files written (``index.html`` last)."""
    steps = ReportSteps(progress)
    result = compute_compare(out_dir, builtin=builtin, trajectory=trajectory,
                             machine=machine, iterations=iterations, sliding=sliding,
                             ppi=ppi, pids=pids, model_errors=model_errors, progress=steps)
    computed = time.perf_counter()
    steps.step("writing the report")
    files = write_compare_report(result)
    end = time.perf_counter()
    result.timings.update(report=end - computed, total=result.timings["compute"] + end - computed)
    steps.finish(f"done in {result.timings['total']:.1f} s")
    return replace(result, files=tuple(files))
