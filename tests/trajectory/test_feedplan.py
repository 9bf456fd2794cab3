from dataclasses import replace

import numpy as np
import pytest

from precontour import load_machine
from precontour.trajectory.builtin_paths import builtin_path
from precontour.errors import PrecontourError
from precontour.trajectory.feedplan import _acceleration_passes, axis_limits, plan_feed
from precontour.trajectory.pathspline import fit_path, fit_toolpath

TS = 0.001
RTOL = 1e-9


@pytest.fixture(scope="module")
def machine():
    return load_machine("zhang2013")


def _check_limits(profile, machine, feed=100.0, acceleration=2000.0, jerk=50000.0,
                  feed_of_s=None):
    """Independent check of every limit on every sample with finite differences."""
    ts = profile.ts
    v, a, j = axis_limits(machine)
    q, P, s = profile.q, profile.P, profile.s
    assert np.all(np.abs(np.diff(q, axis=0)) / ts <= v * (1 + RTOL))
    assert np.all(np.abs(np.diff(q, 2, axis=0)) / ts**2 <= a * (1 + RTOL))
    assert np.all(np.abs(np.diff(q, 3, axis=0)) / ts**3 <= j * (1 + RTOL))
    tip_speed = np.linalg.norm(np.diff(P, axis=0), axis=1) / ts
    limit = feed if feed_of_s is None else feed_of_s(0.5 * (s[1:] + s[:-1]))
    assert np.all(tip_speed <= limit * (1 + RTOL) + 1e-9)
    assert np.all(np.linalg.norm(np.diff(P, 2, axis=0), axis=1) / ts**2
                  <= acceleration * (1 + RTOL))
    assert np.all(np.abs(np.diff(s, 3)) / ts**3 <= jerk * (1 + RTOL))
    assert np.all(np.diff(s) >= 0)
    # At rest at both ends, to within one sample of the jerk limit.
    for end in (np.diff(s[:3]), np.diff(s[-3:])):
        assert np.all(end / ts <= jerk * ts**2)


def test_acceleration_passes_match_brute_force():
    rng = np.random.default_rng(1)
    n, h = 300, 0.1
    v_lim = rng.uniform(5, 100, n)
    a_lim = rng.uniform(500, 3000, n)
    v = _acceleration_passes(v_lim.copy(), a_lim, h)
    sigma = np.concatenate([[0.0], np.cumsum(0.5 * (a_lim[1:] + a_lim[:-1]) * h)])
    v2 = v_lim**2
    v2[0] = v2[-1] = 0
    brute = np.array([min(v2[k] + 2 * abs(sigma[i] - sigma[k]) for k in range(n))
                      for i in range(n)])
    np.testing.assert_allclose(v**2, np.minimum(brute, v2), rtol=1e-12, atol=1e-9)
    # Consecutive squared speeds change by at most 2 * integral of a_lim (the passes' bound).
    assert np.all(np.abs(np.diff(v**2)) <= 2 * np.diff(sigma) * (1 + 1e-12))


@pytest.mark.parametrize("name", ["paper", "cone"])
def test_all_limits_hold_on_every_sample(machine, name):
    profile = plan_feed(fit_toolpath(builtin_path(name)), machine)
    _check_limits(profile, machine)
    assert profile.s[0] == 0 and abs(profile.s[-1] - fit_toolpath(builtin_path(name)).length) < 1e-9
    np.testing.assert_allclose(profile.t, np.arange(profile.t.size) * TS)


def test_tight_axis_limits_are_respected_and_slow_the_path(machine):
    path = fit_toolpath(builtin_path("paper"))
    fast = plan_feed(path, machine)
    drives = list(machine.drives)
    drives[4] = replace(drives[4], v_max=0.8, a_max=10.0, j_max=200.0)
    drives[3] = replace(drives[3], v_max=0.8)
    slow_machine = replace(machine, drives=tuple(drives))
    slow = plan_feed(path, slow_machine)
    _check_limits(slow, slow_machine)
    assert slow.t[-1] > fast.t[-1] * 1.2
    assert np.abs(np.diff(slow.q[:, 4])).max() / TS > 0.7  # the C limit is actually reached


def test_programmed_feed_is_respected(machine):
    u = np.linspace(0, 1, 101)
    P = np.stack([200 * u, 20 * np.sin(3 * u), np.zeros_like(u)], axis=-1)
    O = np.tile([0.0, np.sin(0.3), np.cos(0.3)], (u.size, 1))
    feed = np.where(u <= 0.5, 40.0, np.nan)  # NaN: the maximum feed applies
    path = fit_path(P, O)
    profile = plan_feed(path, machine, programmed_feed=feed)
    s_half = path.s_points[50]
    _check_limits(profile, machine, feed_of_s=lambda s: np.where(s <= s_half, 40.0, 100.0))
    tip_speed = np.linalg.norm(np.diff(profile.P, axis=0), axis=1) / TS
    mid = 0.5 * (profile.s[1:] + profile.s[:-1])
    assert tip_speed[mid < s_half].max() > 38.0
    assert tip_speed[mid > s_half].max() > 90.0


def test_lower_feed_and_jerk_options(machine):
    path = fit_toolpath(builtin_path("circle"))
    profile = plan_feed(path, machine, feed=50.0, acceleration=800.0, jerk=10000.0)
    _check_limits(profile, machine, feed=50.0, acceleration=800.0, jerk=10000.0)
    assert profile.t[-1] > path.length / 50.0


@pytest.mark.parametrize("kwargs, match", [
    ({"feed": 0.0}, "feed must be positive and finite, got 0.0"),
    ({"ts": -1.0}, "ts must be positive and finite"),
    ({"jerk": np.inf}, "jerk must be positive and finite"),
    ({"programmed_feed": np.r_[np.nan, -5.0, np.ones(498)]},
     "row 2, field 'feed': programmed feed must be positive, got -5 mm/s"),
    ({"programmed_feed": np.ones(7)},
     r"field 'feed': programmed feed must have one entry per point, got shape \(7,\)"),
    ({"grid_step": 0.0}, "grid_step must be positive and finite, got 0.0"),
])
def test_bad_arguments(machine, kwargs, match):
    with pytest.raises(ValueError, match=match):
        plan_feed(fit_toolpath(builtin_path("paper")), machine, **kwargs)


def test_singular_orientation_is_refused(machine):
    # The orientation passes through straight down (A = pi), where A-C trunnion A jumps.
    phi = np.linspace(2.6, 3.6, 41)
    P = np.stack([np.linspace(0, 40, 41), np.zeros(41), np.zeros(41)], axis=-1)
    O = np.stack([np.sin(phi), np.zeros(41), np.cos(phi)], axis=-1)
    with pytest.raises(PrecontourError, match="axis A jumps by .* rad within .* mm near s = .*singular direction"):
        plan_feed(fit_path(P, O), machine)


def test_runaway_duration_is_refused(machine):
    with pytest.raises(PrecontourError, match="more than 1000 samples"):
        plan_feed(fit_toolpath(builtin_path("paper")), machine, max_samples=1000)


@pytest.mark.parametrize("name, tilt", [("zhang2013", "A"), ("head-table-bc", "B")])
def test_c_jump_too_close_to_vertical_is_refused(name, tilt):
    # Passing 1e-6 rad from vertical: C would turn half a revolution within one grid step;
    # the message names the machine's own tilt axis
    machine = load_machine(name)
    u = np.linspace(0, 1, 41)
    phi = 0.5 - u
    P = np.stack([60 * u, np.zeros_like(u), np.zeros_like(u)], axis=-1)
    O = np.stack([np.sin(phi), np.full_like(u, 1e-6), np.cos(phi)], axis=-1)
    O /= np.linalg.norm(O, axis=1)[:, None]
    with pytest.raises(PrecontourError, match=f"axis C jumps by .* too close to {tilt} = 0"):
        plan_feed(fit_path(P, O), machine)


def test_erode_matches_brute_force():
    """Each point's value reaches the points within its band's speed * reach (speed rounded
    up to a power-of-two fraction of the fastest), checked point by point."""
    from precontour.trajectory.feedplan import _erode
    rng = np.random.default_rng(5)
    for trial in range(40):
        n = int(rng.integers(1, 300))
        speed = rng.uniform(0.0, 100.0, n) * (rng.random(n) < 0.9)
        values = rng.normal(size=n)
        reach, h = rng.uniform(0.001, 0.2), rng.uniform(0.01, 0.5)
        expected = values.copy()
        moving = speed[speed > 0]
        if moving.size:
            fastest = moving.max()
            for k in np.flatnonzero(speed > 0):
                level = fastest
                while speed[k] <= 0.5 * level:
                    level *= 0.5
                width = int(np.ceil(level * reach / h))
                lo, hi = max(0, k - width), min(n, k + width + 1)
                expected[lo:hi] = np.minimum(expected[lo:hi], values[k])
        np.testing.assert_array_equal(_erode(values, speed, reach, h), expected)


def _violation_reference(s, P, q, ts, feed_here, lim):
    """The check's ratios with numpy: each difference folded onto the samples it touches."""
    ratio = np.zeros(s.size - 2)

    def fold(values, limit, order, offset):
        r = ((np.abs(values) / limit) ** (1.0 / order)).reshape(values.shape[0], -1).max(axis=1)
        np.maximum.at(ratio, np.clip(np.arange(r.size) + offset, 0, ratio.size - 1), r)

    vP = np.linalg.norm(np.diff(P, axis=0), axis=1) / ts
    for offset in (-1, 0):
        fold(vP / np.minimum(feed_here[:-1], feed_here[1:]), 1.0, 1, offset)
        fold(np.diff(s) / ts, lim.feed, 1, offset)
        fold(np.diff(q, axis=0) / ts / lim.v, 1.0, 1, offset)
    fold(np.linalg.norm(np.diff(P, 2, axis=0), axis=1) / ts**2, lim.acceleration, 2, 0)
    fold(np.diff(s, 3) / ts**3, lim.jerk, 3, 0)
    fold(np.diff(q, 2, axis=0) / ts**2 / lim.a, 1.0, 2, 0)
    fold(np.diff(q, 3, axis=0) / ts**3 / lim.j, 1.0, 3, 0)
    fold(np.diff(q, 3, axis=0) / ts**3 / lim.j, 1.0, 3, 1)
    return ratio


def test_violation_ratios_match_numpy(machine):
    from precontour.trajectory.feedplan import _Limits, _violation
    rng = np.random.default_rng(2)
    n = 500
    s = np.cumsum(rng.uniform(0.0, 0.12, n))
    P = np.cumsum(rng.normal(scale=0.05, size=(n, 3)), axis=0)
    q = np.cumsum(rng.normal(scale=0.05, size=(n, 5)), axis=0)
    s_grid = np.linspace(0.0, s[-1] + 1.0, 400)
    feed_of_s = rng.uniform(20.0, 100.0, s_grid.size)
    lim = _Limits(100.0, 2000.0, 50000.0, *axis_limits(machine))
    ratio = _violation(s, P, q, TS, feed_of_s, s_grid, lim)
    feed_here = feed_of_s[np.clip(np.rint(s / s_grid[1]).astype(int), 0, s_grid.size - 1)]
    np.testing.assert_allclose(ratio, _violation_reference(s, P, q, TS, feed_here, lim),
                               rtol=1e-14)
    assert ratio.max() > 1.0


def test_limit_curves_match_numpy_gradients(machine):
    """The compiled limit curves take the axes' derivatives as numpy.gradient would."""
    from precontour.trajectory.feedplan import (CURVATURE_SHARE, MARGIN, _acceleration_limit,
                                                _first_jump, _speed_limit)
    rng = np.random.default_rng(4)
    n, h = 700, 0.05
    q = np.cumsum(np.cumsum(rng.normal(scale=1e-3, size=(n, 5)), axis=0), axis=0)
    q[:, 2] = 1.0                                   # an axis that does not move
    dP, ddP = rng.uniform(0.5, 1.0, n), rng.uniform(0.0, 0.1, n)
    feed_of_s = rng.uniform(20.0, 100.0, n)
    v, a, j = axis_limits(machine)
    cap = _speed_limit(dP, ddP, q, h, feed_of_s, 100.0, 2000.0, v, a, j, MARGIN,
                       CURVATURE_SHARE)
    dq = np.abs(np.gradient(q, h, axis=0))
    ddq = np.abs(np.gradient(np.gradient(q, h, axis=0), h, axis=0))
    dddq = np.abs(np.gradient(np.gradient(np.gradient(q, h, axis=0), h, axis=0), h, axis=0))
    m, c = MARGIN, CURVATURE_SHARE
    with np.errstate(divide="ignore", invalid="ignore"):
        expected = np.minimum.reduce([
            np.full(n, 100.0), feed_of_s / dP, np.sqrt(c * m * 2000.0 / ddP),
            np.min(m * v / dq, axis=1), np.min(np.sqrt(c * m * a / ddq), axis=1),
            np.min(np.cbrt(c * m * j / dddq), axis=1)])
        np.testing.assert_allclose(cap, expected, rtol=1e-14)
        left = np.where(np.isnan((m * a - ddq * cap[:, None] ** 2) / dq), np.inf,
                        (m * a - ddq * cap[:, None] ** 2) / dq)
        expected_a = np.minimum(m * 2000.0 - ddP * cap**2, left.min(axis=1))
    np.testing.assert_allclose(_acceleration_limit(ddP, q, h, cap, 2000.0, a, m), expected_a,
                               rtol=1e-14)
    q[300, 4] += 2.5                                # C jumps by 2.5 rad at one grid point
    row, axis, step = _first_jump(q, h, 3, 1.0)
    assert (row, axis) == (299, 4) and step == pytest.approx(
        abs(np.gradient(q[:, 4], h)[299]) * h)


def test_grid_points_do_not_depend_on_round_off():
    """A short path gets 2000 steps whether or not L / (L / 2000) rounds above 2000 (this
    length's does, which once gave the built-in `fan` one grid point more)."""
    from precontour.trajectory.feedplan import grid_points
    length = 81.98218436861193
    assert length / (length / 2000.0) > 2000.0
    assert grid_points(length, 100.0, TS) == 2001
    assert grid_points(1000.0, 100.0, TS) == 20001
    assert grid_points(1000.0, 100.0, TS, grid_step=0.3) == 3335
    with pytest.raises(ValueError, match="grid_step"):
        grid_points(1000.0, 100.0, TS, grid_step=-1.0)
