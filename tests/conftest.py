"""Shared fixtures: the built-in machine and a smooth analytic five-axis trajectory."""

from __future__ import annotations

import numpy as np
import pytest

from precontour import load_machine


@pytest.fixture(scope="session")
def machine():
    return load_machine("zhang2013")


def smoothstep7(s):
    """C3 rest-to-rest ramp 0 -> 1 on s in [0, 1] (zero velocity, acceleration, jerk at ends)."""
    s = np.clip(s, 0.0, 1.0)
    return 35 * s**4 - 84 * s**5 + 70 * s**6 - 20 * s**7


def analytic_axis(t, duration, start, travel, wiggle, freq):
    """A smooth axis motion with its first three derivatives computed exactly (numpy.polynomial
    for the ramp, product rule for the wiggle), returned as (x, v, a, j)."""
    from numpy.polynomial import Polynomial as Poly

    ramp = Poly([0, 0, 0, 0, 35, -84, 70, -20])
    bump = Poly([0, 0, 0, 0, 1]) * Poly([1, -1]) ** 4 * 256   # zero v, a, j at both ends
    s = t / duration
    derivs = []
    for k in range(4):
        r = ramp.deriv(k)(s) / duration**k if k else ramp(s)
        # wiggle * bump(s) * sin(2 pi f t): Leibniz rule for the k-th derivative
        total = 0.0
        from math import comb
        for i in range(k + 1):
            b = bump.deriv(i)(s) / duration**i if i else bump(s)
            w = (2 * np.pi * freq) ** (k - i) * np.sin(2 * np.pi * freq * t + (k - i) * np.pi / 2)
            total = total + comb(k, i) * b * w
        derivs.append(start * (k == 0) + travel * r + wiggle * total)
    return tuple(derivs)
