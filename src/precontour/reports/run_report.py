"""Report of ``precontour run`` (:mod:`precontour.workflow`): figures, the end-of-run table
and a self-contained ``index.html`` in a folder.

Figures: simulated contour errors, uncompensated vs compensated, as an envelope over the whole
program (the largest error in each of at most :data:`ENVELOPE_WINDOWS` time windows, so that an
hour-long program stays readable) with a zoom on the samples around the largest remaining
errors, named by source line and time (:func:`plot_contour_envelope`); and the speed along the
program as a fraction of the planned one with each axis's peak jerk against its limit, before
and after the local slow-downs. The summary and the page name the line and time of the largest
errors (:meth:`~precontour.workflow.RunResult.largest_errors`). With a contour-error tolerance
(``run --tolerance``), also the feed along the path of the three variants with their errors
under the tolerance band (:func:`plot_feed_within_tolerance`). Only the report's own files are
written.
"""

from __future__ import annotations

import html
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from matplotlib.figure import Figure

from ..machine.drives import AXES
from ..tables import write_text
from ..trajectory.limits import AxisLimits, check_limits
from .demo_report import _data_uri, _figure, figure_png, save_png

if TYPE_CHECKING:  # pragma: no cover
    from ..workflow import LargestError, RunResult

#: Files of a run report, in the folder given.
RUN_REPORT_FILES: tuple[str, ...] = ("contour_errors.png", "speed_and_limits.png",
                                     "summary.txt", "index.html")
#: The further figure of a run with a contour-error tolerance (``run --tolerance``).
FEED_FIGURE = "feed_within_tolerance.png"


def run_report_files(tolerance: bool = False) -> tuple[str, ...]:
    """The files of a run report: :data:`RUN_REPORT_FILES`, and :data:`FEED_FIGURE` for a
    run with a contour-error tolerance."""
    return RUN_REPORT_FILES + ((FEED_FIGURE,) if tolerance else ())


#: Largest number of time windows of the envelope plot: a few per pixel column of the figure.
ENVELOPE_WINDOWS = 600
#: Half width of the zoom around the largest remaining error, s: at least this, and at least
#: ZOOM_SAMPLES samples, at most the whole program.
ZOOM_HALF_WIDTH = 0.1
ZOOM_SAMPLES = 50
#: Decades shown below the top of a log axis; smaller errors are drawn at its floor.
LOG_DECADES = 4


def window_peaks(t: np.ndarray, values: np.ndarray, windows: int = ENVELOPE_WINDOWS
                 ) -> tuple[np.ndarray, np.ndarray]:
    """The largest value in each of at most ``windows`` runs of consecutive samples of about
    equal length: ``(edges, peaks)``, ``edges`` the ``len(peaks) + 1`` window bounds in time.
    Each sample holds for one sampling period: a window ends where the next begins, the last
    one sampling period after ``t[-1]``."""
    n = t.size
    starts = np.unique(np.linspace(0, n, min(windows, n) + 1).astype(np.int64)[:-1])
    peaks = np.maximum.reduceat(values, starts)
    step = (t[-1] - t[0]) / (n - 1) if n > 1 else 1.0
    edges = np.append(t[starts], t[-1] + step)
    return edges, peaks


def plot_contour_envelope(result: "RunResult") -> Figure:
    """Simulated contour errors of ``run``, uncompensated and compensated, tip (top) and
    orientation (bottom). Left: the largest error per time window over the whole program
    (:func:`window_peaks`), log scale, the largest of each marked. Right: every sample around
    the largest remaining (compensated) error, with its source line and time."""
    t = result.limited.reference.t
    largest = {(e.quantity, e.commands): e for e in result.largest_errors()}
    fig = _figure(12.0, 7.4)
    grid = fig.subplots(2, 2, gridspec_kw={"width_ratios": [3, 2]})
    rows = (("tip", "tool tip", "um"), ("orientation", "orientation", "mrad"))
    for (attr, name, unit), (left, right) in zip(rows, grid):
        before = 1e3 * getattr(result.simulated_before, attr)
        after = 1e3 * getattr(result.simulated_after, attr)
        top = max(float(before.max()), float(after.max()))
        for label, values, color in (("uncompensated", before, "tab:red"),
                                     ("compensated", after, "tab:blue")):
            edges, peaks = window_peaks(t, values)
            left.stairs(_floored(peaks, top), edges, baseline=None, color=color, lw=1.0,
                        label=f"{label}, largest per {_window_label(edges)}")
            worst = largest[(attr, label)]
            left.plot([worst.time], [_floored(1e3 * worst.value, top)], "v", color=color,
                      ms=6)
        _scale(left, top)
        left.set_ylabel(f"{name} contour error ({unit})")
        left.set_xlim(t[0], edges[-1])
        worst = largest[(attr, "compensated")]
        left.set_title(f"{name}: max {before.max():.3g} \u2192 {after.max():.3g} {unit}; "
                       f"largest remaining at {_where(worst)}", fontsize=9)
        span = _zoom(t, worst.index)
        # time from the largest remaining error, in ms: absolute times of a long program
        # would crowd the ticks
        for label, values, color in (("uncompensated", before, "tab:red"),
                                     ("compensated", after, "tab:blue")):
            right.plot(1e3 * (t[span] - worst.time), _floored(values[span], top), color=color,
                       lw=1.0)
        right.axvline(0.0, color="k", lw=0.6, ls=":")
        _scale(right, top)
        right.set_title(f"zoom: {_where(worst)}", fontsize=9)
    handles, labels = grid[0, 0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="upper center", bbox_to_anchor=(0.5, 0.955), ncol=2,
               fontsize=9, frameon=False)
    grid[1, 0].set_xlabel("time (s)")
    grid[1, 1].set_xlabel("time from the largest remaining error (ms)")
    fig.suptitle(f"{Path(result.source).name} on {result.machine.name}, {result.controller}: "
                 "realistic virtual machine", fontsize=11)
    fig.subplots_adjust(left=0.07, right=0.98, top=0.87, bottom=0.08, hspace=0.25, wspace=0.15)
    return fig


def _floored(values, top: float):
    """Values drawn on a log axis: at least its floor (zero errors, at rest, included)."""
    return np.maximum(values, _floor(top))


def _floor(top: float) -> float:
    return 10.0 ** -LOG_DECADES * top if top > 0 else 1.0


def _scale(ax, top: float) -> None:
    """A log axis LOG_DECADES decades deep under ``top``; linear when every error is zero
    (no motion of that kind), where a log axis has nothing to show."""
    if top > 0:
        ax.set_yscale("log")
        ax.set_ylim(_floor(top), 2.0 * top)
    else:
        ax.set_ylim(0.0, 2.0)
    ax.grid(alpha=0.3)


def _zoom(t: np.ndarray, k: int) -> slice:
    half = max(ZOOM_HALF_WIDTH, ZOOM_SAMPLES * (t[1] - t[0]) if t.size > 1 else 0.0)
    first, last = np.searchsorted(t, [t[k] - half, t[k] + half])
    return slice(int(first), int(max(last, first + 1)))


def _where(largest: "LargestError") -> str:
    if largest.value == 0:
        return "nowhere (zero throughout)"
    at = f"{largest.where} {largest.line}, " if largest.line is not None else ""
    return f"{at}t = {largest.time:.3f} s"


def _window_label(edges: np.ndarray) -> str:
    width = float(np.median(np.diff(edges)))
    return f"{1e3 * width:.3g} ms" if width < 1.0 else f"{width:.3g} s"


def plot_speed_and_limits(result: "RunResult") -> Figure:
    """Left: speed as a fraction of the planned speed over the planned time (1 where not
    slowed). Right: each axis's peak velocity, acceleration and jerk as % of its limit, for
    the uncompensated, the first compensated and the final commands."""
    limited = result.limited
    ts = limited.reference.ts
    fig = _figure(11.0, 3.8)
    left, right = fig.subplots(1, 2, gridspec_kw={"width_ratios": [3, 2]})
    planned_t = limited.reference.t[0] + limited.planned_index * ts
    speed = np.ones(planned_t.size)
    speed[1:] = np.diff(limited.planned_index)
    left.plot(planned_t, 100 * speed, color="tab:blue", lw=1.0)
    left.set_xlabel("planned time (s)")
    left.set_ylabel("speed (% of planned)")
    left.set_ylim(0, 105)
    left.set_title(f"{len(limited.slowdowns)} slowed window(s), +{limited.added_time:.3f} s")
    limits = AxisLimits.from_machine(result.machine)
    checks = [("uncompensated", check_limits(result.planned.q, ts, limits)),
              ("compensated, first", limited.first_check),
              ("compensated, final", limited.check)]
    width = 0.27
    x = np.arange(len(AXES))
    for i, (label, check) in enumerate(checks):
        with np.errstate(divide="ignore", invalid="ignore"):
            peak = 100 * check.peaks["jerk"] / limits.jerk
        right.bar(x + (i - 1) * width, np.nan_to_num(peak), width, label=label)
    right.axhline(100, color="k", lw=0.8)
    right.set_xticks(x, AXES)
    right.set_ylabel("peak jerk (% of limit)")
    right.legend(fontsize=7)
    fig.tight_layout()
    return fig


def write_run_report(result: "RunResult", out_dir: str | Path) -> list[Path]:
    """Write the report files (:data:`RUN_REPORT_FILES`) into ``out_dir`` (created)."""
    out = Path(out_dir)
    out.mkdir(parents=False, exist_ok=True)
    contour = plot_contour_envelope(result)
    speed = plot_speed_and_limits(result)
    pngs = [figure_png(contour), figure_png(speed)]
    files = [save_png(contour, out / RUN_REPORT_FILES[0]),
             save_png(speed, out / RUN_REPORT_FILES[1])]
    if result.feed is not None:
        feed = plot_feed_within_tolerance(result)
        pngs.append(figure_png(feed))
        files.append(save_png(feed, out / FEED_FIGURE))
    table = result.table()
    files.append(write_text(out / RUN_REPORT_FILES[2], table + "\n"))
    files.append(write_text(out / RUN_REPORT_FILES[3], _html(result, table, pngs)))
    return files


#: Points per curve of the feed figure (peaks of windows of samples along the path).
FEED_POINTS = 2000


def _along_path(traj, values: np.ndarray, points: int = FEED_POINTS):
    """``values`` per sample against the tool tip's distance along the path (mm): the
    largest in each of at most ``points`` windows of samples."""
    step = np.linalg.norm(np.diff(traj.P, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(step)])
    starts = np.unique(np.linspace(0, s.size, min(points, s.size) + 1).astype(np.int64)[:-1])
    return s[starts], np.maximum.reduceat(values, starts)


def _feed_of(traj) -> np.ndarray:
    """Tool tip speed at each sample, mm/s (the step before it; the first copies the next)."""
    v = np.linalg.norm(np.diff(traj.P, axis=0), axis=1) / traj.ts
    return np.concatenate([v[:1], v]) if v.size else np.zeros(traj.n_samples)


def plot_feed_within_tolerance(result: "RunResult") -> Figure:
    """``run --tolerance``: the tool tip feed along the path as programmed, uncompensated
    within the tolerance and compensated within it (top), and the contour errors of the
    two searches (the worst draw at each sample) under the tolerance band (below: tip, and
    orientation when bounded), against the distance along the path."""
    feed = result.feed
    bounded = feed.tolerance.orientation is not None
    fig = _figure(11.0, 7.6 if bounded else 5.6)
    axes = fig.subplots(3 if bounded else 2, 1, sharex=True)
    variants = (("as programmed", feed.programmed, None, "0.5"),
                ("uncompensated within tolerance", feed.baseline.reference, feed.baseline,
                 "tab:red"),
                ("compensated within tolerance", feed.compensated.reference, feed.compensated,
                 "tab:blue"))
    for label, traj, search, color in variants:
        s, v = _along_path(traj, _feed_of(traj))
        axes[0].plot(s, v, color=color, lw=1.0, label=f"{label}: {traj.duration:,.3f} s")
        if search is None:
            continue
        for ax, attr, limit in ((axes[1], "tip", feed.tolerance.tip),
                                (axes[2] if bounded else None, "orientation",
                                 feed.tolerance.orientation)):
            if ax is None:
                continue
            s, e = _along_path(traj, getattr(search.errors, attr))
            ax.plot(s, 1e3 * e, color=color, lw=1.0)
    axes[0].set_ylabel("tool tip feed (mm/s)")
    axes[0].legend(fontsize=8, loc="upper right")
    axes[0].set_title(f"{Path(result.source).name} on {result.machine.name}, "
                      f"{result.controller}: fastest within {feed.tolerance.describe()} "
                      f"(compensated {100 * (1 - feed.ratio):.1f} % shorter than "
                      "uncompensated)", fontsize=10)
    for ax, limit, name, unit in ((axes[1], feed.tolerance.tip, "tip", "um"),
                                  (axes[2] if bounded else None, feed.tolerance.orientation,
                                   "orientation", "mrad")):
        if ax is None:
            continue
        ax.axhspan(0.0, 1e3 * limit, color="tab:green", alpha=0.12, lw=0)
        ax.axhline(1e3 * limit, color="tab:green", lw=1.0, label="tolerance")
        ax.set_ylabel(f"{name} contour error ({unit})")
        ax.set_ylim(0.0, 1.5e3 * limit)
        ax.legend(fontsize=8, loc="upper right")
    for ax in axes:
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("distance along the tool tip path (mm)")
    fig.tight_layout()
    return fig


def _html(result: "RunResult", table: str, pngs: list[bytes]) -> str:
    slow = "".join(f"<li>{html.escape(s.format())}</li>" for s in result.limited.slowdowns)
    return f"""<!DOCTYPE html>
<html><head><meta charset="utf-8"><title>precontour run: {html.escape(result.source)}</title>
<style>body{{font-family:sans-serif;max-width:1100px;margin:2em auto}}
pre{{background:#f4f4f4;padding:1em}}img{{max-width:100%}}</style></head><body>
<h1>precontour run: {html.escape(Path(result.source).name)}</h1>
<p>Machine <b>{html.escape(result.machine.name)}</b>, controller
<b>{html.escape(result.controller)}</b>; contour pre-compensation
({result.limited.result.iterations} pass(es)) within the machine's axis limits
({result.limited.rounds} compensation round(s)); checked on the realistic virtual machine
(discrete controller at the servo period, friction, feed-forward friction compensation).</p>
<pre>{html.escape(table)}</pre>
<h2>Where the largest errors are</h2>
{_largest_table(result)}
<h2>Contour errors on the virtual machine</h2>
<img src="{_data_uri(pngs[0])}" alt="contour errors">
<h2>Speed and limits</h2>
<ul>{slow or "<li>not slowed: the compensated commands kept every limit</li>"}</ul>
<img src="{_data_uri(pngs[1])}" alt="speed and limits">
{_feed_html(pngs)}</body></html>
"""


def _feed_html(pngs: list[bytes]) -> str:
    if len(pngs) < 3:
        return ""
    return (f'<h2>Feed within the tolerance</h2>\n<img src="{_data_uri(pngs[2])}" '
            'alt="feed within the tolerance">\n')


def _largest_table(result: "RunResult") -> str:
    rows = ["<table><tr><th>error</th><th>commands</th><th>largest</th><th>where</th>"
            "<th>time (s)</th></tr>"]
    for e in result.largest_errors():
        digits = 3 if e.quantity == "tip" else 4
        where = f"{e.where} {e.line}" if e.line is not None else "-"
        rows.append(f"<tr><td>{e.quantity}</td><td>{e.commands}</td>"
                    f"<td>{1e3 * e.value:.{digits}f} {e.unit}</td><td>{where}</td>"
                    f"<td>{e.time:.3f}</td></tr>")
    return "\n".join(rows + ["</table>"])
