"""Figures of library results, for their ``.plot()`` methods (python-control's style:
results plot themselves, and matplotlib stays in ``reports/``).

:func:`plot_contour_errors` draws tool tip and orientation contour errors against time for
any number of labelled :class:`~precontour.prediction.ContourErrors` on the same samples;
:func:`plot_tracking_errors` the axes' tracking errors (linear in um, rotary in urad).
"""

from __future__ import annotations

from typing import Mapping

import numpy as np

from ..machine.drives import AXES
from ..prediction.contour import ContourErrors

#: Colours of the labels, in order (uncompensated first, as in every report).
COLOURS = ("tab:red", "tab:blue", "tab:green", "tab:orange", "tab:purple")


def plot_contour_errors(t: np.ndarray, errors: Mapping[str, ContourErrors], *,
                        title: str | None = None, axes=None):
    """Tip (um, top) and orientation (mrad, bottom) contour errors against time ``t`` (s),
    one line per entry of ``errors`` (label -> ContourErrors on the samples ``t``).
    ``axes``: two matplotlib axes to draw into (default: a new figure). Returns the figure."""
    t = np.asarray(t, dtype=float)
    for label, e in errors.items():
        if e.tip.shape != t.shape:
            raise ValueError(f"{label}: {e.tip.size} samples, the times have {t.size}")
    if axes is None:
        from matplotlib.figure import Figure

        fig = Figure(figsize=(8.0, 5.4), layout="constrained")
        axes = fig.subplots(2, 1, sharex=True)
    else:
        fig = axes[0].figure
    tip_ax, ori_ax = axes
    for (label, e), colour in zip(errors.items(), COLOURS):
        tip_ax.plot(t, 1e3 * e.tip, color=colour, lw=0.9,
                    label=f"{label}: max {1e3 * e.tip.max():.3g} um")
        ori_ax.plot(t, 1e3 * e.orientation, color=colour, lw=0.9,
                    label=f"{label}: max {1e3 * e.orientation.max():.3g} mrad")
    tip_ax.set_ylabel("tool tip contour error (um)")
    ori_ax.set_ylabel("orientation error (mrad)")
    ori_ax.set_xlabel("time (s)")
    for ax in axes:
        ax.legend(fontsize=8, frameon=False)
        ax.grid(True, lw=0.3)
    if title:
        tip_ax.set_title(title, fontsize=10)
    return fig


def plot_tracking_errors(t: np.ndarray, e: np.ndarray, *, axis_names=AXES,
                         contour: ContourErrors | None = None, title: str | None = None,
                         axes=None):
    """Tracking errors ``e`` (N, 5; mm, rad) against time ``t`` (s): the linear axes in um
    (top), the rotary ones in urad (below), and, where ``contour`` is given, the tip and
    orientation contour errors beneath. ``axes``: matplotlib axes to draw into, one per row
    (default: a new figure). Returns the figure."""
    t = np.asarray(t, dtype=float)
    e = np.asarray(e, dtype=float)
    if e.shape != (t.size, 5):
        raise ValueError(f"tracking errors of shape {e.shape}, the times have {t.size}")
    rows = 2 if contour is None else 4
    if axes is None:
        from matplotlib.figure import Figure

        fig = Figure(figsize=(8.0, 2.5 * rows), layout="constrained")
        axes = fig.subplots(rows, 1, sharex=True)
    else:
        fig = axes[0].figure
    for ax, slots, scale, unit in ((axes[0], range(3), 1e3, "um"),
                                   (axes[1], range(3, 5), 1e6, "urad")):
        for i, colour in zip(slots, COLOURS):
            ax.plot(t, scale * e[:, i], color=colour, lw=0.9,
                    label=f"{axis_names[i]}: max |e| {scale * np.abs(e[:, i]).max():.3g} {unit}")
        ax.set_ylabel(f"tracking error ({unit})")
    if contour is not None:
        plot_contour_errors(t, {"contour error": contour}, axes=axes[2:4])
    axes[rows - 1].set_xlabel("time (s)")
    for ax in axes[:2]:
        ax.legend(fontsize=8, frameon=False)
        ax.grid(True, lw=0.3)
    if title:
        axes[0].set_title(title, fontsize=10)
    return fig
