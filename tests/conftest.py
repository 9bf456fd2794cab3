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


class AnalyticAxis:
    """A smooth rest-to-rest axis motion start + travel*ramp(s) + wiggle*bump(s)*sin(2 pi f t),
    s = t / duration, with exact derivatives (numpy.polynomial and the Leibniz rule)."""

    def __init__(self, duration, start, travel, wiggle, freq):
        from numpy.polynomial import Polynomial as Poly

        ramp = Poly([0, 0, 0, 0, 35, -84, 70, -20])
        bump = Poly([0, 0, 0, 0, 1]) * Poly([1, -1]) ** 4 * 256   # zero v, a, j at both ends
        self.duration, self.start, self.travel, self.wiggle, self.freq = (
            duration, start, travel, wiggle, freq)
        self.ramp = [ramp.deriv(k) if k else ramp for k in range(4)]
        self.bump = [bump.deriv(k) if k else bump for k in range(4)]

    def __call__(self, t, k=0):
        """k-th time derivative at t (k = 0..3)."""
        from math import comb

        t = np.asarray(t, dtype=float)
        s = t / self.duration
        omega = 2 * np.pi * self.freq
        total = 0.0
        for i in range(k + 1):
            b = self.bump[i](s) / self.duration**i
            total = total + comb(k, i) * b * omega ** (k - i) * np.sin(omega * t + (k - i) * np.pi / 2)
        return self.start * (k == 0) + self.travel * self.ramp[k](s) / self.duration**k + self.wiggle * total


def analytic_axis(t, duration, start, travel, wiggle, freq):
    """(x, v, a, j) of :class:`AnalyticAxis` at t."""
    axis = AnalyticAxis(duration, start, travel, wiggle, freq)
    return tuple(axis(t, k) for k in range(4))
