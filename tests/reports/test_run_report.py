"""The figures of ``run``'s report: the envelope of the contour errors against a brute-force
maximum per window, and a long program's plot (its size and that it warns of nothing)."""

from __future__ import annotations

import warnings
from types import SimpleNamespace

import numpy as np
import pytest

from precontour.reports.run_report import (ENVELOPE_WINDOWS, plot_contour_envelope,
                                           window_peaks)
from precontour.workflow import largest_error


@pytest.mark.parametrize("n, windows", [(7, 600), (600, 600), (601, 600), (10_007, 600),
                                        (1_000_000, 600), (5, 2)])
def test_window_peaks_are_the_maximum_of_each_window(n, windows):
    rng = np.random.default_rng(n)
    t = 1e-3 * np.arange(n)
    values = rng.random(n)
    edges, peaks = window_peaks(t, values, windows)
    assert peaks.size == min(n, windows) and edges.size == peaks.size + 1
    # each sample holds for one period: the last window ends a period after the last sample
    assert edges[0] == t[0] and edges[-1] == pytest.approx(t[-1] + 1e-3, abs=1e-12)
    assert np.all(np.diff(edges) > 0)
    # brute force: every sample belongs to the window whose start it is at or after
    owner = np.searchsorted(edges[:-1], t, side="right") - 1
    for k in range(0, peaks.size, max(1, peaks.size // 50)):
        assert peaks[k] == values[owner == k].max()
    assert peaks.max() == values.max()
    sizes = np.bincount(owner)
    assert sizes.max() - sizes.min() <= 1  # windows of (about) equal length


def _fake_result(t, tip_before, tip_after, ori_before, ori_after, line):
    """What plot_contour_envelope reads of a RunResult."""
    errors = (SimpleNamespace(tip=tip_before, orientation=ori_before),
              SimpleNamespace(tip=tip_after, orientation=ori_after))

    def largest_errors():
        return tuple(largest_error(getattr(e, q), t, line, quantity=q, commands=c)
                     for c, e in (("compensated", errors[1]), ("uncompensated", errors[0]))
                     for q in ("tip", "orientation"))

    return SimpleNamespace(limited=SimpleNamespace(reference=SimpleNamespace(t=t)),
                           simulated_before=errors[0], simulated_after=errors[1],
                           largest_errors=largest_errors, source="long.ngc",
                           machine=SimpleNamespace(name="zhang2013"), controller="pid-high")


def test_long_program_plot_is_an_envelope_and_warns_of_nothing():
    """460 s at 1 kHz, as the long program of the issue; no rotary motion (orientation
    errors all zero, where a log axis has nothing to show) must not warn."""
    n = 460_000
    t = 1e-3 * np.arange(n)
    rng = np.random.default_rng(1)
    tip_before = 1e-3 * (5 + rng.random(n))
    tip_after = 1e-4 * rng.random(n)
    tip_after[123_456] = 2e-3  # one spike: the largest remaining error
    zeros = np.zeros(n)
    line = 10 + np.arange(n) // 1000
    result = _fake_result(t, tip_before, tip_after, zeros, zeros, line)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        fig = plot_contour_envelope(result)
        fig.canvas.draw()
    envelope, zoom, ori_envelope, ori_zoom = fig.axes
    stairs = [a for a in envelope.patches]
    assert len(stairs) == 2
    for artist in stairs:
        assert len(artist.get_data().values) <= ENVELOPE_WINDOWS
    assert "line 133, t = 123.456 s" in envelope.get_title()
    assert "line 133, t = 123.456 s" in zoom.get_title()
    # the zoom shows the samples around the spike, not the whole program
    x = zoom.lines[0].get_xdata()  # ms from the spike
    assert x[0] < 0 < x[-1] and x[-1] - x[0] < 1000.0
    np.testing.assert_array_equal(zoom.lines[1].get_ydata()[x == 0], [2.0])  # um
    assert ori_envelope.get_yscale() == "linear"
    assert "nowhere (zero throughout)" in ori_envelope.get_title() + ori_zoom.get_title()
    assert largest_error(zeros, t, line, quantity="orientation", commands="compensated"
                         ).format().split()[-5:] == ["-", "t", "=", "0.000", "s"]
    assert envelope.get_yscale() == "log"
