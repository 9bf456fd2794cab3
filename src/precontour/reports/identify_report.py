"""Report of an identification (:mod:`precontour.identification.identify`): Bode plots of the
identified vs the base closed loops, measured vs modelled tracking errors and their residuals
per axis, the summary table, and an ``index.html`` with everything embedded. Axes are named by
the machine's letters (``residuals_B.png``, "axis B" on a B-C machine).
"""

from __future__ import annotations

import html
from pathlib import Path

import numpy as np
from scipy import signal

from ..files import OutputSet, make_folder
from ..machine.drives import AXES
from .demo_report import _axis_scale, _data_uri, _figure, _write, figure_png

#: Bode plot frequency range, Hz.
BODE_RANGE = (0.5, 500.0)


def identify_report_files(axes=AXES) -> tuple[str, ...]:
    """The files of an identification report whose identified axes are ``axes`` (the
    machine's letters; all five of ``Machine.axis_names`` for every file it may write)."""
    return ("bode.png",) + tuple(f"residuals_{axis}.png" for axis in axes) + ("index.html",)


#: Every file an identification report of an X Y Z A C machine may write.
IDENTIFY_REPORT_FILES: tuple[str, ...] = identify_report_files()


def plot_bode(result) -> "Figure":  # noqa: F821
    """|x/X| and phase of the identified and the base closed loop of every axis."""
    fig = _figure(10, 6)
    mag_ax, phase_ax = fig.subplots(2, 1, sharex=True)
    f = np.geomspace(*BODE_RANGE, 400)
    w = 2 * np.pi * f
    models = result.identified_models()
    for i, axis in enumerate(result.axis_names):
        color = f"C{i}"
        for model, style, label in ((models[i], "-", f"{axis} identified"),
                                    (result.base_models[i], ":", f"{axis} base")):
            _, h = signal.freqs(np.polysub(model.den, model.num), model.den, w)
            mag_ax.semilogx(f, 20 * np.log10(np.abs(h)), style, color=color, label=label)
            phase_ax.semilogx(f, np.degrees(np.unwrap(np.angle(h))), style, color=color)
    mag_ax.axhline(-3, color="grey", lw=0.5)
    mag_ax.set_ylabel("|x/X| (dB)")
    mag_ax.set_ylim(-30, 10)
    mag_ax.legend(ncol=5, fontsize=7)
    phase_ax.set_ylabel("phase (deg)")
    phase_ax.set_xlabel("frequency (Hz)")
    mag_ax.set_title(f"closed loops: {result.name} (solid) vs {result.base_controller.name} (dotted)")
    fig.tight_layout()
    return fig


def plot_residuals(result, axis: str) -> "Figure":  # noqa: F821
    """Measured vs modelled tracking error of one axis (a q slot, a key of ``result.axes``)
    over the log, and their difference."""
    fit = result.axes[axis]
    name = result.letter(axis)
    t = result.log.t
    e = result.log.command[axis] - result.log.actual[axis]
    scale, unit = _axis_scale(axis)
    fig = _figure(10, 5)
    top, bottom = fig.subplots(2, 1, sharex=True)
    top.plot(t, e * scale, lw=0.6, label="measured e")
    top.plot(t, fit.e_model * scale, lw=0.6, label="identified model")
    top.axvline(t[fit.holdout_start], color="grey", ls="--", lw=0.8, label="held-out part starts")
    top.set_ylabel(f"e {name} ({unit})")
    top.legend(fontsize=7)
    bottom.plot(t, (fit.e_model - e) * scale, lw=0.6, color="tab:red")
    bottom.set_ylabel(f"model - measured ({unit})")
    bottom.set_xlabel("t (s)")
    top.set_title(f"axis {name}: order {fit.order}, fit {fit.fit_pct:.2f} % of max|e| "
                  f"(held-out {fit.holdout_pct:.2f} %)")
    fig.tight_layout()
    return fig


def _rows_html(result) -> str:
    head = ["axis", "order", "fit % max|e|", "held-out %", "bandwidth Hz", "base bandwidth Hz",
            "poles rad/s", "base poles rad/s"]
    out = ["<table>", "<tr>" + "".join(f"<th>{h}</th>" for h in head) + "</tr>"]
    fmt = lambda p: ", ".join(f"{z:.4g}" for z in np.sort_complex(p))  # noqa: E731
    for row in result.summary_rows():
        cells = [row["axis"], row.get("order", "base"),
                 f"{row['fit_pct']:.2f}" if "fit_pct" in row else "-",
                 f"{row['holdout_pct']:.2f}" if "holdout_pct" in row else "-",
                 f"{row['bw']:.2f}", f"{row['base_bw']:.2f}", fmt(row["poles"]),
                 fmt(row["base_poles"])]
        out.append("<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in cells) + "</tr>")
    out.append("</table>")
    return "\n".join(out)


def write_identify_report(result, out_dir: str | Path) -> Path:
    """Write ``bode.png``, ``residuals_<axis>.png`` and ``index.html`` to ``out_dir`` (created
    if missing; only these files are overwritten, all together: an
    :class:`~precontour.files.OutputSet`). Returns the path of ``index.html``."""
    out = Path(out_dir)
    names = identify_report_files(tuple(result.letter(axis) for axis in result.axes))
    figures = [(names[0], "Closed loops x/X, identified vs base", figure_png(plot_bode(result)))]
    for name, axis in zip(names[1:-1], result.axes):
        figures.append((name, f"Axis {result.letter(axis)}: tracking error, measured vs model",
                        figure_png(plot_residuals(result, axis))))
    outputs = OutputSet()
    out = outputs.folder(out, names, what="identification report")
    with outputs:
        return _write_report(result, out, figures)


def _write_report(result, out: Path, figures) -> Path:
    make_folder(out)
    for name, _, png in figures:
        _write(out / name, png)
    notes = "".join(f"<li>{html.escape(n)}</li>" for n in result.notes.values())
    physical = "".join(
        f"<li>{html.escape(result.letter(a))}: J {p.J:.4g} kg m^2, B {p.B:.4g} kg m^2/s, torque fit "
        f"{p.torque_fit_pct:.2f} % ({p.windows} windows)</li>" for a, p in result.physical.items())
    body = [f"<h1>Identification: {html.escape(result.name)}</h1>",
            f"<p>Log {html.escape(result.log.source)}: {result.log.n_samples} samples at "
            f"{result.log.period * 1e3:.6g} ms. Base machine {html.escape(result.base.name)}, "
            f"base controller {html.escape(result.base_controller.name)}. Fit errors are the "
            "largest |model - measured| tracking error in % of the largest measured |e|, on "
            "the samples in the linear regime (away from rests and reversals).</p>",
            _rows_html(result)]
    if notes:
        body.append(f"<ul>{notes}</ul>")
    if physical:
        body.append(f"<h2>Drives from motor currents</h2><ul>{physical}</ul>")
    for name, caption, png in figures:
        body.append(f'<figure><img src="{_data_uri(png)}" alt="{html.escape(caption)}">'
                    f"<figcaption>{html.escape(caption)}</figcaption></figure>")
    style = ("body{font-family:sans-serif;max-width:1100px;margin:auto}table{border-collapse:"
             "collapse}td,th{border:1px solid #ccc;padding:2px 6px;font-size:13px}img{width:100%}")
    page = ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>precontour "
            f"identify</title><style>{style}</style></head><body>\n" + "\n".join(body)
            + "\n</body></html>\n")
    return _write(out / "index.html", page.encode("utf-8"))
