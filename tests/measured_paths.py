"""The test paths of ``scripts/measure_compensation.py`` that the tests use too (``fan25``,
``flank``): written once here, for the tests that measure on them."""

from __future__ import annotations

import numpy as np
from scipy.interpolate import make_interp_spline

from precontour.toolpath import ToolPath


def tilted(tilt_x, tilt_y):
    """Unit tool orientations tilted by ``tilt_x`` about x and ``tilt_y`` about y (rad)."""
    O = np.stack([np.sin(tilt_y), np.sin(tilt_x) * np.cos(tilt_y),
                  np.cos(tilt_x) * np.cos(tilt_y)], axis=1)
    return O / np.linalg.norm(O, axis=1, keepdims=True)


def fan25():
    """scripts/measure_compensation.py's `fan25`: the tip reverses in x mid-path, the tool
    fans about x through vertical and ends while still turning (unlike the built-in paths)."""
    u = np.linspace(0.0, 1.0, 25)
    P = np.stack([20.0 * np.sin(np.pi * u), 60.0 * u - 30.0, 4.0 * np.sin(2 * np.pi * u)], axis=1)
    return ToolPath(P=P, O=tilted(0.5 * np.sin(1.75 * np.pi * u), 0.1 + 0.15 * u))


def flank():
    """scripts/measure_compensation.py's `flank`: flank milling between two B-spline curves."""
    s = np.linspace(0.0, 1.0, 40)
    knots = np.linspace(0.0, 1.0, 6)
    lower = make_interp_spline(knots, np.array(
        [[-40, -10, 0], [-20, 8, 2], [0, 12, 0], [20, 4, -3], [35, -12, 0], [45, -25, 2.0]]), k=3)
    upper = make_interp_spline(knots, np.array(
        [[-35, -18, 30], [-18, 2, 31], [4, 16, 30], [18, 12, 28], [38, -4, 30], [52, -14, 31.0]]),
        k=3)
    P, top = lower(s), upper(s)
    return ToolPath(P=P, O=(top - P) / np.linalg.norm(top - P, axis=1, keepdims=True))
