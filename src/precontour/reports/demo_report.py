"""Report: figures, tables and an HTML page of the pipeline's results.

The only module that imports matplotlib (Agg, drawn on :class:`matplotlib.figure.Figure`
objects without pyplot's global state). Figure functions take result objects or plain arrays
and return a Figure; table functions take row dicts (:func:`table_rows`) and return or write
text; :func:`write_demo_report` writes the folder of :func:`precontour.reports.demo.run_demo`. Figures
follow the paper's (Zhang, Yuen & Altintas 2013): Fig. 8 (path and axis commands), Fig. 17
(predicted vs measured tracking errors), Figs. 18-19 (contour errors without and with
pre-compensation); the table follows its Tables 3-4 (spec section 7).
"""

from __future__ import annotations

import base64
import csv
import html
import io
import time
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Mapping, Sequence

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator

from ..prediction.contour import ContourErrors
from ..machine.drives import AXES, ROTARY_AXES

from ..files import OutputSet, atomic_write, make_folder
from ..machine.machine_file import Machine
from .demo import MACHINE_MODELS, DemoResult, compute_demo, demo_file_names
from .progress import Progress, ReportSteps

if TYPE_CHECKING:  # pragma: no cover
    from ..trajectory.sampled import Trajectory

#: The paper's measurements on its machine (Tables 3-4; spec section 7): controller ->
#: trajectory kind -> (tip max um, tip mean um, orientation max mrad, orientation mean mrad).
#: They belong to the paper's path on the zhang2013 machine.
PAPER_TABLES: dict[str, dict[str, tuple[float, float, float, float]]] = {
    "pid-high": {"uncompensated": (43.10, 12.60, 0.56, 0.10),
                 "pre-compensated": (20.00, 5.50, 0.27, 0.05)},
    "pid-low": {"uncompensated": (265.26, 85.62, 2.30, 0.70),
                "pre-compensated": (81.37, 26.72, 0.99, 0.30)},
}
PAPER_MACHINE = "zhang2013"
PAPER_PATH = "paper"

#: Values of the table's ``machine`` column and what they mean.
MACHINE_LABELS: dict[str, str] = {
    "paper-measured": "the paper's real machine (Tables 3-4), its own path",
    "realistic": "virtual machine: discrete PID at the servo period with zero-order hold, "
                 "Stribeck friction, feed-forward friction compensation",
    "exact": "virtual machine: the exact linear model (continuous PID, no friction)",
}

#: Numeric columns of the table: (key, header, summary key of ContourErrors.summary()).
VALUE_COLUMNS: tuple[tuple[str, str, str], ...] = (
    ("tip_max_um", "tip max (um)", "tip_max_um"),
    ("tip_mean_um", "tip mean (um)", "tip_mean_um"),
    ("ori_max_mrad", "orientation max (mrad)", "ori_max_mrad"),
    ("ori_mean_mrad", "orientation mean (mrad)", "ori_mean_mrad"),
)
REDUCTION_COLUMNS: tuple[tuple[str, str], ...] = tuple(
    (key.rsplit("_", 1)[0] + "_reduction_pct", header.split(" (")[0] + " reduction (%)")
    for key, header, _ in VALUE_COLUMNS)
#: CSV columns, in order.
TABLE_COLUMNS: tuple[str, ...] = (("path", "controller", "machine", "trajectory")
                                  + tuple(key for key, _, _ in VALUE_COLUMNS)
                                  + tuple(key for key, _ in REDUCTION_COLUMNS))

_UNCOMP, _COMP = "uncompensated", "pre-compensated"
_DPI = 110
#: Titles at a fixed height (matplotlib's default place): left to matplotlib, each title
#: measures every tick label of its axes at every draw to dodge them, a third of the time a
#: figure takes to draw.
_TITLE_Y = 1.0


# --------------------------------------------------------------------------------------------
# Tables
# --------------------------------------------------------------------------------------------

def comparison_rows(path: str, controller: str, machine: str, before: Mapping[str, float],
                    after: Mapping[str, float]) -> list[dict]:
    """Two table rows, uncompensated and pre-compensated, from ``ContourErrors.summary()``
    dicts (um, mrad); the second carries the reductions 100 (1 - after / before) in %."""
    rows = []
    for kind, summary in ((_UNCOMP, before), (_COMP, after)):
        row = dict(path=path, controller=controller, machine=machine, trajectory=kind)
        for key, _, source in VALUE_COLUMNS:
            row[key] = float(summary[source])
        for (key, _), (_, _, source) in zip(REDUCTION_COLUMNS, VALUE_COLUMNS):
            row[key] = (None if kind == _UNCOMP
                        else 100.0 * (1.0 - float(after[source]) / float(before[source])))
        rows.append(row)
    return rows


def paper_rows(controller: str) -> list[dict]:
    """The paper's measured rows for ``controller`` (``pid-high`` / ``pid-low``), or []."""
    if controller not in PAPER_TABLES:
        return []
    before, after = ({source: value for (_, _, source), value in
                      zip(VALUE_COLUMNS, PAPER_TABLES[controller][kind])}
                     for kind in (_UNCOMP, _COMP))
    return comparison_rows(PAPER_PATH, controller, "paper-measured", before, after)


def table_rows(result: "DemoResult") -> list[dict]:
    """The Tables 3/4-style rows of a demo: for each path and controller, the paper's
    measurement (paper path on zhang2013 only), then the realistic and the exact machine,
    each uncompensated then pre-compensated. Keys are :data:`TABLE_COLUMNS`."""
    rows = []
    for case in result.cases:
        if case.path == PAPER_PATH and result.machine.name == PAPER_MACHINE:
            rows.extend(paper_rows(case.controller))
        for model in MACHINE_MODELS:
            rows.extend(comparison_rows(case.path, case.controller, model,
                                        case.run(model, _UNCOMP).contour.summary(),
                                        case.run(model, _COMP).contour.summary()))
    return rows


def _number(value: float | None, published: bool = False) -> str:
    if value is None:
        return ""
    # The paper's numbers as published (two decimals); ours to four significant digits.
    return f"{value:.2f}" if published else f"{value:#.4g}"


def _percent(value: float | None) -> str:
    return "" if value is None else f"{value:.1f}"


def _cells(row: Mapping) -> list[str]:
    return ([row["path"], row["controller"], row["machine"], row["trajectory"]]
            + [_number(row[key], row["machine"] == "paper-measured")
               for key, _, _ in VALUE_COLUMNS]
            + [_percent(row[key]) for key, _ in REDUCTION_COLUMNS])


def format_table(rows: Sequence[Mapping]) -> str:
    """Fixed-width text table of :func:`table_rows` (um, mrad, %), for a terminal."""
    head = ["path", "controller", "machine", "trajectory", "tip max", "tip mean", "ori max",
            "ori mean", "red. tip", "max/mean", "red. ori", "max/mean"]
    units = ["", "", "", "", "um", "um", "mrad", "mrad", "%", "%", "%", "%"]
    body = [_cells(row) for row in rows]
    widths = [max(len(r[i]) for r in [head, units] + body) for i in range(len(head))]
    right = [False] * 4 + [True] * 8

    def line(cells):
        return "  ".join(c.rjust(w) if r else c.ljust(w)
                         for c, w, r in zip(cells, widths, right)).rstrip()
    out = [line(head), line(units), line(["-" * w for w in widths])]
    previous = None
    for row, cells in zip(rows, body):
        group = (row["path"], row["controller"])
        if previous is not None and group != previous:
            out.append("")
        previous = group
        out.append(line(cells))
    return "\n".join(out)


def markdown_table(rows: Sequence[Mapping]) -> str:
    """GitHub-flavoured Markdown table of :func:`table_rows`."""
    head = (["path", "controller", "machine", "trajectory"]
            + [header for _, header, _ in VALUE_COLUMNS]
            + [header for _, header in REDUCTION_COLUMNS])
    lines = ["| " + " | ".join(head) + " |",
             "|" + "|".join(["---"] * 4 + ["---:"] * 8) + "|"]
    lines += ["| " + " | ".join(_cells(row)) + " |" for row in rows]
    return "\n".join(lines)


def write_table_csv(rows: Sequence[Mapping], file: str | Path) -> Path:
    """Write :func:`table_rows` as CSV with the header :data:`TABLE_COLUMNS` (full precision;
    reductions empty on uncompensated rows)."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(TABLE_COLUMNS)
    for row in rows:
        writer.writerow(["" if row[key] is None else (repr(row[key]) if isinstance(row[key], float)
                                                     else row[key]) for key in TABLE_COLUMNS])
    return _write(file, buffer.getvalue().encode())


def write_table_markdown(rows: Sequence[Mapping], file: str | Path) -> Path:
    """Write :func:`markdown_table` with a legend of the ``machine`` column."""
    legend = "\n".join(f"- `{key}`: {text}" for key, text in MACHINE_LABELS.items())
    text = ("Contour errors: tool tip (um) and orientation (mrad), max and mean over the "
            "trajectory; reductions = 100 (1 - pre-compensated / uncompensated).\n\n"
            + markdown_table(rows) + "\n\n" + legend + "\n")
    return _write(file, text.encode())


# --------------------------------------------------------------------------------------------
# Figures
# --------------------------------------------------------------------------------------------

def _figure(width: float, height: float) -> Figure:
    fig = Figure(figsize=(width, height), dpi=_DPI)
    FigureCanvasAgg(fig)
    return fig


def _axis_scale(axis: str) -> tuple[float, str]:
    """Factor and unit that show an axis's errors (mm -> um, rad -> mrad)."""
    return (1e3, "mrad") if axis in ROTARY_AXES else (1e3, "um")


def plot_path(traj: "Trajectory", *, title: str = "", n_arrows: int = 40,
              arrow_length: float = 15.0, axis_names: Sequence[str] = AXES) -> Figure:
    """Fig. 8 of the paper: the reference tool tip in 3-D with tool orientations (left) and
    the five axis commands over time (right).

    Parameters
    ----------
    traj : Trajectory
        With the reference ``P`` (mm) and ``O``.
    n_arrows : int
        About how many orientation vectors to draw.
    arrow_length : float
        Drawn length of an orientation vector, mm.
    axis_names : sequence of str
        The machine's five axis letters (``Machine.axis_names``: B in slot 3 on B-C machines).
    """
    if not traj.has_reference:
        raise ValueError("plot_path needs a trajectory with its reference tool path P, O")
    fig = _figure(13.0, 6.4)
    layout = fig.add_gridspec(len(AXES), 2, width_ratios=(1.15, 1.0), left=0.0, right=0.98,
                              top=0.9, bottom=0.08, wspace=0.22, hspace=0.15)
    ax3 = fig.add_subplot(layout[:, 0], projection="3d")
    P, O = traj.P, traj.O
    ax3.plot(*P.T, color="k", lw=1.4, label="tool tip")
    every = max(1, traj.n_samples // n_arrows)
    ax3.quiver(*P[::every].T, *(arrow_length * O[::every]).T, color="tab:blue", lw=0.8,
               arrow_length_ratio=0.15, label=f"tool orientation ({arrow_length:g} mm)")
    ax3.scatter(*P[0], color="tab:green", s=30, label="start")
    ax3.set_xlabel("x (mm)")
    ax3.set_ylabel("y (mm)")
    ax3.set_zlabel("z (mm)")
    cloud = np.vstack([P, P + arrow_length * O])
    lo, hi = cloud.min(axis=0), cloud.max(axis=0)
    # Equal scales on the three axes, so orientations look as they are.
    span = np.maximum(hi - lo, 0.15 * (hi - lo).max())
    mid = 0.5 * (lo + hi)
    for setter, m, s in zip((ax3.set_xlim, ax3.set_ylim, ax3.set_zlim), mid, span):
        setter(m - s / 2, m + s / 2)
    ax3.set_box_aspect(span)
    for axis, extent in zip((ax3.xaxis, ax3.yaxis, ax3.zaxis), span):
        # a short axis (a flat path) would otherwise crowd its tick labels
        axis.set_major_locator(MaxNLocator(nbins=2 + int(5 * extent / span.max())))
    ax3.legend(loc="upper left", fontsize=8)
    ax3.set_title("tool path (workpiece frame)", fontsize=10)
    units = ["mm", "mm", "mm", "rad", "rad"]
    ax = None
    for i, axis in enumerate(axis_names):
        ax = fig.add_subplot(layout[i, 1], sharex=ax)
        ax.plot(traj.t, traj.q[:, i], lw=1.2)
        ax.set_ylabel(f"{axis} ({units[i]})")
        ax.grid(alpha=0.3)
        if i < len(AXES) - 1:
            ax.tick_params(labelbottom=False)
    ax.set_xlabel("time (s)")
    if title:
        fig.suptitle(title, fontsize=11)
    return fig


def plot_tracking(t: np.ndarray, predicted: np.ndarray, simulated: np.ndarray, *,
                  simulated_label: str = "simulated", title: str = "",
                  axis_names: Sequence[str] = AXES) -> Figure:
    """Fig. 17 of the paper: predicted vs simulated (measured) tracking errors, one panel per
    axis, in um (X, Y, Z) and mrad (A, C).

    Parameters
    ----------
    t : ndarray, shape (N,)
        Time, s.
    predicted, simulated : ndarray, shape (N, 5)
        Tracking errors command - actual, mm and rad.
    """
    t = np.asarray(t, dtype=float)
    predicted = np.asarray(predicted, dtype=float)
    simulated = np.asarray(simulated, dtype=float)
    if predicted.shape != (t.size, len(AXES)) or simulated.shape != predicted.shape:
        raise ValueError(f"tracking errors must have shape ({t.size}, 5); got "
                         f"{predicted.shape} and {simulated.shape}")
    fig = _figure(11.0, 9.0)
    axes = fig.subplots(len(AXES), 1, sharex=True)
    for i, (axis, ax) in enumerate(zip(axis_names, axes)):
        scale, unit = _axis_scale(AXES[i])   # by slot: slot 3 is rotary whatever its letter
        sim, pred = scale * simulated[:, i], scale * predicted[:, i]
        ax.plot(t, sim, color="tab:orange", lw=2.4, alpha=0.6, label=simulated_label)
        ax.plot(t, pred, color="k", lw=0.9, label="predicted (closed form)")
        gap = np.abs(pred - sim).max()
        ax.text(0.995, 0.95, f"max |predicted - {simulated_label.split(' ')[0]}| = {gap:.3g} "
                f"{unit}  (max |e| = {np.abs(sim).max():.3g} {unit})",
                transform=ax.transAxes, ha="right", va="top", fontsize=8,
                bbox=dict(facecolor="white", alpha=0.8, edgecolor="none", pad=1.5))
        ax.set_ylabel(f"e{axis} ({unit})")
        ax.grid(alpha=0.3)
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, 0.955), ncol=2,
               fontsize=9, frameon=False)
    axes[-1].set_xlabel("time (s)")
    if title:
        fig.suptitle(title, fontsize=11)
    fig.subplots_adjust(left=0.09, right=0.98, top=0.92, bottom=0.06, hspace=0.12)
    return fig


def plot_contour(t: np.ndarray, uncompensated: ContourErrors, compensated: ContourErrors, *,
                 exact_compensated: ContourErrors | None = None, label: str = "realistic machine",
                 title: str = "") -> Figure:
    """Figs. 18-19 of the paper: tool tip (um) and orientation (mrad) contour errors over
    time, uncompensated vs pre-compensated.

    Left column: both on one linear scale, as in the paper. Right column: the same on a log
    scale (four decades below the uncompensated peak), so that the pre-compensated errors,
    10 to 1000 times smaller, stay readable; with those of the exact linear model when
    ``exact_compensated`` is given.
    """
    fig = _figure(12.0, 7.4)
    grid = fig.subplots(2, 2, sharex=True)
    rows = (("tip", "tool tip", "um"), ("orientation", "orientation", "mrad"))
    for (attr, name, unit), (left, right) in zip(rows, grid):
        unc = 1e3 * getattr(uncompensated, attr)
        comp = 1e3 * getattr(compensated, attr)
        for ax in (left, right):
            ax.plot(t, unc, color="tab:red", lw=1.0, label=f"uncompensated, {label}")
            ax.plot(t, comp, color="tab:blue", lw=1.0, label=f"pre-compensated, {label}")
            ax.set_ylabel(f"{name} contour error ({unit})")
        left.set_ylim(bottom=0.0)
        left.grid(alpha=0.3)
        left.set_title(f"{name}: max {unc.max():.3g} \u2192 {comp.max():.3g} {unit}, "
                       f"mean {unc.mean():.3g} \u2192 {comp.mean():.3g} {unit}", fontsize=9,
                       y=_TITLE_Y)
        note = ""
        if exact_compensated is not None:
            exact = 1e3 * getattr(exact_compensated, attr)
            right.plot(t, exact, color="k", lw=0.7, ls="--",
                       label="pre-compensated, exact linear model")
            note = f"; exact model: max {exact.max():.3g}, mean {exact.mean():.3g} {unit}"
        right.set_title(f"log scale{note}", fontsize=9, y=_TITLE_Y)
        top = max(unc.max(), comp.max())
        if not top > 0.0:
            # errors that are all zero (the orientation of a program that never turns the
            # tool) have nothing to show on a log scale: any decades will do
            top = 1.0
        # limits first: switching to log autoscales, which warns on data without a positive
        # value
        right.set_ylim(1e-4 * top, 2.0 * top)
        right.set_yscale("log")
        right.grid(alpha=0.3)
    handles, labels = grid[0, 1].get_legend_handles_labels()
    fig.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, 0.955), ncol=3,
               fontsize=9, frameon=False)
    for ax in grid[1]:
        ax.set_xlabel("time (s)")
    if title:
        fig.suptitle(title, fontsize=11)
    fig.subplots_adjust(left=0.07, right=0.98, top=0.87, bottom=0.08, hspace=0.2, wspace=0.2)
    return fig


def figure_png(fig: Figure) -> bytes:
    """PNG bytes of ``fig``."""
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=_DPI)
    return buffer.getvalue()


def save_png(fig: Figure, file: str | Path) -> Path:
    """Write ``fig`` as a PNG file (atomically) and return its path."""
    return _write(file, figure_png(fig))


# --------------------------------------------------------------------------------------------
# The demo folder
# --------------------------------------------------------------------------------------------

def write_demo_report(result: "DemoResult", rows: Sequence[Mapping] | None = None) -> list[Path]:
    """Write the report folder of a demo: one PNG per figure, the table as CSV and Markdown,
    and ``index.html``, which shows the table and the PNG files beside it (linked, not
    embedded: base64 made the page 1.3 MB and took time to write). Overwrites only these
    files.

    Returns the paths written, ``index.html`` last. The files replace the old ones together,
    when all are written (:class:`~precontour.files.OutputSet`).
    """
    with OutputSet():
        return _write_demo_files(result, table_rows(result) if rows is None else rows)


def _write_demo_files(result: "DemoResult", rows: Sequence[Mapping]) -> list[Path]:
    out = make_folder(result.out_dir)
    names = demo_file_names(result.paths, result.controllers)
    written = [write_table_csv(rows, out / names["table.csv"]),
               write_table_markdown(rows, out / names["table.md"])]
    sections = []
    for path in result.paths:
        summary = result.summaries[path]
        traj = result.cases[[c.path for c in result.cases].index(path)].trajectory
        png = figure_png(plot_path(traj, title=(
            f"path '{path}': {summary.duration:.3f} s, {summary.n_samples} samples, peak feed "
            f"{summary.peak_feed:.1f} mm/s on {result.machine.name}"),
            axis_names=result.machine.axis_names))
        written.append(_write(out / names[f"path:{path}"], png))
        figures = [(f"Path '{path}': tool tip and orientations, and the five axis commands "
                    "(like the paper's Fig. 8).", names[f"path:{path}"])]
        for controller in result.controllers:
            case = result.case(path, controller)
            realistic_unc = case.run("realistic", _UNCOMP)
            png = figure_png(plot_contour(
                case.trajectory.t, realistic_unc.contour, case.run("realistic", _COMP).contour,
                exact_compensated=case.run("exact", _COMP).contour,
                title=f"contour errors, path '{path}', controller {controller} "
                      f"({_passes(case.compensation.iterations)})"))
            written.append(_write(out / names[f"contour:{path}:{controller}"], png))
            figures.append((f"Path '{path}', {controller}: contour errors on the realistic "
                            "machine without and with contour pre-compensation (like the "
                            "paper's Figs. 18-19).", names[f"contour:{path}:{controller}"]))
            t = case.trajectory.t
            png = figure_png(plot_tracking(
                t, case.prediction(t), realistic_unc.simulation.e,
                simulated_label="simulated (realistic machine)",
                title=f"tracking errors, path '{path}', controller {controller}, uncompensated",
                axis_names=result.machine.axis_names))
            written.append(_write(out / names[f"tracking:{path}:{controller}"], png))
            figures.append((f"Path '{path}', {controller}: predicted vs simulated axis tracking "
                            "errors of the uncompensated commands (like the paper's Fig. 17).",
                            names[f"tracking:{path}:{controller}"]))
        sections.append((path, figures))
    written.append(_write(out / names["index.html"],
                          _demo_html(result, rows, sections).encode("utf-8")))
    return written


def _passes(n: int) -> str:
    return "uncompensated kept: no pass improved" if n == 0 else (
        f"{n} compensation pass" + ("es" if n > 1 else ""))


def _data_uri(png: bytes) -> str:
    return "data:image/png;base64," + base64.b64encode(png).decode("ascii")


def _html_table(rows: Sequence[Mapping]) -> str:
    head = (["path", "controller", "machine", "trajectory"]
            + [header for _, header, _ in VALUE_COLUMNS]
            + [header for _, header in REDUCTION_COLUMNS])
    out = ["<table>", "<tr>" + "".join(f"<th>{html.escape(h)}</th>" for h in head) + "</tr>"]
    for row in rows:
        cls = ' class="paper"' if row["machine"] == "paper-measured" else ""
        cells = _cells(row)
        out.append(f"<tr{cls}>" + "".join(
            f'<td class="{"num" if i >= 4 else "txt"}">{html.escape(c)}</td>'
            for i, c in enumerate(cells)) + "</tr>")
    out.append("</table>")
    return "\n".join(out)


def _demo_html(result: "DemoResult", rows, sections) -> str:
    machine = result.machine
    kin = machine.kinematics
    geometry = ", ".join(f"{name} = {getattr(kin, name):g} mm" for name in ("L_ac", "L_ty")
                         if hasattr(kin, name))
    paths = "".join(
        f"<li><b>{html.escape(p)}</b>: {s.duration:.3f} s, {s.n_samples} samples at "
        f"{s.ts * 1e3:g} ms, peak feed {s.peak_feed:.1f} mm/s</li>"
        for p, s in result.summaries.items())
    controllers = "".join(
        f"<li><b>{html.escape(name)}</b>: closed-loop -3 dB bandwidth "
        + ", ".join(f"{axis} {bw:.1f} Hz"
                    for axis, bw in zip(machine.axis_names, result.bandwidths[name]))
        + "</li>" for name in result.controllers)
    legend = "".join(f"<li><code>{html.escape(k)}</code>: {html.escape(v)}</li>"
                     for k, v in MACHINE_LABELS.items())
    timing = result.timings or {}
    body = [
        "<h1>precontour demo: contour-error pre-compensation on a virtual five-axis machine</h1>",
        "<h2>Setup</h2>",
        f"<p>Machine <b>{html.escape(machine.name)}</b> ({html.escape(machine.description)}); "
        f"A-C trunnion kinematics, {geometry}; servo period {machine.servo_period * 1e3:g} ms. "
        "Each path is turned into a jerk-limited trajectory within the axis limits; each "
        "axis's tracking error is predicted in closed form from its linear closed-loop model; "
        f"the commands are contour pre-compensated (up to {result.iterations} pass(es), "
        "orientation first, then tool tip); and both the uncompensated and the pre-compensated "
        "commands are run on two virtual machines, whose actual motion is measured against "
        "the reference path.</p>",
        f"<ul>{legend}</ul>",
        f"<p>Paths:</p><ul>{paths}</ul>",
        f"<p>Controllers (PID, Table 1 of the paper):</p><ul>{controllers}</ul>",
        "<p>The paper's rows are measurements on its real machine and its own (unpublished) "
        "path; the built-in path 'paper' only resembles it, and the virtual machine lacks "
        "backlash, gear and screw compliance, which the paper names as the source of the "
        "errors left after compensation. All other numbers were measured in this run"
        + (f" (computed in {timing['compute']:.1f} s)" if "compute" in timing else "")
        + ".</p>",
        "<h2>Contour errors (the paper's Tables 3-4)</h2>",
        "<p>Tool tip in um, orientation in mrad; max and mean over the trajectory; "
        "reductions = 100 (1 - pre-compensated / uncompensated) %.</p>",
        _html_table(rows),
    ]
    for path, figures in sections:
        body.append(f"<h2>Path '{html.escape(path)}'</h2>")
        for caption, file_name in figures:
            body.append(f'<figure><img src="{html.escape(file_name)}" '
                        f'alt="{html.escape(caption)}">'
                        f"<figcaption>{html.escape(caption)}</figcaption></figure>")
    style = ("body{font-family:sans-serif;max-width:1320px;margin:1em auto;padding:0 1em;"
             "color:#222}table{border-collapse:collapse;font-size:13px}"
             "th,td{border:1px solid #ccc;padding:2px 6px}td.num{text-align:right;"
             "font-variant-numeric:tabular-nums}tr.paper{background:#f3f3f3;font-style:italic}"
             "img{max-width:100%}figure{margin:1.5em 0}figcaption{font-size:13px;color:#555}")
    return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            "<title>precontour demo</title>"
            f"<style>{style}</style></head><body>\n" + "\n".join(body) + "\n</body></html>\n")


def _write(file: str | Path, data: bytes) -> Path:
    """Write bytes through a temporary file and a rename, so a reader never sees half."""
    return atomic_write(file, data)


def run_demo(out_dir: str | Path, *, paths: tuple[str, ...] = ("paper",),
             controllers: tuple[str, ...] = ("pid-high", "pid-low"), iterations: int = 1,
             machine: str | Path | Machine = "zhang2013",
             progress: Progress | None = None) -> DemoResult:
    """Run the paper's evaluation on the virtual machine and write the report folder.

    Parameters are those of :func:`precontour.reports.demo.compute_demo`. Returns the
    :class:`DemoResult` with its table rows and the files written (``index.html`` last).
    """
    steps = ReportSteps(progress)
    result = compute_demo(out_dir, paths=paths, controllers=controllers,
                          iterations=iterations, machine=machine, progress=steps)
    computed = time.perf_counter()
    steps.step("writing the report")
    rows = table_rows(result)
    files = write_demo_report(result, rows)
    end = time.perf_counter()
    timings = result.timings
    timings.update(report=end - computed, total=timings["compute"] + end - computed)
    steps.finish(f"done in {timings['total']:.1f} s")
    return replace(result, rows=rows, files=tuple(files))
