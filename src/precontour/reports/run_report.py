"""Report of ``precontour run`` (:mod:`precontour.workflow`): figures, the end-of-run table
and a self-contained ``index.html`` in a folder.

Figures: simulated contour errors over time, uncompensated vs compensated (the demo's
:func:`~precontour.reports.demo_report.plot_contour`); and the speed along the program as a
fraction of the planned one with each axis's peak jerk against its limit, before and after
the local slow-downs. Only the report's own files are written.
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
from .demo_report import _data_uri, _figure, figure_png, plot_contour, save_png

if TYPE_CHECKING:  # pragma: no cover
    from ..workflow import RunResult

#: Files of a run report, in the folder given.
RUN_REPORT_FILES: tuple[str, ...] = ("contour_errors.png", "speed_and_limits.png",
                                     "summary.txt", "index.html")


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
    commands = result.commands
    contour = plot_contour(commands.t, result.simulated_before, result.simulated_after,
                           title=f"{Path(result.source).name} on {result.machine.name}, "
                                 f"{result.controller}: realistic virtual machine")
    speed = plot_speed_and_limits(result)
    pngs = [figure_png(contour), figure_png(speed)]
    files = [save_png(contour, out / RUN_REPORT_FILES[0]),
             save_png(speed, out / RUN_REPORT_FILES[1])]
    table = result.table()
    files.append(write_text(out / RUN_REPORT_FILES[2], table + "\n"))
    files.append(write_text(out / RUN_REPORT_FILES[3], _html(result, table, pngs)))
    return files


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
<h2>Contour errors on the virtual machine</h2>
<img src="{_data_uri(pngs[0])}" alt="contour errors">
<h2>Speed and limits</h2>
<ul>{slow or "<li>not slowed: the compensated commands kept every limit</li>"}</ul>
<img src="{_data_uri(pngs[1])}" alt="speed and limits">
</body></html>
"""
